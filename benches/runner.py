"""Execute a compiled procedure on a bench, recording everything, always leaving the table at rest.

Bench time is the unit's sample clock: the runner advances only by reading samples from the unit, so a
simulated bench runs as fast as the machine allows and a real one in real time, and every wait (in
position, settling, at rate, at rest) is counted in samples. Each step's samples go to the recorder, and
the table is read once per acquisition block.

Safety: every command of the procedure is checked against the turntable's limits before anything moves;
the controller gets a heartbeat every block; on Ctrl-C (SIGINT), SIGTERM, SIGHUP (the terminal or SSH connection
closed), a controller fault, or a lost link
the runner stops the table under control, waits for rest (bounded), records the interrupted step, marks the
recording, and says how to resume. On a simulated bench ``resume`` replays the completed steps without
recording them (the simulator is deterministic), so the resumed recording equals an uninterrupted one.
"""

from __future__ import annotations

import logging
import math
import signal
import threading
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from drivers.protocols import (
    ImuBlock,
    InertialUnit,
    LinkError,
    TableError,
    TableState,
    TableStatus,
    Turntable,
)
from procedures.steps import THERMAL_STEPS, Hold, Move, Note, Spin, Step, Warmup, limit_problems, move_time

from .progress import NullProgress, ProgressDisplay
from .recording import Recorder, StepRecord
from .thermal.steps import ThermalSteps

log = logging.getLogger(__name__)


class RunAborted(RuntimeError):
    """The run stopped before the end (interrupt, fault, lost link); the recording is closed cleanly."""

    def __init__(self, status: str, reason: str) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason


class SampleObserver(Protocol):
    """Receives the samples of the run as they arrive (e.g. the streaming identifier)."""

    def on_block(self, step: Step, block: ImuBlock, table: TableState, counts: bool) -> None:
        """A block of samples and the table reading after it; ``counts``: inside the acquisition window."""
        ...

    def on_step_end(self, step: Step, record: StepRecord) -> None:
        """A step finished (any status)."""
        ...


@dataclass
class RunResult:
    """Outcome of :meth:`Runner.run`."""

    status: str
    completed: list[int] = field(default_factory=list)
    samples: int = 0
    bench_seconds: float = 0.0
    reason: str = ""
    at_rest: bool = True
    """False when the final stop could not be commanded or rest could not be confirmed (the table may still be
    moving); ``rest_problem`` says why."""
    rest_problem: str = ""


STOP_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n)
)


class _InterruptFlag:
    """Turns SIGINT/SIGTERM/SIGHUP into a flag checked between blocks (installed only in the main thread)."""

    def __init__(self) -> None:
        self.signal_name: str | None = None
        self._old: dict[int, Any] = {}

    def __enter__(self) -> _InterruptFlag:
        if threading.current_thread() is threading.main_thread():
            for sig in STOP_SIGNALS:
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def _handler(self, signum: int, _frame: Any) -> None:
        if self.signal_name is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt  # a second Ctrl-C: stop waiting politely
        self.signal_name = signal.Signals(signum).name

    def __exit__(self, *exc: Any) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


STEP_EXECUTORS: dict[type[Step], Callable[[Runner, Step], None]] = {}
"""Step kinds taught to the runner beyond the built-in ones: step class → ``executor(runner, step)``."""


def register_step(step_type: type[Step], executor: Callable[[Runner, Step], None]) -> None:
    """Teach the runner a step kind (a frozen :class:`procedures.steps.Step` subclass): ``executor(runner, step)``
    runs it with the runner's primitives (``runner.set_device``, acquisition counted in samples, never a sleep).
    docs/extending.md, recipe 3."""
    if step_type in STEP_EXECUTORS:
        raise ValueError(f"step kind {step_type.__name__} already has a runner")
    STEP_EXECUTORS[step_type] = executor


def unregister_step(step_type: type[Step]) -> None:
    """Forget a step kind taught with :func:`register_step` (a test that taught a toy one)."""
    STEP_EXECUTORS.pop(step_type, None)


class Runner:
    """Run compiled steps on a bench.

    Parameters
    ----------
    turntable, unit : Turntable, InertialUnit
        The bench's drivers (real or simulated, in-process or over transports).
    steps : sequence of Step
        The compiled procedure's steps (``procedures.steps.Step``).
    recorder : Recorder
        Where the run is written.
    position_tolerance : float
        rad; a hold verifies the table is within this of its target before acquiring.
    block_seconds : float
        Acquisition block length (bench s); the table is read and the heartbeat sent once per block.
    observers : iterable of SampleObserver
    progress : ProgressDisplay or None
    total_bench_s : float or None
        Estimated procedure duration (for progress).
    aux : mapping or None
        Named auxiliary devices of the bench; ``"chamber"`` runs the soak and ramp steps
        (:mod:`benches.thermal.steps`), and is left as the chamber safety rules say on every exit path.
    resume_soak : Soak or None
        A resumed run that stopped mid-plateau: this soak is executed again before the first recorded step
        (its samples belong to that step, outside its acquisition window).
    """

    def __init__(
        self,
        turntable: Turntable,
        unit: InertialUnit,
        steps: Sequence[Step],
        recorder: Recorder,
        *,
        position_tolerance: float,
        block_seconds: float = 0.2,
        observers: Iterable[SampleObserver] = (),
        progress: ProgressDisplay | None = None,
        rest_rate: float = math.radians(0.01),
        stop_timeout_s: float = 120.0,
        aux: Mapping[str, Any] | None = None,
        resume_soak: Step | None = None,
        aux_every: Mapping[str, float] | None = None,
    ) -> None:
        self.aux = dict(aux or {})
        self.aux_every = {name: float(every) for name, every in (aux_every or {}).items() if name in self.aux}
        self._aux_next = dict.fromkeys(self.aux_every, -math.inf)
        self.resume_soak = resume_soak
        self.aborted = RunAborted  # the exception a chamber step raises to stop the run (benches.thermal.steps)
        self.thermal = ThermalSteps(self) if any(isinstance(s, THERMAL_STEPS) for s in steps) else None
        self.table = turntable
        self.unit = unit
        self.steps = list(steps)
        self.rec = recorder
        self.tol = float(position_tolerance)
        self.rate = float(unit.sample_rate)
        self.block = max(1, int(round(block_seconds * self.rate)))
        self.observers = list(observers)
        self.progress = progress or NullProgress()
        self.rest_rate = rest_rate
        self.stop_timeout_s = stop_timeout_s
        self.limits = tuple(turntable.limits())
        self._recording = True
        self._sample = 0  # samples read from the unit in this process (recorded or replayed)
        self._state: TableState | None = None
        self._interrupt: _InterruptFlag | None = None
        self._step_start = 0
        self._acq: tuple[int, int] | None = None
        self._progress_base = 0.0

    # ---- acquisition primitives -----------------------------------------------------------------------------
    def _read_block(self, step: Step, n: int, counts: bool) -> TableState:
        block = self.unit.read(n)
        state = self.table.read_state()
        self.table.heartbeat()
        self._state = state
        if self.thermal is not None:
            self.thermal.on_block(step, block)
        if self._recording:
            self.rec.add_samples(block)
            self.rec.add_table(state)
            t_ev = float(block.time[-1]) if len(block) else state.time
            for msg in block.events:  # the driver's link events (format, gaps, resets, duplicates, rejects)
                self.rec.event(t_ev, "warning" if "(s)" in msg else "info", f"{msg} (step {step.name})")
            if (block.dropped or block.rejected) and not block.events:
                self.rec.event(
                    t_ev,
                    "warning",
                    f"unit link: {block.dropped} frame(s) dropped, {block.rejected} rejected in step {step.name}",
                )
            for obs in self.observers:
                obs.on_block(step, block, state, counts)
            if self.aux_every:
                self._record_aux(float(block.time[-1]) if len(block) else state.time)
        self._sample += len(block)
        self._progress_base += len(block) / self.rate
        self._show(self.progress.update, self._progress_base)
        if self._interrupt is not None and self._interrupt.signal_name is not None:
            raise RunAborted("interrupted", f"{self._interrupt.signal_name} received")
        if state.status & TableStatus.FAULT:
            raise RunAborted("failed", f"turntable fault: {state.fault_code.name} (status {int(state.status):#x})")
        return state

    def _acquire(self, step: Step, n: int, counts: bool) -> None:
        left = int(n)
        while left > 0:
            k = min(self.block, left)
            self._read_block(step, k, counts)
            left -= k

    def _record_aux(self, t: float) -> None:
        """Record every auxiliary device that is due (``aux_every``) under ``/aux/<name>``."""
        for name, every in self.aux_every.items():
            if t >= self._aux_next[name]:
                self._aux_next[name] = t + every
                try:
                    reading = self.aux[name].read()
                except Exception as exc:  # a device link lost mid-run stops the run with its reason
                    raise RunAborted("failed", f"auxiliary device {name!r}: reading failed: {exc}") from exc
                self.rec.add_aux(name, t, reading)  # type: ignore[attr-defined]

    def set_device(self, step: Step, name: str, setpoint: float, *, timeout_s: float) -> None:
        """Command the auxiliary device ``name`` (a :class:`drivers.protocols.Settable`) to ``setpoint`` (SI) and
        acquire (recorded, not counted) until it reports ``settled()``; the step fails after ``timeout_s`` of
        bench time. For step kinds taught to the runner with :func:`register_step`."""
        device = self.aux.get(name)
        if device is None:
            have = ", ".join(sorted(self.aux)) or "none"
            raise RunAborted("failed", f"step {step.name!r}: the bench has no auxiliary device {name!r} ({have})")
        try:
            device.set(float(setpoint))
        except Exception as exc:
            raise RunAborted("failed", f"step {step.name!r}: {name} refused set point {setpoint:g}: {exc}") from exc
        if self._recording:
            line = f"{name}: set point {setpoint:g}; {device.status()} (step {step.name})"
            self.rec.event(self._time(), "info", line)
        limit = self._sample + int(math.ceil(timeout_s * self.rate))
        while not device.settled():
            if self._sample >= limit:
                raise RunAborted("failed", f"step {step.name!r}: {name} did not settle within {timeout_s:.0f} s")
            self._read_block(step, self.block, False)

    def _wait_until(self, step: Step, predicate: Callable[[TableState], bool], timeout_s: float, what: str) -> None:
        limit = self._sample + int(math.ceil(timeout_s * self.rate))
        state = self._state if self._state is not None else self.table.read_state()
        while not predicate(state):
            if self._sample >= limit:
                raise RunAborted("failed", f"step {step.name!r}: table did not {what} within {timeout_s:.0f} s")
            state = self._read_block(step, self.block, False)

    # ---- steps -------------------------------------------------------------------------------------------------
    def _in_position(self, target: Sequence[float]) -> Callable[[TableState], bool]:
        tgt = np.asarray(target, dtype=float)

        def ok(s: TableState) -> bool:
            return bool(
                s.status & TableStatus.IN_POSITION
                and not s.status & TableStatus.MOVING
                and np.all(np.abs(s.angles - tgt) <= self.tol)
            )

        return ok

    def _at_rest(self, s: TableState) -> bool:
        return bool(not s.status & TableStatus.MOVING and np.all(np.abs(s.rates) <= self.rest_rate))

    def _move(self, step: Step, target: Sequence[float]) -> None:
        state = self._state if self._state is not None else self.table.read_state()
        if self._in_position(target)(state):
            return
        self.table.move_to(np.asarray(target, dtype=float))
        t = move_time(state.angles, np.asarray(target), self.limits)
        self._wait_until(step, self._in_position(target), 3 * t + 30.0, "reach position")

    def _execute(self, step: Step) -> None:
        if isinstance(step, Note):
            if self._recording:
                self.rec.event(self._time(), "info", f"note: {step.text}")
        elif isinstance(step, Move):
            self._move(step, step.angles)
        elif isinstance(step, (Hold, Warmup)):
            if step.angles is not None:
                self._move(step, step.angles)  # a hold always verifies its attitude
            self._acquire(step, int(round(step.settle * self.rate)), False)
            a0 = self._sample
            self._acq = (a0, a0)
            self._acquire(step, int(round(step.duration * self.rate)), True)
            self._acq = (a0, self._sample)
        elif isinstance(step, Spin):
            self.table.spin(step.axis, float(step.rate))
            ramp = step.ramp_time(self.limits)
            self._wait_until(step, lambda s: bool(s.status & TableStatus.AT_RATE), 3 * ramp + 30.0, "reach rate")
            self._acquire(step, int(round(step.settle * self.rate)), False)
            a0 = self._sample
            self._acq = (a0, a0)
            self._acquire(step, int(round(step.duration * self.rate)), True)
            self._acq = (a0, self._sample)
            self.table.stop()
            self._wait_until(step, self._at_rest, 3 * ramp + 30.0, "come to rest")
        elif isinstance(step, THERMAL_STEPS) and self.thermal is not None:
            self.thermal.execute(step)
        elif type(step) in STEP_EXECUTORS:
            STEP_EXECUTORS[type(step)](self, step)
        else:
            raise RunAborted("failed", f"step {step.name!r}: no runner for a {type(step).__name__} step")

    def _time(self) -> float:
        return self._state.time if self._state is not None else 0.0

    def _record_step(self, step: Step, status: str) -> StepRecord:
        acq = self._acq or (self._sample, self._sample)
        rec = StepRecord(
            index=int(step.index),
            name=step.name,
            kind=step.kind,
            group=step.group or "",
            start_sample=self._step_start,
            acq_start=acq[0],
            acq_end=acq[1],
            end_sample=self._sample,
            status=status,
            axis=-1 if step.axis is None else int(step.axis),
            rate=float(step.rate),
            angles=tuple(step.angles) if step.angles is not None else (math.nan, math.nan, math.nan),
        )
        self.rec.end_step(rec)
        for obs in self.observers:
            obs.on_step_end(step, rec)
        return rec

    # ---- the run -----------------------------------------------------------------------------------------------
    def _safe_stop(self) -> str:
        """Stop the table under control and wait (bounded) for rest; never raises. Returns "" when the table was
        seen at rest, else what went wrong (the table may still be moving)."""
        try:
            self.table.stop()
        except Exception as exc:  # noqa: BLE001 - cleanup must go on
            log.error("could not command stop: %s", exc)
            if self._recording:
                self.rec.event(self._time(), "error", f"stop command failed: {exc}")
            return f"the stop command failed ({exc})"
        limit = self._sample + int(self.stop_timeout_s * self.rate)
        try:
            state = self.table.read_state()
            while not self._at_rest(state) and self._sample < limit:
                block = self.unit.read(self.block)
                if self._recording:
                    self.rec.add_samples(block)
                self._sample += len(block)
                state = self.table.read_state()
                if self._recording:
                    self.rec.add_table(state)
            rest = self._at_rest(state)
            if self._recording:
                self.rec.event(state.time, "info", "table at rest" if rest else "table not at rest")
            return "" if rest else f"the table did not come to rest within {self.stop_timeout_s:g} s of the stop"
        except KeyboardInterrupt:  # a second Ctrl-C: the stop was sent; do not wait for rest
            log.warning("stop sent; not waiting for the table to come to rest (second interrupt)")
            if self._recording:
                self.rec.event(self._time(), "warning", "stop sent; wait for rest abandoned by a second interrupt")
            return "the stop was sent but the wait for rest was abandoned (second interrupt)"
        except Exception as exc:  # noqa: BLE001 - cleanup must go on
            log.error("while waiting for rest: %s", exc)
            if self._recording:
                self.rec.event(self._time(), "error", f"could not confirm rest: {exc}")
            return f"the stop was sent but rest could not be confirmed ({exc})"

    def run(self, *, replay: Iterable[int] = (), start_sample: int = 0) -> RunResult:
        """Run the steps; those in ``replay`` are executed without recording (simulated resume).

        Returns
        -------
        RunResult
            status "complete", or "interrupted" / "failed" with the reason (the recording is closed
            cleanly in every case; the table is left at rest).
        """
        problems = limit_problems(self.steps, self.limits)
        if problems:
            raise TableError("refusing to start, nothing moved: " + "; ".join(problems))
        replay_set = set(replay)
        last_replayed = max(replay_set) if replay_set else -1
        completed: list[int] = []
        status, reason = "complete", ""
        self._sample = 0
        current: Step | None = None
        unexpected: Exception | None = None
        rest_problem = ""
        with _InterruptFlag() as flag:
            self._interrupt = flag
            try:
                self._state = self.table.read_state()
                for step in self.steps:
                    current = step
                    self._recording = step.index not in replay_set
                    self._step_start = self._sample
                    self._acq = None
                    self._show(self.progress.step, step.name + (" (replay)" if not self._recording else ""), step.text)
                    if self._recording and self.resume_soak is not None and self.thermal is not None:
                        # a run resumed mid-plateau soaks again at that plateau before its next step
                        self.rec.event(self._time(), "info", f"resumed mid-plateau: soak {self.resume_soak.name} again")
                        self.thermal.execute(self.resume_soak)
                        self.resume_soak = None
                    self._execute(step)
                    if self._recording:
                        self._record_step(step, "complete")
                    elif step.index == last_replayed and self._sample != start_sample:
                        raise RunAborted(
                            "failed",
                            f"replay of the completed steps gave {self._sample} samples but the recording holds "
                            f"{start_sample} (different bench, seed or software?); cannot resume",
                        )
                    completed.append(step.index)
                    current = None
            except RunAborted as exc:
                status, reason = exc.status, exc.reason
            except KeyboardInterrupt:
                status, reason = "interrupted", "interrupted by the user"
            except LinkError as exc:
                status, reason = "failed", f"link lost: {exc}"
            except TableError as exc:
                status, reason = "failed", f"turntable refused a command: {exc}"
            except Exception as exc:  # noqa: BLE001 - never leave the table moving or the recording "complete"
                status, reason = "failed", f"unexpected error: {exc.__class__.__name__}: {exc}"
                unexpected = exc
            finally:
                self._recording = True
                if status != "complete":
                    self.rec.event(self._time(), "error", f"run stopped: {reason}")
                    rest_problem = self._safe_stop()
                    if current is not None:
                        try:
                            self._record_step(current, status)
                        except Exception as exc:  # noqa: BLE001
                            log.error("could not record the interrupted step: %s", exc)
                else:
                    rest_problem = self._safe_stop()
                if self.thermal is not None:
                    self.thermal.leave_safe()
                self.rec.set_status(status)
                self._interrupt = None
                self._show(self.progress.update, self._progress_base, force=True)
        if unexpected is not None:
            raise unexpected
        return RunResult(
            status, completed, self._sample, self._sample / self.rate, reason, not rest_problem, rest_problem
        )

    def _show(self, fn: Callable[..., None], *args: Any, **kw: Any) -> None:
        """Progress output; a closed terminal (SIGHUP, EIO/EPIPE) silences it instead of stopping the run."""
        try:
            fn(*args, **kw)
        except OSError:
            self.progress = NullProgress()
