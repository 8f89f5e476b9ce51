"""Where a chamber is and how to talk to it: the dialect, the link and the settings (no I/O, light imports).

:mod:`drivers.chamber.connect` opens the link; :mod:`drivers.chamber.bench_section` reads this from a bench file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from drivers.chamber.base import ChamberSettings

Dialect = Literal["watlow_f4", "watlow_f4t", "espec", "simserv"]
DIALECTS: tuple[str, ...] = ("watlow_f4", "watlow_f4t", "espec", "simserv")
DEFAULT_TCP_PORT = {"watlow_f4": 502, "watlow_f4t": 502, "espec": 10001, "simserv": 2049}


@dataclass(frozen=True)
class ChamberLink:
    """Where the chamber is and how its line is set.

    Attributes
    ----------
    kind : {"serial", "tcp", "visa"}
    address : str
        Serial device or pyserial URL (``/dev/ttyUSB0``, ``COM3``), ``host`` for TCP, or a VISA resource string.
    port : int or None
        TCP port (None: the dialect's usual one — Modbus 502, Espec forwarder 10001, simserv 2049).
    baudrate, bytesize, parity, stopbits : serial line settings (defaults 9600 8N1; a bench setting because the
        public clients disagree: 9600 or 19200, 1 or 2 stop bits).
    framing : {"rtu", "tcp"} or None
        Watlow only: Modbus framing (None: TCP framing on a ``tcp`` link, RTU on a serial line).
    send_delay : float or None
        Watlow only: pause after each request, s (None: 30 ms on RTU, 0 on Modbus TCP).
    """

    kind: Literal["serial", "tcp", "visa"] = "serial"
    address: str = ""
    port: int | None = None
    baudrate: int = 9600
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1
    framing: Literal["rtu", "tcp"] | None = None
    send_delay: float | None = None


@dataclass(frozen=True)
class ChamberConfig:
    """A bench's chamber: dialect, link, shared settings and the dialect's own settings.

    Attributes
    ----------
    dialect : {"watlow_f4", "watlow_f4t", "espec", "simserv"}
    link : ChamberLink
    settings : ChamberSettings
    options : WatlowF4Settings | WatlowF4TSettings | EspecSettings | SimservSettings or None
        The dialect's open points (None: the documented defaults).
    address : int
        Modbus address (Watlow); ignored by the other dialects (Espec RS-485: ``EspecSettings.address``).
    name : str
    """

    dialect: Dialect
    link: ChamberLink = field(default_factory=ChamberLink)
    settings: ChamberSettings = field(default_factory=ChamberSettings)
    options: Any = None
    address: int = 1
    name: str = "chamber"


