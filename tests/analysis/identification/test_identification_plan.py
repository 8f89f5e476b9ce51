"""Identification plan: predicted σ before motion, flags and wording, against achieved Monte-Carlo scatter."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats

from analysis.identification import batch as bi
from analysis.identification import model as am
from analysis.identification import plan as ip
from analysis.identification.kalman import StreamingIdentifier
from analysis.units import DEG, MM, UG
from tests.identification_synth import P0, PRIOR_SIGMA, TRUTH, G, noise_sd, simulate

RATE = 100.0
SD = noise_sd(15.0, RATE)
R = np.full(3, SD**2)


def test_plan_white_sigma_equals_filter_covariance() -> None:
    full = ip.ten_step_sequence(G, RATE, hold_s=30.0, spin_rate=1.6 * DEG)
    outputs = simulate(full, TRUTH, SD, np.random.default_rng(0))
    kf = StreamingIdentifier(R, P0)
    for st, fo in zip(full, outputs, strict=True):
        kf.update(fo, st.f_ref, st.omega, st.label)
    plan_full = ip.plan_identification(full, R, P0)
    np.testing.assert_allclose(plan_full.sigma_white, kf.sigma, rtol=1e-9)
    np.testing.assert_allclose(plan_full.sigma_total, plan_full.sigma_white, rtol=1e-12)  # σ_bi = 0
    # Compressed nominal points (360 per revolution, one per hold) predict the same to < 0.5 %.
    plan_c = ip.plan_identification(
        ip.ten_step_sequence(G, RATE, hold_s=30.0, spin_rate=1.6 * DEG, points_per_rev=360), R, P0
    )
    np.testing.assert_allclose(plan_c.sigma_white, plan_full.sigma_white, rtol=5e-3)
    assert plan_c.n_samples == pytest.approx(plan_full.n_samples)
    assert plan_c.rank == 18 and plan_c.max_rate == pytest.approx(1.6 * DEG)


def test_plan_flags_size_effect_at_published_rate_only() -> None:
    slow = ip.plan_identification(
        ip.ten_step_sequence(G, RATE, spin_rate=1.6 * DEG, points_per_rev=360), R, P0, bias_stability=1 * UG
    )
    fast = ip.plan_identification(
        ip.ten_step_sequence(G, RATE, spin_rate=30 * DEG, points_per_rev=360), R, P0, bias_stability=1 * UG
    )
    assert slow.unidentifiable == ("r_x", "r_y", "r_z")
    assert fast.unidentifiable == () and fast.warnings == []
    (msg,) = slow.warnings
    assert msg.startswith("r_x, r_y, r_z (size effect) will not be identified: predicted 1σ ")
    assert "30 mm prior" in msg and "spins reach only 1.6 °/s; spin at ≥ " in msg
    # The recommended rate, applied, must actually clear the flag (the advice is honest).
    need = float(msg.split("spin at ≥ ")[1].split(" °/s")[0])
    fixed = ip.plan_identification(
        ip.ten_step_sequence(G, RATE, spin_rate=need * DEG, revolutions=need / 1.6, points_per_rev=360),
        R,
        P0,
        bias_stability=1 * UG,
    )
    assert fixed.unidentifiable == ()
    # Spec figures: 1 µg of unmodelled DC moves r by ~12.6 mm at 1.6 °/s; r σ at 30 °/s well below 1 mm.
    assert 5 * MM < slow.sigma_data_total[15] < 25 * MM
    assert fast.sigma_total[15:].max() < 0.5 * MM
    assert np.all(slow.sigma_total[15:] > slow.sigma_white[15:])


def test_plan_static_24_positions_reports_unobservable_size_effect() -> None:
    plan = ip.plan_identification(ip.cube24_sequence(G, RATE, compress=True), R, P0, bias_stability=1 * UG)
    assert plan.rank == 15 and np.isinf(plan.condition)
    assert plan.unidentifiable == ("r_x", "r_y", "r_z")
    assert np.all(np.isinf(plan.sigma_data_total[15:]))
    np.testing.assert_allclose(plan.sigma_total[15:], PRIOR_SIGMA[15:], rtol=1e-9)
    assert "not observable" in plan.warnings[0] and "add constant-rate spins" in plan.warnings[0]
    assert "NOT IDENTIFIED" in plan.table()


def test_plan_white_limited_advice_and_bad_input() -> None:
    plan = ip.plan_identification(
        ip.ten_step_sequence(G, RATE, hold_s=0.5, spin_rate=30 * DEG, points_per_rev=360),
        R,
        P0,
        magnitudes=np.abs(TRUTH),
    )
    assert plan.unidentifiable
    assert any("× longer at each position" in w and "datasheet magnitude" in w for w in plan.warnings)
    with pytest.raises(ValueError, match="no steps"):
        ip.plan_identification([], R, P0)
    with pytest.raises(ValueError, match="plan step 'x'"):
        ip.PlanStep("x", np.zeros((2, 3)), np.zeros((3, 3)), np.ones(2))
    with pytest.raises(ValueError, match="bias_stability"):
        ip.plan_identification(ip.cube24_sequence(G, RATE, compress=True), R, P0, bias_stability=-1.0)


def _scatter(spin_rate: float, sbi: float, n_runs: int, hold_s: float) -> tuple[np.ndarray, ip.IdentificationPlan]:
    """Monte Carlo: truth drawn from the prior, white noise, and an independent DC offset per step."""
    full = ip.ten_step_sequence(G, RATE, hold_s=hold_s, spin_rate=spin_rate)
    plan = ip.plan_identification(
        ip.ten_step_sequence(G, RATE, hold_s=hold_s, spin_rate=spin_rate, points_per_rev=720), R, P0, sbi
    )
    chol = np.linalg.cholesky(P0)
    errs = np.empty((n_runs, 18))
    for k in range(n_runs):
        rng = np.random.default_rng(500 + k)
        truth = chol @ rng.normal(size=18)
        offsets = {st.label: rng.normal(0.0, sbi, 3) for st in full}
        outputs = simulate(full, truth, SD, rng, offsets)
        kf = StreamingIdentifier(R, P0)
        for st, fo in zip(full, outputs, strict=True):
            kf.update(fo, st.f_ref, st.omega, st.label)
        errs[k] = kf.estimate - truth
    return errs, plan


def test_plan_sigma_matches_achieved_scatter_with_bias_instability() -> None:
    n_runs = 40
    errs, plan = _scatter(1.6 * DEG, 3 * UG, n_runs, hold_s=20.0)
    # Joint check: Σ eᵀ C_total⁻¹ e over runs is χ² with 18·n dof.
    c_inv = np.linalg.inv(plan.covariance_total / np.outer(plan.sigma_total, plan.sigma_total))
    e_n = errs / plan.sigma_total
    stat = float(np.einsum("ki,ij,kj->", e_n, c_inv, e_n))
    lo, hi = scipy.stats.chi2.ppf([0.001, 0.999], 18 * n_runs)
    assert lo < stat < hi, stat / n_runs
    ratio = np.sqrt((errs**2).mean(axis=0)) / plan.sigma_total
    assert np.all((ratio > 0.6) & (ratio < 1.5)), dict(zip(am.PARAM_NAMES, np.round(ratio, 2), strict=True))
    # The white-only σ (the filter's own P) is optimistic for r under bias instability: the systematic
    # term is what makes the prediction match.
    assert np.all(plan.sigma_total[15:] > 1.3 * plan.sigma_white[15:])
    assert np.sqrt((errs[:, 15:] ** 2).mean()) > 1.2 * plan.sigma_white[15:].max()


@pytest.mark.slow
def test_plan_sigma_matches_scatter_monte_carlo_large() -> None:
    for rate in (1.6 * DEG, 30 * DEG):
        errs, plan = _scatter(rate, 2 * UG, 200, hold_s=30.0)
        ratio = np.sqrt((errs**2).mean(axis=0)) / plan.sigma_total
        assert np.all((ratio > 0.8) & (ratio < 1.2)), dict(zip(am.PARAM_NAMES, np.round(ratio, 2), strict=True))


def test_bias_drift_during_spins_expected_failure_at_published_rate() -> None:
    """Spec acceptance: a 1 µg bias shift during the spins moves r̂ by ~1 cm at 1.6 °/s, < 0.1 mm at 30 °/s."""
    for rate, lo, hi in ((1.6 * DEG, 5 * MM, 20 * MM), (30 * DEG, 0.0, 0.1 * MM)):
        steps = ip.ten_step_sequence(G, 10.0, hold_s=60.0, spin_rate=rate)
        offsets = {st.label: np.full(3, 1 * UG) for st in steps if "spin" in st.label}
        outputs = simulate(steps, TRUTH, 0.0, np.random.default_rng(0), offsets)
        res = bi.batch_identify(
            np.concatenate(outputs),
            np.concatenate([s.f_ref for s in steps]),
            np.concatenate([s.omega for s in steps]),
            R,
        )
        err = np.abs(res.x[15:] - TRUTH[15:])
        assert np.all((err > lo) & (err < hi)), (rate / DEG, err / MM)
