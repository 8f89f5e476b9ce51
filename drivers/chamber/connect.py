"""Open a chamber link and build its driver: the one place chamber ports are opened.

:class:`ChamberLink` says where the chamber is: a serial device (``serial``; RS-232/485 or a USB adapter),
a TCP stream (``tcp``; Modbus TCP, simserv, or a serial-to-Ethernet forwarder) or a VISA resource (``visa``;
Espec over GPIB or a TCPIP SOCKET). :func:`open_chamber` opens it with pyserial (``serial_for_url``, a
``socket://host:port`` URL for TCP) or pyvisa-py and returns a :class:`drivers.connect.Connection` whose
``close()`` releases the driver and then the port. The caller is responsible for calling
:func:`drivers.chamber.safety.leave_safe` before closing (docs/protocols/chambers.md).
"""

from __future__ import annotations

from typing import Any

import serial

from drivers.chamber.base import Chamber, ChamberLinkError
from drivers.chamber.config import DEFAULT_TCP_PORT, DIALECTS, ChamberConfig
from drivers.chamber.espec import EspecChamber, EspecSettings
from drivers.chamber.modbus_rtu import ModbusMaster
from drivers.chamber.simserv import SimservChamber, SimservSettings
from drivers.chamber.stream import LineChannel
from drivers.chamber.watlow import WatlowF4, WatlowF4Settings, WatlowF4T, WatlowF4TSettings
from drivers.connect import Connection
from drivers.transport import VisaTransport, open_visa


def _open_stream(cfg: ChamberConfig) -> Any:
    link = cfg.link
    try:
        if link.kind == "tcp":
            port = link.port if link.port is not None else DEFAULT_TCP_PORT[cfg.dialect]
            return serial.serial_for_url(f"socket://{link.address}:{port}", timeout=0.05)
        return serial.serial_for_url(
            link.address,
            baudrate=link.baudrate,
            bytesize=link.bytesize,
            parity=link.parity,
            stopbits=link.stopbits,
            timeout=0.05,
        )
    except (serial.SerialException, ValueError, OSError) as exc:
        where = f"{link.address}:{link.port}" if link.kind == "tcp" else link.address
        raise ChamberLinkError(
            f"{cfg.name}: cannot open {link.kind} link {where!r} ({exc}); check the chamber section of the bench file"
        ) from exc


def _build(cfg: ChamberConfig, stream: Any) -> Chamber:
    s = cfg.settings
    if cfg.dialect in ("watlow_f4", "watlow_f4t"):
        framing = cfg.link.framing or ("tcp" if cfg.link.kind == "tcp" else "rtu")
        delay = cfg.link.send_delay if cfg.link.send_delay is not None else (0.03 if framing == "rtu" else 0.0)
        m = ModbusMaster(stream, framing, cfg.address, timeout=s.timeout, send_delay=delay, name=cfg.name)
        if cfg.dialect == "watlow_f4":
            return WatlowF4(m, s, cfg.options or WatlowF4Settings(), name=cfg.name)
        return WatlowF4T(m, s, cfg.options or WatlowF4TSettings(), name=cfg.name)
    if cfg.dialect == "espec":
        link = stream if isinstance(stream, VisaTransport) else LineChannel(stream, cfg.name, s.timeout)
        return EspecChamber(link, s, cfg.options or EspecSettings(), name=cfg.name)
    if cfg.dialect == "simserv":
        return SimservChamber(stream, s, cfg.options or SimservSettings(), name=cfg.name)
    raise ValueError(f"unknown chamber dialect {cfg.dialect!r}; expected one of {', '.join(DIALECTS)}")


def open_chamber(cfg: ChamberConfig) -> Connection[Chamber]:
    """Open the chamber's link, build the driver and let it learn what it must (Watlow decimals and units)."""
    if cfg.link.kind == "visa":
        if cfg.dialect != "espec":
            raise ValueError(f"{cfg.name}: a VISA link is for the Espec dialect only, not {cfg.dialect!r}")
        res = open_visa(cfg.link.address, cfg.settings.timeout)
        res.write_termination = "\r\n"
        stream: Any = VisaTransport(res, cfg.link.address)
        close_port = res.close
    else:
        stream = _open_stream(cfg)
        close_port = stream.close
    try:
        driver = _build(cfg, stream)
        driver.connect()
    except BaseException:
        close_port()
        raise
    return Connection(driver, stream, [driver.close, close_port])
