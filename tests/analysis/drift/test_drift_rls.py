"""Online RLS / extended LS (docs/methods/drift.md "Online"): equality with batch LS, accuracy, forgetting."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.drift.arma import fit_arma, simulate_arma
from analysis.drift.preprocess import DriftInputError
from analysis.drift.rls import OnlineArma, RecursiveLeastSquares, batch_least_squares, lag_matrix

# ML standard errors of ARMA(1,1), φ = 0.9, θ = −0.4 (statsmodels sign +0.4), per √(5000/n): spec values.
SE_PHI_5000, SE_THETA_5000 = 0.0064, 0.0136


def test_rls_equals_batch_least_squares_ar() -> None:
    """λ = 1: the recursion started from the batch fit of the first samples equals the batch fit of all."""
    rng = np.random.default_rng(40)
    x = simulate_arma([0.5, 0.2, -0.1], [], 1.0, 20000, rng)
    est = OnlineArma(3, 0).initialise(x[:500])
    est.feed(x[500:1234])
    for v in x[1234:1240]:
        est.update(float(v))  # single-sample path
    est.feed(x[1240:])
    batch, P = batch_least_squares(lag_matrix(x, 3, 3), x[3:])
    st = est.state()
    np.testing.assert_allclose(st.phi, batch, rtol=0, atol=1e-12)
    np.testing.assert_allclose(st.P, P, rtol=1e-9, atol=0)


def test_generic_rls_with_forgetting_equals_weighted_batch() -> None:
    rng = np.random.default_rng(41)
    n, n0, lam = 3000, 100, 0.995
    phi = rng.standard_normal((n, 4))
    y = phi @ np.array([1.0, -2.0, 0.5, 3.0]) + 0.1 * rng.standard_normal(n)
    rls = RecursiveLeastSquares.from_batch(phi[:n0], y[:n0], lam)
    for k in range(n0, n):
        rls.update(float(y[k]), phi[k])
    w = np.r_[np.full(n0, lam ** (n - n0)), lam ** (n - 1 - np.arange(n0, n))]
    ref = np.linalg.solve(phi.T @ (w[:, None] * phi), phi.T @ (w * y))
    np.testing.assert_allclose(rls.theta, ref, rtol=0, atol=1e-12)


def test_kernel_with_forgetting_equals_weighted_batch() -> None:
    rng = np.random.default_rng(42)
    x = simulate_arma([0.7, -0.2], [], 1.0, 5000, rng)
    n0, lam = 400, 0.998
    est = OnlineArma(2, 0, lam).initialise(x[:n0])
    est.feed(x[n0:])
    reg, tgt = lag_matrix(x, 2, 2), x[2:]
    t = np.arange(2, x.size)
    w = np.where(t < n0, lam ** (x.size - n0), lam ** (x.size - 1.0 - t))
    ref = np.linalg.solve(reg.T @ (w[:, None] * reg), reg.T @ (w * tgt))
    np.testing.assert_allclose(est.state().phi, ref, rtol=0, atol=1e-12)


def test_extended_ls_is_least_squares_on_its_own_residuals() -> None:
    """ELS = batch LS on [x lags, ε lags] once the a-posteriori residuals ε are fixed (to 1e-12)."""
    rng = np.random.default_rng(43)
    x = simulate_arma([0.9], [-0.4], 1.0, 20000, rng)
    n0 = 2000
    est = OnlineArma(1, 1).initialise(x[:n0])
    eps = np.r_[est.init_residuals, np.asarray(est.feed(x[n0:], record_residuals=True))]
    reg0, y0 = est.init_regression
    rows = np.stack([x[n0 - 1 : -1], eps[n0 - 1 : -1]], axis=1)
    reg = np.vstack([reg0, rows])
    coef, _ = batch_least_squares(reg, np.r_[y0, x[n0:]])
    st = est.state()
    np.testing.assert_allclose(np.r_[st.phi, -st.theta], coef, rtol=0, atol=1e-12)


def test_extended_ls_accuracy_arma11() -> None:
    """Spec: extended LS on ARMA(1,1), n = 2·10⁴, within 3σ (σ: ML standard errors scaled to n)."""
    rng = np.random.default_rng(44)
    n = 20000
    s = np.sqrt(5000 / n)
    for _ in range(10):
        x = simulate_arma([0.9], [-0.4], 1.0, n, rng)
        est = OnlineArma(1, 1).initialise(x[:1000])
        est.feed(x[1000:])
        st = est.state()
        assert abs(st.phi[0] - 0.9) < 3 * SE_PHI_5000 * s
        assert abs(st.theta[0] + 0.4) < 3 * SE_THETA_5000 * s


def test_online_converges_to_batch_on_30_minute_record() -> None:
    """30 min at 100 Hz fed sample by sample: the online estimate ends within a fraction of the batch SE."""
    rng = np.random.default_rng(45)
    x = simulate_arma([0.9], [-0.4], 4e-8, 180000, rng) + 1e-5  # gyro-like, rad/s
    x = x - x.mean()
    batch = fit_arma(x, 1, 1)
    est = OnlineArma(1, 1).initialise(x[:2000])
    est.feed(x[2000:])
    st = est.state()
    assert abs(st.phi[0] - batch.phi[0]) < 0.5 * batch.se_phi[0]
    assert abs(st.theta[0] - batch.theta[0]) < 0.5 * batch.se_theta[0]


def test_forgetting_tracks_a_change() -> None:
    rng = np.random.default_rng(46)
    x = np.r_[simulate_arma([0.5], [], 1.0, 20000, rng), simulate_arma([0.9], [], 1.0, 20000, rng)]
    slow = OnlineArma(1, 0, 1.0).initialise(x[:1000])
    fast = OnlineArma(1, 0, 0.999).initialise(x[:1000])
    slow.feed(x[1000:])
    fast.feed(x[1000:])
    assert abs(fast.state().phi[0] - 0.9) < 0.05 < abs(slow.state().phi[0] - 0.9)


def test_online_errors() -> None:
    with pytest.raises(DriftInputError, match="initialise"):
        OnlineArma(1, 1).feed(np.zeros(10))
    with pytest.raises(DriftInputError, match="too few"):
        OnlineArma(2, 1).initialise(np.random.default_rng(0).standard_normal(30))
    with pytest.raises(DriftInputError, match="forgetting"):
        OnlineArma(1, 0, 1.5)
    with pytest.raises(DriftInputError, match="p\\+q"):
        OnlineArma(0, 0)
    est = OnlineArma(1, 0).initialise(np.random.default_rng(0).standard_normal(100))
    with pytest.raises(DriftInputError, match="finite"):
        est.feed(np.array([1.0, np.nan]))
