"""Device-level simulated drivers: the :class:`~drivers.protocols.Turntable` and
:class:`~drivers.protocols.InertialUnit` protocols implemented directly on a :class:`SimulatedWorld`
(no transport, no threads). These are the fast path for tests and the ``in-process`` simulated bench;
the wire-level simulators (Modbus / serial on loopback) exercise the real drivers instead.

Both drivers share one world, hence one clock: reading ``n`` samples from the unit advances the table too.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from drivers.imu_unit.counts import counter_gaps, frames_to_block
from drivers.protocols import AxisLimits, ImuBlock, LinkError, TableState
from drivers.sim.world import SimulatedWorld


class SimTurntable:
    """:class:`~drivers.protocols.Turntable` on a simulated world (angles rad, rates rad/s, gimbal order
    outer, middle, inner)."""

    def __init__(self, world: SimulatedWorld) -> None:
        self.world = world
        self._closed = False

    def _check(self) -> None:
        if self._closed:
            raise LinkError("simulated turntable driver is closed")

    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-axis limits (outer, middle, inner)."""
        return self.world.table_limits()

    def move_to(self, angles: NDArray[np.float64] | list[float]) -> None:
        """Command absolute gimbal angles, rad (TableError if out of limits or a fault is latched)."""
        self._check()
        self.world.command_position(angles)

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis``."""
        self._check()
        self.world.command_rate(axis, rate)

    def stop(self) -> None:
        """Controlled stop of every axis."""
        self._check()
        self.world.command_stop()

    def read_state(self) -> TableState:
        """Controller reading at the current bench time."""
        self._check()
        return self.world.table_state()

    def heartbeat(self) -> None:
        """Feed the controller watchdog."""
        self._check()
        self.world.heartbeat()

    def clear_fault(self) -> None:
        """Reset a latched fault."""
        self._check()
        self.world.clear_fault()

    def close(self) -> None:
        """Release the driver (the world stays usable by others)."""
        self._closed = True


class SimInertialUnit:
    """:class:`~drivers.protocols.InertialUnit` on a simulated world: ``read(n)`` advances the shared clock
    by ``n`` sample periods and returns the frames emitted, decoded with the unit's count scale (body frame,
    SI); ``dropped`` counts counter gaps, including the one from the previous block."""

    def __init__(self, world: SimulatedWorld) -> None:
        self.world = world
        # the frame before the next one: a drop of the very first frame is counted too
        self._last: int | None = (world.samples_produced - 1) % (1 << 32)
        self._closed = False

    @property
    def sample_rate(self) -> float:
        """Nominal sample rate, Hz."""
        return self.world.sample_rate

    def read(self, n: int) -> ImuBlock:
        """The next ``n`` sample periods (fewer samples if frames were dropped)."""
        if self._closed:
            raise LinkError("simulated inertial unit driver is closed")
        frames = self.world.produce(n)
        dropped = counter_gaps(self._last, frames.counter)
        if len(frames):
            self._last = int(frames.counter[-1])
        block = frames_to_block(frames, self.world.scale, dropped=dropped)
        block.host_time = self.world.host_time()
        return block

    def close(self) -> None:
        """Release the driver."""
        self._closed = True
