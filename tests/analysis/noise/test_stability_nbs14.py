"""NBS14 10-point set (tests/data/noise/nbs14/README.md): every estimator at τ = 1, 2 from phase and from
frequency data equals the printed NIST SP 1065 / Stable32 values to their 5–7 digits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.noise.stability import stability
from tests import REPO_ROOT

DATA = REPO_ROOT / "tests" / "data" / "noise" / "nbs14" / "values.txt"


def _load() -> tuple[np.ndarray, np.ndarray, dict[str, tuple[float, float]]]:
    phase = freq = None
    ref = {}
    for line in DATA.read_text(encoding="utf-8").splitlines():
        if line.startswith("# phase:"):
            phase = np.array(line.split(":")[1].split(), dtype=float)
        elif line.startswith("# freq:"):
            freq = np.array(line.split(":")[1].split(), dtype=float)
        elif line and not line.startswith("#"):
            name, a, b = line.split()
            ref[name] = (float(a), float(b))
    return phase, freq, ref


PHASE, FREQ, REF = _load()


@pytest.mark.parametrize("name", sorted(REF))
@pytest.mark.parametrize("data_type", ["phase", "freq"])
def test_nbs14(name: str, data_type: str) -> None:
    data = PHASE if data_type == "phase" else FREQ
    res = stability(data, 1.0, (name,), [1.0, 2.0], data_type, confidence=None)
    est = res.estimates[name]
    expect = list(REF[name])
    if name == "htotdev":  # the printed τ = 2 value carries the white-FM bias correction 1/√0.995
        expect[1] *= math.sqrt(0.995)
    np.testing.assert_array_equal(est.m, [1, 2])
    np.testing.assert_allclose(est.dev[:, 0], expect, rtol=1e-4)
