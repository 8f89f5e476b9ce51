"""A simulated ACUTROL3000: the ACUTROL command language (ACL) executed against the one simulated world.

:class:`AclController` is the controller without a wire: :meth:`AclController.handle` takes one program
message and returns the reply lines it would send. :class:`~drivers.sim.acl_server.AclTableServer` serves it
on loopback TCP (reachable as a pyvisa-py ``TCPIP0::127.0.0.1::PORT::SOCKET`` resource) and
:meth:`AclController.transport` gives an in-memory :class:`~drivers.transport.MessageTransport` with the same
behaviour (the in-process simulated bench). It is written from ``docs/protocols/acutrol-acl.md`` and the
settings of :class:`~drivers.acutrol.settings.AclSettings`; it shares no code with the driver.

Parser (strict, as the real one): mnemonics in long, short or one-letter form (table :data:`TREE`), any
case; the first colon of a message optional; after a subsystem command the parser stays in that subsystem
until a command starting with ``:``; ``*`` common commands do not move it. Header and arguments are separated
by white space, arguments by commas; ``ALL`` as the axis of commands (not queries); enumerated arguments by
unique prefix; numbers as integer, fixed or exponent form of at most 28 characters. A misspelt or unknown
mnemonic, a bad axis, a bad number or a demand outside the limits rejects the whole message (nothing in it
executes), sets ``*ESR?`` bit 2 and puts a message in the error queue, which sets ``*STB?`` bit 7 (EQ) until
read with ``:Status:MSG? QERROR``. Errors are never echoed as text.

Replies: all commands of a message act on one frame (one world reading, one motion update). Query answers
are joined by ``;`` in order; numbers are fixed point with ``settings.decimals`` digits; positions are
wrapped into [−FS/2, FS/2). Reply profile ``gpib``: only messages with queries are answered; ``tcp``: a
message without queries is answered by an empty line.

Motion: ``:Interlock:Close`` servoes an axis (in Off mode); ``:Mode:Position/Rate`` need a servoed axis;
position demands on a continuous axis take the shortest path (limited axes go to the demand); Off = rate
zero at the acceleration limit. A fault latched in the world (stall, limit, amplifier, …) opens every
interlock and sets ``*STB?`` bit 0 (SI) until ``:Interlock:Reset``, which clears the world's fault; the axes
stay unservoed until closed again. Working limits per mode: position mode cruises at ``slew_fraction ·
rate_max``, rate mode at ``rate_max``. There is no watchdog (ACL has none) and a client disconnect stops
nothing (the behaviour of the real controller is undocumented; the host must stop the axes itself).
"""

from __future__ import annotations

import collections
import functools
import logging
import math
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from analysis.units import DEG
from drivers.acutrol.settings import AclSettings
from drivers.protocols import FaultCode, LinkError, TableError, TableState

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld  # type only: the world imports scipy (tablebench --help)

log = logging.getLogger(__name__)

SIM_TIME_VARIABLE = 1
"""The system-variable number under which the simulated controller serves its time clock."""
IDN = "Acutronic R&D USA (simulated),Acutrol3000,SIM-0001,tablebench-sim-1"

# node: (short form, one-letter form or None, children)
TREE: dict[str, tuple[str, str | None, dict[str, tuple[str, str | None]]]] = {
    "DEMAND": ("DEM", "D", {"POSITION": ("POS", "P"), "RATE": ("RATE", "R"), "DELTAPOSITION": ("DELT", "D")}),
    "INTERLOCK": ("INT", "I", {"CLOSE": ("CLOS", "C"), "OPEN": ("OPEN", "O"), "RESET": ("RES", "R")}),
    "LIMIT": (
        "LIM",
        "L",
        {
            "RATE": ("RATE", "R"),
            "ACCELERATION": ("ACC", "A"),
            "HIGHPOSITION": ("HPOS", "H"),
            "LOWPOSITION": ("LPOS", "L"),
            "ABSOLUTE": ("ABS", None),
        },
    ),
    "MODE": (
        "MODE",
        "M",
        {"POSITION": ("POS", "P"), "RATE": ("RATE", "R"), "OFF": ("OFF", "O"), "SYNTHESIS": ("SYNT", "S")},
    ),
    "READ": (
        "READ",
        "R",
        {"POSITION": ("POS", "P"), "RATE": ("RATE", "R"), "ACCELERATION": ("ACC", "A"), "VARIABLE": ("VAR", None)},
    ),
    "STATUS": ("STAT", None, {"STB": ("STB", None), "MSG": ("MSG", None), "MSGCLR": ("MSGCLR", None)}),
}
MODES = ("POSITION", "RATE", "ARATE", "SYNTHESIS", "TRACK", "ABORT", "OFF")
QUEUES = ("QERROR", "QFAULT", "QCMMD", "QDATA", "QALL")
COMMON = {"*IDN?", "*STB?", "*ESR?", "*CLS"}
NOT_IMPLEMENTED = {"*OPC", "*OPC?", "*RST", "*TST?", "*WAI"}
_HEADER = re.compile(r"^:?[A-Za-z]+(:[A-Za-z]+)*\??$")
_NRF = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)(\s*[eE]\s*[+-]?\s*\d+)?$")
_NR1 = re.compile(r"^\d+$")
_WORDS = {"POSITION": "Position", "RATE": "Rate", "OFF": "Off", "SYNTHESIS": "Synthesis"}

STB_SI, STB_ESB, STB_MSS, STB_EQ = 1, 1 << 5, 1 << 6, 1 << 7
_UNCOMPILED: list = []  # marker: a message not looked at yet


class AclError(Exception):
    """A message the controller rejects (goes to the error queue)."""


@dataclass
class Command:
    """One parsed command: canonical path (e.g. ("MODE", "POSITION")), query flag, raw arguments."""

    path: tuple[str, ...]
    query: bool
    args: list[str] = field(default_factory=list)
    text: str = ""


def _resolve(node: dict, mnemonic: str) -> str | None:
    m = mnemonic.upper()
    for name, spec in node.items():
        short, letter = spec[0], spec[1]
        if m in (name, short) or (letter is not None and m == letter):
            return name
    return None


def parse_message(message: str) -> list[Command]:
    """Parse one program message into commands (AclError on the first error)."""
    return list(_parse_cached(message))


@functools.lru_cache(maxsize=256)
def _parse_cached(message: str) -> tuple[Command, ...]:
    """The parse of a message (a host repeats the same reading message every block: parsed once)."""
    return tuple(_parse(message))


def _parse(message: str) -> list[Command]:
    text = message.strip()
    if not text:
        raise AclError("empty message")
    out: list[Command] = []
    current: tuple[str, ...] = ()
    for i, raw in enumerate(text.split(";")):
        cmd = raw.strip()
        if not cmd:
            raise AclError(f"empty command in {message!r}")
        head, _, rest = cmd.partition(" ") if " " in cmd else (cmd, "", "")
        head, rest = head.strip(), rest.strip()
        if "\t" in head:
            head, _, more = head.partition("\t")
            rest = (more + " " + rest).strip()
        if head.startswith("*"):
            h = head.upper()
            if h in NOT_IMPLEMENTED:
                raise AclError(f"{head} is not implemented on the controller")
            if h not in COMMON:
                raise AclError(f"undefined common command {head!r}")
            if rest:
                raise AclError(f"{head} takes no argument")
            out.append(Command((h,), h.endswith("?"), [], cmd))
            continue
        if not _HEADER.match(head):
            raise AclError(f"bad header {head!r} in {cmd!r} (mnemonics separated by ':', arguments after a space)")
        query = head.endswith("?")
        names = head.rstrip("?")
        from_root = names.startswith(":") or i == 0
        parts = names.lstrip(":").split(":")
        path = () if from_root else current
        for mn in parts:
            children = _children(path)
            if children is None:
                raise AclError(f"{head!r}: {':'.join(path)} has no sub-commands")
            name = _resolve(children, mn)
            if name is None:
                raise AclError(f"undefined header {mn!r} in {cmd!r}")
            path = path + (name,)
        current = path[:-1]
        args = [a.strip() for a in rest.split(",")] if rest else []
        if any(a == "" for a in args):
            raise AclError(f"empty argument in {cmd!r}")
        if path[0] == "READ":
            query = True  # Act2000 compatibility: the '?' is optional on :Read
        out.append(Command(path, query, args, cmd))
    return out


_ROOT = {k: (v[0], v[1]) for k, v in TREE.items()}


def _children(path: tuple[str, ...]) -> dict | None:
    if not path:
        return _ROOT
    if len(path) == 1:
        return TREE[path[0]][2]
    return None


def _mode_arg(text: str) -> str:
    u = text.upper()
    hits = [m for m in MODES if m.startswith(u)] if u else []
    if len(hits) != 1:
        raise AclError(f"mode {text!r} is {'ambiguous' if hits else 'unknown'} (one of {', '.join(MODES)})")
    return hits[0]


def _number(text: str) -> float:
    if len(text) > 28 or not _NRF.match(text):
        raise AclError(f"bad number {text!r}")
    return float(re.sub(r"\s+", "", text))


class AclController:
    """The simulated ACUTROL3000 on a SimulatedWorld (thread-safe; see the module docstring).

    Parameters
    ----------
    world : SimulatedWorld
    settings : AclSettings
        How this unit answers (reply profile, mode reply, precision, axis numbers, full scale, time variable).
    """

    def __init__(self, world: SimulatedWorld, settings: AclSettings | None = None) -> None:
        self.world = world
        self.settings = settings or AclSettings()
        self._lock = threading.RLock()
        self._gimbal = {int(a): i for i, a in enumerate(self.settings.axes)}
        self._limits = tuple(world.table_limits())
        self._fs = float(self.settings.full_scale_deg)
        self._time_var = self.settings.time_variable if self.settings.time_variable is not None else SIM_TIME_VARIABLE
        self.servoed = [False, False, False]
        self.mode = ["OFF", "OFF", "OFF"]
        self.pos_demand = [0.0, 0.0, 0.0]  # deg, as demanded (wrapped range)
        self.rate_demand = [0.0, 0.0, 0.0]  # deg/s
        self.fault: str = ""  # latched interlock fault description ("" none)
        self.errors: collections.deque[str] = collections.deque(maxlen=64)
        self.esr = 0
        self.messages = 0
        self._spec = f".{int(self.settings.decimals)}f"
        self._readers: dict[str, list[Callable[[TableState], str]] | None] = {}

    # ---- transport for the in-process bench -------------------------------------------------------------------
    def transport(self, timeout: float = 2.0) -> InMemoryTransport:
        """An in-memory MessageTransport to this controller (same replies as over TCP)."""
        return InMemoryTransport(self, timeout)

    # ---- helpers ---------------------------------------------------------------------------------------------
    def _fmt(self, x: float) -> str:
        s = format(x, self._spec)
        if s[0] == "-" and float(s) == 0.0:
            s = s[1:]
        return s

    def _wrap(self, deg: float) -> float:
        return deg - self._fs * math.floor((deg + self._fs / 2.0) / self._fs)

    def _axes(self, text: str, allow_all: bool) -> list[int]:
        if text.upper() == "ALL":
            if not allow_all:
                raise AclError("ALL is not allowed as the axis of a query")
            return [0, 1, 2]
        if not _NR1.match(text) or int(text) not in self._gimbal:
            raise AclError(f"parameter out of range: axis {text!r} (axes {', '.join(map(str, self.settings.axes))})")
        return [self._gimbal[int(text)]]

    def _nargs(self, c: Command, n: int) -> None:
        if len(c.args) != n:
            raise AclError(f"{c.text!r}: expected {n} argument(s), got {len(c.args)}")

    def _continuous(self, i: int) -> bool:
        lim = self._limits[i]
        return lim.position_min is None and lim.position_max is None

    def _sync_fault(self, state: TableState) -> None:
        code = FaultCode(state.fault_code)
        if code != FaultCode.NONE and not self.fault:
            self.fault = code.name
            self.servoed = [False, False, False]
            self.mode = ["OFF", "OFF", "OFF"]
            log.info("simulated ACUTROL: interlock fault %s; all axes opened", code.name)

    def status_byte(self) -> int:
        """The status byte (SI, ESB, MSS, EQ)."""
        stb = 0
        if self.fault:
            stb |= STB_SI
        if self.esr:
            stb |= STB_ESB
        if self.errors:
            stb |= STB_EQ
        if stb:
            stb |= STB_MSS
        return stb

    # ---- message handling ------------------------------------------------------------------------------------
    def handle(self, message: str) -> list[str]:
        """Execute one program message; return the reply lines (without terminators) to send."""
        with self._lock:
            self.messages += 1
            readers = self._readers.get(message, _UNCOMPILED)
            if readers is _UNCOMPILED:
                if len(self._readers) >= 256:  # commands carry numbers: do not keep every message ever sent
                    self._readers.clear()
                readers = self._readers[message] = self._compile_reading(message)
            if readers is not None:  # a valid message of readings only: one frame, no state changed
                state = self.world.table_state()
                self._sync_fault(state)
                return [";".join([read(state) for read in readers])]
            try:
                cmds = parse_message(message)
            except AclError as exc:
                return self._reject(message, str(exc), queries=True)
            has_query = any(c.query for c in cmds)
            try:
                replies = self._execute(cmds)
            except AclError as exc:
                return self._reject(message, str(exc), queries=has_query)
            if has_query:
                return [";".join(replies)]
            return [""] if self.settings.reply_profile == "tcp" else []

    def _compile_reading(self, message: str) -> list[Callable[[TableState], str]] | None:
        """The answer of a message made only of table readings (positions, rates, modes, status byte, the time
        variable) as one function per query, checked once: the host sends the same reading message every
        block, and its replies are those :meth:`_execute` gives (same formatting, same frame). None: any other
        message (or one the controller rejects), executed by :meth:`_execute`."""
        try:
            cmds = parse_message(message)
        except AclError:
            return None
        readers: list[Callable[[TableState], str]] = []
        d = self._fmt
        for c in cmds:
            p, a = c.path, c.args
            try:
                if p in (("READ", "POSITION"), ("READ", "RATE"), ("MODE",)):
                    self._nargs(c, 1)
                    (i,) = self._axes(a[0], False)
                    if p[1:] == ("POSITION",):
                        readers.append(lambda s, i=i: d(self._wrap(float(s.angles[i]) / DEG)))
                    elif p[1:] == ("RATE",):
                        readers.append(lambda s, i=i: d(float(s.rates[i]) / DEG))
                    elif self.settings.mode_reply == "letter":
                        readers.append(lambda s, i=i: self.mode[i][0])
                    else:
                        readers.append(lambda s, i=i: _WORDS[self.mode[i]])
                elif p == ("READ", "VARIABLE"):
                    self._nargs(c, 1)
                    if not _NR1.match(a[0]) or int(a[0]) != self._time_var:
                        return None
                    readers.append(lambda s: d(float(s.time) / self.settings.time_scale_s))
                elif p == ("STATUS", "STB") and not a:
                    readers.append(lambda s: str(self.status_byte()))
                else:
                    return None
            except AclError:
                return None
        return readers

    def _reject(self, message: str, reason: str, queries: bool) -> list[str]:
        self.errors.append(f'-100,"{reason}"')
        self.esr |= 1 << 2
        log.info("simulated ACUTROL rejected %r: %s", message, reason)
        # nothing executed; a TCP client still gets its line so it does not hang
        return [""] if self.settings.reply_profile == "tcp" else []

    def _execute(self, cmds: list[Command]) -> list[str]:
        w = self.world
        state = w.table_state()  # one frame for every reading in this message
        self._sync_fault(state)
        servoed, mode = list(self.servoed), list(self.mode)
        pos, rate = list(self.pos_demand), list(self.rate_demand)
        fault, reset, clear_errors = self.fault, False, False
        changed: set[int] = set()
        replies: list[str] = []
        for c in cmds:
            p, a = c.path, c.args
            if p[0].startswith("*"):
                if p[0] == "*IDN?":
                    replies.append(IDN)
                elif p[0] == "*STB?":
                    replies.append(str(self.status_byte()))
                    self.esr = 0  # reading *STB? clears the event bits
                elif p[0] == "*ESR?":
                    replies.append(str(self.esr))
                    self.esr = 0
                else:  # *CLS
                    clear_errors = True
                continue
            if c.query:
                replies.append(self._query(c, state, mode))
                continue
            if p == ("DEMAND", "POSITION") or p == ("DEMAND", "DELTAPOSITION"):
                self._nargs(c, 2)
                v = _number(a[1])
                for i in self._axes(a[0], True):
                    nv = pos[i] + v if p[1] == "DELTAPOSITION" else v
                    if not -self._fs / 2 <= nv <= self._fs / 2:
                        raise AclError(f"parameter out of range: position {nv:g} outside ±{self._fs / 2:g}")
                    lim = self._limits[i]
                    if not self._continuous(i) and not lim.allows_position(nv * DEG):
                        raise AclError(f"parameter out of range: position {nv:g}° beyond the limits of axis {a[0]}")
                    pos[i] = nv
                    changed.add(i)
            elif p == ("DEMAND", "RATE"):
                self._nargs(c, 2)
                v = _number(a[1])
                for i in self._axes(a[0], True):
                    if not self._limits[i].allows_rate(v * DEG):
                        raise AclError(f"parameter out of range: rate {v:g} °/s beyond the rate limit of axis {a[0]}")
                    rate[i] = v
                    changed.add(i)
            elif p[0] == "MODE":
                if len(p) == 1:
                    self._nargs(c, 2)
                    m, axes = _mode_arg(a[1]), self._axes(a[0], True)
                else:
                    self._nargs(c, 1)
                    m, axes = p[1], self._axes(a[0], True)
                if m not in ("POSITION", "RATE", "OFF"):
                    raise AclError(f"{m.title()} mode is not available on the simulated controller")
                for i in axes:
                    if m != "OFF" and not servoed[i]:
                        raise AclError(f"axis {self.settings.axes[i]} is not servoed (:Interlock:Close it first)")
                    mode[i] = m
                    changed.add(i)
            elif p == ("INTERLOCK", "RESET"):
                self._nargs(c, 0)
                reset, fault = True, ""
            elif p == ("INTERLOCK", "CLOSE"):
                self._nargs(c, 1)
                for i in self._axes(a[0], True):
                    if fault:
                        raise AclError(f"interlock fault {fault} latched: :Interlock:Reset first")
                    if not servoed[i]:
                        servoed[i], mode[i] = True, "OFF"
                        changed.add(i)
            elif p == ("INTERLOCK", "OPEN"):
                self._nargs(c, 1)
                for i in self._axes(a[0], True):
                    servoed[i], mode[i] = False, "OFF"
                    changed.add(i)
            elif p == ("STATUS", "MSGCLR"):
                self._nargs(c, 1)
                clear_errors = True
            else:
                raise AclError(f"{c.text!r} is not a command (a query needs '?')")
        # the frame is valid: apply it
        if reset and self.fault:
            w.clear_fault()
        self.fault = fault
        self.servoed, self.pos_demand, self.rate_demand = servoed, pos, rate
        old_mode, self.mode = self.mode, mode
        if clear_errors:
            self.errors.clear()
            self.esr = 0
        self._apply(changed, old_mode, state)
        return replies

    def _apply(self, changed: set[int], old_mode: list[str], state: TableState) -> None:
        w = self.world
        if not changed:
            return
        if all(m == "OFF" for m in self.mode):
            if any(old_mode[i] != "OFF" or abs(float(state.rates[i])) > 0 for i in changed):
                w.command_stop()
            return
        try:
            for i in sorted(changed):
                m = self.mode[i]
                if m == "POSITION":
                    target = self.pos_demand[i] * DEG
                    if self._continuous(i):
                        cur = float(state.angles[i])
                        target = cur + self._wrap((target - cur) / DEG) * DEG  # shortest path [§4.7.4]
                    w.command_axis_position(i, target)
                elif m == "RATE":
                    w.command_rate(i, self.rate_demand[i] * DEG)
                elif old_mode[i] != "OFF" or abs(float(state.rates[i])) > 0:
                    w.command_rate(i, 0.0)
        except TableError as exc:  # e.g. a fault latched in the world at this very sample
            self.errors.append(f'-200,"execution error: {exc}"')
            self.esr |= 1 << 4

    def _query(self, c: Command, state: TableState, mode: list[str]) -> str:
        p, a = c.path, c.args
        d = self._fmt
        if p[0] == "READ":
            if p == ("READ",):
                raise AclError(f"{c.text!r}: :Read needs a sub-command")
            if p[1] == "VARIABLE":
                self._nargs(c, 1)
                if not _NR1.match(a[0]) or int(a[0]) != self._time_var:
                    raise AclError(f"parameter out of range: variable {a[0]!r}")
                return d(float(state.time) / self.settings.time_scale_s)
            self._nargs(c, 1)
            (i,) = self._axes(a[0], False)
            if p[1] == "POSITION":
                return d(self._wrap(float(state.angles[i]) / DEG))
            if p[1] == "RATE":
                return d(float(state.rates[i]) / DEG)
            return d(float(self.world.table_acceleration()[i]) / DEG)
        if p == ("MODE",):
            self._nargs(c, 1)
            (i,) = self._axes(a[0], False)
            m = mode[i]
            return m[0] if self.settings.mode_reply == "letter" else _WORDS[m]
        if p == ("INTERLOCK",):
            self._nargs(c, 1)
            (i,) = self._axes(a[0], False)
            return "Fault" if self.fault else ("Closed" if self.servoed[i] else "Open")
        if p[0] == "LIMIT" and len(p) == 2:
            return self._limit(c)
        if p == ("STATUS", "STB"):
            self._nargs(c, 0)
            return str(self.status_byte())
        if p == ("STATUS", "MSG"):
            if not 1 <= len(a) <= 2 or a[0].upper() not in QUEUES:
                raise AclError(f"{c.text!r}: :Status:MSG? <qid>[,<n>|ALL] with qid one of {', '.join(QUEUES)}")
            n = len(self.errors) if len(a) == 2 and a[1].upper() == "ALL" else int(a[1]) if len(a) == 2 else 1
            if a[0].upper() not in ("QERROR", "QALL"):
                return ""
            out = [self.errors.popleft() for _ in range(min(n, len(self.errors)))]
            return ",".join(out)
        if p[0] == "DEMAND" and len(p) == 2:
            self._nargs(c, 1)
            (i,) = self._axes(a[0], False)
            return d(self.pos_demand[i] if p[1] == "POSITION" else self.rate_demand[i] if p[1] == "RATE" else 0.0)
        raise AclError(f"{c.text!r} is not a query")

    def _limit(self, c: Command) -> str:
        p, a, d = c.path, c.args, self._fmt
        if p[1] == "ABSOLUTE":
            self._nargs(c, 1)
            (i,) = self._axes(a[0], False)
            lim = self._limits[i]
            lo, hi = self._pos_range(i)
            return ",".join(
                [d(lim.rate_max / DEG), d(lim.accel_max / DEG), d(0.0), d(lo), d(hi), d(1.1 * lim.rate_max / DEG)]
            )
        self._nargs(c, 2)
        m = _mode_arg(a[0])
        (i,) = self._axes(a[1], False)
        lim = self._limits[i]
        if p[1] == "RATE":
            factor = {"POSITION": self.world.cfg.table.slew_fraction, "RATE": 1.0, "ARATE": 1.0}.get(m, 0.0)
            return d(factor * lim.rate_max / DEG)
        if p[1] == "ACCELERATION":
            return d(lim.accel_max / DEG)
        lo, hi = self._pos_range(i)
        return d(hi if p[1] == "HIGHPOSITION" else lo)

    def _pos_range(self, i: int) -> tuple[float, float]:
        lim = self._limits[i]
        if self._continuous(i):
            return -self._fs / 2, self._fs / 2
        assert lim.position_min is not None and lim.position_max is not None
        return lim.position_min / DEG, lim.position_max / DEG


class InMemoryTransport:
    """:class:`~drivers.transport.MessageTransport` straight into an :class:`AclController` (no bytes, no thread)."""

    def __init__(self, controller: AclController, timeout: float = 2.0) -> None:
        self.controller = controller
        self.timeout = float(timeout)
        self._replies: collections.deque[str] = collections.deque()
        self.closed = False

    def write(self, message: str) -> None:
        """Deliver one message; its replies wait for :meth:`read`."""
        if self.closed:
            raise LinkError("simulated ACUTROL link is closed")
        self._replies.extend(self.controller.handle(message))

    def read(self) -> str:
        """The next reply line (LinkError at once if the controller sent none: a real link would time out)."""
        if self.closed:
            raise LinkError("simulated ACUTROL link is closed")
        if not self._replies:
            raise LinkError(f"simulated ACUTROL: no reply within {self.timeout:.3g} s")
        return self._replies.popleft()

    def query(self, message: str) -> str:
        """Write then read."""
        self.write(message)
        return self.read()

    def close(self) -> None:
        """Close the link."""
        self.closed = True


__all__ = [
    "AclController",
    "AclError",
    "Command",
    "IDN",
    "InMemoryTransport",
    "SIM_TIME_VARIABLE",
    "TREE",
    "parse_message",
]
