"""Turntable driver for an Ideal Aerosmith single-axis rate table (three-letter text commands, RS-232).

Protocol (docs/protocols/ideal-aerosmith.md; the open points are :class:`AerosmithSettings`): a command is
three letters and an optional number, ``JOG-12.5`` (rate, °/s), ``ACL50`` (acceleration, °/s²), ``SRV1``
(servo on), ``HOM`` (home), ``STO`` (stop), followed by the command terminator; a query is the three letters and
``?``. Every reply ends with the controller's prompt; a command is accepted when nothing but the prompt comes back,
and whatever comes before the prompt is the controller's message (an error, reported as :class:`TableError`).
No prompt within the timeout is a :class:`LinkError`.

The table has one axis: it is the bench's ``settings.axis`` gimbal; the other two are absent. ``move_to`` accepts
only the home position (0 on the table's axis, the absent axes at 0: ``HOM``) — the public command set has no
move to an arbitrary angle; ``spin`` commands ``ACL`` (the bench's acceleration limit) then ``JOG``. "At rate" and
"in position" are decided from readings (rate within ``rate_tolerance`` of the demand, home within
``position_tolerance``). The driver receives an open pyserial-like byte stream and never opens it.
Frames: gimbal angles rad, rates rad/s (see drivers.protocols); degrees on the wire.
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
from drivers.aerosmith.settings import AerosmithSettings
from drivers.protocols import (
    AXIS_NAMES,
    AxisLimits,
    AxisMode,
    FaultCode,
    LinkError,
    TableError,
    TableState,
    TableStatus,
)

log = logging.getLogger(__name__)

_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def format_value(x: float) -> str:
    """A number as sent: fixed point, at most 6 decimals, trailing zeros dropped (``12.5``, ``-360``)."""
    if not math.isfinite(x):
        raise TableError(f"cannot send a non-finite number ({x!r})")
    s = f"{x:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


class AerosmithTable:
    """Single-axis Ideal Aerosmith table. Implements :class:`drivers.protocols.Turntable`.

    Parameters
    ----------
    stream : pyserial-like byte stream
        Open link (``write``, ``read_until``, ``timeout``); the caller owns it.
    limits : tuple of 3 AxisLimits
        The bench's limits (outer, middle, inner), SI; the two gimbals the table does not have are
        :meth:`AxisLimits.absent_axis`.
    settings : AerosmithSettings
    position_tolerance, rate_tolerance : float
        rad and rad/s: "home" and "at rate" windows.
    clock : callable
        Host clock (s): the controller sends no time tag.
    """

    def __init__(
        self,
        stream: Any,
        limits: tuple[AxisLimits, AxisLimits, AxisLimits],
        *,
        settings: AerosmithSettings | None = None,
        position_tolerance: float = 0.01 * DEG,
        rate_tolerance: float = 0.01 * DEG,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.s = stream
        self.settings = settings or AerosmithSettings()
        self._limits = tuple(limits)
        self.ax = self.settings.index
        for i, lim in enumerate(self._limits):
            if i != self.ax and not lim.absent:
                raise ValueError(
                    f"an Ideal Aerosmith table has one axis ({self.settings.axis}); the {AXIS_NAMES[i]} axis limits "
                    "must be absent"
                )
        self.tol = float(position_tolerance)
        self.rate_tol = float(rate_tolerance)
        self._clock = clock
        self._t0 = clock()
        self._servo = False
        self._rate_demand: float | None = None
        self._homing = False
        self._motion = False
        self._closed = False
        self.fault_report = ""

    # ---- wire ------------------------------------------------------------------------------------------------
    def _exchange(self, text: str) -> str:
        """Send ``text`` + terminator; return what came before the prompt (LinkError without a prompt)."""
        if self._closed:
            raise LinkError("Ideal Aerosmith: driver is closed")
        prompt = self.settings.prompt.encode("ascii")
        try:
            self.s.write((text + self.settings.command_terminator).encode("ascii"))
            reply = self.s.read_until(prompt)
        except (OSError, ValueError) as exc:
            raise LinkError(f"Ideal Aerosmith: link failed on {text!r}: {exc.__class__.__name__}: {exc}") from exc
        if not reply.endswith(prompt):
            raise LinkError(
                f"Ideal Aerosmith: no prompt after {text!r} within {getattr(self.s, 'timeout', '?')} s "
                f"(got {reply[:60]!r}); check the cable, 9600 8N1, and turntable.aerosmith.prompt / "
                "command_terminator"
            )
        return reply[: -len(prompt)].decode("ascii", "replace").strip()

    def command(self, text: str) -> None:
        """A command: accepted when only the prompt comes back, else TableError with the controller's text."""
        said = self._exchange(text)
        if said:
            raise TableError(f"Ideal Aerosmith refused {text!r}: {said!r}")

    def query(self, name: str) -> float:
        """``NAME?`` → a number."""
        said = self._exchange(name + "?")
        if not _NUMBER.match(said):
            raise LinkError(
                f"Ideal Aerosmith: {name}? answered {said!r}, not a number; check turntable.aerosmith "
                f"(position_query / rate_query) against the controller's manual"
            )
        return float(said)

    # ---- Turntable protocol ----------------------------------------------------------------------------------
    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-gimbal limits (outer, middle, inner), SI; two of them absent."""
        return self._limits  # type: ignore[return-value]

    def _servo_on(self) -> None:
        if not self._servo:
            self.command("SRV1")
            self._servo = True

    def move_to(self, angles: NDArray[np.float64] | list[float]) -> None:
        """Home the table (``HOM``): the only position the public command set reaches."""
        a = np.asarray(angles, dtype=float).reshape(-1)
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise TableError(f"move_to needs 3 finite gimbal angles (rad), got {angles!r}; nothing was sent")
        for i, x in enumerate(a):
            if i != self.ax and not self._limits[i].allows_position(x):
                raise TableError(
                    f"move_to: the table has no {AXIS_NAMES[i]} axis ({math.degrees(x):g}° asked); nothing was sent"
                )
        if abs(float(a[self.ax])) > 1e-12:
            raise TableError(
                f"move_to {math.degrees(float(a[self.ax])):g}°: an Ideal Aerosmith rate table moves only home (HOM, "
                "0°) and at rate (JOG); nothing was sent"
            )
        self._servo_on()
        self.command("HOM")
        self._homing, self._rate_demand, self._motion = True, None, True

    def spin(self, axis: int, rate: float) -> None:
        """Constant rate (rad/s, signed) on the table's axis: ``ACL`` (the acceleration limit), then ``JOG``."""
        if axis != self.ax:
            raise TableError(
                f"spin: the table has no {AXIS_NAMES[axis] if 0 <= axis <= 2 else repr(axis)} axis; its axis is "
                f"{self.settings.axis}; nothing was sent"
            )
        lim = self._limits[self.ax]
        r = float(rate)
        if not lim.allows_rate(r):
            raise TableError(
                f"spin: {math.degrees(r):.4f} °/s exceeds the {self.settings.axis} axis limit "
                f"{math.degrees(lim.rate_max):g} °/s; nothing was sent"
            )
        self._servo_on()
        self.command(f"ACL{format_value(lim.accel_max / DEG)}")
        self.command(f"JOG{format_value(r / DEG)}")
        self._rate_demand, self._homing, self._motion = r, False, True

    def stop(self) -> None:
        """Controlled stop (``STO``)."""
        self.command("STO")
        self._rate_demand, self._homing, self._motion = None, False, False

    def read_state(self) -> TableState:
        """Position and rate of the table's axis (two queries), time from the host clock."""
        pos = self.query(self.settings.position_query) * DEG
        rate = self.query(self.settings.rate_query) * DEG
        t = self._clock() - self._t0
        angles = np.zeros(3)
        rates = np.zeros(3)
        angles[self.ax], rates[self.ax] = pos, rate
        status = TableStatus.REMOTE
        mode = AxisMode.STOP
        if self._rate_demand is not None:
            mode = AxisMode.RATE
            if abs(rate - self._rate_demand) <= self.rate_tol:
                status |= TableStatus.AT_RATE
        elif self._homing:
            mode = AxisMode.POSITION
            if abs(math.remainder(pos, 2 * math.pi)) <= self.tol and abs(rate) <= self.rate_tol:
                status |= TableStatus.IN_POSITION
        if abs(rate) > self.rate_tol:
            status |= TableStatus.MOVING
        if not self._servo:
            status |= TableStatus.INTERLOCK_OPEN
        modes = [AxisMode.STOP] * 3
        modes[self.ax] = mode
        return TableState(
            time=t,
            angles=angles,
            rates=rates,
            status=status,
            fault_code=FaultCode.NONE,
            modes=tuple(modes),  # type: ignore[arg-type]
        )

    def heartbeat(self) -> None:
        """Nothing to send: the public command set has no host heartbeat."""

    def clear_fault(self) -> str:
        """Nothing latched to reset in the public command set; servo on again."""
        self._servo = False
        self._servo_on()
        return ""

    def close(self) -> None:
        """Stop the table if motion was commanded (best effort); the stream is the caller's to close."""
        if self._closed:
            return
        try:
            if self._motion:
                self.stop()
        except (LinkError, TableError) as exc:
            log.info("Ideal Aerosmith: while closing: %s", exc)
        finally:
            self._closed = True


__all__ = ["AerosmithTable", "format_value"]
