"""Monte Carlo of the simulated thermal calibration: recovery of every simulated coefficient, order selection
by BIC, the residual after compensation and the simulation speed (docs/methods/thermal.md).

Used by the slow test ``tests/benches/test_thermal_montecarlo.py`` and ``benchmarks/bench_thermal.py``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from analysis.thermal.model import fit_thermal_model
from analysis.thermal.soak import SoakCriterion
from analysis.units import celsius_to_kelvin
from benches.thermal.plateau import THERMAL_PARAM_NAMES
from benches.thermal.simrun import ThermalPlan, run_thermal
from benches.thermal.truth import thermal_sim_config, truth_polynomials
from drivers.sim.world import SimulatedWorld

PLATEAUS_C = (-20.0, 0.0, 20.0, 40.0, 60.0)
SOAK = SoakCriterion(tolerance=0.03, rate_limit=0.003 / 60.0, dwell=120.0, rate_window=300.0)
"""Soak of the Monte Carlo plan: the unit within 0.03 K, changing < 0.003 K/min, for 2 min — so that its
temperature moves by less than ~0.01 K during the 20-minute sequence (a looser soak leaves the gyro bias,
whose cubic slope reaches 0.1 °/h/K at the range ends, drifting by a fraction of its uncertainty within the
sequence, and the plateau's estimate then belongs to no single temperature)."""


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
    residual_points: int = 0
    speed: list[float] = field(default_factory=list)  # bench time / wall time per seed
    cpu_speed: list[float] = field(default_factory=list)  # bench time / process CPU time per seed
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


def run_montecarlo(seeds: range | list[int], progress: Callable[[str], None] | None = None) -> MonteCarlo:
    """Simulate a 5-plateau thermal calibration per seed and score it against the simulated truth."""
    cfg = thermal_sim_config()
    truth = truth_polynomials(cfg)
    true_orders = [len(c) - 1 for c in truth]
    ref = cfg.thermal.reference  # type: ignore[union-attr]
    plan = ThermalPlan(plateaus=tuple(celsius_to_kelvin(t) for t in PLATEAUS_C), soak=SOAK)
    grid = np.linspace(celsius_to_kelvin(PLATEAUS_C[0]), celsius_to_kelvin(PLATEAUS_C[-1]), 17)
    mc = MonteCarlo(residual_points=grid.size)
    for seed in seeds:
        run = run_thermal(SimulatedWorld(cfg, seed), plan, reference=ref)
        assert run.model is not None
        mc.seeds.append(seed)
        mc.speed.append(run.bench_seconds / run.wall_seconds)
        mc.cpu_speed.append(run.bench_seconds / max(run.cpu_seconds, 1e-9))
        mc.bench_seconds.append(run.bench_seconds)
        fixed = fit_thermal_model(run.plateaus, THERMAL_PARAM_NAMES, reference=ref, orders=true_orders)
        values, u = run.model.evaluate(grid)
        zs, hits, res = [], [], []
        for p, name in enumerate(THERMAL_PARAM_NAMES):
            c, cov = fixed.parameter(name)
            zs.append(np.abs(c - np.asarray(truth[p])) / np.sqrt(np.diag(cov)))
            hits.append(run.model.orders[p] == true_orders[p])
            p_true = np.polyval(np.asarray(truth[p])[::-1], grid - ref)
            res.append(int(np.sum(np.abs(p_true - values[:, p]) > 2.0 * u[:, p])))
        mc.z.append(zs)
        mc.order_hit.append(hits)
        mc.residual_outside.append(res)
        if progress is not None:
            progress(f"seed {seed}: orders {run.model.orders}, {mc.speed[-1]:.0f}x real time")
    return mc
