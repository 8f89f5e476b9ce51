"""A simulated turntable controller speaking the ASCII dialect of :mod:`drivers.ascii_table` on loopback TCP.

:class:`AsciiTableServer` listens on 127.0.0.1 (ephemeral port by default), serves one client at a time in
a background thread, and executes each command line against the world (degrees on the wire, SI for the
world). Commands on one line (``;``-separated) form a batch: the ``:dem:pos`` demands of a batch are applied
as ONE ``world.command_position`` call, so a multi-axis move is synchronous, as in process.

Safety behaviour: limits checked here too; ``:hb`` feeds ``world.heartbeat`` and a wall-clock watchdog
(``watchdog_s``; once a heartbeat has been seen, no heartbeat for that long while motion is commanded →
``world.command_stop`` + injected COMMUNICATION_LOST + WATCHDOG reported until ``:fault:reset``); a client
disconnecting while motion is commanded → ``world.command_stop``.
"""

from __future__ import annotations

import logging
import math
import select
import socket
import threading
import time
from typing import Any

from analysis.units import DEG
from drivers.ascii_table import fmt
from drivers.modbus_table import check_position, check_rate
from drivers.protocols import AxisMode, FaultCode, TableError, TableStatus
from drivers.sim.tcp_server import SingleClientServer

log = logging.getLogger(__name__)


class _CommandError(Exception):
    def __init__(self, code: FaultCode, text: str) -> None:
        super().__init__(text)
        self.code = code


class AsciiTableServer(SingleClientServer):
    """Serve a SimulatedWorld's table in the ASCII dialect on 127.0.0.1.

    Parameters
    ----------
    world : SimulatedWorld
    port : int
        TCP port; 0 = ephemeral (read :attr:`port`).
    watchdog_s : float or None
        Wall-clock heartbeat timeout, s (None/0 disables).
    """

    def __init__(self, world: Any, port: int = 0, *, watchdog_s: float | None = None) -> None:
        self.world = world
        self.watchdog_s = float(watchdog_s) if watchdog_s else None
        self._limits = tuple(world.table_limits())
        self._mode_demand = [AxisMode.STOP] * 3
        self._pos_demand: list[float] | None = None
        self._last_hb: float | None = None
        self._motion_commanded = False
        self._watchdog_latched = False
        self._listener = socket.create_server(("127.0.0.1", port))
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._stop = threading.Event()
        self._client: socket.socket | None = None
        self._client_lock = threading.Lock()
        self._thread = threading.Thread(target=self._serve, name=f"sim-ascii-table:{self.port}", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        """pyserial URL (``socket://127.0.0.1:PORT``)."""
        return f"socket://127.0.0.1:{self.port}"

    @property
    def watchdog_tripped(self) -> bool:
        return self._watchdog_latched

    # ---- command execution -------------------------------------------------------------------------------------
    @staticmethod
    def _axis(arg: str) -> int:
        try:
            a = int(arg)
        except ValueError:
            raise _CommandError(FaultCode.BAD_COMMAND, f"bad axis {arg!r} (1, 2 or 3)") from None
        if not 1 <= a <= 3:
            raise _CommandError(FaultCode.BAD_COMMAND, f"bad axis {a} (1, 2 or 3)")
        return a - 1

    @staticmethod
    def _axis_value(arg: str) -> tuple[int, float]:
        parts = arg.split(",")
        if len(parts) != 2:
            raise _CommandError(FaultCode.BAD_COMMAND, f"expected <axis>,<value>, got {arg!r}")
        a = AsciiTableServer._axis(parts[0].strip())
        try:
            v = float(parts[1])
        except ValueError:
            raise _CommandError(FaultCode.BAD_COMMAND, f"bad number {parts[1]!r}") from None
        if not math.isfinite(v):
            raise _CommandError(FaultCode.BAD_COMMAND, f"non-finite value {parts[1]!r}")
        return a, v

    def _state_fault(self, s: Any) -> tuple[int, FaultCode]:
        status = int(s.status)
        fault = FaultCode(s.fault_code)
        if self._watchdog_latched:
            status |= int(TableStatus.WATCHDOG | TableStatus.FAULT)
            fault = fault or FaultCode.COMMUNICATION_LOST
        return status, fault

    def _fault_now(self) -> FaultCode:
        return self._state_fault(self.world.table_state())[1]

    def _motion_allowed(self) -> None:
        if self._watchdog_latched:
            raise _CommandError(FaultCode.COMMUNICATION_LOST, "watchdog tripped; :fault:reset first")

    def _one(self, cmd: str, pending: dict[str, Any]) -> str | None:
        head, _, arg = cmd.partition(" ")
        head = head.lower()
        arg = arg.strip()
        w = self.world
        if head == ":mode:pos":
            self._mode_demand[self._axis(arg)] = AxisMode.POSITION
            return None
        if head == ":mode:rate":
            self._mode_demand[self._axis(arg)] = AxisMode.RATE
            return None
        if head == ":dem:pos":
            a, v = self._axis_value(arg)
            if self._mode_demand[a] != AxisMode.POSITION:
                raise _CommandError(FaultCode.BAD_COMMAND, f"axis {a + 1} not in position mode (:mode:pos {a + 1})")
            if pending.get("pos") is None:
                pending["pos"] = [None, None, None]
            pending["pos"][a] = v * DEG
            return None
        if head == ":dem:rate":
            a, v = self._axis_value(arg)
            if self._mode_demand[a] != AxisMode.RATE:
                raise _CommandError(FaultCode.BAD_COMMAND, f"axis {a + 1} not in rate mode (:mode:rate {a + 1})")
            self._motion_allowed()
            try:
                ax, r = check_rate(a, v * DEG, self._limits)  # type: ignore[arg-type]
                w.command_rate(ax, r)
            except TableError as exc:
                raise _CommandError(self._fault_now() or FaultCode.RATE_LIMIT, str(exc)) from None
            self._motion_commanded = True
            return None
        if head == ":stop":
            w.command_stop()
            self._motion_commanded = False
            self._pos_demand = None
            return None
        if head == ":hb":
            self._last_hb = time.monotonic()
            w.heartbeat()
            return None
        if head == ":fault:reset":
            w.clear_fault()
            self._watchdog_latched = False
            return None
        if head == "*stb?":
            return str(self._state_fault(w.table_state())[0])
        if head in (":pos?", ":rate?"):
            a = self._axis(arg)
            s = w.table_state()
            return fmt((s.angles if head == ":pos?" else s.rates)[a] / DEG)
        if head == ":fault?":
            f = self._state_fault(w.table_state())[1]
            return f"{int(f)},{f.name}"
        if head in (":limit:abs?", ":limit:absolute?"):
            lim = self._limits[self._axis(arg)]
            lo = "none" if lim.position_min is None else fmt(lim.position_min / DEG)
            hi = "none" if lim.position_max is None else fmt(lim.position_max / DEG)
            return f"{fmt(lim.rate_max / DEG)},{fmt(lim.accel_max / DEG)},{lo},{hi}"
        if head == ":state?":
            s = w.table_state()
            status, fault = self._state_fault(s)
            vals = [s.time, *(x / DEG for x in s.angles), *(x / DEG for x in s.rates)]
            return ",".join([*(fmt(v) for v in vals), str(status), str(int(fault)), *(str(int(m)) for m in s.modes)])
        raise _CommandError(FaultCode.BAD_COMMAND, f"unknown command {cmd!r}")

    def execute_line(self, line: str) -> str:
        """Execute one command line (possibly ``;``-separated) and return the reply line (no CR-LF)."""
        replies: list[str] = []
        pending: dict[str, Any] = {}
        try:
            for cmd in (c.strip() for c in line.split(";")):
                if cmd:
                    r = self._one(cmd, pending)
                    if r is not None:
                        replies.append(r)
            if pending.get("pos") is not None:
                self._motion_allowed()
                if None in pending["pos"]:  # axes without a demand in this batch keep theirs (or stay put)
                    base = self._pos_demand or [float(x) for x in self.world.table_state().angles]
                    pending["pos"] = [b if p is None else p for p, b in zip(pending["pos"], base, strict=True)]
                try:
                    angles = check_position(pending["pos"], self._limits)  # type: ignore[arg-type]
                    self.world.command_position(angles)
                except TableError as exc:
                    raise _CommandError(self._fault_now() or FaultCode.POSITION_LIMIT, str(exc)) from None
                self._pos_demand = [float(x) for x in angles]
                self._motion_commanded = True
        except _CommandError as exc:
            return f"ERR {int(exc.code)} {exc}"
        except Exception as exc:  # never kill the server on a bug
            log.exception("simulated ASCII controller: internal error on %r", line)
            return f"ERR {int(FaultCode.AMPLIFIER)} internal error {exc.__class__.__name__}"
        return ";".join(replies) if replies else "OK"

    # ---- serving -------------------------------------------------------------------------------------------------
    def _check_watchdog(self) -> None:
        if self.watchdog_s is None or self._last_hb is None or self._watchdog_latched or not self._motion_commanded:
            return
        if time.monotonic() - self._last_hb > self.watchdog_s:
            log.warning("simulated ASCII controller: no heartbeat for %.3g s; stopping the table", self.watchdog_s)
            self.world.command_stop()
            try:
                self.world.inject_fault(FaultCode.COMMUNICATION_LOST)
            except Exception:
                log.debug("inject_fault not supported", exc_info=True)
            self._watchdog_latched = True
            self._motion_commanded = False

    name = "simulated ASCII controller"

    def _on_idle(self) -> None:
        self._check_watchdog()

    def _on_client_gone(self) -> None:
        if self._motion_commanded and not self._stop.is_set():
            log.warning("simulated ASCII controller: client disconnected during motion; stopping the table")
            self.world.command_stop()
            self._motion_commanded = False

    def _handle(self, conn: socket.socket) -> None:
        buf = b""
        while not self._stop.is_set():
            self._check_watchdog()
            r, _, _ = select.select([conn], [], [], 0.05)
            if not r:
                continue
            chunk = conn.recv(4096)
            if not chunk:
                return
            buf += chunk
            while b"\n" in buf:
                line, buf = buf.split(b"\n", 1)
                text = line.decode("ascii", "replace").strip()
                if text:
                    reply = self.execute_line(text).replace("°", " deg").replace("²", "^2")
                    conn.sendall(reply.encode("ascii", "replace") + b"\r\n")
