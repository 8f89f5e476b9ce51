"""Drift tests: sizes on white noise, power on drifting data, agreement with statsmodels (docs/methods/drift.md)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from analysis.drift.arma import simulate_arma
from analysis.drift.hypothesis_tests import (
    acf,
    correlation_bands,
    daniel_test,
    jarque_bera_test,
    ljung_box_test,
    pacf,
    reverse_arrangement_test,
    segment_stats,
    welch_tones,
)
from analysis.drift.preprocess import DriftInputError


def _rates(runs: int, seed: int) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    count = {"daniel": 0, "ra_mean": 0, "ra_msq": 0, "jb": 0}
    for _ in range(runs):
        x = rng.standard_normal(5000)
        count["daniel"] += daniel_test(x[:400]).rejected
        count["ra_mean"] += reverse_arrangement_test(segment_stats(x[:2000], 50, "mean")).rejected
        count["ra_msq"] += reverse_arrangement_test(segment_stats(x[2000:4000], 50, "mean_square")).rejected
        count["jb"] += jarque_bera_test(x).rejected
    return {k: v / runs for k, v in count.items()}


def test_white_noise_rejection_rates() -> None:
    """Spec: Daniel, reverse-arrangement and JB reject 5 % ± 1.5 % of white-noise runs (at α = 5 %)."""
    rates = _rates(2000, 20)
    for name, r in rates.items():
        assert 0.035 <= r <= 0.065, (name, r)


@pytest.mark.slow
def test_white_noise_rejection_rates_long() -> None:
    rates = _rates(10000, 21)
    for name, r in rates.items():
        assert 0.035 <= r <= 0.065, (name, r)


def test_tests_reject_drift() -> None:
    """Power: a linear trend, a variance ramp and a uniform distribution are detected."""
    rng = np.random.default_rng(3)
    n = 5000
    x = rng.standard_normal(n)
    ramp = x + np.linspace(0.0, 0.5, n)
    assert daniel_test(segment_stats(ramp, 50)).rejected
    assert reverse_arrangement_test(segment_stats(ramp, 50)).rejected
    growing = x * np.linspace(0.5, 1.5, n)
    assert reverse_arrangement_test(segment_stats(growing, 50, "mean_square")).rejected
    assert not reverse_arrangement_test(segment_stats(growing, 50, "mean")).rejected
    assert jarque_bera_test(rng.uniform(-1, 1, n)).rejected


def test_reverse_arrangement_counts_and_daniel_formula() -> None:
    z = np.array([5.0, 3.0, 4.0, 1.0, 2.0])
    r = reverse_arrangement_test(z)
    assert r.extra["A"] == 8  # (5>3,4,1,2)=4, (3>1,2)=2, (4>1,2)=2
    big = np.random.default_rng(0).standard_normal(5000)
    assert reverse_arrangement_test(big).extra["A"] == reverse_arrangement_test(big[:5000].copy()).extra["A"]
    x = np.random.default_rng(1).standard_normal(300) + np.linspace(0, 0.3, 300)
    d = daniel_test(x)
    q = stats.spearmanr(np.arange(300), x).statistic
    assert abs(d.extra["spearman_q"] - q) < 1e-12
    assert abs(d.statistic - q * np.sqrt(298) / np.sqrt(1 - q * q)) < 1e-9


def test_inversion_count_large_matches_quadratic() -> None:
    from analysis.drift.hypothesis_tests import _inversions

    z = np.random.default_rng(2).standard_normal(700)
    brute = int(np.count_nonzero(np.triu(z[:, None] > z[None, :], k=1)))
    assert _inversions(z) == brute


def test_agreement_with_statsmodels() -> None:
    from statsmodels.stats.diagnostic import acorr_ljungbox
    from statsmodels.stats.stattools import jarque_bera
    from statsmodels.tsa.stattools import acf as sm_acf
    from statsmodels.tsa.stattools import pacf as sm_pacf

    rng = np.random.default_rng(4)
    x = simulate_arma([0.6, -0.2], [-0.3], 1.0, 3000, rng)
    np.testing.assert_allclose(acf(x, 30), sm_acf(x, nlags=30, fft=True), atol=1e-12)
    np.testing.assert_allclose(pacf(x, 20), sm_pacf(x, nlags=20, method="ywm"), atol=1e-10)
    jb = jarque_bera_test(x)
    sm_jb = jarque_bera(x)
    assert abs(jb.statistic - sm_jb[0]) < 1e-8 * sm_jb[0] and abs(jb.p_value - sm_jb[1]) < 1e-10
    assert abs(jb.threshold - 5.991) < 1e-3
    lb = ljung_box_test(x, lags=15, dof_used=3)
    sm_lb = acorr_ljungbox(x, lags=[15], model_df=3)
    assert abs(lb.statistic - float(sm_lb["lb_stat"].iloc[0])) < 1e-8 * lb.statistic
    assert abs(lb.p_value - float(sm_lb["lb_pvalue"].iloc[0])) < 1e-10


def test_correlation_bands() -> None:
    r = acf(np.random.default_rng(5).standard_normal(1000), 10)
    band = correlation_bands(1000, r)
    assert band.size == r.size and band[0] == 0.0
    assert abs(band[1] - 1.96 / np.sqrt(1000)) < 1e-3 and np.all(np.diff(band[1:]) >= 0)
    assert abs(correlation_bands(1000)[0] - 1.96 / np.sqrt(1000)) < 1e-3


def test_welch_tones_detects_and_locates() -> None:
    rng = np.random.default_rng(6)
    rate = 100.0
    t = np.arange(40000) / rate
    x = simulate_arma([0.9], [-0.4], 1.0, t.size, rng) + 1.0 * np.sin(2 * np.pi * 12.5 * t)
    r = welch_tones(x, rate)
    assert r.rejected and len(r.extra["frequencies"]) == 1
    assert abs(r.extra["frequencies"][0] - 12.5) <= rate / r.extra["nperseg"]
    assert abs(r.extra["tones"][0]["amplitude"] - 1.0) < 0.3


def test_welch_false_alarms_on_coloured_drift() -> None:
    """α = 1 % family-wise: smooth coloured spectra (steep near DC) must not produce tones."""
    rng = np.random.default_rng(7)
    alarms = 0
    runs = 0
    for phi in ([], [0.9], [0.99], [1.5, -0.7]):
        for _ in range(40):
            alarms += welch_tones(simulate_arma(phi, [-0.4] if phi else [], 1.0, 20000, rng), 100.0).rejected
            runs += 1
    assert alarms / runs <= 0.04


def test_errors() -> None:
    with pytest.raises(DriftInputError):
        reverse_arrangement_test([1.0, 2.0])
    with pytest.raises(DriftInputError, match="lags"):
        ljung_box_test(np.random.default_rng(0).standard_normal(100), lags=3, dof_used=4)
    with pytest.raises(DriftInputError):
        segment_stats(np.arange(10.0), 50)
