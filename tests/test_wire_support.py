"""Shared helpers for the wire-transport tests: a world to serve (the real SimulatedWorld when it is
available, else a small deterministic stand-in with the same API) and server/driver fixtures."""

from __future__ import annotations

import math
import threading

import numpy as np

from drivers.imu_counts import CountScale, RawFrames
from drivers.protocols import AxisLimits, AxisMode, FaultCode, TableError, TableState, TableStatus

LIMITS = (
    AxisLimits(rate_max=math.radians(300), accel_max=math.radians(100)),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100), position_min=-math.pi, position_max=math.pi),
    AxisLimits(rate_max=math.radians(200), accel_max=math.radians(100)),
)


class FakeWorld:
    """Deterministic stand-in for drivers.sim.world.SimulatedWorld (same public API, trivial physics).

    Angles move at a constant 50 °/s towards position targets; rates are reached at once; counts are seeded
    noise plus the current angles, so that table commands visibly change the unit's output.
    """

    def __init__(self, seed: int = 0, sample_rate: float = 1000.0, drop_every: int = 0) -> None:
        self._lock = threading.RLock()
        self._rng = np.random.default_rng(seed)
        self._rate = float(sample_rate)
        self._n = 0
        self._angles = np.zeros(3)
        self._rates = np.zeros(3)
        self._target: np.ndarray | None = None
        self._modes = [AxisMode.STOP] * 3
        self._fault = FaultCode.NONE
        self.heartbeats = 0
        self.stops = 0
        self.drop_every = drop_every

    sample_rate = property(lambda self: self._rate)
    scale = property(lambda self: CountScale(accel_lsb=1e-6, gyro_lsb=1e-7))
    time = property(lambda self: self._n / self._rate)
    samples_produced = property(lambda self: self._n)

    def table_limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        return LIMITS

    def _check(self) -> None:
        if self._fault:
            raise TableError(f"fault {self._fault.name} latched")

    def command_position(self, angles) -> None:
        with self._lock:
            self._check()
            a = np.asarray(angles, float)
            for x, lim in zip(a, LIMITS, strict=True):
                if (lim.position_min is not None and x < lim.position_min) or (
                    lim.position_max is not None and x > lim.position_max
                ):
                    raise TableError("position out of limits")
            self._target = a.copy()
            self._rates[:] = 0
            self._modes = [AxisMode.POSITION] * 3

    def command_rate(self, axis: int, rate: float) -> None:
        with self._lock:
            self._check()
            if abs(rate) > LIMITS[axis].rate_max:
                raise TableError("rate limit")
            self._target = None
            self._rates[axis] = rate
            self._modes[axis] = AxisMode.RATE

    def command_stop(self) -> None:
        with self._lock:
            self.stops += 1
            self._target = None
            self._rates[:] = 0
            self._modes = [AxisMode.STOP] * 3

    def clear_fault(self) -> None:
        with self._lock:
            self._fault = FaultCode.NONE

    def heartbeat(self) -> None:
        with self._lock:
            self.heartbeats += 1

    def inject_fault(self, fault: FaultCode) -> None:
        with self._lock:
            self._fault = FaultCode(fault)
            self._target = None
            self._rates[:] = 0

    def table_state(self) -> TableState:
        with self._lock:
            status = TableStatus.REMOTE
            moving = bool(np.any(self._rates != 0)) or self._target is not None
            if moving:
                status |= TableStatus.MOVING
            elif AxisMode.POSITION in self._modes:
                status |= TableStatus.IN_POSITION
            if self._fault:
                status |= TableStatus.FAULT
            return TableState(
                time=self.time,
                angles=self._angles.copy(),
                rates=self._rates.copy(),
                status=status,
                fault_code=self._fault,
                modes=tuple(self._modes),  # type: ignore[arg-type]
            )

    def produce(self, n: int) -> RawFrames:
        with self._lock:
            dt = 1.0 / self._rate
            idx = np.arange(self._n, self._n + n)
            ang = np.empty((n, 3))
            step = math.radians(50) * dt
            a = self._angles.copy()
            # piecewise motion, vectorised per call: constant rate and/or constant slew towards the target
            k = np.arange(1, n + 1)[:, None]
            ang = a + self._rates * dt * k
            if self._target is not None:
                d = self._target - a
                ang = a + np.sign(d) * np.minimum(np.abs(d), step * k)
                if np.allclose(ang[-1], self._target):
                    self._target = None
            self._angles = ang[-1].copy()
            self._n += n
            noise = self._rng.integers(-1000, 1000, (n, 6))
            counts = (noise + np.hstack([ang, ang]) * 1e5).astype(np.int32)
            frames = RawFrames(
                counter=idx.astype(np.uint32),
                timestamp_ns=(idx * round(1e9 * dt)).astype(np.uint64),
                counts=counts,
                temperature=np.full(n, 2500, np.int16),
                status=np.zeros(n, np.uint16),
            )
            if self.drop_every:
                keep = idx % self.drop_every != 0
                frames = RawFrames(
                    frames.counter[keep],
                    frames.timestamp_ns[keep],
                    frames.counts[keep],
                    frames.temperature[keep],
                    frames.status[keep],
                )
            return frames


def make_world(seed: int = 0):
    """The real SimulatedWorld (default truth, the LIMITS above) if available, else the FakeWorld."""
    try:
        from drivers.sim.config import SimConfig, TableModel
        from drivers.sim.world import SimulatedWorld
    except ImportError:  # pragma: no cover - before the world existed
        return FakeWorld(seed)
    return SimulatedWorld(SimConfig(table=TableModel(limits=LIMITS)), seed)
