"""State-space ARMA, Kalman filter and the sliding-window LM graph smoother vs filterpy's RTS smoother."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, rts_smoother

from analysis.drift.arma import arma_acvf, simulate_arma
from analysis.drift.preprocess import DriftInputError
from analysis.drift.smoother import (
    arma_state_space,
    kalman_filter,
    lm_window,
    sliding_window_smoother,
    steady_state_filter,
)

MODELS = [([0.9], [0.4]), ([0.9], [-0.4]), ([0.5, 0.3], [0.2]), ([1.2, -0.4, 0.1], [0.3, -0.2, 0.1]), ([0.7], [])]


def _filterpy(ss, z, x0, P0):
    kf = KalmanFilter(dim_x=ss.m, dim_z=1)
    kf.F, kf.H, kf.Q, kf.R = ss.F, ss.H, ss.Q, np.array([[ss.R]])
    kf.x, kf.P = np.array(x0, dtype=float).copy(), np.array(P0, dtype=float).copy()
    mu, cov, _, _ = kf.batch_filter(z)
    xs, _, _, _ = rts_smoother(mu, cov, [ss.F] * len(z), [ss.Q] * len(z))
    return mu.reshape(len(z), ss.m), xs.reshape(len(z), ss.m)


def test_state_space_reproduces_arma_autocovariance() -> None:
    phi, theta = [1.2, -0.4, 0.1], [0.3, -0.2, 0.1]
    ss = arma_state_space(phi, theta, 2.0, 1.0, process_floor=1e-12)
    gam = arma_acvf(phi, theta, 2.0, 5)
    for k in range(6):  # Cov(d_{t+k}, d_t) = H F^k P0 Hᵀ
        assert abs((ss.H @ np.linalg.matrix_power(ss.F, k) @ ss.P0 @ ss.H.T).item() - gam[k]) < 1e-8 * gam[0]
    assert ss.m == 4  # max(p, q + 1)


@pytest.mark.parametrize("phi,theta", MODELS)
def test_lm_graph_equals_rts_smoother(phi: list[float], theta: list[float]) -> None:
    """Spec: the LM graph solution equals the RTS smoother to 1e-6 (full record as one window)."""
    rng = np.random.default_rng(50)
    ss = arma_state_space(phi, theta, 1.0, 0.5)
    z = simulate_arma(phi, theta, 1.0, 600, rng) + np.sqrt(0.5) * rng.standard_normal(600)
    mu, xs = _filterpy(ss, z, ss.x0, ss.P0)
    kf = kalman_filter(ss, z)
    np.testing.assert_allclose(kf.x, mu, atol=1e-10)
    res = lm_window(ss, z, kf.x_pred[0], kf.P_pred[0])
    assert res.iterations > 1  # damped iterations, not one linear solve
    np.testing.assert_allclose(res.x, xs, rtol=0, atol=1e-6)
    sm = sliding_window_smoother(ss, z, window=10_000, stride=10_000)
    np.testing.assert_allclose(sm.x, xs, rtol=0, atol=1e-6)


def test_sliding_windows_equal_rts_of_each_window() -> None:
    """Each window with its Kalman prior equals filterpy's RTS on that window started from the same filter state."""
    rng = np.random.default_rng(51)
    phi, theta = [0.5, 0.3], [0.2]
    ss = arma_state_space(phi, theta, 1.0, 0.3)
    z = simulate_arma(phi, theta, 1.0, 1000, rng) + np.sqrt(0.3) * rng.standard_normal(1000)
    kf = kalman_filter(ss, z)
    k0, k1 = 400, 700
    _, xs = _filterpy(ss, z[k0:k1], kf.x[k0 - 1], kf.P[k0 - 1])
    res = lm_window(ss, z[k0:k1], kf.x_pred[k0], kf.P_pred[k0])
    np.testing.assert_allclose(res.x, xs, rtol=0, atol=1e-6)
    sm = sliding_window_smoother(ss, z, window=300, stride=100)
    np.testing.assert_allclose(sm.x[k0 : k0 + 100], xs[:100], rtol=0, atol=1e-6)
    # fixed-lag windows approach the full smoother away from the window ends
    _, full = _filterpy(ss, z, ss.x0, ss.P0)
    assert np.max(np.abs(sm.x[:800, 0] - full[:800, 0])) < 1e-3 * np.std(z)


def test_steady_state_filter_and_compensation() -> None:
    rng = np.random.default_rng(52)
    phi, theta = [0.9], [-0.4]
    ss = arma_state_space(phi, theta, 1.0, 1e-3)
    z = simulate_arma(phi, theta, 1.0, 20000, rng) + np.sqrt(1e-3) * rng.standard_normal(20000)
    xs, pred = steady_state_filter(ss, z)
    kf = kalman_filter(ss, z[:3000])
    np.testing.assert_allclose(xs[200:3000], kf.x[200:], atol=1e-9)
    # one-step prediction residual ≈ innovation σ (R small): the predictable part of the drift is removed
    after = float(np.std(z[100:] - pred[100:]))
    assert abs(after - 1.0) < 0.03 and float(np.std(z)) > 1.5


def test_state_space_errors() -> None:
    with pytest.raises(DriftInputError, match="stationary"):
        arma_state_space([1.0], [], 1.0, 1.0)
    with pytest.raises(DriftInputError):
        arma_state_space([0.5], [], 1.0, 0.0)
    with pytest.raises(DriftInputError, match="window"):
        sliding_window_smoother(arma_state_space([0.5], [], 1.0, 1.0), np.zeros(10), window=1)
