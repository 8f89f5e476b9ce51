"""The time-base sensitivities' one-pass interpolation of many windows against the reference function.

``benches.timebase._interpolate_windows`` must give exactly (to the last bit) what
``benches.reference.interpolate_table`` gives per window: inside a span, before and after its readings, with no
reading inside the span, and at reading times exactly.
"""

from __future__ import annotations

import numpy as np

from benches.reference import interpolate_table
from benches.timebase import _interpolate_windows


def test_same_bits_as_the_reference_function_per_window() -> None:
    rng = np.random.default_rng(7)
    tt = np.cumsum(rng.uniform(0.005, 0.02, 400))
    tt[50] = tt[49]  # a repeated time stamp
    angles = np.cumsum(rng.normal(0.0, 0.01, (400, 3)), axis=0)
    rates = rng.normal(0.0, 0.5, (400, 3))
    tq, spans = [], []
    for _ in range(40):
        a, b = np.sort(rng.uniform(tt[0] - 0.5, tt[-1] + 0.5, 2))
        if rng.random() < 0.2:  # a span between two readings: none inside it
            k = int(rng.integers(1, 399))
            a, b = tt[k] + 1e-4, tt[k] + 2e-4
        q = np.sort(rng.uniform(a - 0.1, b + 0.1, int(rng.integers(1, 60))))
        q[: min(3, q.size)] = tt[rng.integers(0, 400, min(3, q.size))]  # at reading times exactly
        tq.append(np.sort(q))
        spans.append((float(a), float(b)))
    ang, rat = _interpolate_windows(tq, spans, tt, angles, rates)
    ref = [interpolate_table(q, tt, angles, rates, s) for q, s in zip(tq, spans, strict=True)]
    np.testing.assert_array_equal(ang, np.concatenate([r[0] for r in ref]))
    np.testing.assert_array_equal(rat, np.concatenate([r[1] for r in ref]))
