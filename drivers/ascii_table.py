"""Turntable driver for an SCPI-style ASCII dialect (in the style of ACUTROL controllers) over a serial link.

The link is any pyserial-like port (``serial.Serial`` on RS-232, ``serial.serial_for_url("socket://host:port")``
over TCP); the driver never opens it. Lines are CR-LF terminated. Angles and rates are **degrees** and
**degrees per second** in the wire text and SI (rad, rad/s) in the API; the conversion is
:data:`analysis.units.DEG`. Values are written with full double precision (``repr``), so a value crosses the
link exact to about one ulp (rad → deg → rad is not always bit-exact: ~9 % of doubles move by one ulp), so
an ASCII run matches the in-process run to that level, not bit for bit (Modbus float64 is bit-exact). Axes
are numbered 1 (outer), 2 (middle), 3 (inner) on the wire, 0/1/2 in the API.

Dialect (one reply line per command line; several commands may share a line separated by ``;``, which the
controller executes as one batch — a batch of ``:dem:pos`` is one synchronous multi-axis move)::

    :mode:pos <a>            axis a to position mode               → OK
    :dem:pos <a>,<deg>       absolute position demand              → OK
    :mode:rate <a>           axis a to rate mode                   → OK
    :dem:rate <a>,<deg/s>    rate demand                           → OK
    :stop                    all axes to rest under control        → OK
    :hb                      heartbeat (watchdog feed)             → OK
    :fault:reset             reset a latched fault                 → OK
    *stb?                    status byte (TableStatus bits)        → <int>
    :pos? <a>                reported angle, deg                   → <float>
    :rate? <a>               reported rate, deg/s                  → <float>
    :fault?                  latched fault                         → <code>,<NAME>
    :limit:abs? <a>          limits → <rate_max deg/s>,<accel_max deg/s²>,<pos_low deg|none>,<pos_high deg|none>
    :state?                  one consistent snapshot (tablebench extension):
                             <time s>,<pos1>,<pos2>,<pos3>,<rate1>,<rate2>,<rate3>,<stb>,<fault>,<mode1>,<mode2>,<mode3>

Errors are answered ``ERR <code> <text>`` (code: :class:`drivers.protocols.FaultCode`), which the driver
raises as :class:`TableError`; a missing or garbled reply within ``timeout`` is a :class:`LinkError`.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.units import DEG
from drivers.modbus_table import check_position, check_rate
from drivers.protocols import AxisLimits, AxisMode, FaultCode, LinkError, TableError, TableState, TableStatus

log = logging.getLogger(__name__)


def fmt(x: float) -> str:
    """A float as wire text with full double precision (round-trips exactly)."""
    return repr(float(x))


class AsciiTurntable:
    """Three-axis table speaking the ASCII dialect above.

    Parameters
    ----------
    port : pyserial-like object
        Open port with ``write``, ``read_until`` and a settable ``timeout``.
    timeout : float
        Longest wait for a reply line, s.
    limits : tuple of 3 AxisLimits or None
        Limits for checks before sending; None reads them with ``:limit:abs?``.
    """

    def __init__(
        self, port: Any, timeout: float = 1.0, limits: tuple[AxisLimits, AxisLimits, AxisLimits] | None = None
    ) -> None:
        self.port = port
        self.timeout = float(timeout)
        try:
            self.port.timeout = self.timeout
        except (AttributeError, ValueError):  # pragma: no cover
            pass
        self._closed = False
        self._limits = tuple(limits) if limits is not None else tuple(self._read_limit(a) for a in (1, 2, 3))

    # ---- transport -------------------------------------------------------------------------------------------
    def query(self, line: str) -> str:
        """Send one command line and return the controller's reply (without CR-LF).

        Raises TableError for ``ERR`` replies and LinkError for timeouts / lost links.
        """
        if self._closed:
            raise LinkError("ASCII turntable: driver is closed")
        try:
            self.port.write(line.encode("ascii") + b"\r\n")
            raw = self.port.read_until(b"\r\n")
        except Exception as exc:  # serial.SerialException, OSError
            raise LinkError(f"ASCII turntable: link failed on {line!r} ({exc.__class__.__name__}: {exc})") from exc
        if not raw.endswith(b"\r\n"):
            raise LinkError(
                f"ASCII turntable: no complete reply to {line!r} within {self.timeout:.3g} s "
                f"(got {raw[:60]!r}); check the cable, baud rate and that the controller is in remote mode"
            )
        reply = raw[:-2].decode("ascii", "replace").strip()
        if reply.startswith("ERR"):
            parts = reply.split(maxsplit=2)
            raise TableError(f"ASCII turntable refused {line!r}: {reply[4:] if len(parts) > 1 else reply}")
        return reply

    def _numbers(self, line: str, n: int) -> list[str]:
        reply = self.query(line)
        fields = [f.strip() for f in reply.split(",")]
        if len(fields) != n:
            raise LinkError(f"ASCII turntable: reply to {line!r} should have {n} field(s), got {reply!r}")
        return fields

    def _read_limit(self, axis: int) -> AxisLimits:
        f = self._numbers(f":limit:abs? {axis}", 4)
        try:
            lo = None if f[2].lower() == "none" else float(f[2]) * DEG
            hi = None if f[3].lower() == "none" else float(f[3]) * DEG
            return AxisLimits(rate_max=float(f[0]) * DEG, accel_max=float(f[1]) * DEG, position_min=lo, position_max=hi)
        except ValueError as exc:
            raise LinkError(f"ASCII turntable: malformed limits for axis {axis}: {f}") from exc

    # ---- Turntable protocol ----------------------------------------------------------------------------------
    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-axis limits (outer, middle, inner), SI."""
        return self._limits  # type: ignore[return-value]

    def move_to(self, angles: NDArray[np.float64] | list[float]) -> None:
        """Command absolute gimbal angles (outer, middle, inner), rad; one synchronous multi-axis move."""
        a = check_position(angles, self._limits)  # type: ignore[arg-type]
        modes = ";".join(f":mode:pos {i + 1}" for i in range(3))
        dems = ";".join(f":dem:pos {i + 1},{fmt(x / DEG)}" for i, x in enumerate(a))
        self.query(f"{modes};{dems}")

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis`` (0 outer, 1 middle, 2 inner)."""
        ax, r = check_rate(axis, rate, self._limits)  # type: ignore[arg-type]
        self.query(f":mode:rate {ax + 1};:dem:rate {ax + 1},{fmt(r / DEG)}")

    def stop(self) -> None:
        """Bring every axis to rest under control."""
        self.query(":stop")

    def read_state(self) -> TableState:
        """One consistent snapshot (``:state?``): time, angles, rates, status, fault, modes."""
        f = self._numbers(":state?", 12)
        try:
            v = [float(x) for x in f[:7]]
            status = TableStatus(int(f[7]))
            fault = FaultCode(int(f[8]))
            modes = tuple(AxisMode(int(m)) for m in f[9:12])
        except ValueError as exc:
            raise LinkError(f"ASCII turntable: malformed state reply {','.join(f)!r}") from exc
        return TableState(
            time=v[0],
            angles=np.array(v[1:4]) * DEG,
            rates=np.array(v[4:7]) * DEG,
            status=status,
            fault_code=fault,
            modes=modes,  # type: ignore[arg-type]
        )

    def position(self, axis: int) -> float:
        """Reported angle of one axis (``:pos?``), rad."""
        return float(self._numbers(f":pos? {int(axis) + 1}", 1)[0]) * DEG

    def rate(self, axis: int) -> float:
        """Reported rate of one axis (``:rate?``), rad/s."""
        return float(self._numbers(f":rate? {int(axis) + 1}", 1)[0]) * DEG

    def status_byte(self) -> TableStatus:
        """``*stb?`` as TableStatus."""
        return TableStatus(int(self.query("*stb?")))

    def heartbeat(self) -> None:
        """Feed the controller's watchdog."""
        self.query(":hb")

    def clear_fault(self) -> None:
        """Reset a latched fault (the table stays at rest)."""
        self.query(":fault:reset")

    def close(self) -> None:
        """Release the driver (the port is the caller's to close)."""
        self._closed = True


__all__ = ["AsciiTurntable", "fmt"]
