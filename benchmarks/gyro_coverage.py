"""Coverage of the whole unit's certificate, gyros included (issue 25, "Done when"), on the simulated bench.

Seeded ``ten-step-fast-spin`` runs on :func:`unit_coverage_bench`: the accelerometer coverage bench
(:func:`benchmarks.coverage.coverage_bench`: other accelerometer truth, site, ±2″ / ±500 ppm table, u(g) = 2 mGal)
with a gyro truth different from ``benches/sim.yaml`` (a navigation-grade FOG triad: ARW 0.002 °/√h, bias
instability 0.005 °/h, so that the g-sensitivity is resolved by the 60 s holds) and a table whose azimuth
alignment is stated (u = 10″). ``realise_uncertainty_inputs: true`` realises every type-B input of the budget:
local g anomaly, per-command attitude error, table rate error (the table turns off its command), azimuth
alignment, the middle/inner axis non-orthogonality, the site latitude's u, and separate unit/controller/host
clocks (the time base is estimated per run). Each run is identified (33 states) and certified as the CLI
does; errors against the simulator's truth are scored per class against the certificate's u and U = 2u.

The plan's σ (before motion, identification only: white noise and bias instability) is compared with the
Monte Carlo RMS of the errors **less the first-order effect of the run-level type-B inputs the simulator
realised and reports** (local g, azimuth, latitude, axis tilts: their sensitivities from the same estimator,
times the realised values); what remains is the identification's own error plus the per-step attitude error
and the time base's residual.

``python -m benchmarks.gyro_coverage`` (120 runs) writes the section "gyro_coverage" of RESULTS.md; on two cores,
``--runs 60 --first-seed 25000 --save a.npz`` and ``--runs 60 --first-seed 25060 --save b.npz`` side by side, then
``--merge a.npz b.npz``.
"""

from __future__ import annotations

import argparse
import io
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from benchmarks.coverage import CLASSES as ACCEL_CLASSES
from benchmarks.coverage import CoverageResult, coverage_bench

AX = "xyz"
GYRO_CLASSES: dict[str, list[str]] = {
    "gyro b": [f"gyro_b_{a}" for a in AX],
    "gyro S": [f"gyro_S_{a}" for a in AX],
    "gyro τ": [f"gyro_tau_{p}" for p in ("xy", "xz", "yx", "yz", "zx", "zy")],
    "gyro G": [f"gyro_G_{a}{a}" for a in AX],
}
"""The gyro classes the issue scores, by parameter name."""

COVERAGE_RUNS = 120
"""Runs of the slow test and the benchmark (seeds 25000–25119; the issue asks for at least 30). With 30 runs a
correct budget passes all nine classes' fraction bands with probability ≈ 0.44 (binomial: 90 or 180 values per
class, p = 4.55 %), with 120 runs ≈ 0.95, as the accelerometer's 120-run coverage test
(benchmarks.bench_calibration). Decided on 2026-11-28 04:28 UTC, after seeds 25000–25059 and before any run of
25060–25119 (benchmarks/RESULTS.md, "gyro_coverage")."""

TARGET_OUTSIDE = (0.02, 0.09)
TARGET_RMS = (0.8, 1.25)
PLAN_RATIO = 1.2


def unit_coverage_bench(folder: Path, rate: float = 100.0) -> Path:
    """The accelerometer coverage bench with a different gyro truth and a stated table azimuth alignment."""
    text = coverage_bench(folder, rate).read_text(encoding="utf-8")
    subs = [
        ("name: sim-coverage", "name: sim-unit-coverage"),
        ("attitude_accuracy_arcsec: 2.0", "attitude_accuracy_arcsec: 2.0\n  azimuth_uncertainty_arcsec: 10.0"),
        ("arw_deg_per_sqrt_h: [0.01, 0.01, 0.01]\n    gyro_bias_instability_dph: [0.05, 0.05, 0.05]",
         "arw_deg_per_sqrt_h: [0.002, 0.002, 0.002]\n    gyro_bias_instability_dph: [0.005, 0.005, 0.005]"),
        ("gyro_g_sensitivity_dph_per_g: 0.05", "gyro_g_sensitivity_dph_per_g: 0.3"),
        ("bias_dph: [0.5, -0.3, 0.4]", "bias_dph: [-1.2, 0.8, 0.3]"),
        ("scale_ppm: [50.0, -40.0, 60.0]", "scale_ppm: [-120.0, 80.0, 35.0]"),
        ("misalignment_arcsec: [10.0, -8.0, 6.0, 12.0, -9.0, 7.0]",
         "misalignment_arcsec: [-25.0, 18.0, 9.0, -30.0, 22.0, -14.0]"),
        ("g_sensitivity_dph_per_g: [[0.02, 0, 0], [0, 0.02, 0], [0, 0, 0.02]]",
         "g_sensitivity_dph_per_g: [[0.12, 0, 0], [0, -0.08, 0], [0, 0, 0.15]]"),
        ("arw_deg_per_sqrt_h: [0.01, 0.01, 0.01]\n    bias_instability_dph: [0.05, 0.05, 0.05]",
         "arw_deg_per_sqrt_h: [0.002, 0.002, 0.002]\n    bias_instability_dph: [0.005, 0.005, 0.005]"),
    ]  # fmt: skip
    for old, new in subs:
        if text.count(old) != 1:
            raise RuntimeError(f"unit_coverage_bench: {old!r} is not in the coverage bench exactly once")
        text = text.replace(old, new)
    p = Path(folder) / f"sim-unit-coverage-{int(rate)}Hz.yaml"
    p.write_text(text, encoding="utf-8")
    return p


@dataclass
class UnitCoverage:
    """A unit coverage Monte Carlo: certificate scores, the plan, and the realised run-level inputs."""

    result: CoverageResult
    names: list[str]
    plan_sigma: np.ndarray
    """The plan's σ_total per state (before motion)."""
    plan_unidentified: tuple[str, ...]
    type_b_effect: np.ndarray
    """(runs, n): first-order effect of the realised local g, azimuth, latitude and axis tilts, SI."""
    wall_s: float = 0.0
    notes: list[str] = field(default_factory=list)

    def index(self, names: list[str]) -> list[int]:
        return [self.names.index(n) for n in names]


def _classes(names: list[str]) -> dict[str, list[int]]:
    out = {k: list(range(sl.start, sl.stop)) for k, sl in ACCEL_CLASSES.items()}
    out.update({k: [names.index(n) for n in v] for k, v in GYRO_CLASSES.items()})
    return out


def _run_level_effect(g, realised: dict[str, np.ndarray]) -> np.ndarray:  # noqa: ANN001
    """First-order effect on the state of the realised run-level inputs (same estimator as the budget)."""
    from analysis.identification.budget import input_sensitivity
    from analysis.identification.gyro_budget import earth_rate_inputs
    from analysis.identification.table_axes import orthogonality_input

    cal = g.cal
    model = cal.error_model
    a_inv, nv, geo = cal.covariance_white, cal.noise_variance, g.geometry
    lat = np.radians(float(g.binfo.latitude_deg))
    inputs = {i.key: i for i in earth_rate_inputs(model, lat, 1.0, 1.0)}
    inputs |= {i.key: i for i in orthogonality_input(model, 1.0, g.binfo.g, "")}
    values = {
        "azimuth": np.atleast_1d(realised["table_azimuth_error"]),
        "latitude": np.atleast_1d(realised["latitude_error"]),
        "axis_orthogonality": np.atleast_1d(realised["table_axis_tilt"]),
    }
    out = np.zeros(model.n_params)
    for key, val in values.items():
        sens = [c for c in input_sensitivity(a_inv, geo, nv, inputs[key].shape, model) if c is not None]
        out += sum(sens, np.zeros((model.n_params, val.size))) @ val
    gs = [c for c in input_sensitivity(a_inv, geo, nv, lambda s: model.gravity_shape(s.f, s.omega, g.binfo.g), model)
          if c is not None]  # fmt: skip
    out += sum(gs, np.zeros((model.n_params, 1)))[:, 0] * float(realised["gravity_anomaly"])
    return out


def run_unit_coverage(
    n_runs: int, *, rate: float = 100.0, first_seed: int = 25000, log: Callable[[str], None] | None = None
) -> UnitCoverage:
    """Run, identify (33 states) and certify ``n_runs`` seeded ten-step-fast-spin runs on the unit coverage bench."""
    from benches.bench_config import load_bench
    from benches.certificate.build import assemble, decide_conformity, gather
    from benches.identify import identify_run, plan_for, write_calibration
    from benches.session import execute, prepare
    from drivers.sim.world import SimulatedWorld

    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="tb-unit-coverage-"))
    bench = unit_coverage_bench(tmp, rate)
    prep = prepare(bench, "ten-step-fast-spin")
    plan = plan_for(prep.compiled, prep.config)
    cfg = load_bench(bench)
    errs, us, big_u, seeds, effects = [], [], [], [], []
    comp: dict[str, list[np.ndarray]] = {}
    names: list[str] = []
    for k in range(n_runs):
        seed = first_seed + k
        folder = tmp / f"run{k:03d}"
        folder.mkdir()
        res = execute(prep, folder, seed=seed, transport=None, live=False, stream=io.StringIO())
        if res.status != "complete":
            raise RuntimeError(f"unit coverage run seed {seed}: {res.reason}")
        cal = identify_run(folder)
        write_calibration(cal, folder / "calibration.json")
        g = gather(folder)
        cert = assemble(g, decide_conformity(g), "2026-01-01", with_plots=False)
        names = [p.name for p in cert.parameters]
        x = np.array([p.value for p in cert.parameters])
        truth = np.array([cal.truth.values[n] for n in names])
        errs.append(x - truth)
        us.append(np.array([p.standard_uncertainty for p in cert.parameters]))
        big_u.append(np.array([p.expanded_uncertainty for p in cert.parameters]))
        keys = {key for p in cert.parameters for key in p.budget}
        for key in keys:
            comp.setdefault(key, []).append(np.array([p.budget.get(key, 0.0) ** 2 for p in cert.parameters]))
        effects.append(_run_level_effect(g, SimulatedWorld.from_bench(cfg, seed).truth_arrays()))
        seeds.append(seed)
        if log is not None:
            z = (x - truth) / us[-1]
            j = int(np.argmax(np.abs(z)))
            log(f"seed {seed}: max |error|/u {abs(z[j]):.2f} ({names[j]}), {time.perf_counter() - t0:.0f} s")
        for p in folder.iterdir():  # keep the disk small: recordings are not needed once scored
            if p.suffix == ".h5":
                p.unlink()
    if list(plan.names) != names:
        raise RuntimeError("the plan's states differ from the certificate's")
    n_comp = len(seeds)
    res_c = CoverageResult(
        np.array(errs), np.array(us), np.array(big_u),
        {k: np.array(v) for k, v in comp.items() if len(v) == n_comp}, seeds, _classes(names),
    )  # fmt: skip
    return UnitCoverage(
        res_c, names, np.asarray(plan.sigma_total), tuple(plan.unidentifiable), np.array(effects),
        time.perf_counter() - t0,
    )  # fmt: skip


def parameter_shares(uc: UnitCoverage, cls: str) -> dict[str, float]:
    """Share of each budget component in u², per parameter and run, averaged over the class.

    Unlike :meth:`benchmarks.coverage.CoverageResult.share` (class-mean component variance over class-mean u²) this
    weighs every parameter alike: in the gyro τ class u(τ_yx), u(τ_yz) (the table's inner-axis tilt, ≈ 1.2″) are
    ~100× those of the other four (white noise, ≈ 0.013″), so the variance-weighted share reads "axis
    orthogonality 100 %" for a class whose four other parameters have none of it.
    """
    idx = uc.result.classes[cls]
    u2 = uc.result.u[:, idx] ** 2
    return {k: float(np.mean(v[:, idx] / u2)) for k, v in uc.result.component_var.items()}


def class_table(uc: UnitCoverage) -> list[tuple[str, int, float, float, bool, dict[str, float]]]:
    """Per class: (class, runs × params, fraction outside U, RMS(error/u), in both bands, mean per-parameter
    shares of u², :func:`parameter_shares`)."""
    out = []
    for cls, idx in uc.result.classes.items():
        frac, rms = uc.result.fraction_outside(cls), uc.result.rms_normalised(cls)
        ok = TARGET_OUTSIDE[0] <= frac <= TARGET_OUTSIDE[1] and TARGET_RMS[0] <= rms <= TARGET_RMS[1]
        out.append((cls, len(uc.result.seeds) * len(idx), frac, rms, ok, parameter_shares(uc, cls)))
    return out


def plan_ratios(uc: UnitCoverage) -> dict[str, np.ndarray]:
    """Per gyro class: MC RMS of (error − realised run-level type-B effect) / the plan's σ, per parameter
    (one parameter's ratio scatters by ±1/√(2·runs): ±13 % over 30 runs, ±6.5 % over 120, for a correct plan)."""
    e = uc.result.errors - uc.type_b_effect
    rms = np.sqrt(np.mean(e**2, axis=0))
    return {cls: rms[uc.index(v)] / uc.plan_sigma[uc.index(v)] for cls, v in GYRO_CLASSES.items()}


def plan_class_ratios(uc: UnitCoverage) -> dict[str, float]:
    """The issue's plan check, read per class (gyro b, S, τ, G): the RMS over the class's parameters and the runs of
    (error − realised run-level type-B effect) / the plan's σ_total; target within ×1.2 either way.

    Parameters the plan flags as not identified are left out of their class (the plan prints no σ for them).
    With 120 runs the class figure scatters by ±3.7 % (3 parameters) or ±2.6 % (6) for a correct plan (±7 % / ±5 %
    with 30), so the ×1.2 band is a ≥ 5σ test of the plan; the slow test checks the per-parameter ratios
    (:func:`plan_ratios`, ±6.5 %) against ×1.2 as well.
    """
    z = (uc.result.errors - uc.type_b_effect) / uc.plan_sigma[None, :]
    out = {}
    for cls, names in GYRO_CLASSES.items():
        idx = uc.index([n for n in names if n not in uc.plan_unidentified])
        out[cls] = float(np.sqrt(np.mean(z[:, idx] ** 2))) if idx else float("nan")
    return out


def section(uc: UnitCoverage, rate: float) -> str:
    """The RESULTS.md section "gyro_coverage" (written) as Markdown."""
    from benchmarks._results import write_section
    from benchmarks.coverage import expected_spread

    n = len(uc.result.seeds)
    lines = [
        f"{n} seeded `ten-step-fast-spin` runs at {rate:.0f} Hz (seeds {uc.result.seeds[0]}–{uc.result.seeds[-1]}) "
        "on `benchmarks.gyro_coverage.unit_coverage_bench`: the accelerometer coverage bench with a gyro truth "
        "different from benches/sim.yaml (navigation-grade FOG: ARW 0.002 °/√h, bias instability 0.005 °/h; bias "
        "[−1.2, 0.8, 0.3] °/h, scale [−120, 80, 35] ppm, misalignment up to 30″, G diag [0.12, −0.08, 0.15] °/h/g) "
        "and a table azimuth alignment stated to u = 10″, with `realise_uncertainty_inputs: true` (local g, "
        "attitude per command, table rate error, azimuth, middle/inner axis non-orthogonality, latitude; separate "
        "clocks with the time base estimated per run). Each run identified with 33 states and certified as the CLI "
        f"does; u = the certificate's combined standard uncertainty, U = 2u. Wall time {uc.wall_s / 60:.1f} min "
        "(machine shared).",
        "",
        r"| class | runs × params | fraction \|error\| > U | RMS(error/u) | in band (2–9 %, 0.8–1.25) | "
        "1σ sampling spread (fraction / RMS) for a correct budget | share of u² by component (mean over the "
        "class's parameters) |",
        "|---|---:|---:|---:|---|---:|---|",
    ]
    for cls, m, frac, rms, ok, share in class_table(uc):
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in sorted(share.items(), key=lambda kv: -kv[1]) if v >= 0.01)
        idx = uc.result.classes[cls]
        rect = np.mean(uc.result.component_var.get("axis_orthogonality", np.zeros_like(uc.result.u))[:, idx]
                       / uc.result.u[:, idx] ** 2, axis=0)  # fmt: skip
        sd_f, sd_r, _p = expected_spread(n, m // n, share.get("local_g", 0.0), trials=4000, rect_share=rect)
        lines.append(
            f"| {cls} | {m} | {100 * frac:.1f} % | {rms:.2f} | {'yes' if ok else 'NO'} | "
            f"±{100 * sd_f:.1f} % / ±{sd_r:.2f} | {shares} |"
        )
    lines += ["", "Plan (before motion) against the Monte Carlo, gyro parameters: RMS over the runs of the error "
              "less the realised run-level type-B effect (local g, azimuth, latitude, axis tilts; first order, same "
              "estimator), divided by the plan's σ_total. The check is read per class (the issue's \"per class (gyro "
              "bias, scale, misalignment, g-sensitivity)\"): the RMS over the class's parameters and runs, target "
              "within ×1.2 either way; with 120 runs the per-parameter ratios are held to ×1.2 too (the slow "
              "test):", "",
              "| class | class ratio | within ×1.2 | 1σ sampling spread | parameters | ratio per parameter |",
              "|---|---:|---|---:|---|---|"]  # fmt: skip
    per_class = plan_class_ratios(uc)
    for cls, r in plan_ratios(uc).items():
        names = GYRO_CLASSES[cls]
        c = per_class[cls]
        ok = 1 / PLAN_RATIO <= c <= PLAN_RATIO
        flag = [n for n in names if n in uc.plan_unidentified]
        lines.append(
            f"| {cls} | {c:.2f} | {'yes' if ok else 'NO'} | ±{1 / np.sqrt(2 * n * (len(names) - len(flag))):.2f} | "
            f"{', '.join(names)} | {', '.join(f'{v:.2f}' for v in r)}"
            + (f" (plan flags {', '.join(flag)})" if flag else "")
            + " |"
        )
    lines += [
        "",
        f"With {n} runs the RMS of one parameter scatters by about ±{100 / np.sqrt(2 * n):.0f} % (1σ) even for a "
        "correct σ. The per-step attitude error and the time base's residual stay in the compared errors.",
    ]
    lines += uc.notes
    body = "\n".join(lines)
    write_section("gyro_coverage", "Coverage of the whole unit's certificate, gyros included (issue 25)", body)
    return body


@dataclass
class NoiseCheck:
    """The gyro parameters' errors from the simulated gyro noise alone, through the estimator (:func:`noise_check`)."""

    names: list[str]
    effect: np.ndarray
    """(seeds, gyro states): δx̂ = A⁻¹ Σ_k H_kᵀ R⁻¹ v_k for each seed's noise v, SI."""
    sigma: np.ndarray
    """The run's identification σ (white noise ⊕ bias instability: the budget's first two lines), SI."""
    seeds: list[int]
    run_error: np.ndarray
    """The recorded run's own error (estimate − truth) of the gyro states, SI."""
    run_effect: np.ndarray
    """The recorded run's own realised gyro noise through the same gain, SI."""

    def class_rms(self) -> dict[str, float]:
        """RMS of effect/σ per gyro class (over seeds and the class's parameters); 1 for a correct budget."""
        z = self.effect / self.sigma
        idx = {c: [self.names.index(n) for n in v] for c, v in GYRO_CLASSES.items()}
        return {c: float(np.sqrt(np.mean(z[:, i] ** 2))) for c, i in idx.items()}


def noise_check(folder: Path, seeds: list[int]) -> NoiseCheck:
    """Many realisations of the only noise that matters for the gyro states, through the actual estimator.

    For each seed the simulated world's own gyro noise streams (white ARW + the bias-instability flicker bank; they
    depend on the seed and the sample index only, drivers.sim.imu_model) at the sample indices of one recorded run's
    acquisition windows, times the identification's linear gain on that run's data, K_k = A⁻¹ H_kᵀ R⁻¹ (the batch
    estimate is linear in the output; KF ≡ batch): δx̂ = Σ_k K_k v_k. Compared with the run's identification
    covariance, white noise ⊕ bias instability (calibration.json's, the budget's first two lines), this tests the
    budget's and the plan's propagation of the gyro noise without the other inputs and without running the motion.
    """
    from benches.identify import combined_uncertainty, estimate, load_run
    from drivers.sim.world import SimulatedWorld

    data = load_run(folder)
    model = data.model
    est = estimate(data, "batch")
    unc = combined_uncertainty(data, est)
    gi = [k for k, n in enumerate(model.names) if n.startswith("gyro_")]
    fs, r = float(data.config.unit.sample_rate), est.noise_variance
    gains, index = [], []
    for w in data.windows:
        h = model.design_matrix(w.f_ref, w.omega, w.earth)[:, 3:, :]  # the gyro rows of H
        gains.append(np.einsum("pq,maq->mpa", est.covariance_white[gi], h) / r[None, None, 3:])
        index.append(np.rint(w.t * fs).astype(np.int64))  # unit time stamps k/f_s (+ µs jitter) → sample k
    k_all, idx = np.concatenate(gains), np.concatenate(index)

    def effect(seed: int) -> np.ndarray:
        world = SimulatedWorld.from_bench(data.config, seed)  # type: ignore[arg-type]
        noise = world._model.streams(0, int(idx.max()) + 1)[idx, 3:6]  # the gyro's output-referred noise
        return np.einsum("mpa,ma->p", k_all, noise)

    p_time = unc.time_covariance if unc.time_covariance is not None else 0.0
    sigma = np.sqrt(np.diag(unc.covariance - p_time))[gi]
    names = [model.names[k] for k in gi]
    assert data.truth is not None
    truth = np.array([data.truth[n] for n in names])
    run_seed = int(data.run.header.seed)
    return NoiseCheck(names, np.array([effect(s) for s in seeds]), sigma, list(seeds), est.x[gi] - truth,
                      effect(run_seed))  # fmt: skip


def save_scores(uc: UnitCoverage, out: Path) -> Path:
    """Write a Monte Carlo's scores (errors, u, U, run-level effect, plan, seeds, names, u² components, wall) to npz."""
    np.savez(out, errors=uc.result.errors, u=uc.result.u, U=uc.result.expanded, effect=uc.type_b_effect,
             plan=uc.plan_sigma, seeds=np.array(uc.result.seeds), names=np.array(uc.names),
             unidentified=np.array(uc.plan_unidentified, dtype=str), wall=np.array(uc.wall_s),
             **{f"comp_{k}": v for k, v in uc.result.component_var.items()})  # fmt: skip
    return out


def load_scores(paths: list[Path]) -> UnitCoverage:
    """One Monte Carlo from the scores of parts run in separate processes (:func:`save_scores`), in seed order;
    the wall time is the longest part's (the parts ran at the same time)."""
    parts = [np.load(p) for p in paths]
    names = [str(n) for n in parts[0]["names"]]
    if any([str(n) for n in q["names"]] != names for q in parts):
        raise RuntimeError("the score files hold different states")
    order = np.argsort(np.concatenate([q["seeds"] for q in parts]), kind="stable")
    cat = {k: np.concatenate([q[k] for q in parts])[order] for k in ("errors", "u", "U", "effect", "seeds")}
    keys = set.intersection(*({k for k in q.files if k.startswith("comp_")} for q in parts))
    comp = {k[5:]: np.concatenate([q[k] for q in parts])[order] for k in sorted(keys)}
    seeds = [int(x) for x in cat["seeds"]]
    res = CoverageResult(cat["errors"], cat["u"], cat["U"], comp, seeds, _classes(names))
    return UnitCoverage(res, names, parts[0]["plan"], tuple(str(x) for x in parts[0]["unidentified"]), cat["effect"],
                        max(float(q["wall"]) for q in parts))  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run the Monte Carlo (or a part of it: ``--first-seed``, ``--save``) and write its RESULTS.md section; or
    write the section from parts run in separate processes (``--merge a.npz b.npz``)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=COVERAGE_RUNS)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--first-seed", type=int, default=25000)
    ap.add_argument("--save", type=Path, default=None, help="write the scores here and no RESULTS.md section")
    ap.add_argument("--merge", type=Path, nargs="+", default=None, help="score files of parts: write the section")
    args = ap.parse_args(argv)
    if args.merge:
        uc = load_scores(args.merge)
        print(section(uc, args.rate))
        return 0
    uc = run_unit_coverage(args.runs, rate=args.rate, first_seed=args.first_seed, log=print)
    out = args.save or Path(tempfile.mkdtemp(prefix="tb-unit-coverage-scores-")) / "scores.npz"
    save_scores(uc, out)
    if args.save is None:
        print(section(uc, args.rate))
    print(f"scores saved to {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
