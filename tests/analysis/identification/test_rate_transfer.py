"""Rate-transfer figures (IEEE Std 952/1431 definitions) against independent computations."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.rate_transfer import rate_transfer_axis
from analysis.units import DEG, PPM


def test_line_nonlinearity_and_asymmetry_against_numpy_fits() -> None:
    rng = np.random.default_rng(2)
    x = np.array([1, -1, 3, -3, 10, -10, 30, -30, 100, -100, 300, -300], dtype=float) * DEG
    x = np.concatenate([[5e-5, 5e-5], x])  # two holds (Earth rate along the axis)
    y = 1e-6 + (1 + 60 * PPM) * x + 0.2 * PPM / DEG * x**2 + 40 * PPM * np.abs(x)
    u = np.full(x.size, 1e-7)
    r = rate_transfer_axis("z", x, y, u)
    k, b = np.polyfit(x, y, 1)  # equal weights: the same straight line
    res = y - (k * x + b)
    assert r.scale_factor == pytest.approx(k, rel=1e-12) and r.bias == pytest.approx(b, abs=1e-15)
    assert r.nonlinearity_ppm == pytest.approx(np.max(np.abs(res)) / (abs(k) * np.max(np.abs(x))) * 1e6, rel=1e-9)
    # asymmetry from the two half-range slopes with one common bias, solved independently
    a = np.column_stack([np.ones_like(x), np.where(x > 0, x, 0), np.where(x > 0, 0, x)])
    _, kp, kn = np.linalg.lstsq(a, y, rcond=None)[0]
    assert r.asymmetry_ppm == pytest.approx((kp - kn) / (0.5 * (kp + kn)) * 1e6, rel=1e-9)
    # u by propagation equals the Monte Carlo scatter of the figures
    draws = [rate_transfer_axis("z", x, y + rng.normal(0, u), u) for _ in range(400)]
    assert np.std([d.asymmetry_ppm for d in draws]) == pytest.approx(r.u_asymmetry_ppm, rel=0.15)
    assert np.std([d.scale_factor for d in draws]) == pytest.approx(r.u_scale_factor, rel=0.15)


def test_refuses_one_direction_or_too_few_points() -> None:
    with pytest.raises(ValueError, match="both signs"):
        rate_transfer_axis("x", [1, 2, 3, 4], [1, 2, 3, 4], [1, 1, 1, 1])
    with pytest.raises(ValueError, match="at least 4"):
        rate_transfer_axis("x", [1, -1], [1, -1], [1, 1])
