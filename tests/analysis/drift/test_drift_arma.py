"""ARMA modelling (drift-timeseries.md): moment estimates, exact-ML and CSS fits with standard errors, order
selection, Ljung–Box whiteness, agreement with statsmodels.

Acceptance model: ARMA(1,1), φ = 0.9, |θ| = 0.4, n = 5000. The spec's ML standard errors (0.0064 for φ,
0.0136 for θ) are those of x_t − 0.9 x_{t−1} = e_t + 0.4 e_{t−1}, i.e. θ = −0.4 in this project's Box–Jenkins
sign convention; the literal θ = +0.4 (standard errors 0.0079, 0.0166 by the same asymptotic formula) is
checked too.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np
import pytest

from analysis.drift.arma import (
    arma_acvf,
    css_residuals,
    fit_arma,
    moment_estimates,
    select_order,
    simulate_arma,
)
from analysis.drift.hypothesis_tests import ljung_box_test
from analysis.drift.preprocess import DriftInputError


def ml_se_arma11(phi: float, theta: float, n: int) -> tuple[float, float]:
    """Asymptotic ML standard errors of ARMA(1,1) (Box–Jenkins signs: x − φx₋₁ = e − θe₋₁)."""
    c = 1.0 - phi * theta
    d = (phi - theta) ** 2 * n
    return math.sqrt((1 - phi**2) * c**2 / d), math.sqrt((1 - theta**2) * c**2 / d)


@pytest.mark.parametrize("theta", [-0.4, 0.4])
def test_spec_standard_errors(theta: float) -> None:
    se = ml_se_arma11(0.9, theta, 5000)
    if theta < 0:
        assert abs(se[0] - 0.0064) < 1e-4 and abs(se[1] - 0.0136) < 1e-4


def _monte_carlo(theta: float, runs: int, seed: int) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    se_phi, se_th = ml_se_arma11(0.9, theta, 5000)
    out = {"bic": 0, "aic": 0, "mom_phi": 0, "mom_theta": 0, "lb": 0, "fit_phi": 0, "fit_theta": 0, "se_ratio": 0.0}
    for _ in range(runs):
        x = simulate_arma([0.9], [theta], 1.0, 5000, rng)
        sel = select_order(x)
        out["bic"] += sel.by_bic == (1, 1)
        out["aic"] += sel.by_aic == (1, 1)
        mom = moment_estimates(x, 1, 1)
        out["mom_phi"] += abs(mom.phi[0] - 0.9) < 3 * se_phi
        out["mom_theta"] += abs(mom.theta[0] - theta) < 3 * se_th
        m = sel.models[(1, 1)]
        out["fit_phi"] += abs(m.phi[0] - 0.9) < 3 * se_phi
        out["fit_theta"] += abs(m.theta[0] - theta) < 3 * se_th
        out["se_ratio"] += m.se_phi[0] / se_phi / runs
        out["lb"] += not ljung_box_test(css_residuals(x - x.mean(), m.phi, m.theta), dof_used=2).rejected
    return {k: (v / runs if k != "se_ratio" else v) for k, v in out.items()}


def _check(r: dict[str, float], moment_fraction: float) -> None:
    assert r["bic"] >= 0.90, r  # spec: BIC picks (1,1) in ≥ 90 % of runs
    assert r["lb"] >= 0.90, r  # spec: Ljung–Box passes on residuals in ≥ 90 % of runs
    # Moment estimates within 3× the ML standard errors. The moment estimator is less efficient than ML
    # (1000 runs: sd 0.0068 / 0.0200 against ML 0.0064 / 0.0136 for θ = −0.4; 0.0102 / 0.0245 against
    # 0.0079 / 0.0166 for θ = +0.4), so 2–5 % of runs fall outside; the fraction is asserted.
    assert r["mom_phi"] >= moment_fraction and r["mom_theta"] >= moment_fraction, r
    assert r["fit_phi"] >= 0.95 and r["fit_theta"] >= 0.95, r
    assert abs(r["se_ratio"] - 1.0) < 0.1, r


@pytest.mark.parametrize("theta", [-0.4, 0.4])
def test_arma11_acceptance_quick(theta: float) -> None:
    _check(_monte_carlo(theta, 30, 60 if theta < 0 else 61), 0.85)


@functools.lru_cache(maxsize=4)
def _long_monte_carlo(theta: float) -> dict[str, float]:
    return _monte_carlo(theta, 150, 62 if theta < 0 else 63)


@pytest.mark.slow
@pytest.mark.parametrize("theta", [-0.4, 0.4])
def test_arma11_acceptance_monte_carlo(theta: float) -> None:
    r = _long_monte_carlo(theta)
    print(f"theta={theta}: {r}")
    _check(r, 0.93)


def _aic_rate_css(theta: float, runs: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    hits = sum(
        select_order(simulate_arma([0.9], [theta], 1.0, 5000, rng), method="css").by_aic == (1, 1) for _ in range(runs)
    )
    return hits / runs


AIC_REASON = (
    "spec asks AIC ≥ 70 % over the p ≥ q, p, q ≤ 3 grid; not reachable with a correct likelihood maximiser. Measured "
    "(150 runs per θ = −0.4 / +0.4): exact ML 35 % / 40 %, CSS 49 % / 55 %; BIC 97–100 % with either. Five grid "
    "models nest ARMA(1,1); (2,2), (3,2) and (3,3) contain it through a common AR/MA factor that is not identified, "
    "and the maximised likelihood gain over that factor (a near-cancelling root pair fitting a chance spectral bump) "
    "exceeds AIC's penalty of 2 per parameter far more often than χ² predicts — (3,3) alone is chosen in ~35–40 % "
    "of runs by exact ML. statsmodels' exact ML gave ~63 % (82 runs) only because its optimiser stops short of "
    "those maxima (our likelihood at its optimum is higher by up to 2.4 and equals statsmodels' loglike there)."
)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=AIC_REASON)
@pytest.mark.parametrize("theta", [-0.4, 0.4])
def test_aic_selection_rate_exact_ml(theta: float) -> None:
    assert _long_monte_carlo(theta)["aic"] >= 0.70


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=AIC_REASON)
@pytest.mark.parametrize("theta", [-0.4, 0.4])
def test_aic_selection_rate_css(theta: float) -> None:
    assert _aic_rate_css(theta, 150, 64 if theta < 0 else 65) >= 0.70


def test_ml_order_search_never_loses_likelihood_to_a_nested_model() -> None:
    """Each candidate is also started from its best nested model: its maximised likelihood is never lower."""
    x = simulate_arma([0.9], [-0.4], 1.0, 3000, np.random.default_rng(67))
    sel = select_order(x)
    ll = {k: m.aic - 2.0 * (k[0] + k[1] + 1) for k, m in sel.models.items()}  # = n ln σ̂²_eff = −2 ln L + const
    for (p, q), v in ll.items():
        for (pp, qq), w in ll.items():
            if pp <= p and qq <= q:
                assert v <= w + 1e-6, ((p, q), (pp, qq), v, w)


def test_ml_fit_reaches_statsmodels_maximum() -> None:
    """For the well-posed ARMA(1,1) and ARMA(2,1) the exact-ML fit equals statsmodels' optimum."""
    from statsmodels.tsa.arima.model import ARIMA

    rng = np.random.default_rng(68)
    for phi, theta in (([0.9], [-0.4]), ([1.2, -0.5], [0.3])):
        x = simulate_arma(phi, theta, 1.0, 4000, rng)
        x = x - x.mean()
        fit = fit_arma(x, len(phi), len(theta))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ref = ARIMA(x, order=(len(phi), 0, len(theta)), trend="n").fit()
        ll = -0.5 * (fit.aic - 2.0 * (len(phi) + len(theta) + 1) + x.size * (1.0 + math.log(2.0 * math.pi)))
        assert ll >= ref.llf - 1e-4
        assert ll - ref.llf < 1e-2
        np.testing.assert_allclose(fit.phi, ref.params[: len(phi)], atol=0.05 * fit.se_phi.max())
        np.testing.assert_allclose(fit.theta, -ref.params[len(phi) : -1], atol=0.05 * fit.se_theta.max())
        np.testing.assert_allclose(fit.se_phi, ref.bse[: len(phi)], rtol=0.1)


def test_agreement_with_statsmodels() -> None:
    """Exact-ML and CSS fits and moment estimates agree with statsmodels' exact ML within the ML standard errors."""
    from statsmodels.tsa.arima.model import ARIMA

    rng = np.random.default_rng(64)
    for theta in (-0.4, 0.4):
        se_phi, se_th = ml_se_arma11(0.9, theta, 5000)
        for _ in range(1):
            x = simulate_arma([0.9], [theta], 1.0, 5000, rng)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ref = ARIMA(x, order=(1, 0, 1), trend="n").fit()
            sm_phi, sm_theta = float(ref.params[0]), -float(ref.params[1])  # statsmodels MA sign is opposite
            for method in ("ml", "css"):
                fit = fit_arma(x, 1, 1, method=method)
                assert abs(fit.phi[0] - sm_phi) < se_phi and abs(fit.theta[0] - sm_theta) < se_th
                assert abs(fit.se_phi[0] - ref.bse[0]) < 0.1 * ref.bse[0]
                assert abs(fit.se_theta[0] - ref.bse[1]) < 0.1 * ref.bse[1]
                assert abs(fit.sigma2 - ref.params[2]) < 3 * ref.bse[2]
            mom = moment_estimates(x, 1, 1)
            assert abs(mom.phi[0] - sm_phi) < 3 * se_phi and abs(mom.theta[0] - sm_theta) < 3 * se_th


def test_higher_order_moment_estimates_and_fit() -> None:
    rng = np.random.default_rng(65)
    phi, theta = [1.2, -0.5], [0.3]
    x = simulate_arma(phi, theta, 2.0, 40000, rng)
    mom = moment_estimates(x, 2, 1)
    np.testing.assert_allclose(mom.phi, phi, atol=0.05)
    np.testing.assert_allclose(mom.theta, theta, atol=0.08)
    fit = fit_arma(x, 2, 1)
    assert np.all(np.abs(fit.phi - phi) < 4 * fit.se_phi) and np.all(np.abs(fit.theta - theta) < 4 * fit.se_theta)
    assert abs(fit.sigma2 - 2.0) < 4 * fit.se_sigma2
    # MA(2) moment iteration reproduces the autocovariances exactly from theoretical values
    from analysis.drift.arma import _ma_from_acvf

    g = arma_acvf([], [0.5, -0.3], 1.5, 2)
    c, s2, note = _ma_from_acvf(g)
    np.testing.assert_allclose(-c, [0.5, -0.3], atol=1e-8)
    assert abs(s2 - 1.5) < 1e-8 and note == ""


def test_white_noise_selects_zero_order() -> None:
    x = np.random.default_rng(66).standard_normal(5000)
    sel = select_order(x)
    assert sel.by_bic == (0, 0) and sel.best.criterion == "bic"
    assert len({m.n for m in sel.models.values()}) == 1  # every candidate judged on the same samples
    assert len({m.n for m in select_order(x, method="css").models.values()}) == 1
    assert {(r["p"], r["q"]) for r in sel.table} == {
        (0, 0), (1, 0), (1, 1), (2, 0), (2, 1), (2, 2), (3, 0), (3, 1), (3, 2), (3, 3)
    }  # fmt: skip


def test_bad_input_messages() -> None:
    x = np.random.default_rng(0).standard_normal(30)
    with pytest.raises(DriftInputError, match="too short for ARMA\\(3,3\\)"):
        fit_arma(x, 3, 3)
    with pytest.raises(DriftInputError, match="constant"):
        select_order(np.full(500, 2.0))
    y = np.random.default_rng(0).standard_normal(500)
    y[3] = np.nan
    with pytest.raises(DriftInputError, match="NaN"):
        moment_estimates(y, 1, 0)
    with pytest.raises(DriftInputError, match="criterion"):
        select_order(np.random.default_rng(0).standard_normal(500), criterion="hqic")
    # too short for the large orders: they are skipped, small ones still fitted
    sel = select_order(np.random.default_rng(1).standard_normal(45))
    assert (3, 3) not in sel.models and (0, 0) in sel.models


@pytest.mark.slow
def test_aic_overfit_is_a_true_likelihood_maximum() -> None:
    """Evidence for the AIC expected failure: on a true ARMA(1,1) record where AIC picks (3,3), our (3,3) optimum
    (a near-cancelling AR/MA pair: a spurious spectral line) has a likelihood, by statsmodels' own ``loglike``,
    well above both statsmodels' fitted (3,3) optimum and the ARMA(1,1) maximum — the overfit is AIC's, not an
    estimator artefact."""
    from statsmodels.tsa.arima.model import ARIMA

    x = simulate_arma([0.9], [-0.4], 1.0, 5000, np.random.default_rng(82))
    x = x - x.mean()
    sel = select_order(x)
    assert sel.by_aic == (3, 3) and sel.by_bic == (1, 1)
    m = sel.models[(3, 3)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = ARIMA(x, order=(3, 0, 3), trend="n")
        ll_ours = model.loglike(np.r_[m.phi, -m.theta, m.sigma2])
        ll_sm = model.fit().llf
        ll_11 = ARIMA(x, order=(1, 0, 1), trend="n").fit().llf
    assert ll_ours > ll_sm + 1.0
    assert 2.0 * (ll_ours - ll_11) > 2.0 * 4  # the likelihood gain beats AIC's penalty for the 4 extra parameters
