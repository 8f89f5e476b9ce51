"""Turntable driver for Modbus TCP tables whose register map is data (:mod:`drivers.modbus.register_map`; the default
is the tablebench controller's map, ``drivers/modbus/maps/tablebench.yaml``).

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

from drivers.modbus.register_map import ModbusMap, map_with_word_order
from drivers.protocols import (
    AXIS_NAMES,
    AxisLimits,
    LinkError,
    TableError,
    TableState,
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
    """Three-axis table on a Modbus TCP register map.

    Parameters
    ----------
    client : pymodbus.client.ModbusTcpClient
        Connected synchronous client (the caller owns it; set its ``timeout``/``retries`` short).
    unit_id : int
        Modbus device (unit) id.
    word_order : {"big", "little"} or None
        Overrides the map's float word order (None: the map's).
    limits : tuple of 3 AxisLimits or None
        Table limits used for checks before sending; None reads them from the controller.
    register_map : ModbusMap or None
        The controller's register map (None: the shipped tablebench map).
    """

    def __init__(
        self,
        client: Any,
        unit_id: int = 1,
        word_order: str | None = None,
        limits: tuple[AxisLimits, AxisLimits, AxisLimits] | None = None,
        register_map: ModbusMap | None = None,
    ) -> None:
        m = map_with_word_order(register_map, word_order)
        self.map = m
        self.client = client
        self.unit_id = int(unit_id)
        self.word_order = m.word_order
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
                f"({_EXCEPTION_NAMES.get(code, 'unknown')}); check unit_id={self.unit_id} and the register map "
                f"({self.map.source})"
            )
        return rr

    def _read_fn(self) -> Any:
        return (
            self.client.read_input_registers
            if self.map.state_registers == "input"
            else self.client.read_holding_registers
        )

    def _reject_reason(self) -> str:
        st = self.map.state
        lo = min(st["status"], st["fault_code"], st["last_reject"])
        hi = max(st["status"], st["fault_code"], st["last_reject"]) + 1
        try:
            rr = self._read_fn()(lo, count=hi - lo, device_id=self.unit_id)
            if rr is None or rr.isError():
                return "unknown"
            fault = self.map.fault_from(rr.registers[st["fault_code"] - lo])
            last = self.map.fault_from(rr.registers[st["last_reject"] - lo])
            return f"{last.name}" + (f" (latched fault {fault.name}; clear_fault() first)" if fault else "")
        except Exception:  # the reason is best effort; the refusal itself is already known
            return "unknown"

    def _write(self, what: str, address: int, values: list[int]) -> None:
        self._call(what, self.client.write_registers, address, values)

    def _read_state_regs(self, what: str, address: int, count: int) -> list[int]:
        rr = self._call(what, self._read_fn(), address, count=count)
        regs = list(rr.registers)
        if len(regs) != count:
            raise LinkError(f"Modbus turntable: {what}: expected {count} registers, got {len(regs)}")
        return regs

    def _read_limits(self) -> tuple[AxisLimits, AxisLimits, AxisLimits]:
        m = self.map
        raw = m.unpack(self._read_state_regs("limits readback", m.state["limits"], m.size("limits")))
        out = []
        for i in range(3):
            rmax, amax, pmin, pmax = raw[4 * i : 4 * i + 4]
            rmax, amax = rmax * m.rate_scale, amax * m.rate_scale
            pmin, pmax = pmin * m.angle_scale, pmax * m.angle_scale
            plausible = 0 < rmax < 1e3 and 0 < amax < 1e4 and all(math.isnan(p) or abs(p) < 1e3 for p in (pmin, pmax))
            if not plausible:
                raise LinkError(
                    f"Modbus turntable: implausible limits read back for the {AXIS_NAMES[i]} axis "
                    f"(rate_max={rmax:.6g}, accel_max={amax:.6g}); check float_word_order "
                    f"(now {self.word_order!r}), the unit id and the register map ({m.source})"
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
        m = self.map
        self._write("move_to (set-points)", m.holding["position_setpoint"], m.pack([x / m.angle_scale for x in a]))
        self._write("move_to", m.holding["command"], [m.commands["move"]])

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis`` (0 outer, 1 middle, 2 inner)."""
        ax, r = check_rate(axis, rate, self._limits)  # type: ignore[arg-type]
        m = self.map
        self._write("spin (set-point)", m.holding["rate_setpoint"] + m.value_regs * ax, m.pack(r / m.rate_scale))
        if m.holding["command"] == m.holding["command_axis"] + 1:
            self._write("spin", m.holding["command_axis"], [ax, m.commands["spin"]])
        else:
            self._write("spin (axis)", m.holding["command_axis"], [ax])
            self._write("spin", m.holding["command"], [m.commands["spin"]])

    def stop(self) -> None:
        """Bring every axis to rest under control."""
        self._write("stop", self.map.holding["command"], [self.map.commands["stop"]])

    def read_state(self) -> TableState:
        """Read time, angles, rates, status, fault code and modes in one request."""
        m = self.map
        lo, n = m.state_span()
        r = self._read_state_regs("read_state", lo, n)

        def field(name: str) -> list[int]:
            a = m.state[name] - lo
            return r[a : a + m.size(name)]

        try:
            t = m.unpack(field("time"))[0] * m.time_scale
            ang = np.array(m.unpack(field("angles"))) * m.angle_scale
            rat = np.array(m.unpack(field("rates"))) * m.rate_scale
            modes = tuple(m.mode_from(v) for v in field("mode"))
            fault = m.fault_from(field("fault_code")[0])
        except ValueError as exc:
            raise LinkError(f"Modbus turntable: read_state: invalid value ({exc}); check the register map") from exc
        return TableState(
            time=t,
            angles=ang,
            rates=rat,
            status=m.status_from(field("status")[0]),
            fault_code=fault,
            modes=modes,  # type: ignore[arg-type]
        )

    def heartbeat(self) -> None:
        """Feed the controller's watchdog (writes an incrementing counter)."""
        self._hb = (self._hb + 1) & 0xFFFF
        self._write("heartbeat", self.map.holding["heartbeat"], [self._hb])

    def clear_fault(self) -> None:
        """Reset a latched fault (the table stays at rest)."""
        self._write("clear_fault", self.map.holding["fault_reset"], [1])

    def close(self) -> None:
        """Release the driver (the client is the caller's to close)."""
        self._closed = True
