"""The simulated ACUTROL3000 on loopback TCP: :class:`~drivers.sim.acl_controller.AclController` behind a socket.

:class:`AclTableServer` listens on 127.0.0.1 (ephemeral port by default) and serves one client at a time in a
background thread, like the controller's TCP port 9878. A program message ends with LF (a CR before it is
ignored); replies end with CR-LF in the ``tcp`` reply profile and LF in the ``gpib`` one. Reach it with the
VISA resource :attr:`AclTableServer.resource` (``TCPIP0::127.0.0.1::PORT::SOCKET``, pyvisa-py).
"""

from __future__ import annotations

import logging
import select
import socket
from typing import TYPE_CHECKING

from drivers.acutrol.settings import AclSettings
from drivers.sim.acl_controller import AclController
from drivers.sim.tcp_server import SingleClientServer

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)

MAX_MESSAGE = 32768
"""The controller's input buffer (TM-8004 §2.5): a longer message is discarded."""


class AclTableServer(SingleClientServer):
    """Serve a SimulatedWorld's table in ACL on 127.0.0.1.

    Parameters
    ----------
    world : SimulatedWorld
    settings : AclSettings
    port : int
        TCP port; 0 = ephemeral (read :attr:`port`).
    """

    name = "simulated ACUTROL"

    def __init__(self, world: SimulatedWorld, settings: AclSettings | None = None, port: int = 0) -> None:
        self.controller = AclController(world, settings)
        self.settings = self.controller.settings
        self._terminator = b"\r\n" if self.settings.reply_profile == "tcp" else b"\n"
        self._listen(port, "sim-acutrol")
        self._thread.start()

    @property
    def resource(self) -> str:
        """The VISA resource string of this controller."""
        return f"TCPIP0::127.0.0.1::{self.port}::SOCKET"

    def _handle(self, conn: socket.socket) -> None:
        buf = b""
        while not self._stop.is_set():
            r, _, _ = select.select([conn], [], [], 0.05)
            if not r:
                continue
            chunk = conn.recv(65536)
            if not chunk:
                return
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                text = line.rstrip(b"\r").decode("ascii", "replace")
                if not text.strip():
                    continue
                out = b"".join(r.encode("ascii", "replace") + self._terminator for r in self.controller.handle(text))
                if out:
                    conn.sendall(out)
            if len(buf) > MAX_MESSAGE:
                log.warning("simulated ACUTROL: message longer than %d characters discarded", MAX_MESSAGE)
                buf = b""


__all__ = ["AclTableServer"]
