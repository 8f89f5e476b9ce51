"""A Modbus turntable's register map as data: a YAML file, validated, used by the driver and the simulator.

The shipped map (``drivers/modbus/maps/tablebench.yaml``) is the tablebench controller's; a PLC table with
another layout is described by another file named in the bench (``turntable.modbus_map``), not by code.
Every mistake in a map file is a :class:`~core.yaml_source.ConfigError` naming file, line and key.

Keys (see the shipped file for a complete example):

``addressing``
    ``0-based`` (the numbers are PDU addresses, as on the wire) or ``1-based`` (register numbers as HMI tools
    and many manuals print them: 1 → address 0). Pinned here, once: nothing else adds or subtracts 1.
``word_order``
    ``big`` (most significant 16-bit word first) or ``little``, for multi-register values.
``value_type``
    ``float64`` (4 registers), ``float32`` (2) or ``int32`` (2, signed) for time, angles, rates, set-points
    and limits; ``scale`` converts a register value to SI (``angle`` rad, ``rate`` rad/s, ``time`` s per
    unit; e.g. a PLC in degrees: ``angle: 0.017453292519943295``).
``holding``
    command registers: ``position_setpoint`` (3 values), ``rate_setpoint`` (3 values), ``command_axis``,
    ``command``, ``heartbeat``, ``fault_reset`` (one register each). ``heartbeat`` is optional (a PLC without a
    watchdog: the driver then sends no heartbeat); ``command_axis`` and ``command`` are optional where the
    control scheme does not use them (below).
``control`` (optional; default ``scheme: command-register``)
    how motion is started, the part that varies between PLC families:

    * ``scheme: command-register`` — one command register (``holding.command``, values in ``commands:``) and,
      for a spin, the axis in ``holding.command_axis``: the tablebench controller's scheme;
    * ``scheme: per-axis`` — one control word per axis, ``axis_command: [outer, middle, inner]`` (addresses);
      a move writes ``commands.move`` to all three words (one write when they are consecutive), a spin
      ``commands.spin`` to the spinning axis's word, a stop ``commands.stop`` to all three;
    * ``start_coils: {move: C, spin: C, stop: C}`` (either scheme, optional) — after the set-points (and, per
      axis, the control words) the driver switches coil C on (function code 5) to start the action, instead of
      writing the command register (``commands`` then only name the control-word values, if any).

    A status register without an ``AT_RATE`` bit (``status_bits``) is allowed: the driver then reports
    AT_RATE itself when a rate-mode axis reads within its rate tolerance of the demanded rate.
``state_registers``, ``state``
    where the state is read (``input``: function code 4, or ``holding``: 3) and its fields: ``time`` (1 value),
    ``angles`` (3), ``rates`` (3), ``status``, ``fault_code``, ``mode`` (3 registers), ``last_reject``,
    ``heartbeat_echo`` (1 register each) and ``limits`` (12 values: per axis rate_max, accel_max,
    position_min, position_max; NaN = continuous).
``commands``, ``status_bits``, ``modes``, ``fault_codes``
    values of the command register (``move``, ``spin``, ``stop``, ``clear_fault``); bit number of each
    :class:`~drivers.protocols.TableStatus` flag in the status register; register value of each
    :class:`~drivers.protocols.AxisMode`; register value of each :class:`~drivers.protocols.FaultCode`.
"""

from __future__ import annotations

import dataclasses
import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from core.yaml_source import ConfigError, KeyPath, SourceMap, check_keys, get_mapping, get_number, get_str, load_yaml
from drivers.protocols import AxisMode, FaultCode, TableStatus

DEFAULT_MAP = Path(__file__).resolve().parent / "maps" / "tablebench.yaml"
VALUE_TYPES = {"float64": 4, "float32": 2, "int32": 2}
OPTIONAL_HOLDING = ("command_axis", "command", "heartbeat")
HOLDING_FIELDS = {
    "position_setpoint": 3,
    "rate_setpoint": 3,
    "command_axis": 0,
    "command": 0,
    "heartbeat": 0,
    "fault_reset": 0,
}
STATE_FIELDS = {
    "time": 1,
    "angles": 3,
    "rates": 3,
    "status": 0,
    "fault_code": 0,
    "mode": -3,
    "last_reject": 0,
    "heartbeat_echo": 0,
    "limits": 12,
}
"""Field sizes: n > 0 = n values (value_type), 0 = one register, -3 = three registers."""
COMMANDS = ("move", "spin", "stop", "clear_fault")
SCHEMES = ("command-register", "per-axis")
COIL_ACTIONS = ("move", "spin", "stop")


class WordOrderConflict(ConfigError):
    """A float word order given by a bench contradicts the register map's (nothing was sent)."""


@dataclass(frozen=True)
class ModbusMap:
    """A validated register map; addresses are 0-based wire addresses."""

    name: str
    source: str
    word_order: str
    value_type: str
    angle_scale: float
    rate_scale: float
    time_scale: float
    holding: dict[str, int]
    state_registers: str
    state: dict[str, int]
    commands: dict[str, int]
    status_bits: dict[str, int]
    modes: dict[str, int]
    fault_codes: dict[str, int] = field(default_factory=dict)
    scheme: str = "command-register"
    axis_command: tuple[int, int, int] | None = None
    start_coils: dict[str, int] = field(default_factory=dict)

    @property
    def has_heartbeat(self) -> bool:
        """True when the PLC has a heartbeat register (a watchdog to feed)."""
        return "heartbeat" in self.holding

    @property
    def value_regs(self) -> int:
        """Registers per value."""
        return VALUE_TYPES[self.value_type]

    def size(self, name: str) -> int:
        """Registers of a holding or state field."""
        n = HOLDING_FIELDS.get(name, STATE_FIELDS.get(name, 0))
        return self.value_regs * n if n > 0 else (1 if n == 0 else -n)

    def state_span(self) -> tuple[int, int]:
        """(first address, register count) of every state field but the limits: one read gives a TableState."""
        names = [n for n in STATE_FIELDS if n != "limits"]
        lo = min(self.state[n] for n in names)
        hi = max(self.state[n] + self.size(n) for n in names)
        return lo, hi - lo

    # ---- values ----------------------------------------------------------------------------------------------
    def pack(self, values: Sequence[float] | float) -> list[int]:
        """Value(s) in register units → registers (value_type, word order)."""
        vals = [float(values)] if isinstance(values, (int, float)) else [float(v) for v in values]
        out: list[int] = []
        for v in vals:
            if self.value_type == "float64":
                words = list(struct.unpack(">4H", struct.pack(">d", v)))
            elif self.value_type == "float32":
                words = list(struct.unpack(">2H", struct.pack(">f", v)))
            else:
                if not math.isfinite(v) or not -(2**31) <= round(v) < 2**31:
                    raise ValueError(f"{v!r} does not fit an int32 register pair")
                words = list(struct.unpack(">2H", struct.pack(">i", int(round(v)))))
            out.extend(words if self.word_order == "big" else words[::-1])
        return out

    def unpack(self, registers: Sequence[int]) -> list[float]:
        """Registers (a multiple of value_regs) → values in register units."""
        n = self.value_regs
        if len(registers) % n:
            raise ValueError(f"{self.value_type} needs a multiple of {n} registers, got {len(registers)}")
        fmt = {"float64": ">d", "float32": ">f", "int32": ">i"}[self.value_type]
        out = []
        for i in range(0, len(registers), n):
            words = [int(r) & 0xFFFF for r in registers[i : i + n]]
            if self.word_order == "little":
                words = words[::-1]
            out.append(float(struct.unpack(fmt, struct.pack(f">{n}H", *words))[0]))
        return out

    def status_from(self, raw: int) -> TableStatus:
        """Status register → TableStatus."""
        st = TableStatus.NONE
        for name, bit in self.status_bits.items():
            if raw >> bit & 1:
                st |= TableStatus[name]
        return st

    def status_to(self, status: TableStatus) -> int:
        """TableStatus → status register."""
        return sum(1 << bit for name, bit in self.status_bits.items() if status & TableStatus[name])

    def mode_from(self, raw: int) -> AxisMode:
        """Mode register → AxisMode (ValueError if the map has no such value)."""
        for name, v in self.modes.items():
            if v == raw:
                return AxisMode[name]
        raise ValueError(f"mode value {raw} is not in the map's modes {self.modes}")

    def fault_from(self, raw: int) -> FaultCode:
        """Fault register → FaultCode (ValueError if unknown)."""
        for name, v in self.fault_codes.items():
            if v == raw:
                return FaultCode[name]
        raise ValueError(f"fault value {raw} is not in the map's fault_codes")

    def fault_to(self, code: FaultCode) -> int:
        """FaultCode → register value."""
        return self.fault_codes.get(FaultCode(code).name, int(code))


def _int(d: dict, smap: SourceMap, p: KeyPath, key: str, lo: int, hi: int) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        raise smap.error(p + (key,), f"expected a whole number in [{lo}, {hi}], got {v!r}")
    return v


def _table(
    d: Any, smap: SourceMap, p: KeyPath, names: Sequence[str], lo: int, hi: int, required: bool
) -> dict[str, int]:
    m = get_mapping(d, smap, p)
    check_keys(m, smap, p, list(names))
    if required:
        missing = [n for n in names if n not in m]
        if missing:
            raise smap.error(p, f"missing {', '.join(missing)}")
    out = {n: _int(m, smap, p, n, lo, hi) for n in names if n in m}
    seen: dict[int, str] = {}
    for n, v in out.items():
        if v in seen:
            raise smap.error(p + (n,), f"value {v} is also used by {seen[v]}")
        seen[v] = n
    return out


def map_with_word_order(
    register_map: ModbusMap | None, word_order: str | None, where: str = "float_word_order"
) -> ModbusMap:
    """The register map a client or a server uses: ``register_map`` (None: the shipped one).

    ``word_order`` ("big" or "little"; ValueError otherwise) selects the word order of the shipped tablebench
    controller, whose word order is a controller setting. With a map of the bench's own, the map is the
    authority: a ``word_order`` that contradicts it is a :class:`WordOrderConflict` naming both (``where`` is
    the setting's place, e.g. the bench file's line) — raised before anything is sent.
    """
    if word_order is not None and word_order not in ("big", "little"):
        raise ValueError(f"float word order must be 'big' or 'little', got {word_order!r}")
    if register_map is not None:
        if word_order is not None and word_order != register_map.word_order:
            raise WordOrderConflict(
                where,
                None,
                f"float_word_order {word_order!r} contradicts the register map {register_map.source} "
                f"(word_order: {register_map.word_order}); remove float_word_order or correct the map",
            )
        return register_map
    m = load_modbus_map()
    return m if word_order is None else dataclasses.replace(m, word_order=word_order)


def load_modbus_map(path: str | Path = DEFAULT_MAP) -> ModbusMap:
    """Load and validate a register-map file (ConfigError with file:line and key on any mistake)."""
    data, smap, _ = load_yaml(path)
    if data is None:
        raise ConfigError(str(path), None, "the register map file is empty; see drivers/modbus/register_map.py")
    root = get_mapping(data, smap, ())
    keys = [
        "name",
        "addressing",
        "word_order",
        "value_type",
        "scale",
        "holding",
        "state_registers",
        "state",
        "commands",
        "status_bits",
        "modes",
        "fault_codes",
        "control",
    ]
    check_keys(root, smap, (), keys)
    for k in ("addressing", "holding", "state", "commands", "status_bits", "modes"):
        if k not in root:
            raise smap.error((k,), "is required")
    base = {"0-based": 0, "1-based": 1}[get_str(root, smap, (), "addressing", choices=["0-based", "1-based"])]
    sc = get_mapping(root.get("scale") or {}, smap, ("scale",))
    check_keys(sc, smap, ("scale",), ["angle", "rate", "time"])
    scale = {
        k: get_number(sc, smap, ("scale",), k, 1.0, minimum=0, exclusive_minimum=True)
        for k in ("angle", "rate", "time")
    }
    holding = _table(root["holding"], smap, ("holding",), list(HOLDING_FIELDS), base, 65535, False)
    missing = [n for n in HOLDING_FIELDS if n not in holding and n not in OPTIONAL_HOLDING]
    if missing:
        raise smap.error(("holding",), f"missing {', '.join(missing)}")
    state = _table(root["state"], smap, ("state",), list(STATE_FIELDS), base, 65535, True)
    holding = {k: v - base for k, v in holding.items()}
    state = {k: v - base for k, v in state.items()}
    fault_names = [f.name for f in FaultCode]
    scheme, axis_command, coils = _control(root.get("control"), smap, base)
    m = ModbusMap(
        name=get_str(root, smap, (), "name", ""),
        source=str(path),
        word_order=get_str(root, smap, (), "word_order", "big", choices=["big", "little"]),
        value_type=get_str(root, smap, (), "value_type", "float64", choices=list(VALUE_TYPES)),
        angle_scale=scale["angle"],
        rate_scale=scale["rate"],
        time_scale=scale["time"],
        holding=holding,
        state_registers=get_str(root, smap, (), "state_registers", "input", choices=["input", "holding"]),
        state=state,
        commands=_table(root["commands"], smap, ("commands",), COMMANDS, 1, 65535, True),
        status_bits=_table(
            root["status_bits"],
            smap,
            ("status_bits",),
            [f.name for f in TableStatus if f.name and f != TableStatus.NONE],
            0,
            15,
            False,
        ),
        modes=_table(root["modes"], smap, ("modes",), [m.name for m in AxisMode], 0, 65535, True),
        fault_codes=(
            _table(root["fault_codes"], smap, ("fault_codes",), fault_names, 0, 65535, True)
            if root.get("fault_codes") is not None
            else {f.name: int(f) for f in FaultCode}
        ),
        scheme=scheme,
        axis_command=axis_command,
        start_coils=coils,
    )
    _check_scheme(m, smap)
    holding_spans = dict(m.holding)
    for i, a in enumerate(m.axis_command or ()):
        holding_spans[f"control.axis_command[{i}]"] = a
    for sect, fields, p in (("holding", holding_spans, ("holding",)), ("state", m.state, ("state",))):
        spans = sorted((a, a + m.size(n), n) for n, a in fields.items())
        for (a0, e0, n0), (a1, _e1, n1) in zip(spans, spans[1:], strict=False):
            if a1 < e0:
                raise smap.error(p + (n1,), f"overlaps {sect}.{n0} (registers {a0 + base}..{e0 - 1 + base})")
    if m.state_registers == "holding":
        for n, a in m.state.items():
            for hn, ha in m.holding.items():
                if a < ha + m.size(hn) and ha < a + m.size(n):
                    raise smap.error(("state", n), f"overlaps holding.{hn} (state_registers: holding)")
    if m.state_span()[1] > 125:
        raise smap.error(("state",), f"the state fields span {m.state_span()[1]} registers; one read allows 125")
    return m


def _control(c: Any, smap: SourceMap, base: int) -> tuple[str, tuple[int, int, int] | None, dict[str, int]]:
    """The ``control`` section: (scheme, per-axis control-word addresses, start coils), 0-based."""
    if c is None:
        return "command-register", None, {}
    p: KeyPath = ("control",)
    cd = get_mapping(c, smap, p)
    check_keys(cd, smap, p, ["scheme", "axis_command", "start_coils"])
    scheme = get_str(cd, smap, p, "scheme", "command-register", choices=list(SCHEMES))
    axis_command = None
    if cd.get("axis_command") is not None:
        ac = cd["axis_command"]
        if not (isinstance(ac, list) and len(ac) == 3 and all(type(a) is int and base <= a <= 65535 for a in ac)):
            raise smap.error(p + ("axis_command",), f"expected 3 register numbers [outer, middle, inner] >= {base}")
        if len(set(ac)) != 3:
            raise smap.error(p + ("axis_command",), "the three control words must be different registers")
        axis_command = (ac[0] - base, ac[1] - base, ac[2] - base)
    coils = {}
    if cd.get("start_coils") is not None:
        coils = {
            k: v - base
            for k, v in _table(cd["start_coils"], smap, p + ("start_coils",), COIL_ACTIONS, base, 65535, True).items()
        }
    return scheme, axis_command, coils


def _check_scheme(m: ModbusMap, smap: SourceMap) -> None:
    """Every register the control scheme writes is in the map."""
    if m.scheme == "per-axis":
        if m.axis_command is None:
            raise smap.error(("control", "scheme"), "per-axis needs control.axis_command: [outer, middle, inner]")
        need: list[str] = []
    else:
        if m.axis_command is not None:
            raise smap.error(("control", "axis_command"), "is only for scheme: per-axis")
        need = ["command_axis"] + ([] if m.start_coils else ["command"])
    missing = [n for n in need if n not in m.holding]
    if missing:
        raise smap.error(("holding",), f"missing {', '.join(missing)} (control scheme {m.scheme})")


__all__ = ["DEFAULT_MAP", "ModbusMap", "WordOrderConflict", "load_modbus_map", "map_with_word_order"]
