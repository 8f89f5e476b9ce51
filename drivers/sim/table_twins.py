"""The simulated twins of the turntable controllers: one object per controller protocol that builds the table
on the one simulated world, in-process (no bytes) or served on 127.0.0.1 and reached by the real driver over
the real wire.

A twin is what the device registry (``benches/devices.py``) names for a simulated ``simulation.controller``;
:class:`drivers.sim.loopback.Loopback` and the bench factory take a twin and never branch on a controller's
name. A new simulated controller is a new class satisfying :class:`TableTwin` (its server may be absent: set
``in_process_only`` to the message refusing ``--transport loopback``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

from drivers import connect
from drivers.acutrol import AclSettings, AclTurntable
from drivers.aerosmith import AerosmithSettings, AerosmithTable
from drivers.modbus.register_map import ModbusMap
from drivers.protocols import Turntable
from drivers.sim.acl_controller import AclController
from drivers.sim.aerosmith_controller import AerosmithController
from drivers.sim.inprocess import SimTurntable
from drivers.sim.world import SimulatedWorld
from drivers.transport import MessageTransport, VisaTransport, open_visa

if TYPE_CHECKING:  # the servers are imported when one is started (an in-process bench starts none)
    from drivers.sim.acl_server import AclTableServer
    from drivers.sim.aerosmith_server import AerosmithTableServer
    from drivers.sim.modbus_controller import ModbusTableServer

Clock = Callable[[], float]


class TableServer(Protocol):
    """A wire-level controller simulator on 127.0.0.1."""

    port: int

    def close(self) -> None:
        """Stop serving."""
        ...


class TableTwin(Protocol):
    """A simulated turntable controller of one protocol (see the module docstring).

    Attributes
    ----------
    in_process_only : str
        "" if the twin has a server on 127.0.0.1; else the message refusing a loopback transport.
    unit_note : bool
        The in-process bench's line says that the unit's frame format and raw stream apply over loopback only.
    """

    in_process_only: str
    unit_note: bool

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        """The table without a wire and one line saying what it is (``alone``: opened without the unit)."""
        ...

    def serve(self, world: SimulatedWorld) -> TableServer:
        """Start the controller's server for ``world`` on 127.0.0.1."""
        ...

    def connect(self, server: Any, timeout: float, clock: Clock | None, alone: bool = False) -> connect.Connection[Any]:
        """The real driver connected to ``server`` over the real wire (``clock``: the host clock, None: the
        host's monotonic clock; ``alone``: the table opened without the unit, ``tablebench table``)."""
        ...

    def describe(self, server: Any) -> str:
        """The protocol, for the loopback bench's line."""
        ...

    def describe_alone(self, server: Any) -> str:
        """One line when the table is opened alone over loopback."""
        ...


@dataclass
class AclTwin:
    """The simulated ACUTROL3000 (ACL): in memory, or on a TCP socket reached through pyvisa-py.

    Parameters
    ----------
    acl : AclSettings or None
        How the simulated controller answers (None: the language's defaults).
    driver : callable or None
        ``(transport, clock) -> AclTurntable``: the driver with the bench's settings and tolerances; None: the
        world's limits and the controller's settings.
    open_alone : callable or None
        ``(resource, timeout) -> Connection``: the table opened alone over loopback as on hardware (``*IDN?``
        first); None: as in a run.
    """

    acl: AclSettings | None = None
    driver: Callable[[MessageTransport, Clock | None], AclTurntable] | None = None
    open_alone: Callable[[str, float], connect.Connection[Any]] | None = None
    in_process_only: str = ""
    unit_note: bool = True

    def _driver(self, transport: MessageTransport, world: Any, settings: AclSettings, clock: Clock | None) -> Any:
        if self.driver is not None:
            return self.driver(transport, clock)
        extra = {} if clock is None else {"clock": clock}
        return AclTurntable(transport, world.table_limits(), settings=settings, **extra)

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        ctl = AclController(world, self.acl)
        table = self._driver(ctl.transport(timeout), world, ctl.settings, world.host_time)
        return table, "simulated ACUTROL (ACL, in-memory)"

    def serve(self, world: SimulatedWorld) -> AclTableServer:
        from drivers.sim.acl_server import AclTableServer

        return AclTableServer(world, self.acl)

    def connect(self, server: Any, timeout: float, clock: Clock | None, alone: bool = False) -> connect.Connection[Any]:
        if alone and self.open_alone is not None:
            return self.open_alone(server.resource, timeout)
        res = open_visa(server.resource, timeout)
        transport = VisaTransport(res, server.resource)
        try:
            driver = self._driver(transport, server.controller.world, server.settings, clock)
        except BaseException:
            res.close()
            raise
        return connect.Connection(driver, transport, [driver.close, res.close])

    def describe(self, server: Any) -> str:
        return f"ACUTROL (ACL via pyvisa-py {server.resource})"

    def describe_alone(self, server: Any) -> str:
        return f"simulated ACUTROL over pyvisa-py {server.resource}"


@dataclass
class ModbusTwin:
    """The simulated Modbus TCP table controller with its register map (None: the shipped map); a strict PLC
    runs its watchdog from power-up (``watchdog_from_power_up``). ``rate_tolerance`` applies to the table
    opened alone (``tablebench table``)."""

    word_order: Literal["big", "little"] | None = None
    register_map: ModbusMap | None = None
    watchdog_s: float | None = None
    watchdog_from_power_up: bool = False
    rate_tolerance: float | None = None
    unit_id: int = 1
    in_process_only: str = ""
    unit_note: bool = True

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        return SimTurntable(world), "simulated table, in-process driver" if alone else "in-process drivers"

    def serve(self, world: SimulatedWorld) -> ModbusTableServer:
        from drivers.sim.modbus_controller import ModbusTableServer  # lazy: asyncio, pymodbus's server

        return ModbusTableServer(
            world,
            word_order=self.word_order,
            watchdog_s=self.watchdog_s,
            register_map=self.register_map,
            watchdog_from_power_up=self.watchdog_from_power_up,
        )

    def connect(self, server: Any, timeout: float, clock: Clock | None, alone: bool = False) -> connect.Connection[Any]:
        return connect.modbus_table(
            "127.0.0.1",
            server.port,
            word_order=self.word_order,
            register_map=self.register_map,
            unit_id=self.unit_id,
            timeout=timeout,
            retries=0,
            rate_tolerance=self.rate_tolerance if alone else None,
        )

    def describe(self, server: Any) -> str:
        return "Modbus TCP"

    def describe_alone(self, server: Any) -> str:
        return f"simulated Modbus table on 127.0.0.1:{server.port}"


@dataclass
class AerosmithTwin:
    """The simulated Ideal Aerosmith single-axis table: in memory, or served on 127.0.0.1 in its text language
    (:class:`drivers.sim.aerosmith_server.AerosmithTableServer`) and reached through pyserial's ``socket://`` URL
    as through a serial device server. ``driver(stream, clock)`` builds the driver with the bench's settings and
    tolerances (clock None: the host's monotonic clock); None: the world's limits and ``settings``."""

    settings: AerosmithSettings | None = None
    driver: Callable[[Any, Clock | None], Turntable] | None = None
    in_process_only: str = ""
    unit_note: bool = False

    def _driver(self, stream: Any, world: Any, settings: AerosmithSettings | None, clock: Clock | None) -> Any:
        if self.driver is not None:
            return self.driver(stream, clock)
        extra = {} if clock is None else {"clock": clock}
        return AerosmithTable(stream, world.table_limits(), settings=settings, **extra)

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        ctl = AerosmithController(world, self.settings)
        return self._driver(ctl.stream(timeout), world, ctl.settings, None), "simulated Ideal Aerosmith (in-memory)"

    def serve(self, world: SimulatedWorld) -> AerosmithTableServer:
        from drivers.sim.aerosmith_server import AerosmithTableServer

        return AerosmithTableServer(world, self.settings)

    def connect(self, server: Any, timeout: float, clock: Clock | None, alone: bool = False) -> connect.Connection[Any]:
        world, settings = server.controller.world, server.settings
        return connect.aerosmith_table(
            server.url, lambda stream: self._driver(stream, world, settings, None if alone else clock), timeout=timeout
        )

    def describe(self, server: Any) -> str:
        return f"Ideal Aerosmith (text commands via pyserial {server.url})"

    def describe_alone(self, server: Any) -> str:
        return f"simulated Ideal Aerosmith over pyserial {server.url}"


__all__ = ["AclTwin", "AerosmithTwin", "ModbusTwin", "TableServer", "TableTwin"]
