"""Frequency-drift removal before the deviations (analysis/noise/drift_removal.py), against numpy's least squares
and allantools' polynomial detrend."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.noise.drift_removal import remove_drift
from analysis.noise.terms import analyse_noise


@pytest.mark.parametrize(("model", "data_type", "degree"),
                         [("linear", "freq", 1), ("quadratic", "freq", 2), ("linear", "phase", 2),
                          ("quadratic", "phase", 3)])  # fmt: skip
def test_residual_equals_allantools_detrend(model: str, data_type: str, degree: int) -> None:
    """allantools.ci.detrend (np.polyfit of that degree on the sample index, as its noise identification uses):
    the same residual to 1e-9 of the record (a linear frequency drift is a quadratic phase)."""
    from allantools import ci

    rng = np.random.default_rng(degree + 10)
    n = 10_000
    t = np.arange(n) / 20.0
    y = rng.normal(0.0, 1e-3, n) + 2e-5 * t + 3e-8 * t**2 + (4e-11 * t**3 if data_type == "phase" else 0.0) + 0.5
    res, _ = remove_drift(y, 20.0, model, data_type)
    np.testing.assert_allclose(res, ci.detrend(y, degree), rtol=0, atol=1e-9 * np.abs(y).max())


@pytest.mark.parametrize(("model", "order"), [("linear", 1), ("quadratic", 2)])
@pytest.mark.parametrize("data_type", ["freq", "phase"])
def test_removed_polynomial_equals_numpy_lstsq(model: str, order: int, data_type: str) -> None:
    rng = np.random.default_rng(order)
    rate, n = 10.0, 5000
    t = np.arange(n) / rate
    y = 1e-3 + 2e-6 * t - 3e-9 * t**2 + rng.normal(0.0, 1e-4, n)
    if data_type == "phase":
        y = np.cumsum(y) / rate
    y[100:110] = np.nan
    res, coef = remove_drift(y, rate, model, data_type)
    k = order + (data_type == "phase")
    ok = np.isfinite(y)
    span = t[-1]  # the reference in scaled time u = t/span (well conditioned), converted back per power of t
    a = np.vander(t[ok] / span, k + 1, increasing=True)
    ref_u, *_ = np.linalg.lstsq(a, y[ok], rcond=None)
    ref = ref_u / span ** np.arange(k + 1)
    np.testing.assert_allclose(coef, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    np.testing.assert_allclose(res[ok], y[ok] - a @ ref_u, rtol=0, atol=1e-9 * np.abs(y[ok]).max())
    assert np.isnan(res[100:110]).all()


def test_linear_drift_removed_leaves_the_white_noise_terms() -> None:
    rng = np.random.default_rng(5)
    rate, n = 20.0, 40_000
    w = rng.normal(0.0, 1e-3, n)
    ramp = 5e-7 * np.arange(n) / rate
    plain = analyse_noise({"g": w}, rate)["channels"]["g"]
    drifted = analyse_noise({"g": w + ramp}, rate)["channels"]["g"]
    fixed = analyse_noise({"g": w + ramp}, rate, remove_drift="linear")
    ch = fixed["channels"]["g"]
    assert fixed["remove_drift"] == "linear" and ch["drift_removed"]["coefficients"][1] == pytest.approx(5e-7, rel=0.05)
    assert drifted["oadev"][-3] > 2 * plain["oadev"][-3]  # the ramp dominates long τ before removal
    np.testing.assert_allclose(ch["oadev"][:-3], plain["oadev"][:-3], rtol=0.02)
