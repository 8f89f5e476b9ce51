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
from drivers.sim.table_twins import ModbusTwin, TableTwin
from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)


class Loopback:
    """Servers + connected drivers for one world (close() stops everything; safe to call twice).

    Parameters
    ----------
    world : SimulatedWorld
    table : TableTwin or None
        The simulated turntable controller (:mod:`drivers.sim.table_twins`: its server and the real driver
        connected to it); None: the tablebench Modbus controller with the shipped register map.
    corruption : drivers.sim.serial_unit.Corruption or None
        Injected faults on the unit's byte stream.
    timeout : float
        Driver timeouts, s.
    unit_frame : drivers.imu_unit.description.FrameFormat or None
        The frame format the simulated unit speaks and the driver decodes (None: ``tablebench-v1``).
    unit_raw : binary file or None
        Where the unit driver keeps the raw byte stream; ``unit_raw_name`` names it in events.
    realtime : bool
        The unit streams from its server thread in real time at its own clock's rate (1 + ε_u of the world's
        clock model), in batches of ``clocks.batch_frames``; the drivers read it free-running and use the host's
        real clock. Not deterministic (a real bench's timing); the default polls, so the world's clock advances
        only with what the host reads and the world's simulated host clock stamps everything.
    """

    def __init__(
        self,
        world: SimulatedWorld,
        *,
        table: TableTwin | None = None,
        corruption: Corruption | None = None,
        timeout: float = 2.0,
        unit_frame: FrameFormat | None = None,
        unit_raw: BinaryIO | None = None,
        unit_raw_name: str = "",
        realtime: bool = False,
    ) -> None:
        self.world = world
        self.twin: TableTwin = table if table is not None else ModbusTwin()
        if self.twin.in_process_only:
            raise ValueError(self.twin.in_process_only)
        self._closers: list[Callable[[], None]] = []
        self.realtime = bool(realtime)
        clock: dict[str, Any] = {} if realtime else {"clock": world.host_time}  # real time: the host's own clock
        try:
            self.table_server: Any = self.twin.serve(world)
            self._closers.append(self.table_server.close)
            table_conn = self.twin.connect(self.table_server, timeout, clock.get("clock"))
            self._closers.insert(0, table_conn.close)
            self.client: Any = table_conn.transport
            self.turntable: Turntable = table_conn.driver
            if realtime:
                fs = float(world.sample_rate)
                self.unit_server = SerialUnitServer(
                    world,
                    corruption=corruption,
                    frame=unit_frame,
                    stream_factor=world.unit_clock_factor,
                    chunk_s=world.cfg.clocks.batch_frames / fs,
                )
            else:
                self.unit_server = SerialUnitServer(world, corruption=corruption, frame=unit_frame)
            self._closers.append(self.unit_server.close)
            unit = connect.serial_unit(
                self.unit_server.url,
                self.unit_server.frame,
                world.sample_rate,
                polled=not realtime,
                timeout=timeout,
                name="simulated unit",
                raw_sink=unit_raw,
                raw_name=unit_raw_name,
                **clock,
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
