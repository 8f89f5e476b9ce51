"""Turntable driver for Modbus TCP tables whose register map is data (:mod:`drivers.modbus.register_map`; the default
is the tablebench controller's map, ``drivers/modbus/maps/tablebench.yaml``).

:class:`ModbusTurntable` implements :class:`drivers.protocols.Turntable` with an already-connected pymodbus
3.x **synchronous** client (``pymodbus.client.ModbusTcpClient``); the driver never opens or closes it.
Commands are checked against the table's limits before anything is sent (:class:`TableError`, nothing on
the wire); Modbus exception responses from the controller become :class:`TableError` with the controller's
reason; timeouts, lost connections and malformed answers become :class:`LinkError`.

Every value read back (time, angles, rates, limits) is checked for plausibility before it is used or shown
(:func:`check_plausible`): a wrong word order or register map produces numbers no table reaches, and they are
refused with one line naming the value, the bench's limit and the fix (:class:`ImplausibleReading`).

How motion is started (one command register, per-axis control words, start coils) is the map's ``control``
scheme; a status register without an AT_RATE bit is completed from the rates read against the demand.
See docs/protocols/modbus.md.

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
    AxisMode,
    LinkError,
    TableError,
    TableState,
    TableStatus,
    check_angles,
    check_spin,
)

log = logging.getLogger(__name__)

_EXCEPTION_NAMES = {1: "illegal function", 2: "illegal data address", 3: "illegal data value", 4: "device failure"}


ANGLE_MARGIN = math.radians(10.0)
"""Over-travel allowed beyond a limited axis's position limits before a reading is implausible, rad."""
MAX_TURNS = 1e5
"""A continuous axis's unwrapped angle beyond this many turns is implausible."""
RATE_MARGIN = 1.25
"""A rate reading beyond ``RATE_MARGIN × rate_max + 0.01 rad/s`` is implausible."""
MAX_TIME_S = 1e9
"""A controller time beyond ±31.7 years is implausible."""


class ImplausibleReading(LinkError):
    """A value read back is one no table reaches (wrong word order, wrong map, a corrupted register)."""


def _tiny(x: float) -> bool:
    return x != 0.0 and abs(x) < 1e-30  # a subnormal-looking reading: a float read with its words swapped


def check_plausible(
    state: TableState,
    limits: tuple[AxisLimits, AxisLimits, AxisLimits],
    previous: TableState | None = None,
    hint: str = "",
) -> None:
    """Refuse a reading no table reaches (:class:`ImplausibleReading`, one line naming value, limit and fix).

    Checks: every value finite and not subnormal-small; time within ±1e9 s (a controller clock may start
    anywhere) and not running backwards;
    angles of limited axes within their limits ± 10°, of continuous axes within ±1e5 turns; rates within
    1.25 × rate_max + 0.01 rad/s; and, against the previous reading, no angle change faster than the rate limit
    allows (1.25 × rate_max × Δt + 0.05 rad).
    """
    fix = f"; check {hint}" if hint else ""

    def bad(what: str) -> ImplausibleReading:
        return ImplausibleReading(f"implausible reading: {what}{fix}")

    t = float(state.time)
    if not math.isfinite(t) or _tiny(t) or abs(t) > MAX_TIME_S:
        raise bad(f"controller time {t!r} s (expected within ±{MAX_TIME_S:g} s)")
    if previous is not None and t < previous.time:
        raise bad(f"controller time ran backwards ({previous.time:.6g} s → {t:.6g} s)")
    for i, lim in enumerate(limits):
        a, r = float(state.angles[i]), float(state.rates[i])
        name = AXIS_NAMES[i]
        if not math.isfinite(a) or _tiny(a):
            raise bad(f"{name} angle {a!r} rad")
        if lim.position_min is not None and lim.position_max is not None:
            if not lim.position_min - ANGLE_MARGIN <= a <= lim.position_max + ANGLE_MARGIN:
                raise bad(f"{name} angle {math.degrees(a):.6g}° outside its limits {lim.position_range_text()}")
        elif abs(a) > MAX_TURNS * 2 * math.pi:
            raise bad(f"{name} angle {math.degrees(a):.6g}° (a continuous axis, beyond {MAX_TURNS:g} turns)")
        if not math.isfinite(r) or _tiny(r) or abs(r) > RATE_MARGIN * lim.rate_max + 0.01:
            raise bad(f"{name} rate {math.degrees(r):.6g} °/s beyond its limit {math.degrees(lim.rate_max):g} °/s")
        if previous is not None:
            step = abs(a - float(previous.angles[i]))
            allowed = RATE_MARGIN * lim.rate_max * (t - previous.time) + 0.05
            if step > allowed:
                raise bad(
                    f"{name} angle jumped {math.degrees(step):.6g}° in {t - previous.time:.6g} s "
                    f"(its rate limit {math.degrees(lim.rate_max):g} °/s allows {math.degrees(allowed):.6g}°)"
                )


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
        The controller's register map (None: the shipped tablebench map). A ``word_order`` contradicting a map
        given here is refused (:class:`~drivers.modbus.register_map.WordOrderConflict`) before anything is sent.
    rate_tolerance : float
        rad/s: a rate-mode axis within this of its demand is AT_RATE, where the map's status has no such bit.
    """

    def __init__(
        self,
        client: Any,
        unit_id: int = 1,
        word_order: str | None = None,
        limits: tuple[AxisLimits, AxisLimits, AxisLimits] | None = None,
        register_map: ModbusMap | None = None,
        rate_tolerance: float = math.radians(0.01),
    ) -> None:
        m = map_with_word_order(register_map, word_order)
        self.map = m
        self.client = client
        self.unit_id = int(unit_id)
        self.word_order = m.word_order
        self.rate_tol = float(rate_tolerance)
        self._hb = 0
        self._closed = False
        self._last_state: TableState | None = None
        self._rate_demand: list[float | None] = [None, None, None]
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

    def _coil(self, what: str, address: int) -> None:
        self._call(what, self.client.write_coil, address, True)

    @property
    def _hint(self) -> str:
        return (
            f"the word order (now {self.word_order!r}), the unit id and the register map ({self.map.source}) "
            "against the PLC's documentation"
        )

    def _start(self, action: str, axes: tuple[int, ...]) -> None:
        """Start ``action`` (move/spin/stop) on ``axes`` with the map's control scheme (set-points written)."""
        m = self.map
        value = m.commands[action]
        if m.scheme == "per-axis":
            assert m.axis_command is not None
            words = [m.axis_command[a] for a in axes]
            if len(words) > 1 and words == list(range(words[0], words[0] + len(words))):
                self._write(f"{action} (control words)", words[0], [value] * len(words))
            else:
                for a, w in zip(axes, words, strict=True):
                    self._write(f"{action} ({AXIS_NAMES[a]} control word)", w, [value])
        elif action == "spin":
            if not m.start_coils and m.holding.get("command") == m.holding["command_axis"] + 1:
                self._write("spin", m.holding["command_axis"], [axes[0], value])  # axis and command in one write
                return
            self._write("spin (axis)", m.holding["command_axis"], [axes[0]])
        if m.start_coils:
            self._coil(f"{action} (start coil)", m.start_coils[action])
        elif m.scheme != "per-axis":
            self._write(action, m.holding["command"], [value])

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
        a = check_angles(angles, self._limits)  # type: ignore[arg-type]
        m = self.map
        self._write("move_to (set-points)", m.holding["position_setpoint"], m.pack([x / m.angle_scale for x in a]))
        self._start("move", (0, 1, 2))
        self._rate_demand = [None, None, None]

    def spin(self, axis: int, rate: float) -> None:
        """Command a constant rate (rad/s, signed) on gimbal ``axis`` (0 outer, 1 middle, 2 inner)."""
        ax, r = check_spin(axis, rate, self._limits)  # type: ignore[arg-type]
        m = self.map
        self._write("spin (set-point)", m.holding["rate_setpoint"] + m.value_regs * ax, m.pack(r / m.rate_scale))
        self._start("spin", (ax,))
        self._rate_demand[ax] = r

    def stop(self) -> None:
        """Bring every axis to rest under control."""
        self._start("stop", (0, 1, 2))
        self._rate_demand = [None, None, None]

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
        status = m.status_from(field("status")[0])
        if "AT_RATE" not in m.status_bits:  # the PLC has no "at rate" bit: judged here from the demand
            at = [
                md == AxisMode.RATE and d is not None and abs(float(rat[i]) - d) <= self.rate_tol
                for i, (md, d) in enumerate(zip(modes, self._rate_demand, strict=True))
            ]
            status = status | TableStatus.AT_RATE if any(at) else status & ~TableStatus.AT_RATE
        state = TableState(
            time=t,
            angles=ang,
            rates=rat,
            status=status,
            fault_code=fault,
            modes=modes,  # type: ignore[arg-type]
        )
        check_plausible(state, self._limits, self._last_state, self._hint)  # type: ignore[arg-type]
        self._last_state = state
        return state

    def heartbeat(self) -> None:
        """Feed the controller's watchdog (writes an incrementing counter); nothing where the map has none."""
        if not self.map.has_heartbeat:
            return
        self._hb = (self._hb + 1) & 0xFFFF
        self._write("heartbeat", self.map.holding["heartbeat"], [self._hb])

    def clear_fault(self) -> None:
        """Reset a latched fault (the table stays at rest)."""
        self._write("clear_fault", self.map.holding["fault_reset"], [1])

    def close(self) -> None:
        """Release the driver (the client is the caller's to close)."""
        self._closed = True
