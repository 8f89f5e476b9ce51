"""Drift pre-processing: outlier replacement (3σ, MAD), detrending, input checks (docs/methods/drift.md)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.drift.arma import simulate_arma
from analysis.drift.preprocess import DriftInputError, check_series, detrend, remove_tones, replace_outliers


@pytest.mark.parametrize("method", ["sigma", "mad"])
def test_outliers_at_10_sigma_are_removed(method: str) -> None:
    """Spec: ≥ 99 % of outliers injected at 10σ are removed (white and coloured records)."""
    rng = np.random.default_rng(10)
    found = injected = 0
    for coloured in (False, True):
        for _ in range(10):
            n = 20000
            x = simulate_arma([0.9], [-0.4], 1.0, n, rng) if coloured else rng.standard_normal(n)
            sd = float(np.std(x))
            idx = rng.choice(np.arange(1, n), size=100, replace=False)
            x[idx] += 10.0 * sd * rng.choice([-1.0, 1.0], size=idx.size)
            res = replace_outliers(x, 3.0, method)
            found += int(res.mask[idx].sum())
            injected += idx.size
            # replaced with the previous retained sample
            k = idx[~res.mask[idx - 1]][0]
            assert res.cleaned[k] == x[k - 1]
    assert found / injected >= 0.99


def test_outlier_count_and_scales() -> None:
    rng = np.random.default_rng(1)
    x = rng.standard_normal(10000)
    x[[100, 101, 5000]] = [50.0, -60.0, 80.0]
    sig = replace_outliers(x, 3.0, "sigma")
    mad = replace_outliers(x, 3.0, "mad")
    assert sig.mask[[100, 101, 5000]].all() and mad.mask[[100, 101, 5000]].all()
    # consecutive outliers take the last retained value
    assert sig.cleaned[101] == x[99] and sig.cleaned[100] == x[99]
    assert sig.replaced == int(sig.mask.sum())
    assert abs(mad.scale - 1.0) < 0.05 and abs(sig.scale - 1.0) < 0.05
    assert sig.iterations >= 2  # the first pass σ is inflated by the outliers


def test_detrend_recovers_polynomial_and_order() -> None:
    rng = np.random.default_rng(2)
    rate = 10.0
    t = np.arange(20000) / rate
    trend = 1e-3 + 2e-6 * t - 3e-10 * t**2
    x = trend + 1e-4 * rng.standard_normal(t.size)
    res = detrend(x, rate)
    assert res.order == 2
    np.testing.assert_allclose(res.coefficients, [1e-3, 2e-6, -3e-10], rtol=0.05, atol=3e-6)
    np.testing.assert_allclose(res.trend, trend, atol=1e-5)
    fixed = detrend(x, rate, order=1)
    assert fixed.order == 1 and fixed.criteria == {}
    assert abs(float(np.mean(detrend(x, rate, order=0).residual))) < 1e-15


def test_remove_tones_fits_frequency_and_amplitude() -> None:
    rng = np.random.default_rng(3)
    rate = 100.0
    t = np.arange(30000) / rate
    x = 0.3 * np.cos(2 * np.pi * 7.31 * t + 0.4) + 0.1 * rng.standard_normal(t.size)
    y, fits = remove_tones(x, rate, [7.3], 0.1)
    assert abs(fits[0].frequency_hz - 7.31) < 1e-3
    assert abs(fits[0].amplitude - 0.3) < 0.01 and abs(fits[0].phase - 0.4) < 0.05
    assert abs(float(np.std(y)) - 0.1) < 0.005


def test_bad_series_get_clear_errors() -> None:
    with pytest.raises(DriftInputError, match="constant"):
        check_series(np.full(100, 3.0))
    x = np.random.default_rng(0).standard_normal(100)
    x[7] = np.nan
    with pytest.raises(DriftInputError, match="NaN.*sample 7"):
        check_series(x)
    with pytest.raises(DriftInputError, match="at least 16"):
        check_series(np.arange(5.0))
    with pytest.raises(DriftInputError, match="order"):
        detrend(np.arange(100.0) ** 1.5, order=80)
    with pytest.raises(DriftInputError, match="method"):
        replace_outliers(np.arange(100.0), method="iqr")
