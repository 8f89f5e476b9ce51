"""Monte Carlo of the thermal calibration THROUGH THE RUNNER: per seed, ``tablebench run`` of the shipped
thermal procedure (5 plateaus, the ten-step sequence at each) on the simulated thermal bench
``benches/sim-thermal-white.yaml`` (chamber served on loopback in its dialect, recording written), then the
thermal identification of the recording (:func:`benches.thermal.identify.identify_thermal`) scored against the
simulated truth: recovery of every coefficient, order selection by BIC, the residual after compensation, and
the speed of the run (docs/methods/thermal.md).

Used by the slow test ``tests/benches/thermal/test_thermal_run.py`` and ``benchmarks/bench_thermal.py``.
"""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.identification.model import error_matrices
from analysis.thermal.model import fit_thermal_model
from analysis.units import celsius_to_kelvin
from benches.bench_config import load_bench
from benches.cli.main import main
from benches.recording import open_recording
from benches.thermal.calibrate import thermal_calibrate
from benches.thermal.correct import gyro_matrices, thermal_correct
from benches.thermal.document import load_thermal
from benches.thermal.plateau import THERMAL_PARAM_NAMES
from benches.thermal.truth import truth_polynomials

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benches" / "sim-thermal-white.yaml"
PROCEDURE = ROOT / "procedures" / "thermal-plateaus.yaml"
PLATEAUS_C = (-20.0, 0.0, 20.0, 40.0, 60.0)
SHIPPED_SOAK = "tolerance_k: 0.1, rate_k_per_min: 0.01, dwell_s: 120"
MC_SOAK = "tolerance_k: 0.03, rate_k_per_min: 0.003, dwell_s: 120"
"""Soak of the Monte Carlo: the unit within 0.03 K, changing < 0.003 K/min, for 2 min (the shipped procedure:
0.1 K, 0.01 K/min) — so that the unit's temperature moves by less than ~0.03 K during the 25-minute sequence
and each plateau's estimate belongs to one temperature (a cubic gyro bias reaches 0.2 °/h/K at 60 °C)."""


def mc_procedure_text() -> str:
    """The shipped thermal procedure with the Monte Carlo's tighter soak."""
    text = PROCEDURE.read_text(encoding="utf-8")
    if text.count(SHIPPED_SOAK) != len(PLATEAUS_C):
        raise RuntimeError(f"{PROCEDURE}: expected {len(PLATEAUS_C)} soaks '{SHIPPED_SOAK}'")
    return text.replace(SHIPPED_SOAK, MC_SOAK)


def parameter_class(name: str, by_triad: bool = False) -> str:
    """Class of a thermal-model parameter: bias, scale, misalignment, quadratic, size effect (prefixed by the
    triad, accel or gyro, when ``by_triad``)."""
    triad = "gyro" if name.startswith("g") else "accel"
    core = name[1:] if triad == "gyro" else name
    kind = {"b": "bias", "S": "scale", "t": "misalignment", "d": "quadratic", "r": "size effect"}[core[0]]
    return f"{triad} {kind}" if by_triad else kind


@dataclass
class MonteCarlo:
    """Per seed and parameter: |error|/u of each coefficient (fitted at the simulated order), whether BIC chose
    the simulated order, and at how many of the check temperatures the compensated truth left the model's U."""

    seeds: list[int] = field(default_factory=list)
    z: list[list[np.ndarray]] = field(default_factory=list)
    order_hit: list[list[bool]] = field(default_factory=list)
    residual_outside: list[list[int]] = field(default_factory=list)
    residual_ratio: list[np.ndarray] = field(default_factory=list)  # per seed: (grid, P) |truth − model| / U
    compensated: list[np.ndarray] = field(default_factory=list)  # per seed: compensation_residual (grid, 12)
    residual_points: int = 0
    speed: list[float] = field(default_factory=list)  # bench time / wall time of the run, per seed
    cpu_speed: list[float] = field(default_factory=list)  # bench time / process CPU time of the run, per seed
    bench_seconds: list[float] = field(default_factory=list)

    def fractions(self, by_triad: bool = False) -> dict[str, tuple[float, float, float, int]]:
        """Per class: (fraction of coefficients with |error| > U(k=2), BIC order hit rate, fraction of residual
        checks outside U(k=2), number of coefficients)."""
        out: dict[str, list[float]] = {}
        for zs, hits, res in zip(self.z, self.order_hit, self.residual_outside, strict=True):
            for p, name in enumerate(THERMAL_PARAM_NAMES):
                t = out.setdefault(parameter_class(name, by_triad), [0.0, 0.0, 0.0, 0.0, 0.0])
                t[0] += float(np.sum(zs[p] > 2.0))
                t[1] += zs[p].size
                t[2] += float(hits[p])
                t[3] += 1.0
                t[4] += res[p]
        return {c: (t[0] / t[1], t[2] / t[3], t[4] / (t[3] * self.residual_points), int(t[1])) for c, t in out.items()}

    def merge(self, other: MonteCarlo) -> None:
        """Append another Monte Carlo's seeds (same grid) to this one."""
        for name in ("seeds", "z", "order_hit", "residual_outside", "residual_ratio", "compensated", "speed",
                     "cpu_speed", "bench_seconds"):  # fmt: skip
            getattr(self, name).extend(getattr(other, name))
        self.residual_points = other.residual_points or self.residual_points

    def compensated_outside(self) -> dict[str, tuple[float, int]]:
        """Per class (accel/gyro bias/scale): (fraction of checks with residual > stated U, checks)."""
        out: dict[str, list[int]] = {}
        for r in self.compensated:
            for j, name in enumerate(RESIDUAL_PARAMS):
                t = out.setdefault(parameter_class(name, True), [0, 0])
                t[0] += int(np.sum(r[:, j] > 1.0))
                t[1] += r.shape[0]
        return {c: (t[0] / t[1], t[1]) for c, t in out.items()}


def run_one(seed: int, folder: Path, procedure: Path, bench: Path = BENCH) -> tuple[float, float, float]:
    """``tablebench run`` of ``procedure`` on ``bench`` with ``seed`` into ``folder`` (recording only);
    returns (bench seconds, wall seconds, process CPU seconds) of the run."""

    args = ["run", "--bench", str(bench), "--procedure", str(procedure), "--out", str(folder), "--seed", str(seed),
            "--no-identify", "--no-certificate", "--plain"]  # fmt: skip
    wall0, cpu0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stderr(io.StringIO()) as err, contextlib.redirect_stdout(io.StringIO()):
        code = main(args)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    if code != 0:
        raise RuntimeError(f"seed {seed}: tablebench run exited {code}: {err.getvalue()[-2000:]}")
    with open_recording(folder / "recording.h5") as rec:
        bench_s = rec.n_samples / float(rec.header.sample_rate_hz)
    return bench_s, wall, cpu


def score(mc: MonteCarlo, model, plateaus, truth, ref: float, grid: np.ndarray) -> None:  # noqa: ANN001
    """Add one identified run (BIC model, plateau estimates) to ``mc`` against the simulated ``truth``."""
    true_orders = [len(c) - 1 for c in truth]
    fixed = fit_thermal_model(plateaus, THERMAL_PARAM_NAMES, reference=ref, orders=true_orders)
    values, u = model.evaluate(grid)
    zs, hits, res = [], [], []
    ratio = np.zeros_like(values)
    for p, name in enumerate(THERMAL_PARAM_NAMES):
        c, cov = fixed.parameter(name)
        zs.append(np.abs(c - np.asarray(truth[p])) / np.sqrt(np.diag(cov)))
        hits.append(model.orders[p] == true_orders[p])
        p_true = np.polyval(np.asarray(truth[p])[::-1], grid - model.reference)
        ratio[:, p] = np.abs(p_true - values[:, p]) / (2.0 * u[:, p])
        res.append(int(np.sum(ratio[:, p] > 1.0)))
    mc.z.append(zs)
    mc.order_hit.append(hits)
    mc.residual_outside.append(res)
    mc.residual_ratio.append(ratio)


RESIDUAL_PARAMS = ("b_x", "b_y", "b_z", "S_x", "S_y", "S_z", "gb_x", "gb_y", "gb_z", "gS_x", "gS_y", "gS_z")
"""The residual bias and scale factors checked after compensation."""


def compensation_residual(cert: dict, model, truth: list, ref: float) -> np.ndarray:  # noqa: ANN001
    """|residual| / stated U of the residual bias and scale of both triads after compensation, at each
    temperature of the certificate's model table: (grid, 12), ``RESIDUAL_PARAMS`` order.

    The compensation is :func:`benches.thermal.correct.thermal_correct` (what ``tablebench correct`` applies)
    on the simulated unit's exact outputs at that temperature (no noise): zero input gives the residual bias;
    ±1 g (accelerometer) or ±100 °/s (gyro) along each axis, differenced, the residual scale factor. Stated U:
    the certificate's ``U_model_at_grid`` of that parameter at that temperature.
    """

    grid = np.asarray(cert["grid_K"])
    out = np.zeros((grid.size, len(RESIDUAL_PARAMS)))
    g, w = 9.80665, np.radians(100.0)
    for k, t in enumerate(grid):
        x = np.array([np.polyval(np.asarray(c)[::-1], t - ref) for c in truth])  # the truth at t (30,)
        m_a, b_a, d_a, _ = error_matrices(x[:18])
        m_g, b_g = gyro_matrices(x[None, :])
        f_in = np.vstack([np.zeros(3), g * np.eye(3), -g * np.eye(3), np.zeros((6, 3))])
        w_in = np.vstack([np.zeros((7, 3)), w * np.eye(3), -w * np.eye(3)])
        f_out = f_in @ m_a.T + b_a + d_a * f_in**2  # at rest: no size effect; spinning: f = 0
        w_out = w_in @ m_g[0].T + b_g[0]
        f_out[7:] = b_a  # the rate rows have f = 0 (their size effect is checked by the accelerometer rows only)
        hat, _ = thermal_correct(model, f_out, w_out, np.full(len(f_in), t), "warn")
        res = np.concatenate([
            hat[0, :3],
            (np.diag(hat[1:4, :3]) - np.diag(hat[4:7, :3])) / (2 * g) - 1.0,
            hat[0, 3:],
            (np.diag(hat[7:10, 3:]) - np.diag(hat[10:13, 3:])) / (2 * w) - 1.0,
        ])
        stated = np.array([cert["parameters"][n]["U_model_at_grid"][k] for n in RESIDUAL_PARAMS])
        out[k] = np.abs(res) / stated
    return out


def run_montecarlo(
    seeds: range | list[int],
    progress: Callable[[str], None] | None = None,
    workdir: str | Path | None = None,
    keep: bool = False,
) -> MonteCarlo:
    """Per seed: a 5-plateau thermal run through the runner, its thermal calibration and certificate (what
    ``tablebench run`` issues), scored."""

    cfg = load_bench(BENCH).simulation
    assert cfg is not None and cfg.thermal is not None
    truth = truth_polynomials(cfg)
    ref = cfg.thermal.reference
    grid = np.linspace(celsius_to_kelvin(PLATEAUS_C[0]), celsius_to_kelvin(PLATEAUS_C[-1]), 17)
    mc = MonteCarlo(residual_points=grid.size)
    base = Path(tempfile.mkdtemp(prefix="thermal-mc-", dir=workdir))
    proc = base / "thermal-plateaus-mc.yaml"
    proc.write_text(mc_procedure_text(), encoding="utf-8")
    try:
        for seed in seeds:
            folder = base / f"seed-{seed}"
            bench_s, wall, cpu = run_one(seed, folder, proc)
            cal_path, pdf = thermal_calibrate(folder, reference=ref, say=lambda m: None)
            tf = load_thermal(cal_path)
            assert pdf is not None
            cert = json.loads(pdf.with_suffix(".json").read_text(encoding="utf-8"))
            mc.seeds.append(seed)
            mc.speed.append(bench_s / wall)
            mc.cpu_speed.append(bench_s / max(cpu, 1e-9))
            mc.bench_seconds.append(bench_s)
            score(mc, tf.model, tf.estimates(), truth, ref, grid)
            mc.compensated.append(compensation_residual(cert, tf.model, truth, ref))
            if not keep:
                shutil.rmtree(folder, ignore_errors=True)
            if progress is not None:
                progress(f"seed {seed}: orders {tf.model.orders}, {mc.speed[-1]:.0f}x real time (wall), "
                         f"{mc.cpu_speed[-1]:.0f}x (CPU)")  # fmt: skip
    finally:
        if not keep:
            shutil.rmtree(base, ignore_errors=True)
    return mc
