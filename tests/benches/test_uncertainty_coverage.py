"""Issue 12 "Done when": the certificate's uncertainty covers the truth on a bench that realises its inputs.

The slow test runs ≥ 30 seeded ten-step-fast-spin calibrations (benchmarks.coverage) and checks, per
parameter class, the fraction of |error| > U (k = 2) and RMS(error/u) against the issue's bands. The fast
tests check that the simulated bench realises each budget input it claims to.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.units import ARCSEC
from benches.bench_config import load_bench
from benchmarks.coverage import CLASSES, coverage_bench, run_coverage
from drivers.sim.world import SimulatedWorld


def test_coverage_bench_differs_from_sim_and_realises_the_budget_inputs(tmp_path):
    from procedures.paths import resolve_bench

    cfg = load_bench(coverage_bench(tmp_path))
    ref = load_bench(resolve_bench("sim"))
    assert cfg.simulation is not None and ref.simulation is not None
    assert cfg.simulation.accel != ref.simulation.accel
    bi = cfg.simulation.budget_inputs
    assert ref.simulation.budget_inputs is None
    assert bi is not None
    assert bi.gravity_anomaly_std == pytest.approx(cfg.site.g_uncertainty) == pytest.approx(2e-5)
    assert bi.attitude_error_bound == pytest.approx(cfg.turntable.attitude_accuracy) == pytest.approx(2 * ARCSEC)
    assert bi.rate_error_bound == pytest.approx(cfg.turntable.rate_accuracy) == pytest.approx(500e-6)


def test_simulator_draws_gravity_and_rate_errors_within_the_stated_uncertainty(tmp_path):
    cfg = load_bench(coverage_bench(tmp_path))
    g_dev, eps = [], []
    for seed in range(400):
        w = SimulatedWorld.from_bench(cfg, seed)
        ta = w.truth_arrays()
        g_dev.append(float(ta["gravity_anomaly"]))
        eps.append(ta["table_rate_error"])
        assert float(ta["g"]) == pytest.approx(cfg.site.g + g_dev[-1], abs=1e-12)
    g_dev_a = np.array(g_dev)
    # N(0, u(g)²): the sample std within ±15 % (400 draws: ±3.5 % 1σ)
    assert abs(np.std(g_dev_a) / 2e-5 - 1) < 0.15 and abs(np.mean(g_dev_a)) < 4 * 2e-5 / math.sqrt(400)
    e = np.array(eps)
    assert np.all(np.abs(e) <= 500e-6) and np.std(e) == pytest.approx(500e-6 / math.sqrt(3), rel=0.1)


def test_simulator_moves_the_true_attitude_per_command_within_the_stated_accuracy():
    from drivers.sim.config import BudgetInputs, SimConfig

    w = SimulatedWorld(SimConfig(budget_inputs=BudgetInputs(attitude_error_bound=2 * ARCSEC)), 3)  # noise-free
    g = float(w.truth_arrays()["g"])
    seen, f_mean = [], []
    for k in range(20):
        w.command_position([0.0, 0.0, 0.0] if k % 2 else [0.0, 1e-9, 0.0])
        w.produce(int(2 * w.sample_rate))  # settle at rest (the position moves by 1e-9 rad only)
        seen.append(w._dphi.copy())
        frames = w.produce(2000)
        f_mean.append(frames.counts[:, :3].mean(axis=0) * w.scale.accel_lsb)
    d = np.array(seen)
    assert np.all(np.abs(d) <= 2 * ARCSEC) and len({tuple(x) for x in d}) == 20
    # at rest, body = nav (z up): f_b = R(δφ)ᵀ [0, 0, g] ⇒ Δf_x = −g Δδφ_y, Δf_y = +g Δδφ_x between positions
    df = np.diff(np.array(f_mean), axis=0)
    dd = np.diff(d, axis=0)
    pred = np.stack([-g * dd[:, 1], g * dd[:, 0]], axis=1)
    resid = df[:, :2] - pred
    assert np.sqrt(np.mean(resid**2)) < 0.01 * np.sqrt(np.mean(pred**2)), (resid, pred)


def test_without_realisation_the_simulator_streams_are_unchanged(tmp_path):
    from procedures.paths import resolve_bench

    ref = load_bench(resolve_bench("sim"))
    a = SimulatedWorld.from_bench(ref, 5)
    assert a._g == pytest.approx(ref.simulation.local_g) and not np.any(a._rate_error)
    a.command_position([0.1, 0.0, 0.0])
    assert not np.any(a._dphi)


def _gravity_draws(seeds: list[int]) -> np.ndarray:
    import tempfile
    from pathlib import Path

    cfg = load_bench(coverage_bench(Path(tempfile.mkdtemp())))
    return np.array(
        [float(SimulatedWorld.from_bench(cfg, s).truth_arrays()["gravity_anomaly"]) for s in seeds]
    ) / cfg.site.g_uncertainty


@pytest.mark.slow
def test_certificate_uncertainty_covers_the_truth_over_30_seeded_runs():
    res = run_coverage(32)
    report = {c: (round(res.fraction_outside(c), 3), round(res.rms_normalised(c), 2)) for c in CLASSES}
    # the realised gravity anomalies (in u(g)): the three scale factors of a run share one draw, so the S class
    # has an effective sample of ~32 runs, and a few large draws move its fraction by several %
    report["g draws / u(g) beyond ±2"] = int(np.sum(np.abs(_gravity_draws(res.seeds)) > 2))
    for cls in CLASSES:
        frac, rms = res.fraction_outside(cls), res.rms_normalised(cls)
        assert 0.02 <= frac <= 0.09, report
        assert 0.8 <= rms <= 1.25, report
