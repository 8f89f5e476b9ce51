"""The simulated Ideal Aerosmith controller on loopback TCP:
:class:`~drivers.sim.aerosmith_controller.AerosmithController` behind a socket, reached like a serial
device server (pyserial URL ``socket://127.0.0.1:PORT``).

A command ends with the settings' terminator; with an empty terminator (what the public ``aerosmith`` package
sends) a command is what arrived in one burst: the bytes received until the line has been quiet for
:data:`QUIET_S` (a host writes one command and waits for the prompt before the next). Replies are the
controller's text and prompt, as on the RS-232 line (docs/protocols/ideal-aerosmith.md).
"""

from __future__ import annotations

import logging
import select
import socket
from typing import TYPE_CHECKING

from drivers.aerosmith.settings import AerosmithSettings
from drivers.sim.aerosmith_controller import AerosmithController
from drivers.sim.tcp_server import SingleClientServer

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)

QUIET_S = 0.005
"""Without a terminator, a command is complete once no byte has arrived for this long, s."""

MAX_COMMAND = 256
"""A longer line without a terminator is discarded (the controller's input buffer is short)."""


class AerosmithTableServer(SingleClientServer):
    """Serve a SimulatedWorld's single-axis table in the Ideal Aerosmith text language on 127.0.0.1.

    Parameters
    ----------
    world : SimulatedWorld
    settings : AerosmithSettings or None
    port : int
        TCP port; 0 = ephemeral (read :attr:`port`).
    """

    name = "simulated Ideal Aerosmith"

    def __init__(self, world: SimulatedWorld, settings: AerosmithSettings | None = None, port: int = 0) -> None:
        self.controller = AerosmithController(world, settings)
        self.settings = self.controller.settings
        self._listen(port, "sim-aerosmith")
        self._thread.start()

    @property
    def url(self) -> str:
        """The pyserial URL of this controller (a serial device server on loopback)."""
        return f"socket://127.0.0.1:{self.port}"

    def _commands(self, buf: bytes, quiet: bool) -> tuple[list[str], bytes]:
        """Complete commands in ``buf`` and what is left over."""
        term = self.settings.command_terminator.encode("ascii")
        if not term:
            return ([buf.decode("ascii", "replace")] if quiet and buf.strip() else []), (b"" if quiet else buf)
        parts = buf.split(term)
        return [p.decode("ascii", "replace") for p in parts[:-1] if p.strip()], parts[-1]

    def _handle(self, conn: socket.socket) -> None:
        buf = b""
        while not self._stop.is_set():
            r, _, _ = select.select([conn], [], [], QUIET_S if buf else 0.05)
            if r:
                chunk = conn.recv(4096)
                if not chunk:
                    return
                buf += chunk
            commands, buf = self._commands(buf, quiet=not r)
            out = b"".join(self.controller.handle(c).encode("ascii") for c in commands)
            if out:
                conn.sendall(out)
            if len(buf) > MAX_COMMAND:
                log.warning("simulated Ideal Aerosmith: %d bytes without a command end discarded", len(buf))
                buf = b""


__all__ = ["AerosmithTableServer", "QUIET_S"]
