"""The runner's chamber steps: ``soak`` and ``ramp`` with the bench's chamber (docs/methods/thermal.md).

:class:`ThermalSteps` is created by :class:`benches.runner.Runner` when the procedure has chamber steps; it
uses the bench's auxiliary device ``"chamber"`` (:class:`drivers.chamber.base.Chamber`).

* soak: start the chamber, write the set point (read back), then read the unit until its own temperature
  channel meets the soak criterion (:class:`analysis.thermal.soak.SoakMonitor`); the step fails after its
  time-out. The table holds still; samples are recorded, not counted.
* ramp: write the start set point, then move the set point by ``ramp_rate`` every ``RAMP_UPDATE`` s of bench
  time while the following steps (the repeated table sequence) run, until the end temperature.
* every ``RECORD_EVERY`` s of bench time, the chamber's set point and air temperature and the unit's
  temperature go to the recording's own group for the chamber, ``/aux/chamber`` (channels ``setpoint``, ``air``,
  ``unit``, K; ``running``, ``alarm``, 0/1; ``benches/RECORDING.md``), and the same reading to the event log as
  one structured line (``chamber: setpoint_K=… air_K=… unit_K=…``); a chamber alarm stops the run.
* a soak reads the unit in blocks of up to ``SOAK_BLOCK`` s (the table holds still; the soak criterion works
  on 1-second means), so a long soak costs few reads.
* every exit path (end, error, Ctrl-C, lost link) leaves the chamber as the safety rules say
  (:func:`drivers.chamber.safety.leave_safe`: safe set point, optional warm-up, stop).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.thermal.soak import SoakCriterion, SoakMonitor
from analysis.units import kelvin_to_celsius
from drivers.chamber.base import ChamberError
from drivers.chamber.safety import leave_safe
from drivers.protocols import ImuBlock, Reading
from procedures.steps import Ramp, Soak, Step

if TYPE_CHECKING:  # pragma: no cover
    from benches.recorded_run import RecordedRun

RECORD_EVERY = 30.0
"""Bench seconds between chamber readings in the recording."""
RAMP_UPDATE = 10.0
"""Bench seconds between set-point updates during a ramp."""
SOAK_BLOCK = 10.0
"""Largest read during a soak, bench s (at most a quarter of the soak's dwell)."""
AUX_NAME = "chamber"
"""The recording group of the chamber's readings: ``/aux/chamber``."""
AUX_UNITS = {"setpoint": "K", "air": "K", "unit": "K", "running": "1", "alarm": "1"}
"""Units of the recorded chamber channels."""


def is_thermal_run(rr: RecordedRun) -> bool:
    """True when the recording holds a completed soak step (a thermal procedure: ``tablebench run`` then hands
    it to :func:`benches.thermal.calibrate.thermal_calibrate`). Here, beside the soak step, so the run's end asks
    without importing the thermal identification and certificate (a module the runner has loaded anyway)."""
    return any(s.kind == Soak.kind and s.status == "complete" for s in rr.steps)


class ThermalSteps:
    """Soak / ramp execution and the chamber's exit path for one runner."""

    def __init__(self, runner: Any) -> None:
        """``runner``: the :class:`benches.runner.Runner` executing the procedure."""
        self.r = runner
        self.chamber: Any = runner.aux.get("chamber")
        self._monitor: SoakMonitor | None = None
        self._ramp: tuple[float, float, float, float] | None = None  # (t0 s, start K, end K, rate K/s)
        self._next_ramp = -math.inf
        self._next_record = -math.inf
        self._used = False
        self._unit = math.nan

    def _need(self, step: Step) -> Any:
        if self.chamber is None:
            raise self.r.aborted("failed", f"step {step.name!r}: the bench has no temperature chamber")
        return self.chamber

    def _fail(self, step: Step, exc: Exception) -> Exception:
        return self.r.aborted("failed", f"step {step.name!r}: chamber refused: {exc}")

    # ---- per block ------------------------------------------------------------------------------------
    def on_block(self, step: Step, block: ImuBlock) -> None:
        """Feed the soak monitor, move a running ramp, record the chamber now and then."""
        if len(block) == 0:
            return
        t = float(block.time[-1])
        good = np.isfinite(block.temperature)
        if np.any(good):
            self._unit = float(block.temperature[good][-1])
        if self._monitor is not None:
            self._monitor.feed(block.time, block.temperature)
        if self._ramp is not None and t >= self._next_ramp:
            self._move_ramp(step, t)
        if self._used and t >= self._next_record:
            self._next_record = t + RECORD_EVERY
            self.record(step, t)

    def record(self, step: Step, t: float) -> None:
        """One chamber reading into the event log; a chamber alarm stops the run."""
        try:
            r = self.chamber.read()
        except ChamberError as exc:
            raise self._fail(step, exc) from exc
        add_aux = getattr(self.r.rec, "add_aux", None)  # a recorder without auxiliary groups: event log only
        if add_aux is not None:
            values = {"setpoint": float(r.setpoint), "air": float(r.air), "unit": self._unit,
                      "running": float(bool(r.running)), "alarm": float(bool(r.alarm))}  # fmt: skip
            add_aux(AUX_NAME, t, Reading(values, dict(AUX_UNITS)))
        self.r.rec.event(
            t,
            "info",
            f"chamber: setpoint_K={r.setpoint:.3f} air_K={r.air:.3f} unit_K={self._unit:.3f} "
            f"running={r.running} alarm={r.alarm} ({r.detail})",
        )
        if r.alarm:
            raise self.r.aborted("failed", f"step {step.name!r}: the chamber reports an alarm ({r.detail})")

    def _move_ramp(self, step: Step, t: float) -> None:
        assert self._ramp is not None
        t0, start, end, rate = self._ramp
        sp = start + math.copysign(min(rate * (t - t0), abs(end - start)), end - start)
        try:
            self.chamber.set_setpoint(sp)
        except ChamberError as exc:
            raise self._fail(step, exc) from exc
        self._next_ramp = t + RAMP_UPDATE
        if sp == end:
            self._ramp = None
            self.r.rec.event(t, "info", f"chamber: ramp reached {kelvin_to_celsius(end):g} °C")

    # ---- steps ----------------------------------------------------------------------------------------
    def execute(self, step: Step) -> None:
        """Run a soak or a ramp start."""
        ch = self._need(step)
        self._used = True
        try:
            ch.start()
            if isinstance(step, Soak):
                self._ramp = None
                ch.set_setpoint(step.setpoint)
            elif isinstance(step, Ramp):
                ch.set_setpoint(step.start)
        except ChamberError as exc:
            raise self._fail(step, exc) from exc
        t = self.r._time()
        if isinstance(step, Ramp):
            self._ramp = (t, step.start, step.end, step.ramp_rate)
            self._next_ramp = t + RAMP_UPDATE
            self.r.rec.event(t, "info", f"chamber: {step.describe(None)}")
            return
        assert isinstance(step, Soak)
        self.r.rec.event(t, "info", f"chamber: {step.describe(None)}")
        crit = SoakCriterion(
            tolerance=step.tolerance,
            rate_limit=step.rate_limit,
            dwell=step.dwell,
            timeout=step.timeout,
            rate_window=max(60.0, min(300.0, step.dwell)),
        )
        mon = SoakMonitor(crit, step.target, t)
        self._monitor = mon
        n = max(self.r.block, int(round(min(SOAK_BLOCK, step.dwell / 4.0) * self.r.rate)))
        try:
            while not mon.settled:
                if mon.timed_out:
                    raise self.r.aborted("failed", f"step {step.name!r}: soak timed out: {mon.status()}")
                self.r._read_block(step, n, False)  # one read of up to SOAK_BLOCK s: the table holds still
                self.r._show(self.r.progress.step, step.name, mon.status())
        finally:
            self._monitor = None
        self.r.rec.event(mon.now, "info", f"chamber: soaked ({mon.status()})")

    # ---- exit path ------------------------------------------------------------------------------------
    def leave_safe(self) -> None:
        """Safe set point, optional warm-up (reading the unit meanwhile), stop; problems go to the event log."""
        if self.chamber is None or not self._used:
            return
        self._ramp = None

        def wait(seconds: float) -> None:
            n = max(1, int(round(seconds * self.r.rate)))
            block = self.r.unit.read(n)
            self.r.rec.add_samples(block)
            self.r._sample += len(block)

        def clock() -> float:
            return self.r._sample / self.r.rate

        problems = leave_safe(self.chamber, wait=wait, clock=clock)
        t = self.r._time()
        for p in problems:
            self.r.rec.event(t, "error", p)
        if not problems:
            self.r.rec.event(
                t,
                "info",
                f"chamber at its safe set point {kelvin_to_celsius(self.chamber.settings.safe_setpoint):g} "
                "°C and stopped",
            )
