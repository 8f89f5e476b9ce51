"""Turntable driver for an ACUTROL3000 controller speaking the ACUTROL command language (ACL).

Facts from docs/protocols/acutrol-acl.md (TM-8004 sections in brackets); the open points are
:class:`~drivers.acutrol.settings.AclSettings`. The driver receives an open
:class:`~drivers.transport.MessageTransport` (pyvisa-py TCPIP SOCKET / GPIB / ASRL, or the simulator's
in-memory link) and never opens it. Angles are degrees and °/s on the wire, rad and rad/s in the API
(:data:`analysis.units.DEG`); the outer/middle/inner gimbals are the controller axes ``settings.axes``.

Messages the driver sends (``a1 a2 a3`` = controller axes of outer, middle, inner)::

    session start (first contact)     :Status:STB?  (a latched fault refuses motion; old errors are drained)
    enable (before the first motion)  *CLS;:Mode:Off a1;Off a2;Off a3;
                                      :Interlock:Close a1;Close a2;Close a3                     [§4.5.1]
    reset a latched fault (operator)  :Interlock:Reset, then enable                             [§4.5.6]
    move (one frame, synchronous)     :Demand:Position a1,X;Position a2,Y;Position a3,Z;
                                      :Mode:Position a1;Position a2;Position a3                 [§4.3.5, §4.7.4]
    spin                              :Demand:Rate a,R;:Mode:Rate a                             [§4.3.6, §4.7.5]
    stop                              :Mode:Off a1;Off a2;Off a3   (controlled stop, no :stop)  [§4.7.3]
    read (one frame)                  :Read:Position? a1;Position? a2;Position? a3;Rate? a1;Rate? a2;Rate? a3;
                                      :Mode? a1;:Mode? a2;:Mode? a3;:Status:STB?[;:Read:Variable? N]
    after every command               :Status:STB?  (does not clear; *STB? would)               [§4.11.6]
    error queue not empty (bit 7)     :Status:MSG? <error_queue>;:Status:STB?  until bit 7 clears [§4.11.4]
    interlock state (bit 0; status)   :Interlock? a1;:Interlock? a2;:Interlock? a3  (reported verbatim)
    end of session (bench setting)    :Interlock:Open a1;Open a2;Open a3                        [§4.5.5]

Reply profiles: ``gpib`` — plain commands get no reply; ``tcp`` — plain commands are answered by an empty
line, which the driver reads (a non-empty answer, or none, is a LinkError naming the setting and where the bench
file sets it). Queries are answered by one line, fields separated by ``;``. Errors are detected the ACL way
(status byte, error queue) and raised as :class:`TableError` with what the controller reported — never by
expecting an ``ERR`` text. The whole error queue is drained after every message, so each error is reported
with the message that caused it (three errors are reported as three); errors left from before the session are
drained at its start and kept in :attr:`AclTurntable.stale_errors`, never blamed on a command. A query without
an answer is told apart: if the controller still answers ``:Status:STB?`` and its error queue says why, the
query was **refused** (:class:`TableError` with the controller's errors); if it answers but reports nothing,
the reply framing is wrong (LinkError naming the reply-profile setting); if it does not answer, the **link is
dead** (LinkError: cable, power, resource).

A latched interlock fault (status bit 0) is never reset silently: motion is refused until an operator
acknowledges it (:meth:`AclTurntable.clear_fault`, ``tablebench table reset-fault``, which reports what the
fault was). The interlock state reported by :meth:`read_state` before this session closed them is read from
the controller (``:Interlock?``), not assumed.

Positions wrap at ±full_scale/2; the driver unwraps them (turn count from the previous reading and the
rates, so a spin read every block is never mis-counted). A continuous axis in position mode takes the
shortest path to its demand [§4.7.4]; a move that is more than 150° away on a continuous axis is therefore
driven through way-points (≤ 110° apart, the next one sent from :meth:`read_state` as the axis approaches
the current one), so ``move_to`` reaches the *unwrapped* angle it was given, as the Turntable protocol says.

"Settled" and "at rate" are decided here from the readings (the controller has no such bit): an axis in
position mode is settled once every reading for ``settle_time`` s has been within ``position_tolerance`` of
its target; a rate-mode axis is at rate once within ``rate_tolerance`` of its demand for ``settle_time`` s;
an Off axis is at rest once within ``rate_tolerance`` of zero for ``settle_time`` s. Times are the
controller's time clock when ``time_variable`` is set, else the host's monotonic clock. There is no host
heartbeat in ACL: :meth:`heartbeat` sends nothing, and the host stops the axes on every exit path
(:meth:`close` commands Off if motion was commanded, unless :meth:`leave_running` was called).
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.units import DEG
from drivers.acutrol.settings import AclSettings
from drivers.protocols import (
    AXIS_NAMES,
    STATUS_AT_RATE,
    STATUS_FAULT,
    STATUS_IN_POSITION,
    STATUS_INTERLOCK_OPEN,
    STATUS_MOVING,
    STATUS_REMOTE,
    AxisLimits,
    AxisMode,
    FaultCode,
    LinkError,
    TableError,
    TableState,
    TableStatus,
    check_angles,
    check_spin,
)

log = logging.getLogger(__name__)

STB_SI = 1 << 0  # system interlocks summary
STB_EQ = 1 << 7  # error queue not empty

SINGLE_MOVE_DEG = 150.0
"""A continuous axis further than this from its target is driven through way-points."""
WAYPOINT_STEP_DEG = 110.0
WAYPOINT_ADVANCE_DEG = 60.0
"""The next way-point is sent once the axis is within this of the current one (≤ 170° ahead of the axis)."""

_LETTER_MODES = {"P": AxisMode.POSITION, "R": AxisMode.RATE, "O": AxisMode.STOP}
_WORD_MODES = {"position": AxisMode.POSITION, "rate": AxisMode.RATE, "off": AxisMode.STOP, "arate": AxisMode.RATE}
_OTHER_LETTERS = set("ASTH")  # synthesis, track, abort, home: not a tablebench mode → reported as STOP
_OTHER_WORDS = {"synthesis", "track", "abort", "home"}
MAX_QUEUE = 32
"""Most error-queue entries read after one message (a controller that keeps reporting is named as such)."""
_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def format_number(x: float) -> str:
    """A demand as ACL program data: fixed point, at most 10 decimals, trailing zeros dropped (``45``, ``-12.5``)."""
    if not math.isfinite(x):
        raise TableError(f"cannot send a non-finite number ({x!r})")
    s = f"{x:.10f}".rstrip("0").rstrip(".")
    if s in ("-0", "", "-"):
        s = "0"
    if len(s) > 28:
        raise TableError(f"number {x!r} needs more than the 28 characters ACL accepts")
    return s


def wrap_deg(x: float, full_scale: float) -> float:
    """Angle (deg) wrapped into [−full_scale/2, full_scale/2)."""
    return x - full_scale * math.floor((x + full_scale / 2.0) / full_scale)


class AclTurntable:
    """Three-axis table on an ACUTROL3000 (ACL). Implements :class:`drivers.protocols.Turntable`.

    Parameters
    ----------
    transport : MessageTransport
        Open link (the caller owns it).
    limits : tuple of 3 AxisLimits
        The bench's limits (outer, middle, inner), SI; every demand is checked against them before sending.
    settings : AclSettings
        The controller's open points (reply profile, mode reply, precision, axis numbers, full scale, …).
    position_tolerance : float
        rad; settled window.
    settle_time : float
        s; readings must stay inside the window this long.
    rate_tolerance : float
        rad/s; at-rate and at-rest window.
    clock : callable
        Host clock (s): every reading's request and answer times (recorded raw), and its time stamp when the
        controller's time clock is not configured.
    """

    def __init__(
        self,
        transport: Any,
        limits: tuple[AxisLimits, AxisLimits, AxisLimits],
        *,
        settings: AclSettings | None = None,
        position_tolerance: float = 2.0 * math.pi / 180 / 3600,
        settle_time: float = 0.2,
        rate_tolerance: float = 0.01 * DEG,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.t = transport
        self.settings = settings or AclSettings()
        self._limits = tuple(limits)
        if len(self._limits) != 3:
            raise ValueError("limits must be 3 AxisLimits (outer, middle, inner)")
        half = self.settings.full_scale_deg / 2.0 * DEG
        for name, lim in zip(AXIS_NAMES, self._limits, strict=True):
            for p in (lim.position_min, lim.position_max):
                if p is not None and not -half - 1e-12 <= p <= half + 1e-12:
                    raise ValueError(
                        f"{name} axis position limit {math.degrees(p):.4f}° is outside the controller's "
                        f"full-scale range ±{self.settings.full_scale_deg / 2:g}°"
                    )
        self.tol = float(position_tolerance)
        self.settle_time = float(settle_time)
        self.rate_tol = float(rate_tolerance)
        self._clock = clock
        self._t0 = clock()
        self._ax = tuple(int(a) for a in self.settings.axes)
        self._fs = float(self.settings.full_scale_deg)
        self._closed = False
        self._enabled = False
        self._motion = False
        self._leave_running = False
        # reading state (degrees)
        self._raw: list[float] | None = None
        self._u: list[float] | None = None
        self._v: list[float] | None = None
        self._t_last: float | None = None
        # commanded state
        self._target: list[float | None] = [None, None, None]  # rad, unwrapped final target (position mode)
        self._waypoint: list[float | None] = [None, None, None]  # rad, current demand while way-pointing
        self._rate_cmd: list[float | None] = [None, None, None]  # rad/s
        self._since: list[float | None] = [None, None, None]
        self.fault_report = ""
        self.stale_errors: list[str] = []
        self._session_checked = False
        self._interlocks: list[str] | None = None  # ':Interlock?' replies while this session has not enabled
        self._read_msg = self._build_read_message()

    # ---- wire primitives ---------------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise LinkError("ACUTROL: driver is closed")

    def command(self, message: str) -> None:
        """Send a message without queries (tcp profile: read and check the empty acknowledgement line)."""
        self._check_open()
        self.t.write(message)
        if self.settings.reply_profile == "tcp":
            try:
                ack = self.t.read()
            except LinkError as exc:
                raise self._silent(message, exc, command=True) from exc
            if ack.strip():
                raise LinkError(f"ACUTROL: expected an empty line after {message!r}, got {ack[:60]!r}; {self._hint}")

    @property
    def _hint(self) -> str:
        return self.settings.profile_hint

    def query(self, message: str, fields: int | None = None) -> list[str]:
        """Send a message with queries; return the reply's ``;``-separated fields.

        A missing answer is told apart (see the module docstring): refused (TableError with the controller's
        errors), wrong reply framing or a dead link (LinkError).
        """
        self._check_open()
        self.t.write(message)
        try:
            reply = self.t.read()
            if self.settings.reply_profile == "tcp":
                while not reply.strip():  # a late empty acknowledgement never hides the data line
                    reply = self.t.read()
        except LinkError as exc:
            raise self._silent(message, exc) from exc
        if not reply.strip() and self.settings.reply_profile == "gpib":
            raise LinkError(f"ACUTROL: an empty line answered {message!r}; {self._hint}")
        parts = [p.strip() for p in reply.strip().split(";")]
        if fields is not None and len(parts) != fields:
            raise LinkError(
                f"ACUTROL: reply to {message!r} should have {fields} field(s) separated by ';', got {reply[:120]!r}"
            )
        return parts

    def _raw_stb(self) -> int:
        """``:Status:STB?`` without the diagnosis of :meth:`query` (LinkError if unanswered)."""
        self.t.write(":Status:STB?")
        reply = self.t.read()
        while not reply.strip() and self.settings.reply_profile == "tcp":
            reply = self.t.read()
        f = reply.strip()
        if not f.isdigit():
            raise LinkError(f"ACUTROL: status byte should be an integer 0-255, got {f!r}")
        return int(f)

    def _silent(self, message: str, exc: LinkError, command: bool = False) -> Exception:
        """Why ``message`` got no answer: refused (its errors), wrong framing, or a dead link."""
        try:
            stb = self._raw_stb()
        except LinkError as probe:
            return LinkError(
                f"ACUTROL: no answer to {message!r}, nor to a status query: the link is dead (check the cable, "
                f"the controller's power and turntable.resource): {exc}; {probe}"
            )
        if stb & STB_EQ:
            errors = self._drain_errors()
            return TableError(f"ACUTROL refused {message!r}: {self._errors_text(errors)} (status byte {stb})")
        what = "acknowledge the command" if command else "answer the query"
        return LinkError(
            f"ACUTROL: the controller answers status queries (status byte {stb}, no error) but did not {what} "
            f"{message!r}; {self._hint}"
        )

    @staticmethod
    def _number(text: str, what: str) -> float:
        if not _NUMBER.match(text):
            raise LinkError(f"ACUTROL: {what}: expected a number, got {text!r}")
        return float(text)

    def _status_byte(self) -> int:
        f = self.query(":Status:STB?", 1)[0]
        if not f.isdigit():
            raise LinkError(f"ACUTROL: status byte should be an integer 0-255, got {f!r}")
        return int(f)

    def _drain_errors(self) -> list[str]:
        """Read the whole error queue: one entry and the status byte per message, until bit 7 (EQ) clears."""
        errors: list[str] = []
        q = f":Status:MSG? {self.settings.error_queue};:Status:STB?"
        for _ in range(MAX_QUEUE):
            f = self.query(q)
            stb_text = f[-1] if len(f) >= 2 else ""
            if not stb_text.isdigit():
                raise LinkError(f"ACUTROL: reply to {q!r} should end with the status byte, got {';'.join(f)!r}")
            text = ";".join(f[:-1])
            if text:
                errors.append(text)
            if not int(stb_text) & STB_EQ:
                return errors
        errors.append(f"(more than {MAX_QUEUE} entries: the controller keeps reporting errors)")
        return errors

    @staticmethod
    def _errors_text(errors: list[str]) -> str:
        if not errors:
            return "(the error queue was empty)"
        if len(errors) == 1:
            return errors[0]
        return f"{len(errors)} errors: " + "; ".join(f"[{i}] {e}" for i, e in enumerate(errors, 1))

    def _interlock_fields(self) -> list[str]:
        q = ";".join(f":Interlock? {a}" for a in self._ax)
        return self.query(q, 3)

    def _interlock_text(self, fields: list[str] | None = None) -> str:
        fields = fields if fields is not None else self._interlock_fields()
        return ", ".join(
            f"{name} ':Interlock? {a}' → {f!r}" for name, a, f in zip(AXIS_NAMES, self._ax, fields, strict=False)
        )

    def check_errors(self, what: str, *, interlock_ok: bool = False) -> int:
        """Read the status byte after ``what``; TableError with the controller's report if it flags an error
        (the whole error queue, attributed to ``what``) or a latched interlock fault."""
        stb = self._status_byte()
        errors = self._drain_errors() if stb & STB_EQ else []
        if stb & STB_SI and not interlock_ok:
            refused = f"; it refused {what}: {self._errors_text(errors)}" if errors else ""
            self.fault_report = f"interlock fault latched (status byte {stb}; {self._interlock_text()})"
            raise TableError(
                f"ACUTROL: {self.fault_report}{refused}; nothing moves until an operator acknowledges it: "
                "tablebench table reset-fault"
            )
        if errors:
            raise TableError(f"ACUTROL refused {what}: {self._errors_text(errors)} (status byte {stb})")
        return stb

    def _refuse_if_latched(self) -> None:
        if self.fault_report:
            raise TableError(
                f"ACUTROL: {self.fault_report}; nothing was sent: an operator acknowledges it with "
                "tablebench table reset-fault"
            )

    def _start_session(self, stb: int) -> int:
        """First contact (``stb`` the first status byte read): errors left from before the session are drained
        into :attr:`stale_errors` (logged, never blamed on a command); returns the status byte without them."""
        if not self._session_checked and stb & STB_EQ:
            self.stale_errors = self._drain_errors()
            log.warning("ACUTROL: errors left from before this session: %s", self._errors_text(self.stale_errors))
            stb &= ~STB_EQ
        self._session_checked = True
        return stb

    # ---- session -------------------------------------------------------------------------------------------------
    def idn(self) -> str:
        """``*IDN?`` → maker,model,serial,software level."""
        return ";".join(self.query("*IDN?"))

    def controller_limits(self) -> list[dict[str, float]]:
        """The controller's working limits per gimbal (outer, middle, inner), read with ``:Limit:…?`` [§4.6]:
        ``rate_position``, ``rate_rate`` (°/s), ``accel_position``, ``accel_rate`` (°/s²), ``high``, ``low`` (°)."""
        out = []
        for a in self._ax:
            q = (
                f":Limit:Rate? P,{a};Rate? R,{a};Acceleration? P,{a};Acceleration? R,{a};"
                f"HighPosition? P,{a};LowPosition? P,{a}"
            )
            f = [self._number(x, "limit") for x in self.query(q, 6)]
            keys = ("rate_position", "rate_rate", "accel_position", "accel_rate", "high", "low")
            out.append(dict(zip(keys, f, strict=True)))
        return out

    def enable(self) -> None:
        """Set Off mode and close the interlocks of the three axes (servo on).

        A latched interlock fault is **not** reset here: it refuses motion (TableError) until an operator
        acknowledges it with :meth:`clear_fault` (``tablebench table reset-fault``).
        """
        stb = self._start_session(self._status_byte())
        if stb & STB_EQ:
            raise TableError(f"ACUTROL reported errors before enable: {self._errors_text(self._drain_errors())}")
        if stb & STB_SI:
            raise TableError(
                f"ACUTROL: interlock fault latched (status byte {stb}; {self._interlock_text()}); nothing moves "
                "until an operator acknowledges it: tablebench table reset-fault"
            )
        self._send_enable()

    def _send_enable(self) -> None:
        a1, a2, a3 = self._ax
        msg = f"*CLS;:Mode:Off {a1};Off {a2};Off {a3};:Interlock:Close {a1};Close {a2};Close {a3}"
        self.command(msg)
        self.check_errors("enable (" + msg + ")")
        self._enabled = True
        self._interlocks = None
        self._set_all_off()

    def _ensure_enabled(self) -> None:
        if not self._enabled:
            self.enable()

    def _set_all_off(self) -> None:
        self._target = [None, None, None]
        self._waypoint = [None, None, None]
        self._rate_cmd = [None, None, None]
        self._since = [None, None, None]

    def leave_running(self) -> None:
        """Do not stop the axes when the driver is closed (``tablebench table spin`` leaves the axis turning)."""
        self._leave_running = True

    # ---- Turntable protocol ----------------------------------------------------------------------------------
    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-axis limits (outer, middle, inner), SI."""
        return self._limits  # type: ignore[return-value]

    def move_to(self, angles: NDArray[np.float64] | list[float]) -> None:
        """Command absolute (unwrapped) gimbal angles, rad: one message, one controller frame."""
        a = check_angles(angles, self._limits)  # type: ignore[arg-type]
        self._check_open()
        self._refuse_if_latched()
        self._ensure_enabled()
        if self._u is None:
            self.read_state()
        assert self._u is not None
        demands = []
        for i in range(3):
            target = float(a[i])
            self._target[i] = target
            self._rate_cmd[i] = None
            self._since[i] = None
            self._waypoint[i] = None
            cur = self._u[i] * DEG
            continuous = self._limits[i].position_min is None and self._limits[i].position_max is None
            if continuous and abs(target - cur) > SINGLE_MOVE_DEG * DEG:
                self._waypoint[i] = cur + math.copysign(WAYPOINT_STEP_DEG * DEG, target - cur)
                demands.append(self._demand_text(self._waypoint[i]))
            else:
                demands.append(self._demand_text(target))
        a1, a2, a3 = self._ax
        msg = (
            f":Demand:Position {a1},{demands[0]};Position {a2},{demands[1]};Position {a3},{demands[2]};"
            f":Mode:Position {a1};Position {a2};Position {a3}"
        )
        self.command(msg)
        self._motion = True
        self.check_errors(f"move ({msg})")

    def _demand_text(self, angle: float) -> str:
        return format_number(wrap_deg(angle / DEG, self._fs))

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis`` (0 outer, 1 middle, 2 inner)."""
        ax, r = check_spin(axis, rate, self._limits)  # type: ignore[arg-type]
        self._check_open()
        self._refuse_if_latched()
        self._ensure_enabled()
        a = self._ax[ax]
        msg = f":Demand:Rate {a},{format_number(r / DEG)};:Mode:Rate {a}"
        self.command(msg)
        self._motion = True
        self._target[ax] = None
        self._waypoint[ax] = None
        self._rate_cmd[ax] = r
        self._since[ax] = None
        self.check_errors(f"spin ({msg})")

    def stop(self) -> None:
        """Controlled stop of every axis (``:Mode:Off``: zero rate, decelerating within limits)."""
        a1, a2, a3 = self._ax
        msg = f":Mode:Off {a1};Off {a2};Off {a3}"
        self.command(msg)
        self._motion = False
        self._set_all_off()
        self.check_errors(f"stop ({msg})", interlock_ok=True)

    def _build_read_message(self) -> str:
        a1, a2, a3 = self._ax
        msg = (
            f":Read:Position? {a1};Position? {a2};Position? {a3};Rate? {a1};Rate? {a2};Rate? {a3};"
            f":Mode? {a1};:Mode? {a2};:Mode? {a3};:Status:STB?"
        )
        if self.settings.time_variable is not None:
            msg += f";:Read:Variable? {int(self.settings.time_variable)}"
        return msg

    def _mode(self, text: str, axis: int) -> AxisMode:
        if self.settings.mode_reply == "letter":
            m = text.upper()
            if m in _LETTER_MODES:
                return _LETTER_MODES[m]
            if len(m) == 1 and m in _OTHER_LETTERS:
                return AxisMode.STOP
        else:
            w = text.lower()
            if w in _WORD_MODES:
                return _WORD_MODES[w]
            if w in _OTHER_WORDS:
                return AxisMode.STOP
        raise LinkError(
            f"ACUTROL: ':Mode? {axis}' answered {text!r}, not a {self.settings.mode_reply} mode; check "
            "turntable.acl.mode_reply (letter: P/R/O, word: Position/Rate/Off)"
        )

    def read_state(self) -> TableState:
        """Positions, rates, modes and status byte of one controller frame (one message); settled decided here."""
        n = 10 + (self.settings.time_variable is not None)
        h_req = float(self._clock())
        f = self.query(self._read_msg)
        h_ans = float(self._clock())
        if len(f) != n:
            raise LinkError(
                f"ACUTROL: the reading should have {n} fields separated by ';', got {';'.join(f)[:120]!r}; check "
                "turntable.acl (axes, time_variable) against the controller"
            )
        raw = [self._number(x, "position") for x in f[0:3]]
        vel = [self._number(x, "rate") for x in f[3:6]]
        modes = tuple(self._mode(m, a) for m, a in zip(f[6:9], self._ax, strict=True))
        if not f[9].isdigit():
            raise LinkError(f"ACUTROL: status byte should be an integer 0-255, got {f[9]!r}")
        stb = self._start_session(int(f[9])) if not self._session_checked else int(f[9])
        tc = math.nan
        if self.settings.time_variable is not None:
            t = tc = self._number(f[10], "time clock") * self.settings.time_scale_s
        else:
            t = h_ans - self._t0
        self._unwrap(raw, vel, t)
        assert self._u is not None
        angles = np.array(self._u) * DEG
        rates = np.array(vel) * DEG
        self._advance_waypoints(angles)
        status, fault = self._status(t, angles, rates, modes, stb)  # type: ignore[arg-type]
        if stb & STB_EQ:
            errors = self._errors_text(self._drain_errors())
            raise TableError(f"ACUTROL reported an error while reading the table: {errors} (status byte {stb})")
        return TableState(
            time=t,
            angles=angles,
            rates=rates,
            status=status,
            fault_code=fault,
            modes=modes,  # type: ignore[arg-type]
            controller_time=tc,
            host_request=h_req,
            host_answer=h_ans,
        )

    def _unwrap(self, raw: list[float], vel: list[float], t: float) -> None:
        fs = self._fs
        if self._u is None or self._v is None or self._t_last is None:
            self._u = list(raw)
        else:
            dt = t - self._t_last
            out = []
            for r, u0, v0, v1 in zip(raw, self._u, self._v, vel, strict=True):
                predicted = u0 + 0.5 * (v0 + v1) * dt if dt > 0 else u0
                out.append(r + fs * round((predicted - r) / fs))
            self._u = out
        self._raw, self._v, self._t_last = list(raw), list(vel), t

    def _advance_waypoints(self, angles: NDArray[np.float64]) -> None:
        sends = []
        for i in range(3):
            wp, target = self._waypoint[i], self._target[i]
            if wp is None or target is None or abs(float(angles[i]) - wp) > WAYPOINT_ADVANCE_DEG * DEG:
                continue
            rest = target - wp
            if abs(rest) <= WAYPOINT_STEP_DEG * DEG:
                self._waypoint[i] = None
                nxt = target
            else:
                nxt = wp + math.copysign(WAYPOINT_STEP_DEG * DEG, rest)
                self._waypoint[i] = nxt
            sends.append(f"Position {self._ax[i]},{self._demand_text(nxt)}")
        if sends:
            msg = ":Demand:" + ";".join(sends)
            self.command(msg)
            self.check_errors(f"way-point ({msg})")

    def _status(
        self, t: float, angles: NDArray[np.float64], rates: NDArray[np.float64], modes: tuple[AxisMode, ...], stb: int
    ) -> tuple[TableStatus, FaultCode]:
        # the bits as integers (drivers.protocols.STATUS_*), one TableStatus at the end (an IntFlag's | runs Python)
        status = STATUS_REMOTE
        fault = FaultCode.NONE
        steady = []
        for i in range(3):
            m = modes[i]
            if m == AxisMode.POSITION:
                tgt = self._target[i]
                ok = tgt is not None and self._waypoint[i] is None and abs(float(angles[i]) - tgt) <= self.tol
            elif m == AxisMode.RATE:
                cmd = self._rate_cmd[i]
                ok = cmd is not None and abs(float(rates[i]) - cmd) <= self.rate_tol
            else:
                ok = abs(float(rates[i])) <= self.rate_tol
            if not ok:
                self._since[i] = None
            elif self._since[i] is None:
                self._since[i] = t
            since = self._since[i]
            steady.append(ok and since is not None and t - since >= self.settle_time - 1e-9)
        pos = [i for i in range(3) if modes[i] == AxisMode.POSITION]
        rat = [i for i in range(3) if modes[i] == AxisMode.RATE]
        if pos and all(steady[i] for i in pos):
            status |= STATUS_IN_POSITION
        if rat and all(steady[i] for i in rat):
            status |= STATUS_AT_RATE
        spinning = any(abs(float(rates[i])) > self.rate_tol for i in rat)
        if not all(steady) or spinning:
            status |= STATUS_MOVING
        if stb & STB_SI:
            status |= STATUS_FAULT | STATUS_INTERLOCK_OPEN
            fault = FaultCode.INTERLOCK
            if not self.fault_report:
                try:
                    self.fault_report = f"interlock fault latched (status byte {stb}; {self._interlock_text()})"
                except (LinkError, TableError) as exc:
                    self.fault_report = f"interlock fault latched (status byte {stb}); details unreadable: {exc}"
                log.info("ACUTROL: %s", self.fault_report)
        else:
            self.fault_report = ""
            if not self._enabled:  # this session has not closed them: ask the controller, once
                if self._interlocks is None:
                    self._interlocks = self._interlock_fields()
                if not all(f.strip().lower().startswith("clos") for f in self._interlocks):
                    status |= STATUS_INTERLOCK_OPEN
        return TableStatus(status), fault

    def heartbeat(self) -> None:
        """Nothing to send: ACL has no host heartbeat or watchdog; the host stops the axes on every exit path."""
        self._check_open()

    def clear_fault(self) -> str:
        """An operator's acknowledgement: ``:Interlock:Reset`` (unfreezes a latched fault), then Off mode and
        the interlocks closed again. Returns what the fault was (the controller's interlock report), or "" if
        none was latched."""
        self._check_open()
        stb = self._start_session(self._status_byte())
        what = ""
        if stb & STB_SI:
            what = f"interlock fault latched (status byte {stb}; {self._interlock_text()})"
        self.command(":Interlock:Reset")
        self.check_errors("reset (:Interlock:Reset)", interlock_ok=True)
        self._enabled = False
        self.fault_report = ""
        self._send_enable()
        return what

    def close(self) -> None:
        """Release the driver: Off on every axis if motion was commanded (unless :meth:`leave_running`), then
        ``:Interlock:Open`` if the bench asks for it. Best effort; the transport is the caller's to close."""
        if self._closed:
            return
        try:
            if not self._leave_running:
                if self._motion:
                    self.stop()
                if self.settings.open_interlocks_at_end and self._enabled:
                    a1, a2, a3 = self._ax
                    self.command(f":Interlock:Open {a1};Open {a2};Open {a3}")
        except (LinkError, TableError) as exc:
            log.info("ACUTROL: while closing: %s", exc)
        finally:
            self._closed = True


__all__ = ["AclTurntable", "format_number", "wrap_deg"]
