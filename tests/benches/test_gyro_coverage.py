"""Issue 25 "Done when": the whole unit's certificate (gyros included) covers the truth on a bench that realises
every type-B input of its budget (benchmarks.gyro_coverage; the slow Monte Carlo writes nothing, the benchmark
``python -m benchmarks.gyro_coverage`` writes RESULTS.md). The fast tests check the bench and the simulator's
realisation of the inputs the gyro budget adds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.earth import DEFAULT_LATITUDE_U
from analysis.units import ARCSEC, DEG_PER_HOUR, DEG_PER_SQRT_HOUR
from benches.bench_config import load_bench
from benchmarks.gyro_coverage import (
    COVERAGE_RUNS,
    GYRO_CLASSES,
    PLAN_RATIO,
    TARGET_OUTSIDE,
    TARGET_RMS,
    UnitCoverage,
    _classes,
    class_table,
    load_scores,
    noise_check,
    parameter_shares,
    plan_class_ratios,
    plan_ratios,
    run_unit_coverage,
    save_scores,
    unit_coverage_bench,
)
from drivers.sim.world import SimulatedWorld


def test_unit_coverage_bench_differs_from_sim_and_realises_every_gyro_budget_input(tmp_path):
    from procedures.paths import resolve_bench

    cfg = load_bench(unit_coverage_bench(tmp_path))
    ref = load_bench(resolve_bench("sim"))
    assert cfg.simulation is not None and ref.simulation is not None
    assert cfg.simulation.gyro != ref.simulation.gyro and cfg.simulation.accel != ref.simulation.accel
    bi = cfg.simulation.budget_inputs
    assert bi is not None and ref.simulation.budget_inputs is None
    assert bi.azimuth_std == pytest.approx(cfg.turntable.azimuth_uncertainty) == pytest.approx(10 * ARCSEC)
    assert bi.axis_tilt_bound == pytest.approx(cfg.turntable.attitude_accuracy) == pytest.approx(2 * ARCSEC)
    assert bi.latitude_std == pytest.approx(DEFAULT_LATITUDE_U)
    assert bi.gravity_anomaly_std > 0 and bi.attitude_error_bound > 0 and bi.rate_error_bound > 0
    assert cfg.simulation.clocks.separate  # the time base is realised (and estimated per run)
    # a navigation-grade FOG (the datasheet the identification uses), so the holds resolve the g-sensitivity
    np.testing.assert_allclose(cfg.unit.noise.arw, 0.002 * DEG_PER_SQRT_HOUR)
    assert cfg.unit.noise.gyro_bias_instability[0] == pytest.approx(0.005 * DEG_PER_HOUR)


def test_simulator_draws_axis_tilts_and_latitude_within_the_stated_uncertainty(tmp_path):
    cfg = load_bench(unit_coverage_bench(tmp_path))
    tilt, lat = [], []
    for seed in range(300):
        ta = SimulatedWorld.from_bench(cfg, seed).truth_arrays()
        tilt.append(ta["table_axis_tilt"])
        lat.append(float(ta["latitude_error"]))
        np.testing.assert_allclose(ta["non_orthogonality"], ta["table_axis_tilt"])  # the bench states none itself
    t = np.array(tilt)
    a = 2 * ARCSEC
    assert np.all(np.abs(t) <= a) and np.std(t) == pytest.approx(a / math.sqrt(3), rel=0.1)
    assert np.std(lat) == pytest.approx(DEFAULT_LATITUDE_U, rel=0.15)


def test_parts_run_side_by_side_merge_into_one_monte_carlo_in_seed_order(tmp_path):
    from benchmarks.coverage import CoverageResult

    names = [f"p{k}" for k in range(18)] + [n for v in GYRO_CLASSES.values() for n in v]
    rng = np.random.default_rng(0)

    def part(seeds: list[int], wall: float) -> UnitCoverage:
        n, m = len(seeds), len(names)
        e, u = rng.standard_normal((n, m)), rng.uniform(1, 2, (n, m))
        res = CoverageResult(e, u, 2 * u, {"white_noise": u**2}, seeds, _classes(names))
        return UnitCoverage(res, names, np.ones(m), ("gyro_G_xx",), rng.standard_normal((n, m)), wall)

    a, b = part([3, 4], 10.0), part([1, 2], 12.0)
    uc = load_scores([save_scores(a, tmp_path / "a.npz"), save_scores(b, tmp_path / "b.npz")])
    assert uc.result.seeds == [1, 2, 3, 4] and uc.names == names and uc.wall_s == 12.0
    np.testing.assert_array_equal(uc.result.errors, np.vstack([b.result.errors, a.result.errors]))
    np.testing.assert_array_equal(uc.type_b_effect, np.vstack([b.type_b_effect, a.type_b_effect]))
    np.testing.assert_array_equal(uc.result.component_var["white_noise"], np.vstack([b.result.u, a.result.u]) ** 2)
    assert uc.plan_unidentified == ("gyro_G_xx",) and class_table(uc)[0][1] == 4 * 3


def test_class_shares_weigh_each_parameter_alike_when_u_differs_within_a_class():
    """gyro τ: u(τ_yx), u(τ_yz) are the table's inner-axis tilt (rectangular), ~100× the other four's (white
    noise); the table's share must not read "axis orthogonality 100 %" for the class (RESULTS.md, issue 25)."""
    from benchmarks.coverage import CoverageResult

    names = [f"p{k}" for k in range(18)] + [n for v in GYRO_CLASSES.values() for n in v]
    n, m = 4, len(names)
    u = np.full((n, m), 6e-8)
    tau = [names.index(f"gyro_tau_{p}") for p in ("yx", "yz")]
    u[:, tau] = 5.6e-6
    ortho, white = np.zeros((n, m)), u**2
    ortho[:, tau], white[:, tau] = u[:, tau] ** 2, 0.0
    res = CoverageResult(np.zeros((n, m)), u, 2 * u, {"axis_orthogonality": ortho, "white_noise": white},
                         list(range(n)), _classes(names))  # fmt: skip
    uc = UnitCoverage(res, names, np.ones(m), (), np.zeros((n, m)))
    share = parameter_shares(uc, "gyro τ")
    assert share["axis_orthogonality"] == pytest.approx(2 / 6) and share["white_noise"] == pytest.approx(4 / 6)
    assert res.share("gyro τ")["axis_orthogonality"] > 0.99  # the variance-weighted share the table used to show
    row = next(r for r in class_table(uc) if r[0] == "gyro τ")
    assert row[5] == share


@pytest.mark.slow
def test_unit_certificate_covers_the_truth_per_class_and_the_plan_predicts_the_scatter():
    """Issue 25's Monte Carlo, 120 runs, seeds 25000–25119 (:data:`benchmarks.gyro_coverage.COVERAGE_RUNS`).

    The test ran 30 runs (seeds 25000–25029, the issue's minimum) until 2026-11-28; there a correct budget passes
    all nine fraction bands with probability ≈ 0.44, and these seeds failed by one point (gyro b, 1 of 90 outside
    U, seed 25028 at |error|/U 0.9997), an independent 30 (25030–25059) by three classes. The size was raised to
    120 — decided before any of seeds 25060–25119 was run — so that a correct budget passes with probability
    ≈ 0.95, as in the accelerometer's 120-run test.

    Per class (gyro b, S, τ, G and the accelerometer's b, S, τ, d, r): fraction of |error| > U in 2–9 % and
    RMS(error/u) in 0.8–1.25. The plan check — "per class (gyro bias, scale, misalignment, g-sensitivity) … the
    planned σ is within ×1.2 of the Monte Carlo RMS" — is read per class, as the sentence says: the RMS over the
    class's parameters and the runs of (error − realised run-level type-B effect)/planned σ within [1/1.2, 1.2]
    (:func:`benchmarks.gyro_coverage.plan_class_ratios`; decided before the re-run of 2026-11-28 03:20 UTC). Per
    parameter, 120 runs scatter by ±6.5 % (1σ), so ×1.2 is a ≈ 2.8σ test and a correct plan passes all 15 with
    probability ≈ 0.9 (at 30 runs, ±13 % and ≈ 0.07: then the per-parameter ratios were information only); the
    per-parameter reading is checked too, so the test holds under either reading of the issue's sentence. The
    class figure scatters by ±3.7 % (three parameters) or ±2.6 % (six).
    """
    uc = run_unit_coverage(COVERAGE_RUNS)
    rows = {cls: (frac, rms) for cls, _m, frac, rms, _ok, _s in class_table(uc)}
    for cls, (frac, rms) in rows.items():  # gyro b, S, τ, G and the accelerometer's b, S, τ, d, r
        assert TARGET_OUTSIDE[0] <= frac <= TARGET_OUTSIDE[1], (cls, frac, rows)
        assert TARGET_RMS[0] <= rms <= TARGET_RMS[1], (cls, rms, rows)
    ratios = plan_class_ratios(uc)
    for cls, r in ratios.items():
        assert 1 / PLAN_RATIO <= r <= PLAN_RATIO, (cls, r, ratios, plan_ratios(uc))
    for cls, per_parameter in plan_ratios(uc).items():
        assert np.all((1 / PLAN_RATIO <= per_parameter) & (per_parameter <= PLAN_RATIO)), (cls, per_parameter)


@pytest.mark.slow
def test_budget_and_plan_propagate_the_simulated_gyro_noise_through_the_estimator(tmp_path):
    """The gyro noise alone (white ARW + bias-instability flicker, the simulated world's own streams of 200 seeds,
    26000–26199) through the identification's linear gain on one run of the coverage bench (seed 25000) scatters
    the gyro states as the identification's covariance (white ⊕ bias instability: the budget's first two lines
    and the plan's σ) says: RMS(δx/σ) per class within 0.9–1.1 (600 or 1200 values: 1σ ±0.03 / ±0.02). And the
    run's own error of the noise-dominated states (b, G) is its own realised noise through that gain, within 0.3 σ
    (the rest: rate jitter, attitude, azimuth, ≲ 0.15 σ)."""
    import io

    from benches.session import execute, prepare

    prep = prepare(unit_coverage_bench(tmp_path), "ten-step-fast-spin")
    folder = tmp_path / "run"
    folder.mkdir()
    assert execute(prep, folder, seed=25000, transport=None, live=False, stream=io.StringIO()).status == "complete"
    nc = noise_check(folder, list(range(26000, 26200)))
    rms = nc.class_rms()
    for cls, v in rms.items():
        assert 0.9 <= v <= 1.1, (cls, rms)
    idx = [nc.names.index(n) for n in GYRO_CLASSES["gyro b"] + GYRO_CLASSES["gyro G"]]
    np.testing.assert_array_less(np.abs((nc.run_error - nc.run_effect) / nc.sigma)[idx], 0.3)
