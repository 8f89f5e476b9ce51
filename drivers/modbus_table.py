"""Turntable driver for the tablebench Modbus TCP controller (register map: :mod:`drivers.modbus_registers`).

:class:`ModbusTurntable` implements :class:`drivers.protocols.Turntable` with an already-connected pymodbus
3.x **synchronous** client (``pymodbus.client.ModbusTcpClient``); the driver never opens or closes it.
Commands are checked against the table's limits before anything is sent (:class:`TableError`, nothing on
the wire); Modbus exception responses from the controller become :class:`TableError` with the controller's
reason; timeouts, lost connections and malformed answers become :class:`LinkError`.

Frames and units: gimbal angles (outer ψ, middle θ, inner γ), rad, rates rad/s (see drivers.protocols).
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from drivers import modbus_registers as reg
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

_EXCEPTION_NAMES = {1: "illegal function", 2: "illegal data address", 3: "illegal data value", 4: "device failure"}


def check_position(angles: Any, limits: tuple[AxisLimits, AxisLimits, AxisLimits]) -> NDArray[np.float64]:
    """Validate an absolute-angle command (rad, outer/middle/inner) against limits; return it as (3,) float."""
    a = np.asarray(angles, dtype=float).reshape(-1)
    if a.shape != (3,):
        raise TableError(f"move_to needs 3 gimbal angles (outer, middle, inner) in rad, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise TableError(f"move_to: angles must be finite, got {a.tolist()}")
    for i, (x, lim) in enumerate(zip(a, limits, strict=True)):
        if not lim.allows_position(x):
            raise TableError(
                f"move_to: {AXIS_NAMES[i]} axis angle {math.degrees(x):.4f}° outside its limits "
                f"{lim.position_range_text()}; nothing was sent"
            )
    return a


def check_rate(axis: int, rate: float, limits: tuple[AxisLimits, AxisLimits, AxisLimits]) -> tuple[int, float]:
    """Validate a rate command (axis 0/1/2, rad/s) against limits."""
    if not isinstance(axis, (int, np.integer)) or not 0 <= int(axis) <= 2:
        raise TableError(f"spin: axis must be 0 (outer), 1 (middle) or 2 (inner), got {axis!r}")
    r = float(rate)
    if not math.isfinite(r):
        raise TableError(f"spin: rate must be finite, got {rate!r}")
    lim = limits[int(axis)]
    if not lim.allows_rate(r):  # the one limit rule (AxisLimits), as the compiler, runner and controller
        raise TableError(
            f"spin: {AXIS_NAMES[int(axis)]} axis rate {math.degrees(r):.4f} °/s exceeds its limit "
            f"{math.degrees(lim.rate_max):.4f} °/s; nothing was sent"
        )
    return int(axis), r


class ModbusTurntable:
    """Three-axis table on the tablebench Modbus TCP register map.

    Parameters
    ----------
    client : pymodbus.client.ModbusTcpClient
        Connected synchronous client (the caller owns it; set its ``timeout``/``retries`` short).
    unit_id : int
        Modbus device (unit) id.
    word_order : {"big", "little"}
        Float word order of the controller (see :mod:`drivers.modbus_registers`).
    limits : tuple of 3 AxisLimits or None
        Table limits used for checks before sending; None reads them from the controller.
    """

    def __init__(
        self,
        client: Any,
        unit_id: int = 1,
        word_order: reg.WordOrder = "big",
        limits: tuple[AxisLimits, AxisLimits, AxisLimits] | None = None,
    ) -> None:
        reg._check_order(word_order)
        self.client = client
        self.unit_id = int(unit_id)
        self.word_order: reg.WordOrder = word_order
        self._hb = 0
        self._closed = False
        self._limits = tuple(limits) if limits is not None else self._read_limits()
        if len(self._limits) != 3:
            raise ValueError("limits must be 3 AxisLimits (outer, middle, inner)")

    # ---- transport -------------------------------------------------------------------------------------------
    def _call(self, what: str, fn: Any, *args: Any, **kw: Any) -> Any:
        from pymodbus.exceptions import ModbusException

        if self._closed:
            raise LinkError(f"Modbus turntable: driver is closed ({what})")
        try:
            rr = fn(*args, device_id=self.unit_id, **kw)
        except (ModbusException, OSError) as exc:
            raise LinkError(f"Modbus turntable: {what} failed: {exc.__class__.__name__}: {exc}") from exc
        if rr is None:
            raise LinkError(f"Modbus turntable: {what}: no response")
        if rr.isError():
            code = int(getattr(rr, "exception_code", 0) or 0)
            if code in (3, 4):
                reason = self._reject_reason()
                raise TableError(
                    f"Modbus turntable refused {what}: exception {code} ({_EXCEPTION_NAMES[code]}); "
                    f"controller reason: {reason}"
                )
            raise LinkError(
                f"Modbus turntable: {what} answered with exception {code} "
                f"({_EXCEPTION_NAMES.get(code, 'unknown')}); check unit_id={self.unit_id} and the register map"
            )
        return rr

    def _reject_reason(self) -> str:
        try:
            rr = self.client.read_input_registers(reg.IR_STATUS, count=6, device_id=self.unit_id)
            if rr is None or rr.isError():
                return "unknown"
            fault = FaultCode(rr.registers[reg.IR_FAULT_CODE - reg.IR_STATUS])
            last = FaultCode(rr.registers[reg.IR_LAST_REJECT - reg.IR_STATUS])
            return f"{last.name}" + (f" (latched fault {fault.name}; clear_fault() first)" if fault else "")
        except Exception:  # the reason is best effort; the refusal itself is already known
            return "unknown"

    def _write(self, what: str, address: int, values: list[int]) -> None:
        self._call(what, self.client.write_registers, address, values)

    def _read_input(self, what: str, address: int, count: int) -> list[int]:
        rr = self._call(what, self.client.read_input_registers, address, count=count)
        regs = list(rr.registers)
        if len(regs) != count:
            raise LinkError(f"Modbus turntable: {what}: expected {count} registers, got {len(regs)}")
        return regs

    def _read_limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        vals = reg.unpack_float64(
            self._read_input("limits readback", reg.IR_LIMITS, reg.IR_LIMITS_COUNT), self.word_order
        )
        out = []
        for i in range(3):
            rmax, amax, pmin, pmax = vals[4 * i : 4 * i + 4]
            plausible = 0 < rmax < 1e3 and 0 < amax < 1e4 and all(math.isnan(p) or abs(p) < 1e3 for p in (pmin, pmax))
            if not plausible:
                raise LinkError(
                    f"Modbus turntable: implausible limits read back for the {AXIS_NAMES[i]} axis "
                    f"(rate_max={rmax:.6g}, accel_max={amax:.6g}); check float_word_order "
                    f"(now {self.word_order!r}) and the unit id"
                )
            out.append(
                AxisLimits(
                    rate_max=rmax,
                    accel_max=amax,
                    position_min=None if math.isnan(pmin) else pmin,
                    position_max=None if math.isnan(pmax) else pmax,
                )
            )
        return (out[0], out[1], out[2])

    # ---- Turntable protocol ----------------------------------------------------------------------------------
    def limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        """Per-axis limits (outer, middle, inner), SI."""
        return self._limits  # type: ignore[return-value]

    def move_to(self, angles: NDArray[np.float64] | list[float]) -> None:
        """Command absolute gimbal angles (outer, middle, inner), rad; returns at once."""
        a = check_position(angles, self._limits)  # type: ignore[arg-type]
        self._write("move_to (set-points)", reg.HR_POSITION_SETPOINT, reg.pack_float64(a.tolist(), self.word_order))
        self._write("move_to", reg.HR_COMMAND, [int(reg.Command.MOVE)])

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis`` (0 outer, 1 middle, 2 inner)."""
        ax, r = check_rate(axis, rate, self._limits)  # type: ignore[arg-type]
        addr = reg.HR_RATE_SETPOINT + reg.F64_REGS * ax
        self._write("spin (set-point)", addr, reg.pack_float64(r, self.word_order))
        self._write("spin", reg.HR_COMMAND_AXIS, [ax, int(reg.Command.SPIN)])

    def stop(self) -> None:
        """Bring every axis to rest under control."""
        self._write("stop", reg.HR_COMMAND, [int(reg.Command.STOP)])

    def read_state(self) -> TableState:
        """Read time, angles, rates, status, fault code and modes in one request."""
        r = self._read_input("read_state", 0, reg.IR_STATE_COUNT)
        f = reg.unpack_float64(r[: reg.IR_STATUS], self.word_order)
        try:
            modes = tuple(AxisMode(m) for m in r[reg.IR_MODE : reg.IR_MODE + 3])
            fault = FaultCode(r[reg.IR_FAULT_CODE])
        except ValueError as exc:
            raise LinkError(f"Modbus turntable: read_state: invalid mode/fault value ({exc})") from exc
        return TableState(
            time=f[0],
            angles=np.array(f[1:4]),
            rates=np.array(f[4:7]),
            status=TableStatus(r[reg.IR_STATUS]),
            fault_code=fault,
            modes=modes,  # type: ignore[arg-type]
        )

    def heartbeat(self) -> None:
        """Feed the controller's watchdog (writes an incrementing counter)."""
        self._hb = (self._hb + 1) & 0xFFFF
        self._write("heartbeat", reg.HR_HEARTBEAT, [self._hb])

    def clear_fault(self) -> None:
        """Reset a latched fault (the table stays at rest)."""
        self._write("clear_fault", reg.HR_FAULT_RESET, [1])

    def close(self) -> None:
        """Release the driver (the client is the caller's to close)."""
        self._closed = True
