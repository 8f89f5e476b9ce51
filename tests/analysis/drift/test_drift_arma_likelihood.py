"""Exact ARMA likelihood (analysis.drift.arma_likelihood) against a Kalman-filter reference and statsmodels."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import linalg

from analysis.drift.arma import simulate_arma
from analysis.drift.arma_likelihood import exact_residuals, presample_covariance

CASES = [
    ([0.9], [-0.4]),
    ([0.9], [0.4]),
    ([1.2, -0.5], [0.3]),
    ([0.5, 0.2, -0.1], [0.95, -0.1]),
    ([], [0.9]),
    ([0.7], []),
    ([0.6, 0.1, 0.05], [0.3, 0.2, -0.1]),
    ([0.9, 0.0], [0.999, 0.0]),  # near-unit MA root: long start-up transient
]


def kalman_minus_two_log_likelihood(x: np.ndarray, phi: np.ndarray, theta: np.ndarray) -> float:
    """Reference: prediction-error decomposition by the Kalman filter on Harvey's state-space form (σ² concentrated)."""
    p, q = phi.size, theta.size
    m = max(p, q + 1)
    T = np.zeros((m, m))
    T[:p, 0] = phi
    T[np.arange(m - 1), np.arange(1, m)] = 1.0
    G = np.zeros(m)
    G[0] = 1.0
    G[1 : 1 + q] = -theta
    P = linalg.solve_discrete_lyapunov(T, np.outer(G, G))
    a = np.zeros(m)
    v = np.empty(x.size)
    f = np.empty(x.size)
    for t in range(x.size):
        f[t] = P[0, 0]
        v[t] = x[t] - a[0]
        k = P[:, 0] / f[t]
        a = T @ (a + k * v[t])
        P = T @ (P - np.outer(k, P[0])) @ T.T + np.outer(G, G)
    n = x.size
    s2 = np.mean(v**2 / f)
    return n * (np.log(2 * np.pi * s2) + 1.0) + np.sum(np.log(f))


@pytest.mark.parametrize(("phi", "theta"), CASES)
def test_equals_kalman_prediction_error_decomposition(phi: list[float], theta: list[float]) -> None:
    rng = np.random.default_rng(70)
    ph, th = np.array(phi, float), np.array(theta, float)
    x = simulate_arma(ph if ph.size else [0.0], th if th.size else [0.0], 2.0, 1500, rng)
    ex = exact_residuals(x, ph, th)
    ref = kalman_minus_two_log_likelihood(x, ph, th)
    assert abs(ex.minus_two_log_likelihood() - ref) < 1e-8 * abs(ref)


@pytest.mark.parametrize(("phi", "theta"), CASES[:4])
def test_equals_statsmodels_loglike(phi: list[float], theta: list[float]) -> None:
    from statsmodels.tsa.arima.model import ARIMA

    rng = np.random.default_rng(71)
    ph, th = np.array(phi, float), np.array(theta, float)
    x = simulate_arma(ph if ph.size else [0.0], th if th.size else [0.0], 2.0, 3000, rng)
    ex = exact_residuals(x, ph, th)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ll = ARIMA(x, order=(ph.size, 0, th.size), trend="n").loglike(np.r_[ph, -th, ex.sigma2])
    assert abs(-0.5 * ex.minus_two_log_likelihood() - ll) < 1e-6 * abs(ll)


def test_presample_covariance_matches_simulation() -> None:
    """Σ_u of (x_{t−1}, x_{t−2}, e_{t−1}) for ARMA(2,1) against the sample covariance of a long simulation."""
    rng = np.random.default_rng(72)
    phi, theta = np.array([1.2, -0.5]), np.array([0.3])
    n = 400_000
    e = rng.standard_normal(n + 1000)
    from scipy import signal

    x = signal.lfilter(np.r_[1.0, -theta], np.r_[1.0, -phi], e)[1000:]
    e = e[1000:]
    u = np.stack([x[1:-1], x[:-2], e[1:-1]])
    emp = np.cov(u)
    theo = presample_covariance(phi, theta)
    np.testing.assert_allclose(emp, theo, atol=0.03 * np.max(np.abs(theo)))


def test_weighted_residuals_sum_to_effective_variance() -> None:
    rng = np.random.default_rng(73)
    x = simulate_arma([0.9], [-0.4], 1.0, 2000, rng)
    ex = exact_residuals(x, np.array([0.9]), np.array([-0.4]))
    r = ex.weighted()
    assert abs(r @ r - ex.n * ex.sigma2_eff) < 1e-9 * ex.n * ex.sigma2_eff
    assert ex.log_det > 0.0
