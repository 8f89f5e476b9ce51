"""Vötsch / Weiss Technik S!MPAC "simserv" over TCP (port 2049).

A request is ASCII fields joined by the single byte 0xB6 (Latin-1 ¶; UTF-8 would send C2 B6, which is wrong)
and ended by CR: ``<5-digit command>¶<chamber index>[¶arg…]``. A reply is fields joined by 0xB6 and ended by
CR LF; field 0 is the code, 1 = accepted and executed, negative = refused (docs/protocols/chambers.md).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from drivers.chamber.base import (
    ChamberError,
    ChamberLinkError,
    ChamberReading,
    ChamberSettings,
    from_wire_celsius,
    to_wire_celsius,
)
from drivers.chamber.stream import ByteStream, StreamReader

SEP = b"\xb6"
REQUEST_END = b"\r"
REPLY_END = b"\r\n"

CODES = {
    -1: "empty string",
    -2: "chamber id missing",
    -3: "chamber id out of range",
    -4: "chamber not present",
    -5: "unknown command",
    -6: "too few or incorrect parameters",
    -7: "no server",
    -8: "no control variable with this id / data could not be read",
    -9: "execution error",
    -10: "index error",
    -11: "not logged in",
    -12: "no execute right",
    -13: "duplicate login",
}

SET_VALUE, GET_SETPOINT, GET_VALUE = 11001, 11002, 11004
SET_OUTPUT, GET_OUTPUT = 14001, 14003
STATUS, IDENTIFY = 10012, 99997


@dataclass(frozen=True)
class SimservSettings:
    """Open points of simserv as bench settings (docs/protocols/chambers.md).

    Attributes
    ----------
    chamber_index : int
        Field 1 of every request ("irrelevant and can always be 1").
    leading_separator : bool
        Send a ¶ before the command number (one public client does); default False.
    run_pause : float
        Pause after a start/stop write, s (one public client waits 1 s); default 1.0.
    temperature_variable : int
        Control-variable index of the temperature (default 1).
    run_output : int
        Digital output that runs the chamber (default 1, "manual run").
    """

    chamber_index: int = 1
    leading_separator: bool = False
    run_pause: float = 1.0
    temperature_variable: int = 1
    run_output: int = 1

    def __post_init__(self) -> None:
        if self.chamber_index < 1 or self.temperature_variable < 1 or self.run_output < 1:
            raise ValueError("simserv chamber_index, temperature_variable and run_output must be >= 1")
        if self.run_pause < 0:
            raise ValueError(f"simserv run_pause must be >= 0 s, got {self.run_pause!r}")


def encode_request(command: int, index: int, args: tuple[str, ...] = (), leading: bool = False) -> bytes:
    """The bytes of one request (at most 4 arguments)."""
    if len(args) > 4:
        raise ValueError("simserv takes at most 4 arguments")
    fields = [str(command), str(index), *args]
    body = SEP.join(f.encode("ascii") for f in fields)
    return (SEP if leading else b"") + body + REQUEST_END


class SimservChamber:
    """Vötsch / Weiss chamber on simserv (:class:`drivers.chamber.base.Chamber`)."""

    def __init__(
        self,
        stream: ByteStream,
        settings: ChamberSettings | None = None,
        simserv: SimservSettings | None = None,
        name: str = "simserv chamber",
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.settings = settings or ChamberSettings()
        self.simserv = simserv or SimservSettings()
        self.name = name
        self.io = StreamReader(stream, name, self.settings.timeout, clock)
        self._sleep = sleep
        self._closed = False

    def connect(self) -> None:
        """Nothing to learn first."""

    def request(self, command: int, *args: str) -> list[str]:
        """Send one request; return the reply's fields after the code (code 1), else raise."""
        if self._closed:
            raise ChamberLinkError(f"{self.name}: driver is closed")
        s = self.simserv
        self.io.discard_input()
        self.io.write(encode_request(command, s.chamber_index, args, s.leading_separator))
        raw = self.io.read_until(REPLY_END, self.io.deadline(), f"command {command}")
        try:
            fields = raw[: -len(REPLY_END)].decode("latin-1").split("\u00b6")
        except UnicodeDecodeError:  # pragma: no cover - latin-1 decodes every byte
            raise ChamberLinkError(f"{self.name}: reply {raw!r} to command {command} is not text") from None
        if "read failed" in fields[0].lower():
            raise ChamberError(f"{self.name}: command {command}: {fields[0].strip()}")
        try:
            code = int(fields[0].strip())
        except ValueError:
            raise ChamberLinkError(f"{self.name}: reply {raw!r} to command {command} has no numeric code") from None
        if code != 1:
            meaning = CODES.get(code, "unknown code")
            raise ChamberError(f"{self.name}: command {command} refused with code {code} ({meaning})")
        return [f.strip() for f in fields[1:]]

    def _value(self, command: int, *args: str) -> float:
        fields = self.request(command, *args)
        if not fields:
            raise ChamberLinkError(f"{self.name}: command {command} answered without a value")
        try:
            return float(fields[0].replace(",", "."))
        except ValueError:
            raise ChamberLinkError(f"{self.name}: command {command} value {fields[0]!r} is not a number") from None

    def read(self) -> ChamberReading:
        """SP (11002), PV (11004), run output (14003), status (10012; +8 = alarm)."""
        var = str(self.simserv.temperature_variable)
        sp = self._value(GET_SETPOINT, var)
        pv = self._value(GET_VALUE, var)
        running = self._value(GET_OUTPUT, str(self.simserv.run_output)) != 0
        status = int(self._value(STATUS))
        return ChamberReading(
            setpoint=from_wire_celsius(sp),
            air=from_wire_celsius(pv),
            running=running,
            alarm=bool(status & 8),
            detail=f"status {status}",
        )

    def set_setpoint(self, temperature: float) -> float:
        """Clamp, 11001 with one decimal, read back with 11002."""
        target = to_wire_celsius(self.settings.clamp(temperature))
        text = f"{target:.1f}"
        var = str(self.simserv.temperature_variable)
        self.request(SET_VALUE, var, "0.0" if text == "-0.0" else text)
        back = self._value(GET_SETPOINT, var)
        if abs(back - target) > self.settings.readback_tolerance:
            raise ChamberError(f"{self.name}: set point {target:.1f} °C sent, {back:g} °C read back")
        return from_wire_celsius(back)

    def _run(self, on: bool) -> None:
        self.request(SET_OUTPUT, str(self.simserv.run_output), "1" if on else "0")
        if self.simserv.run_pause > 0:
            self._sleep(self.simserv.run_pause)

    def start(self) -> None:
        """Manual run on: ``14001¶1¶1¶1``."""
        self._run(True)

    def stop(self) -> None:
        """Manual run off: ``14001¶1¶1¶0``."""
        self._run(False)

    def identify(self) -> str:
        """System type (99997, i = 1)."""
        return "simserv " + " ".join(self.request(IDENTIFY, "1"))

    def close(self) -> None:
        """Release the driver."""
        self._closed = True
