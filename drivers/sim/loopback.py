"""A simulated bench over real transports on 127.0.0.1: the wire-level simulators plus the real drivers.

:class:`Loopback` starts, for ONE :class:`~drivers.sim.world.SimulatedWorld`,

* a turntable controller server — Modbus TCP (:class:`~drivers.sim.modbus_controller.ModbusTableServer`)
  or the ASCII dialect (:class:`~drivers.sim.ascii_controller.AsciiTableServer`),
* the serial unit server (:class:`~drivers.sim.serial_unit.SerialUnitServer`),

then connects the real drivers to them exactly as on hardware: :class:`~drivers.modbus_table.ModbusTurntable`
through a pymodbus ``ModbusTcpClient`` (or :class:`~drivers.ascii_table.AsciiTurntable` through
``serial.serial_for_url("socket://…")``), and :class:`~drivers.serial_imu.SerialInertialUnit` in polled
(burst) mode through ``serial.serial_for_url``, so the simulated clock advances exactly with the samples the
host reads: a loopback run is bit-identical to the in-process run with the same seed and commands.
"""

from __future__ import annotations

import logging
from typing import Any, Literal

from drivers import connect
from drivers.sim.ascii_controller import AsciiTableServer
from drivers.sim.modbus_controller import ModbusTableServer
from drivers.sim.serial_unit import Corruption, SerialUnitServer
from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)

Dialect = Literal["modbus", "ascii"]


class Loopback:
    """Servers + connected drivers for one world (close() stops everything; safe to call twice).

    Parameters
    ----------
    world : SimulatedWorld
    dialect : {"modbus", "ascii"}
        Turntable controller protocol.
    word_order : {"big", "little"}
        Modbus float word order (both ends use it).
    watchdog_s : float or None
        Wall-clock watchdog of the controller, s.
    corruption : drivers.sim.serial_unit.Corruption or None
        Injected faults on the unit's byte stream.
    timeout : float
        Driver timeouts, s.
    unit_id : int
        Modbus unit id used by the driver.
    unit_frame : drivers.imu_frame_desc.FrameFormat or None
        The frame format the simulated unit speaks and the driver decodes (None: ``tablebench-v1``).
    unit_raw : binary file or None
        Where the unit driver keeps the raw byte stream; ``unit_raw_name`` names it in events.
    """

    def __init__(
        self,
        world: SimulatedWorld,
        *,
        dialect: Dialect = "modbus",
        word_order: Literal["big", "little"] = "big",
        watchdog_s: float | None = None,
        corruption: Corruption | None = None,
        timeout: float = 2.0,
        unit_id: int = 1,
        unit_frame: Any = None,
        unit_raw: Any = None,
        unit_raw_name: str = "",
    ) -> None:
        if dialect not in ("modbus", "ascii"):
            raise ValueError(f"loopback dialect must be 'modbus' or 'ascii', got {dialect!r}")
        self.world = world
        self.dialect = dialect
        self._closers: list[Any] = []
        self.table_server: Any = None
        try:
            if dialect == "modbus":
                self.table_server = ModbusTableServer(world, word_order=word_order, watchdog_s=watchdog_s)
                self._closers.append(self.table_server.close)
                table = connect.modbus_table(
                    "127.0.0.1",
                    self.table_server.port,
                    word_order=word_order,
                    unit_id=unit_id,
                    timeout=timeout,
                    retries=0,
                )
            else:
                self.table_server = AsciiTableServer(world, watchdog_s=watchdog_s)
                self._closers.append(self.table_server.close)
                table = connect.ascii_table(self.table_server.url, timeout=timeout)
            self._closers.insert(0, table.close)
            self.client: Any = table.transport
            self.turntable: Any = table.driver
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
            self.unit: Any = unit.driver
        except BaseException:
            self.close()
            raise

    def describe(self) -> str:
        """One line: which protocols on which ports."""
        table = "Modbus TCP" if self.dialect == "modbus" else "ASCII"
        return (
            f"loopback: {table} controller on 127.0.0.1:{self.table_server.port}, "
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
