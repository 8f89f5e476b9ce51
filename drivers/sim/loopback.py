"""A simulated bench over real transports on 127.0.0.1: the wire-level simulators plus the real drivers.

:class:`Loopback` starts, for ONE :class:`~drivers.sim.world.SimulatedWorld`,

* a turntable controller server — the ACUTROL command language
  (:class:`~drivers.sim.acl_server.AclTableServer`) or Modbus TCP
  (:class:`~drivers.sim.modbus_controller.ModbusTableServer`),
* the serial unit server (:class:`~drivers.sim.serial_unit.SerialUnitServer`),

then connects the real drivers to them exactly as on hardware (:mod:`drivers.connect`):
:class:`~drivers.acutrol.AclTurntable` through pyvisa with the pyvisa-py backend (VISA resource
``TCPIP0::127.0.0.1::PORT::SOCKET``) or :class:`~drivers.modbus.table.ModbusTurntable` through a pymodbus
``ModbusTcpClient``, and :class:`~drivers.imu_unit.serial_unit.SerialInertialUnit` in polled (burst) mode through
``serial.serial_for_url``, so the simulated clock advances exactly with the samples the host reads: a loopback
run equals the in-process run with the same seed and commands (Modbus: bit for bit; ACL: the in-process bench
runs the same driver against the same controller without the wire, so the two are identical too).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, BinaryIO

from drivers import connect
from drivers.imu_unit.description import FrameFormat
from drivers.protocols import InertialUnit, Turntable
from drivers.sim.serial_unit import Corruption, SerialUnitServer
from drivers.sim.table_twins import TableServer, TableTwin
from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)

class Loopback:
    """Servers + connected drivers for one world (close() stops everything; safe to call twice).

    Parameters
    ----------
    world : SimulatedWorld
    table : drivers.sim.table_twins.TableTwin
        The simulated turntable controller (its protocol, settings and driver): served on 127.0.0.1 and
        reached by its real driver. The device registry (``benches/devices.py``) builds it from the bench.
    corruption : drivers.sim.serial_unit.Corruption or None
        Injected faults on the unit's byte stream.
    timeout : float
        Driver timeouts, s.
    unit_frame : drivers.imu_unit.description.FrameFormat or None
        The frame format the simulated unit speaks and the driver decodes (None: ``tablebench-v1``).
    unit_raw : binary file or None
        Where the unit driver keeps the raw byte stream; ``unit_raw_name`` names it in events.
    """

    def __init__(
        self,
        world: SimulatedWorld,
        *,
        table: TableTwin,
        corruption: Corruption | None = None,
        timeout: float = 2.0,
        unit_frame: FrameFormat | None = None,
        unit_raw: BinaryIO | None = None,
        unit_raw_name: str = "",
    ) -> None:
        self.world = world
        self.twin = table
        self._closers: list[Callable[[], None]] = []
        try:
            self.table_server: TableServer = table.serve(world)
            self._closers.append(self.table_server.close)
            conn = table.connect(self.table_server, timeout)
            self._closers.insert(0, conn.close)
            self.client: Any = conn.transport
            self.turntable: Turntable = conn.driver
            self.unit_server = SerialUnitServer(world, corruption=corruption, frame=unit_frame)
            self._closers.append(self.unit_server.close)
            unit = connect.serial_unit(
                self.unit_server.url,
                self.unit_server.frame,
                world.sample_rate,
                polled=True,
                timeout=timeout,
                name="simulated unit",
                raw_sink=unit_raw,
                raw_name=unit_raw_name,
            )
            self._closers.insert(0, unit.close)
            self.unit_port = unit.transport
            self.unit: InertialUnit = unit.driver
        except BaseException:
            self.close()
            raise

    def describe(self) -> str:
        """One line: which protocols on which ports."""
        return (
            f"loopback: {self.twin.describe(self.table_server)} controller on 127.0.0.1:{self.table_server.port}, "
            f"serial unit (polled, {self.unit_server.frame.name}) on 127.0.0.1:{self.unit_server.port}"
        )

    def close(self) -> None:
        """Close drivers, clients/ports, then servers (idempotent; never raises)."""
        closers, self._closers = self._closers, []
        for fn in closers:
            try:
                fn()
            except Exception:  # closing must not mask the original error
                log.debug("loopback close", exc_info=True)

    def __enter__(self) -> Loopback:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
