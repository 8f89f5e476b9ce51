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

from drivers import modbus_registers as reg
from drivers.ascii_table import AsciiTurntable
from drivers.imu_counts import CountScale
from drivers.imu_frame_desc import FrameFormat
from drivers.modbus_table import ModbusTurntable
from drivers.protocols import AxisLimits, LinkError
from drivers.serial_imu import SerialInertialUnit

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
    word_order: reg.WordOrder = "big",
    limits: Limits | None = None,
    unit_id: int = 1,
    timeout: float = 2.0,
    retries: int = 1,
    wrap: Wrap = _same,
) -> Connection[ModbusTurntable]:
    """A Modbus TCP turntable controller at ``host:port`` (see :mod:`drivers.modbus_registers`)."""
    client = ModbusTcpClient(host, port=port, timeout=timeout, retries=retries)
    if not client.connect():
        client.close()
        raise LinkError(f"turntable: no Modbus TCP answer at {host}:{port}; check power, cable and address")
    transport = wrap(client)
    try:
        table = ModbusTurntable(transport, unit_id=unit_id, word_order=word_order, limits=limits)
    except BaseException:
        client.close()
        raise
    return Connection(table, transport, [table.close, client.close])


def _serial_port(what: str, url: str, **kw: Any) -> Any:
    try:
        return serial.serial_for_url(url, **kw)
    except (serial.SerialException, ValueError) as exc:
        raise LinkError(f"{what}: cannot open {url!r}: {exc}") from exc


def ascii_table(
    url: str, *, limits: Limits | None = None, timeout: float = 2.0, wrap: Wrap = _same
) -> Connection[AsciiTurntable]:
    """An ASCII-dialect turntable controller on a serial device or URL (``/dev/ttyS0``, ``socket://h:p``)."""
    port = _serial_port("turntable", url, timeout=timeout)
    transport = wrap(port)
    try:
        table = AsciiTurntable(transport, timeout=timeout, limits=limits)
    except BaseException:
        port.close()
        raise
    return Connection(table, transport, [table.close, port.close])


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
) -> Connection[SerialInertialUnit]:
    """A serial inertial unit on a device or URL: free-running stream, or polled bursts (``polled``); ``frame``
    is its frame format (a bare count scale means the project's own ``tablebench-v1`` frame); ``raw_sink``
    keeps the raw byte stream (see :class:`~drivers.serial_imu.SerialInertialUnit`)."""
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
        )
    except BaseException:
        port.close()
        raise
    return Connection(unit, transport, [unit.close, port.close])
