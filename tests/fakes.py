"""Minimal fake bench devices for orchestrator tests that must not depend on the simulator's physics."""

from __future__ import annotations

import math

import numpy as np

from drivers.protocols import AxisLimits, AxisMode, FaultCode, ImuBlock, TableError, TableState, TableStatus
from procedures.steps import Hold, Move, Note, Spin, Step, Warmup


class FakeClock:
    """Shared sample clock of the fake bench."""

    def __init__(self, rate: float) -> None:
        self.rate = rate
        self.n = 0

    @property
    def time(self) -> float:
        return self.n / self.rate


class FakeTable:
    """A table that moves each axis at constant speed toward its target and spins instantly."""

    def __init__(self, clock: FakeClock, speed: float = math.radians(20.0), fail_after: float | None = None) -> None:
        self.clock = clock
        self.speed = speed
        self.angles = np.zeros(3)
        self.target = np.zeros(3)
        self.rates = np.zeros(3)
        self.t_last = 0.0
        self.fault = FaultCode.NONE
        self.fail_after = fail_after
        self.commands: list[tuple] = []
        self.heartbeats = 0

    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        lim = AxisLimits(rate_max=math.radians(100.0), accel_max=math.radians(50.0))
        return (lim, lim, lim)

    def _advance(self) -> None:
        t = self.clock.time
        dt = t - self.t_last
        self.t_last = t
        if self.fail_after is not None and t >= self.fail_after:
            self.fault = FaultCode.STALL
            self.rates[:] = 0
            return
        spinning = self.rates != 0
        self.angles[spinning] += self.rates[spinning] * dt
        d = self.target - self.angles
        step = np.clip(d, -self.speed * dt, self.speed * dt)
        self.angles[~spinning] += step[~spinning]

    def move_to(self, angles) -> None:
        self._advance()
        if self.fault:
            raise TableError("fault latched")
        self.commands.append(("move", tuple(angles)))
        self.rates[:] = 0
        self.target = np.asarray(angles, dtype=float).copy()

    def spin(self, axis: int, rate: float) -> None:
        self._advance()
        self.commands.append(("spin", axis, rate))
        self.rates[axis] = rate

    def stop(self) -> None:
        self._advance()
        self.commands.append(("stop",))
        self.rates[:] = 0
        self.target = self.angles.copy()

    def read_state(self) -> TableState:
        self._advance()
        moving = bool(np.any(np.abs(self.target - self.angles) > 1e-12) and not self.fault) or bool(
            np.any(self.rates != 0)
        )
        st = TableStatus.REMOTE
        if self.fault:
            st |= TableStatus.FAULT
        if np.any(self.rates != 0):
            st |= TableStatus.AT_RATE | TableStatus.MOVING
        elif moving:
            st |= TableStatus.MOVING
        else:
            st |= TableStatus.IN_POSITION
        modes = tuple(AxisMode.RATE if r else AxisMode.POSITION for r in self.rates)
        return TableState(self.clock.time, self.angles.copy(), self.rates.copy(), st, self.fault, modes)

    def heartbeat(self) -> None:
        self.heartbeats += 1

    def clear_fault(self) -> None:
        self.fault = FaultCode.NONE

    def close(self) -> None:
        pass


class FakeUnit:
    """A unit whose samples are a deterministic function of the sample index."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock

    @property
    def sample_rate(self) -> float:
        return self.clock.rate

    def read(self, n: int) -> ImuBlock:
        i = np.arange(self.clock.n, self.clock.n + n)
        self.clock.n += n
        accel = np.stack([np.sin(i * 0.001), np.cos(i * 0.001), np.full(n, 9.8)], 1)
        return ImuBlock(
            counter=i.astype(np.uint32),
            time=i / self.clock.rate,
            accel=accel,
            gyro=np.zeros((n, 3)),
            temperature=np.full(n, 298.15),
            status=np.zeros(n, np.uint16),
        )

    def close(self) -> None:
        pass


_STEP_TYPES: dict[str, type[Step]] = {t.kind: t for t in (Move, Warmup, Hold, Spin, Note)}


def FakeStep(  # noqa: N802 - reads like the step constructors it stands for
    index: int,
    name: str,
    kind: str,
    group: str = "",
    angles: tuple[float, float, float] | None = None,
    axis: int | None = None,
    rate: float = 0.0,
    duration: float = 0.0,
    settle: float = 0.0,
    text: str = "",
) -> Step:
    """A compiled step of ``kind`` built directly (without a procedure file), e.g. ``FakeStep(2, "h", "hold", ...)``."""
    kw: dict = dict(index=index, name=name, group=group, rate=rate, duration=duration, settle=settle, text=text)
    if angles is not None:
        kw["angles"] = angles
    if axis is not None:
        kw["axis"] = axis
    return _STEP_TYPES[kind](**kw)


def fake_steps() -> list[FakeStep]:
    """A small procedure: hold, move, hold, spin, note."""
    r = math.radians
    return [
        FakeStep(0, "warm", "warmup", "A", (0.0, 0.0, 0.0), duration=2.0),
        FakeStep(1, "A/step-1", "move", "A", (0.0, 0.0, r(45))),
        FakeStep(2, "A/hold-1", "hold", "A", (0.0, 0.0, r(45)), duration=3.0, settle=0.5),
        FakeStep(3, "A/spin", "spin", "A", None, axis=2, rate=r(30), duration=12.0, settle=0.5),
        FakeStep(4, "note", "note", text="done"),
        FakeStep(5, "B/orient", "move", "B", (r(-90), r(-90), 0.0)),
        FakeStep(6, "B/hold", "hold", "B", (r(-90), r(-90), 0.0), duration=2.0),
    ]
