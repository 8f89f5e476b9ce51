"""A thermal calibration run on the simulated world, device level (docs/methods/thermal.md).

For each plateau: command the chamber's set point, soak (the unit's own temperature channel against
:class:`analysis.thermal.soak.SoakCriterion`), then run the calibration sequence — the ten-step groups A, B, C
(eight 45° holds about the group's axis, then one revolution each way at ``spin_rate``) — and identify both
triads from it (:mod:`benches.thermal.plateau`). The plateau estimates are then fitted by
:func:`analysis.thermal.model.fit_thermal_model`. Bench time is the unit's sample clock; the run goes as fast
as the machine allows.

This drives the :class:`~drivers.sim.world.SimulatedWorld` directly (the table and chamber commands the
runner would send), so it serves the Monte Carlo of the thermal model and the speed benchmark.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from analysis.earth import earth_rate_enu
from analysis.gimbal import body_rate, body_to_nav, gravity_in_body
from analysis.identification.plan import GROUPS
from analysis.thermal.model import PlateauEstimate, ThermalModel, fit_thermal_model
from analysis.thermal.soak import SoakCriterion, SoakMonitor
from analysis.units import CELSIUS_ZERO, DEG
from benches.thermal.plateau import THERMAL_PARAM_NAMES, PlateauData, identify_plateau
from drivers.protocols import TableStatus
from drivers.sim.world import SimulatedWorld


@dataclass(frozen=True)
class ThermalPlan:
    """What a simulated thermal run does (SI).

    Attributes
    ----------
    plateaus : tuple of float
        Chamber set points, K, in order.
    soak : SoakCriterion
    hold : float
        Acquisition per held position, s.
    settle : float
        Wait after in-position / at-rate before acquiring, s.
    spin_rate : float
        Rate of the spins, rad/s.
    block : float
        Length of one read, s (the table is read after each).
    """

    plateaus: tuple[float, ...]
    soak: SoakCriterion = field(default_factory=SoakCriterion)
    hold: float = 30.0
    settle: float = 1.0
    spin_rate: float = 30.0 * DEG
    block: float = 0.5


@dataclass
class ThermalRun:
    """Outcome of :func:`run_thermal` (bench time of the run; wall-clock and process CPU time it took, s)."""

    plateaus: list[PlateauEstimate]
    model: ThermalModel | None
    bench_seconds: float
    wall_seconds: float
    soak_seconds: list[float]
    cpu_seconds: float = 0.0


class _Executor:
    """Reads the unit block by block, keeping the table fed and the samples of the counted windows."""

    def __init__(self, world: SimulatedWorld, plan: ThermalPlan) -> None:
        self.w = world
        self.plan = plan
        self.n_block = max(1, int(round(plan.block * world.sample_rate)))
        sc = world.scale
        self._lsb = np.array([sc.accel_lsb] * 3 + [sc.gyro_lsb] * 3)
        self._t_lsb = float(sc.temperature_lsb)
        self._earth_n = earth_rate_enu(world.cfg.latitude)
        self._g = world.cfg.local_g
        self._mount = np.asarray(world.cfg.mounting, dtype=float)

    def read(self, n: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(time (n,), outputs (n, 6) SI, unit temperature (n,) K) of the next ``n`` samples."""
        n = self.n_block if n is None else n
        k0 = self.w.samples_produced
        fr = self.w.produce(n)
        self.w.heartbeat()
        t = fr.counter.astype(np.int64) / self.w.sample_rate if len(fr.counter) else np.arange(k0, k0) / 1.0
        y = fr.counts.astype(float) * self._lsb
        temp = fr.temperature.astype(float) * self._t_lsb + CELSIUS_ZERO
        return t, y, temp

    def wait(self, predicate: Callable[[], bool], timeout: float, what: str) -> None:
        t_end = self.w.time + timeout
        while not predicate():
            if self.w.time > t_end:
                raise RuntimeError(f"simulated thermal run: {what} not reached within {timeout:g} s")
            self.read()

    def acquire(self, seconds: float, data: PlateauData) -> None:
        """Count ``seconds`` of samples, with the table's angles interpolated between block-end readings."""
        s0 = self.w.table_state()
        n_total = int(round(seconds * self.w.sample_rate))
        done = 0
        while done < n_total:
            n = min(self.n_block, n_total - done)
            t, y, temp = self.read(n)
            s1 = self.w.table_state()
            dt = max(s1.time - s0.time, 1e-12)
            frac = (t - s0.time) / dt
            ang = s0.angles[None, :] + frac[:, None] * (s1.angles - s0.angles)[None, :]
            # the block's mean rate from the encoder angles (the true angles): the table's rate jitter averages
            # out of it exactly as it does out of the gyros' mean
            rates = np.broadcast_to((s1.angles - s0.angles) / dt, ang.shape)
            c_bn = body_to_nav(ang, self._mount)
            data.accel.append(y[:, :3])
            data.gyro.append(y[:, 3:])
            data.f_ref.append(gravity_in_body(ang, self._g, self._mount))
            data.omega.append(body_rate(ang, rates, self._mount))
            data.earth.append(np.einsum("j,njk->nk", self._earth_n, c_bn))
            data.temperature.append(temp)
            data.time.append(t)
            s0 = s1
            done += n

    def move(self, angles: Sequence[float]) -> None:
        self.w.command_position(list(angles))
        self.wait(lambda: bool(self.w.table_state().status & TableStatus.IN_POSITION), 120.0, "in position")
        self.read(int(round(self.plan.settle * self.w.sample_rate)))

    def spin(self, axis: int, rate: float, data: PlateauData) -> None:
        self.w.command_rate(axis, rate)
        self.wait(lambda: bool(self.w.table_state().status & TableStatus.AT_RATE), 120.0, "at rate")
        self.read(int(round(self.plan.settle * self.w.sample_rate)))
        self.acquire(2.0 * math.pi / abs(rate), data)
        self.w.command_stop()
        self.wait(lambda: not (self.w.table_state().status & TableStatus.MOVING), 120.0, "at rest")

    def soak(self, setpoint: float) -> float:
        """Set point, then read until the unit has soaked; returns the soak's bench time, s."""
        self.w.chamber_run(True)
        if not self.w.chamber_setpoint(setpoint):
            raise ValueError(f"set point {setpoint - CELSIUS_ZERO:g} °C is outside the simulated chamber's range")
        mon = SoakMonitor(self.plan.soak, setpoint + self.w.cfg.chamber.self_heating, self.w.time)  # type: ignore[union-attr]
        n = max(self.n_block, int(round(10.0 * self.w.sample_rate)))
        while not mon.settled:
            if mon.timed_out:
                raise RuntimeError(f"simulated thermal run: soak at {setpoint - CELSIUS_ZERO:g} °C: {mon.status()}")
            t, _, temp = self.read(n)
            mon.feed(t, temp)
        return mon.now - mon.start

    def sequence(self) -> PlateauData:
        """The ten-step groups: eight 45° holds about the group's gimbal, then a revolution each way."""
        data = PlateauData()
        for base, axis in GROUPS.values():
            for k in range(8):
                ang = list(base)
                ang[axis] += k * math.pi / 4.0
                self.move(ang)
                self.acquire(self.plan.hold, data)
            self.move(list(base))
            for sign in (1.0, -1.0):
                self.spin(axis, sign * self.plan.spin_rate, data)
                self.move(list(base))
        return data


def run_thermal(
    world: SimulatedWorld,
    plan: ThermalPlan,
    *,
    fit: bool = True,
    max_order: int = 3,
    reference: float | None = None,
    progress: Callable[[str], None] | None = None,
) -> ThermalRun:
    """Run the plan on ``world`` (which must have a chamber) and fit the thermal model (``fit``)."""
    if world.chamber is None:
        raise ValueError("a thermal run needs a simulated chamber (simulation: chamber:)")
    ex = _Executor(world, plan)
    cfg = world.cfg
    acc_var = np.asarray(cfg.accel_noise.white, dtype=float) ** 2 * world.sample_rate + world.scale.accel_lsb**2 / 12
    gyr_var = np.asarray(cfg.gyro_noise.white, dtype=float) ** 2 * world.sample_rate + world.scale.gyro_lsb**2 / 12
    wall0, cpu0 = time.perf_counter(), time.process_time()
    t0 = world.time
    estimates: list[PlateauEstimate] = []
    soaks: list[float] = []
    previous = cfg.chamber.ambient  # type: ignore[union-attr]
    for sp in plan.plateaus:
        soaks.append(ex.soak(sp))
        data = ex.sequence()
        x, cov, temp, rate = identify_plateau(data, acc_var, gyr_var)
        direction = "heating" if sp > previous else "cooling"
        previous = sp
        estimates.append(PlateauEstimate(temp, x, cov, rate, direction))
        if progress is not None:
            progress(f"plateau {sp - CELSIUS_ZERO:g} °C: unit {temp - CELSIUS_ZERO:.2f} °C, soak {soaks[-1]:.0f} s")
    model = fit_thermal_model(estimates, THERMAL_PARAM_NAMES, reference=reference, max_order=max_order) if fit else None
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    return ThermalRun(estimates, model, world.time - t0, wall, soaks, cpu)
