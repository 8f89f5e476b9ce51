"""Open a transport and build the driver on it: the one place drivers are constructed.

The drivers themselves never open ports (they receive an open transport); these functions do that part, for
the bench factory (real hardware), the loopback simulated bench and the wire tests alike, and return a
:class:`Connection`: the driver, the transport it talks through (possibly wrapped, e.g. by a test's
counting proxy) and the functions that close what was opened, in the order to call them (driver first).
A transport that cannot be opened raises :class:`~drivers.protocols.LinkError` naming the address.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, BinaryIO, Generic, TypeVar

import serial
from pymodbus.client import ModbusTcpClient

from drivers.acutrol import AclSettings, AclTurntable
from drivers.imu_unit.counts import CountScale
from drivers.imu_unit.description import FrameFormat
from drivers.imu_unit.serial_unit import SerialInertialUnit
from drivers.modbus.register_map import ModbusMap
from drivers.modbus.table import ModbusTurntable
from drivers.protocols import AxisLimits, LinkError
from drivers.transport import VisaTransport, open_visa

D = TypeVar("D")
Limits = tuple[AxisLimits, AxisLimits, AxisLimits]
Wrap = Callable[[Any], Any]


@dataclass
class Connection(Generic[D]):
    """A driver on its open transport; ``close()`` closes the driver, then the transport (never raises)."""

    driver: D
    transport: Any
    closers: list[Callable[[], None]] = field(default_factory=list)

    def close(self) -> None:
        closers, self.closers = self.closers, []
        for fn in closers:
            try:
                fn()
            except Exception:  # noqa: BLE001 - closing must go on and must not mask the original error
                pass


def _same(transport: Any) -> Any:
    return transport


def modbus_table(
    host: str,
    port: int,
    *,
    word_order: str | None = None,
    register_map: ModbusMap | None = None,
    limits: Limits | None = None,
    unit_id: int = 1,
    timeout: float = 2.0,
    retries: int = 1,
    wrap: Wrap = _same,
    rate_tolerance: float | None = None,
) -> Connection[ModbusTurntable]:
    """A Modbus TCP turntable controller at ``host:port`` with its register map (:mod:`drivers.modbus.register_map`)."""
    client = ModbusTcpClient(host, port=port, timeout=timeout, retries=retries)
    if not client.connect():
        client.close()
        raise LinkError(f"turntable: no Modbus TCP answer at {host}:{port}; check power, cable and address")
    transport = wrap(client)
    try:
        extra = {} if rate_tolerance is None else {"rate_tolerance": rate_tolerance}
        table = ModbusTurntable(
            transport, unit_id=unit_id, word_order=word_order, limits=limits, register_map=register_map, **extra
        )
    except BaseException:
        client.close()
        raise
    return Connection(table, transport, [table.close, client.close])


def _serial_port(what: str, url: str, **kw: Any) -> Any:
    try:
        return serial.serial_for_url(url, **kw)
    except (serial.SerialException, ValueError) as exc:
        raise LinkError(f"{what}: cannot open {url!r}: {exc}") from exc


def aerosmith_table(
    url: str, make: Callable[[Any], Any], *, timeout: float = 2.0, wrap: Wrap = _same
) -> Connection[Any]:
    """An Ideal Aerosmith controller on the serial port ``url`` (9600 8N1, pyserial URL: ``/dev/ttyUSB0``, ``COM3``,
    ``socket://host:port`` through a device server); ``make(stream)`` builds the driver on the open stream."""
    port = _serial_port("turntable", url, baudrate=9600, bytesize=8, parity="N", stopbits=1, timeout=timeout)
    stream = wrap(port)
    try:
        table = make(stream)
    except BaseException:
        port.close()
        raise
    return Connection(table, stream, [table.close, port.close])


def acutrol_table(
    resource: str,
    limits: Limits,
    *,
    settings: AclSettings | None = None,
    position_tolerance: float,
    settle_time: float,
    rate_tolerance: float,
    timeout: float = 2.0,
    wrap: Wrap = _same,
    check: bool = True,
) -> Connection[AclTurntable]:
    """An ACUTROL3000 (ACL) at a VISA resource string, opened with pyvisa-py (``TCPIP0::…::9878::SOCKET``,
    ``GPIB0::1::INSTR``, ``ASRL/dev/ttyS0::INSTR``); ``check`` asks ``*IDN?`` before anything else is sent."""
    res = open_visa(resource, timeout)
    transport = wrap(VisaTransport(res, resource))
    try:
        table = AclTurntable(
            transport,
            limits,
            settings=settings,
            position_tolerance=position_tolerance,
            settle_time=settle_time,
            rate_tolerance=rate_tolerance,
        )
        if check:
            try:
                table.idn()
            except LinkError as exc:
                raise LinkError(
                    f"turntable: no answer from the ACUTROL at {resource} ({exc}); check power, cable, the resource "
                    "string and that the controller is in remote mode"
                ) from exc
    except BaseException:
        res.close()
        raise
    return Connection(table, transport, [table.close, res.close])


def serial_unit(
    url: str,
    frame: FrameFormat | CountScale,
    sample_rate: float,
    *,
    baudrate: int | None = None,
    polled: bool = False,
    timeout: float = 2.0,
    name: str = "inertial unit",
    raw_sink: BinaryIO | None = None,
    raw_name: str = "",
    wrap: Wrap = _same,
    clock: Any = None,
) -> Connection[SerialInertialUnit]:
    """A serial inertial unit on a device or URL: free-running stream, or polled bursts (``polled``); ``frame``
    is its frame format (a bare count scale means the project's own ``tablebench-v1`` frame); ``raw_sink``
    keeps the raw byte stream (see :class:`~drivers.imu_unit.serial_unit.SerialInertialUnit`)."""
    kw: dict[str, Any] = {"timeout": 0.02}
    if baudrate is not None:
        kw["baudrate"] = int(baudrate)
    port = _serial_port("unit", url, **kw)
    transport = wrap(port)
    try:
        unit = SerialInertialUnit(
            transport,
            frame,
            sample_rate,
            timeout=timeout,
            polled=polled,
            name=name,
            raw_sink=raw_sink,
            raw_name=raw_name,
            **({} if clock is None else {"clock": clock}),
        )
    except BaseException:
        port.close()
        raise
    return Connection(unit, transport, [unit.close, port.close])
