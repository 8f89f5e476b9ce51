"""Espec ASCII command set (P-300, SCP-220, SH-641 family) over RS-232/485, a TCP forwarder or VISA.

The driver talks through a line channel with ``write``/``read``/``query`` of text lines (a
:class:`drivers.chamber.stream.LineChannel` on a serial port or TCP stream, or a
:class:`drivers.transport.VisaTransport` whose terminator is CR LF). Commands and their replies are in
docs/protocols/chambers.md: a setting command is answered ``OK:`` + an echo of the command, a monitor command
with data only, a refusal with ``NA:`` + a reason. Numbers have one decimal, a ``-`` sign and no ``+``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal, Protocol

from drivers.chamber.base import (
    ChamberError,
    ChamberLinkError,
    ChamberReading,
    ChamberSettings,
    from_wire_celsius,
    to_wire_celsius,
)


class Lines(Protocol):
    """A text-line link (LineChannel, VisaTransport)."""

    def write(self, message: str) -> None: ...

    def read(self) -> str: ...


@dataclass(frozen=True)
class EspecSettings:
    """Open points of the Espec dialect as bench settings (docs/protocols/chambers.md).

    Attributes
    ----------
    address : int or None
        RS-485 address 1–16 (commands are prefixed ``<address>,``); None on RS-232, TCP and GPIB (default).
    setpoint_form : {"spaced", "compact"}
        ``TEMP, S25.0`` (ChamberConnectLibrary, default) or ``TEMP,S25.0`` (ATWG).
    power_off_on_stop : bool
        After ``MODE,STANDBY`` also send ``POWER,off`` (ATWG's stop); default False.
    """

    address: int | None = None
    setpoint_form: Literal["spaced", "compact"] = "spaced"
    power_off_on_stop: bool = False

    def __post_init__(self) -> None:
        if self.address is not None and not 1 <= self.address <= 16:
            raise ValueError(f"Espec RS-485 address must be 1..16, got {self.address!r}")
        if self.setpoint_form not in ("spaced", "compact"):
            raise ValueError(f"Espec setpoint_form must be 'spaced' or 'compact', got {self.setpoint_form!r}")


def format_number(celsius: float) -> str:
    """One decimal, ``-`` sign, no ``+``, no negative zero."""
    text = f"{celsius:.1f}"
    return "0.0" if text == "-0.0" else text


_STATUS = re.compile(r"^\s*(OK|NA)\s*:", re.IGNORECASE)


def _squash(text: str) -> str:
    return "".join(text.split()).upper()


class EspecChamber:
    """Espec chamber controller (:class:`drivers.chamber.base.Chamber`)."""

    def __init__(
        self,
        link: Lines,
        settings: ChamberSettings | None = None,
        espec: EspecSettings | None = None,
        name: str = "Espec chamber",
    ) -> None:
        self.link = link
        self.settings = settings or ChamberSettings()
        self.espec = espec or EspecSettings()
        self.name = name
        self._closed = False

    def connect(self) -> None:
        """Nothing to learn first (``identify`` asks ``TYPE?`` and ``ROM?``)."""

    # ---- exchanges ------------------------------------------------------------------------------------
    def _send(self, command: str) -> str:
        if self._closed:
            raise ChamberLinkError(f"{self.name}: driver is closed")
        prefix = f"{self.espec.address}," if self.espec.address is not None else ""
        self.link.write(prefix + command)
        reply = self.link.read()
        m = _STATUS.match(reply)
        if m is not None:  # "OK:" / "NA:", with or without a space before the colon (EHS manual)
            reply = f"{m.group(1).upper()}:{reply[m.end() :]}"
        if reply.startswith("NA:"):
            raise ChamberError(f"{self.name}: {command!r} refused: {reply[3:].strip()}")
        return reply

    def monitor(self, command: str) -> list[str]:
        """A monitor command (``TEMP?``, ``MON?``...): its comma-separated data fields."""
        reply = self._send(command)
        if reply.startswith("OK:"):
            raise ChamberLinkError(f"{self.name}: {command!r} answered {reply!r}, expected data")
        return [f.strip() for f in reply.split(",")]

    def setting(self, command: str) -> None:
        """A setting command: the reply must be ``OK:`` + an echo of it (address and spacing tolerated)."""
        reply = self._send(command)
        if not reply.startswith("OK:"):
            raise ChamberLinkError(f"{self.name}: {command!r} answered {reply!r}, expected 'OK:{command}'")
        if not _squash(reply[3:]).endswith(_squash(command)):
            raise ChamberLinkError(f"{self.name}: {command!r} acknowledged as {reply!r}")

    def _number(self, text: str, command: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise ChamberLinkError(f"{self.name}: {command!r} gave {text!r}, not a number") from None

    # ---- Chamber --------------------------------------------------------------------------------------
    def read_temp(self) -> tuple[float, float, float, float]:
        """``TEMP?`` → (PV, SP, high limit, low limit), °C."""
        f = self.monitor("TEMP?")
        if len(f) != 4:
            raise ChamberLinkError(f"{self.name}: 'TEMP?' gave {len(f)} fields, expected PV,SP,high,low")
        pv, sp, hi, lo = (self._number(x, "TEMP?") for x in f)
        return pv, sp, hi, lo

    def read_monitor(self) -> tuple[str, int]:
        """``MON?`` → (mode, alarm count); with or without the humidity field (empty or absent)."""
        f = self.monitor("MON?")
        if len(f) not in (3, 4):
            raise ChamberLinkError(f"{self.name}: 'MON?' gave {len(f)} fields, expected temp[,humi],mode,alarms")
        try:
            alarms = int(f[-1])
        except ValueError:
            raise ChamberLinkError(f"{self.name}: 'MON?' alarm count {f[-1]!r} is not an integer") from None
        return f[-2].upper(), alarms

    def read(self) -> ChamberReading:
        """``TEMP?`` then ``MON?``."""
        pv, sp, _, _ = self.read_temp()
        mode, alarms = self.read_monitor()
        return ChamberReading(
            setpoint=from_wire_celsius(sp),
            air=from_wire_celsius(pv),
            running=mode == "CONSTANT" or mode.startswith("RUN"),
            alarm=alarms > 0,
            detail=f"{mode}, {alarms} alarm(s)",
        )

    def set_setpoint(self, temperature: float) -> float:
        """Clamp, send ``TEMP, S<value>``, read it back with ``TEMP?``; return the active set point, K."""
        target = to_wire_celsius(self.settings.clamp(temperature))
        sep = ", " if self.espec.setpoint_form == "spaced" else ","
        self.setting(f"TEMP{sep}S{format_number(target)}")
        _, back, _, _ = self.read_temp()
        if abs(back - target) > self.settings.readback_tolerance:
            raise ChamberError(f"{self.name}: set point {target:.1f} °C sent, {back:g} °C read back")
        return from_wire_celsius(back)

    def start(self) -> None:
        """``POWER,ON`` if the controller is off, then ``MODE,CONSTANT``."""
        mode = self.monitor("MODE?")[0].upper()
        if mode == "OFF":
            self.setting("POWER,ON")
        self.setting("MODE,CONSTANT")

    def stop(self) -> None:
        """``MODE,STANDBY`` (then ``POWER,off`` if the bench asks)."""
        self.setting("MODE,STANDBY")
        if self.espec.power_off_on_stop:
            self.setting("POWER,off")

    def identify(self) -> str:
        """``TYPE?`` and ``ROM?``."""
        kind = ",".join(self.monitor("TYPE?"))
        rom = ",".join(self.monitor("ROM?"))
        return f"Espec {kind} (ROM {rom})"

    def close(self) -> None:
        """Release the driver."""
        self._closed = True
