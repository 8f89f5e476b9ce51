"""A simulated Ideal Aerosmith single-axis controller: its text commands executed against the one simulated world.

Written from docs/protocols/ideal-aerosmith.md and :class:`~drivers.aerosmith.settings.AerosmithSettings` (it
shares no code with the driver): a command is three letters and an optional number, ended by the settings'
terminator (or, with an empty terminator, by the end of what was written at once); every reply ends with the
prompt. ``SRV1``/``SRV0`` servo on/off; ``ACL a`` sets the acceleration (°/s², ≤ the bench's limit);
``JOG r`` spins at r °/s (needs the servo on, |r| ≤ the rate limit); ``STO`` stops under control; ``HOM`` goes
to 0°; ``POS?``/``RAT?`` (the settings' queries) answer degrees and °/s with 6 decimals. An unknown command, a
bad number or a refused demand is answered by an error text before the prompt, and nothing is done.
"""

from __future__ import annotations

import math
import re
import threading
from typing import TYPE_CHECKING

from analysis.units import DEG
from drivers.aerosmith.settings import AerosmithSettings
from drivers.protocols import LinkError, TableError

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld

_COMMAND = re.compile(r"^([A-Z]{3})(\?|[-+]?(\d+\.?\d*|\.\d+)?)$")


class AerosmithController:
    """The controller without a wire: :meth:`handle` takes what the host wrote, returns the reply bytes."""

    def __init__(self, world: SimulatedWorld, settings: AerosmithSettings | None = None) -> None:
        self.world = world
        self.settings = settings or AerosmithSettings()
        self.ax = self.settings.index
        self.lim = world.table_limits()[self.ax]
        self.servo = False
        self.accel = self.lim.accel_max
        self.messages = 0
        self._lock = threading.Lock()

    def handle(self, text: str) -> str:
        """One command or query (terminator stripped) → the reply text, prompt included."""
        with self._lock:
            self.messages += 1
            try:
                said = self._execute(text.strip().upper())
            except (ValueError, TableError) as exc:
                said = f"ERROR {exc}"
            return (said + "\r\n" if said else "") + self.settings.prompt

    def _execute(self, text: str) -> str:
        m = _COMMAND.match(text)
        if m is None:
            raise ValueError(f"not a command: {text!r}")
        cmd, arg = m.group(1), m.group(2)
        s = self.settings
        if arg == "?":
            state = self.world.table_state()
            if cmd == s.position_query.upper():
                return f"{math.degrees(float(state.angles[self.ax])):.6f}"
            if cmd == s.rate_query.upper():
                return f"{math.degrees(float(state.rates[self.ax])):.6f}"
            if cmd == "ACL":
                return f"{self.accel / DEG:.6f}"
            raise ValueError(f"no query {cmd}?")
        value = float(arg) if arg else None
        if cmd == "SRV":
            if value not in (0.0, 1.0):
                raise ValueError("SRV takes 0 or 1")
            if value == 0.0:
                self.world.command_stop()
            self.servo = value == 1.0
        elif cmd == "ACL":
            if value is None or not 0 < value * DEG <= self.lim.accel_max * (1 + 1e-9):
                raise ValueError(f"ACL {arg}: 0 < acceleration <= {self.lim.accel_max / DEG:g} deg/s^2")
            self.accel = value * DEG
        elif cmd == "JOG":
            if not self.servo:
                raise ValueError("servo off (SRV1 first)")
            if value is None or not self.lim.allows_rate(value * DEG):
                raise ValueError(f"JOG {arg}: |rate| <= {self.lim.rate_max / DEG:g} deg/s")
            self.world.command_rate(self.ax, value * DEG)
        elif cmd == "STO":
            self.world.command_stop()
        elif cmd == "HOM":
            if not self.servo:
                raise ValueError("servo off (SRV1 first)")
            self.world.command_axis_position(self.ax, 0.0)
        else:
            raise ValueError(f"unknown command {cmd}")
        return ""

    def stream(self, timeout: float = 2.0) -> InMemoryStream:
        """An in-memory pyserial-like byte stream to this controller (the in-process simulated bench)."""
        return InMemoryStream(self, timeout)


class InMemoryStream:
    """``write``/``read_until``/``timeout`` against an :class:`AerosmithController` (no wire)."""

    def __init__(self, controller: AerosmithController, timeout: float = 2.0) -> None:
        self.c = controller
        self.timeout = timeout
        self._pending = bytearray()
        self._closed = False

    def write(self, data: bytes) -> int:
        if self._closed:
            raise LinkError("simulated Ideal Aerosmith: stream closed")
        term = self.c.settings.command_terminator
        text = data.decode("ascii", "replace")
        for part in text.split(term) if term else [text]:
            if part.strip():
                self._pending += self.c.handle(part).encode("ascii")
        return len(data)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        i = self._pending.find(expected)
        n = len(self._pending) if i < 0 else i + len(expected)
        out = bytes(self._pending[:n])
        del self._pending[:n]
        return out

    def close(self) -> None:
        self._closed = True


__all__ = ["AerosmithController", "InMemoryStream"]
