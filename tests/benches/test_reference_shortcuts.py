"""What the identification's reference does once instead of twice (issue 32) gives what doing it twice gave, bit
for bit: a hold's constant reported rates filled instead of interpolated (benches.reference._interp against
np.interp), a spin's body rate formed once from its angle-over-time rate (window_reference against the reference
with reported rates and the body rate formed again afterwards, with its own sines and cosines), at rest and
spinning, and the largest |ω| of a window (benches.identify._max_norm against np.linalg.norm)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from analysis.gimbal import body_rate, table_to_nav
from benches.identify import _max_norm, angle_over_time, window_reference
from benches.reference import _interp, acquisition_span, earth_in_body, reference_for_window


def _bits(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


def _same(a, b) -> bool:
    return np.shape(a) == np.shape(b) and np.array_equal(_bits(a), _bits(b))


@pytest.mark.parametrize("value", [0.0, -0.0, 1.5, -2e-3, 7e300, np.nan, "mixed zeros", "one differs"])
def test_constant_readings_give_what_np_interp_gives(value) -> None:
    rng = np.random.default_rng(21)
    for n in (1, 2, 50):
        xp = np.sort(rng.uniform(0.0, 10.0, n))
        if n > 2:
            xp[5] = xp[4]  # two readings at one time
        if value == "mixed zeros":
            fp = np.where(rng.random(n) < 0.5, -0.0, 0.0)
        elif value == "one differs":
            fp = np.full(n, 0.25)
            fp[-1] = np.nextafter(0.25, 1.0)
        else:
            fp = np.full(n, value)
        x = np.concatenate([rng.uniform(-1.0, 11.0, 500), xp, [np.nan, -np.inf, np.inf]])
        table = np.column_stack([fp, fp, fp])  # a strided column, as the rule passes it
        assert _same(_interp(x, xp, table[:, 1]), np.interp(x, xp, fp)), (value, n)


def _bench(mounting):
    return SimpleNamespace(unit=SimpleNamespace(mounting=mounting), site=SimpleNamespace(g=9.80665, latitude=0.7))


@pytest.mark.parametrize("spinning", [False, True])
@pytest.mark.parametrize("mounted", [False, True])
def test_window_reference_is_the_reference_then_the_spins_body_rate(spinning: bool, mounted: bool) -> None:
    """window_reference = reference_for_window with the reported rates, then (a spin) the body rate formed again
    from the encoder angles' rate and the angles' own sines and cosines: the same f_ref, ω, angles and Earth
    rate, bit for bit, on random attitudes at rest and spinning."""
    rng = np.random.default_rng(22 + 2 * spinning + mounted)
    mounting = table_to_nav(np.array([0.1, -0.2, 0.3])) if mounted else None
    tt = np.cumsum(rng.uniform(0.008, 0.012, 400))
    rate = rng.normal(0.0, 1.5, 3) if spinning else np.zeros(3)
    ta = rng.uniform(-3.0, 3.0, 3) + tt[:, None] * rate + rng.normal(0.0, 1e-5, (tt.size, 3))
    tr = np.broadcast_to(rate, ta.shape).copy()
    t = np.arange(tt[20], tt[-20], 0.001)
    lat, fs, clock = 0.002, 1000.0, 3e-6
    span = acquisition_span(float(t[0]), float(t[-1]), lat, fs)
    cfg = _bench(mounting)
    fr, om, ang, earth = window_reference(t, tt, ta, tr, cfg, lat, span, spinning, clock, True)
    f0, w0, a0, _, _ = reference_for_window(t, tt, ta, tr, g=cfg.site.g, mounting=mounting, latency=lat, span=span)
    if spinning:
        slope = angle_over_time(t, tt, ta, span) * (1.0 + clock)
        w0 = body_rate(a0, np.broadcast_to(slope, a0.shape), mounting)
    assert _same(fr, f0) and _same(om, w0) and _same(ang, a0)
    assert _same(earth, earth_in_body(a0, cfg.site.latitude, mounting))


def test_max_norm_is_the_largest_norm() -> None:
    rng = np.random.default_rng(23)
    for w in (rng.normal(0.0, 2.0, (5000, 3)), np.where(rng.random((50, 3)) < 0.5, -0.0, 0.0), rng.normal(size=(1, 3))):
        assert _same(_max_norm(w), float(np.max(np.linalg.norm(w, axis=1))))
