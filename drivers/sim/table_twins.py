"""The simulated twins of the turntable controllers: one object per controller protocol that builds the
table either in-process or served on 127.0.0.1 and reached by the real driver over the real wire.

A twin is what the device registry (``benches/devices.py``) names for a controller;
:class:`drivers.sim.loopback.Loopback`
and the bench factory take a twin and never branch on a controller's name.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Protocol

from drivers import connect
from drivers.acutrol import AclSettings, AclTurntable
from drivers.modbus.register_map import ModbusMap
from drivers.protocols import AxisLimits, Turntable
from drivers.sim.acl_controller import AclController
from drivers.sim.acl_server import AclTableServer
from drivers.sim.inprocess import SimTurntable
from drivers.sim.modbus_controller import ModbusTableServer
from drivers.sim.world import SimulatedWorld
from drivers.transport import MessageTransport, VisaTransport, open_visa


class TableServer(Protocol):
    """A wire-level controller simulator on 127.0.0.1."""

    port: int

    def close(self) -> None:
        """Stop serving."""
        ...


class TableTwin(Protocol):
    """A simulated turntable controller of one protocol (see the module docstring)."""

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        """The table without a wire, and one line saying what it is (``alone``: opened without the unit)."""
        ...

    def serve(self, world: SimulatedWorld) -> TableServer:
        """Start the controller's server for ``world`` on 127.0.0.1."""
        ...

    def connect(self, server: TableServer, timeout: float) -> connect.Connection[Any]:
        """The real driver connected to ``server`` over the real wire."""
        ...

    def describe(self, server: TableServer) -> str:
        """The protocol, for the loopback bench's line."""
        ...

    def describe_alone(self, server: TableServer) -> str:
        """One line when the table is opened alone (``tablebench table``)."""
        ...


@dataclass
class AclTwin:
    """The simulated ACUTROL3000 (ACL): in memory, or on a TCP socket reached through pyvisa-py.

    The ACL driver gets ``limits`` and ``options`` (the bench's settings and tolerances: keyword arguments of
    :class:`drivers.acutrol.AclTurntable`); by default the world's limits and the controller's settings.
    """

    acl: AclSettings | None = None
    limits: tuple[AxisLimits, AxisLimits, AxisLimits] | None = None
    options: dict[str, Any] | None = None

    def _driver(self, transport: MessageTransport, world: SimulatedWorld, settings: AclSettings | None) -> AclTurntable:
        if self.options is not None:
            return AclTurntable(transport, self.limits or world.table_limits(), **self.options)
        return AclTurntable(transport, self.limits or world.table_limits(), settings=settings)

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        ctl = AclController(world, self.acl)
        return self._driver(ctl.transport(timeout), world, self.acl), "simulated ACUTROL (ACL, in-memory)"

    def serve(self, world: SimulatedWorld) -> AclTableServer:
        return AclTableServer(world, self.acl)

    def connect(self, server: TableServer, timeout: float) -> connect.Connection[AclTurntable]:
        assert isinstance(server, AclTableServer)
        res = open_visa(server.resource, timeout)
        transport = VisaTransport(res, server.resource)
        try:
            driver = self._driver(transport, server.controller.world, server.settings)
        except BaseException:
            res.close()
            raise
        return connect.Connection(driver, transport, [driver.close, res.close])

    def describe(self, server: TableServer) -> str:
        assert isinstance(server, AclTableServer)
        return f"ACUTROL (ACL via pyvisa-py {server.resource})"

    def describe_alone(self, server: TableServer) -> str:
        assert isinstance(server, AclTableServer)
        return f"simulated ACUTROL over pyvisa-py {server.resource}"


@dataclass
class ModbusTwin:
    """The simulated Modbus TCP table controller with its register map (None: the shipped map)."""

    word_order: Literal["big", "little"] | None = None
    register_map: ModbusMap | None = None
    watchdog_s: float | None = None
    watchdog_from_power_up: bool = False
    rate_tolerance: float | None = None
    unit_id: int = 1

    def in_process(self, world: SimulatedWorld, timeout: float, alone: bool = False) -> tuple[Turntable, str]:
        return SimTurntable(world), "simulated table, in-process driver" if alone else "in-process drivers"

    def serve(self, world: SimulatedWorld) -> ModbusTableServer:
        return ModbusTableServer(
            world,
            word_order=self.word_order,
            watchdog_s=self.watchdog_s,
            register_map=self.register_map,
            watchdog_from_power_up=self.watchdog_from_power_up,
        )

    def connect(self, server: TableServer, timeout: float) -> connect.Connection[Any]:
        return connect.modbus_table(
            "127.0.0.1",
            server.port,
            word_order=self.word_order,
            register_map=self.register_map,
            unit_id=self.unit_id,
            timeout=timeout,
            retries=0,
            rate_tolerance=self.rate_tolerance,
        )

    def describe(self, server: TableServer) -> str:
        return "Modbus TCP"

    def describe_alone(self, server: TableServer) -> str:
        return f"simulated Modbus table on 127.0.0.1:{server.port}"


__all__ = ["AclTwin", "ModbusTwin", "TableServer", "TableTwin"]
