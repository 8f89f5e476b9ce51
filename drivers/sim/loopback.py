"""A simulated bench over real transports on 127.0.0.1: the wire-level simulators plus the real drivers.

:class:`Loopback` starts, for ONE :class:`~drivers.sim.world.SimulatedWorld`,

* a turntable controller server — the ACUTROL command language
  (:class:`~drivers.sim.acl_server.AclTableServer`), Modbus TCP
  (:class:`~drivers.sim.modbus_controller.ModbusTableServer`) or the Ideal Aerosmith text language
  (:class:`~drivers.sim.aerosmith_server.AerosmithTableServer`, reached as a serial device server),
* the serial unit server (:class:`~drivers.sim.serial_unit.SerialUnitServer`),

then connects the real drivers to them exactly as on hardware (:mod:`drivers.connect`):
:class:`~drivers.acutrol.AclTurntable` through pyvisa with the pyvisa-py backend (VISA resource
``TCPIP0::127.0.0.1::PORT::SOCKET``), :class:`~drivers.modbus.table.ModbusTurntable` through a pymodbus
``ModbusTcpClient`` or :class:`~drivers.aerosmith.AerosmithTable` through pyserial's ``socket://`` URL, and
:class:`~drivers.imu_unit.serial_unit.SerialInertialUnit` in polled (burst) mode through
``serial.serial_for_url``, so the simulated clock advances exactly with the samples the host reads: a loopback
run equals the in-process run with the same seed and commands (Modbus: bit for bit; ACL: the in-process bench
runs the same driver against the same controller without the wire, so the two are identical too).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, BinaryIO, Literal

from drivers import connect
from drivers.acutrol import AclSettings, AclTurntable
from drivers.aerosmith import AerosmithTable
from drivers.aerosmith.settings import AerosmithSettings
from drivers.imu_unit.description import FrameFormat
from drivers.modbus.register_map import ModbusMap
from drivers.protocols import InertialUnit, Turntable
from drivers.sim.acl_server import AclTableServer
from drivers.sim.aerosmith_server import AerosmithTableServer
from drivers.sim.modbus_controller import ModbusTableServer
from drivers.sim.serial_unit import Corruption, SerialUnitServer
from drivers.sim.world import SimulatedWorld
from drivers.transport import MessageTransport, VisaTransport, open_visa

log = logging.getLogger(__name__)

Dialect = Literal["acutrol", "modbus", "aerosmith"]


class Loopback:
    """Servers + connected drivers for one world (close() stops everything; safe to call twice).

    Parameters
    ----------
    world : SimulatedWorld
    dialect : {"acutrol", "modbus", "aerosmith"}
        Turntable controller protocol.
    make_aerosmith_table : callable or None
        ``dialect="aerosmith"``: builds the Ideal Aerosmith driver from the open byte stream (the factory's
        settings); None: the driver with the world's limits and ``aerosmith`` settings.
    aerosmith : AerosmithSettings or None
        ``dialect="aerosmith"``: the open points of the table language, for both ends.
    make_acl_table : callable or None
        ``dialect="acutrol"``: builds the ACL driver from an open MessageTransport (the factory's settings).
    acl : AclSettings or None
        ``dialect="acutrol"``: how the simulated controller answers.
    word_order : {"big", "little"} or None
        Modbus float word order (both ends use it; None: the map's).
    register_map : ModbusMap or None
        Modbus register map served and used (None: the shipped tablebench map).
    watchdog_s : float or None
        Wall-clock watchdog of the controller, s.
    corruption : drivers.sim.serial_unit.Corruption or None
        Injected faults on the unit's byte stream.
    timeout : float
        Driver timeouts, s.
    unit_id : int
        Modbus unit id used by the driver.
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
        dialect: Dialect = "modbus",
        make_acl_table: Callable[[MessageTransport], AclTurntable] | None = None,
        acl: AclSettings | None = None,
        make_aerosmith_table: Callable[[Any], Any] | None = None,
        aerosmith: AerosmithSettings | None = None,
        word_order: Literal["big", "little"] | None = None,
        register_map: ModbusMap | None = None,
        watchdog_s: float | None = None,
        strict_watchdog: bool = False,
        corruption: Corruption | None = None,
        timeout: float = 2.0,
        unit_id: int = 1,
        unit_frame: FrameFormat | None = None,
        unit_raw: BinaryIO | None = None,
        unit_raw_name: str = "",
        realtime: bool = False,
    ) -> None:
        if dialect not in ("acutrol", "modbus", "aerosmith"):
            raise ValueError(f"loopback dialect must be 'acutrol', 'modbus' or 'aerosmith', got {dialect!r}")
        self.world = world
        self.dialect = dialect
        self._closers: list[Callable[[], None]] = []
        self.realtime = bool(realtime)
        clock: dict[str, Any] = {} if realtime else {"clock": world.host_time}  # real time: the host's own clock
        self.table_server: ModbusTableServer | AclTableServer | AerosmithTableServer | None = None
        try:
            if dialect == "modbus":
                self.table_server = ModbusTableServer(
                    world,
                    word_order=word_order,
                    watchdog_s=watchdog_s,
                    register_map=register_map,
                    watchdog_from_power_up=strict_watchdog,
                )
                self._closers.append(self.table_server.close)
                table: Any = connect.modbus_table(
                    "127.0.0.1",
                    self.table_server.port,
                    word_order=word_order,
                    register_map=register_map,
                    unit_id=unit_id,
                    timeout=timeout,
                    retries=0,
                )
            elif dialect == "aerosmith":
                self.table_server = AerosmithTableServer(world, aerosmith)
                settings = self.table_server.settings
                table = connect.aerosmith_table(
                    self.table_server.url,
                    make_aerosmith_table
                    or (lambda stream: AerosmithTable(stream, world.table_limits(), settings=settings, **clock)),
                    timeout=timeout,
                )
            else:
                self.table_server = AclTableServer(world, acl)
                self._closers.append(self.table_server.close)
                res = open_visa(self.table_server.resource, timeout)
                transport = VisaTransport(res, self.table_server.resource)
                try:
                    driver = (
                        make_acl_table(transport)
                        if make_acl_table is not None
                        else connect.AclTurntable(
                            transport, world.table_limits(), settings=self.table_server.settings, **clock
                        )
                    )
                except BaseException:
                    res.close()
                    raise
                table = connect.Connection(driver, transport, [driver.close, res.close])
            self._closers.insert(0, table.close)
            self.client: Any = table.transport
            self.turntable: Turntable = table.driver
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
        srv = self.table_server
        if self.dialect == "modbus":
            table = "Modbus TCP"
        elif isinstance(srv, AerosmithTableServer):
            table = f"Ideal Aerosmith (text commands via pyserial {srv.url})"
        else:
            table = f"ACUTROL (ACL via pyvisa-py {getattr(srv, 'resource', '?')})"
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
