"""Frame descriptions as data: the YAML format that says how an inertial unit's binary frame is laid out.

A description (shipped ones in ``drivers/imu_unit/frames/*.yaml``; the format is documented in
``drivers/imu_unit/frames/README.md``) gives the sync/identifier bytes, the frame length, the fields (offset, type,
byte order, channel, scale and unit), the counter (modulus and step, or the tick rate it counts), the status
fields and what "valid" means, the checksum (algorithm, parameters, coverage, zero padding) and the
configuration *options* the unit's output depends on (delta angle vs rate, g vs Δv, range…). Options are not
in the frame: the bench says how its unit is configured (``unit.frame_options``), and
:func:`compile_format` resolves every scale and unit into SI factors for that configuration and sample rate.

Every mistake in a description is a :class:`~core.yaml_source.ConfigError` naming the description file and
line. The decoder itself lives in :mod:`drivers.imu_unit.decoder`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.units import CELSIUS_ZERO, DEG, DEG_PER_HOUR, FOOT, G0, GAUSS, UG
from core.declare import REQUIRED, CoreReader, Field, Section, integer, text
from core.yaml_source import (
    ConfigError,
    KeyPath,
    SourceMap,
    check_keys,
    get_mapping,
    get_str,
    load_yaml,
)
from drivers.imu_unit.checksums import PRESETS, SUM_KINDS, CrcSpec

FRAMES_DIR = Path(__file__).resolve().parent / "frames"
DEFAULT_FRAME = "tablebench-v1"

TYPES: dict[str, tuple[str, int]] = {
    "uint8": ("u1", 1),
    "int8": ("i1", 1),
    "uint16": ("u2", 2),
    "int16": ("i2", 2),
    "uint24": ("u4", 3),
    "int24": ("i4", 3),
    "uint32": ("u4", 4),
    "int32": ("i4", 4),
    "uint64": ("u8", 8),
    "int64": ("i8", 8),
    "float32": ("f4", 4),
    "float64": ("f8", 8),
}
"""Field type → (numpy kind without byte order, bytes on the wire). 24-bit fields are widened to 32."""

# unit → (SI factor, kind). Kinds: inc (angle increment), rate, acc, dv (velocity increment), temp, time, mag, any
UNITS: dict[str, tuple[float, str]] = {
    "rad": (1.0, "inc"),
    "deg": (DEG, "inc"),
    "rad/s": (1.0, "rate"),
    "deg/s": (DEG, "rate"),
    "deg/h": (DEG_PER_HOUR, "rate"),
    "g": (G0, "acc"),
    "ug": (UG, "acc"),
    "m/s^2": (1.0, "acc"),
    "m/s": (1.0, "dv"),
    "ft/s": (FOOT, "dv"),
    "degC": (1.0, "temp"),
    "degF": (5.0 / 9.0, "temp"),
    "K": (1.0, "temp"),
    "s": (1.0, "time"),
    "us": (1e-6, "time"),
    "ns": (1e-9, "time"),
    "gauss": (GAUSS, "mag"),
    "T": (1.0, "mag"),
    "1": (1.0, "any"),
}
TEMP_OFFSET: dict[str, float] = {"degC": CELSIUS_ZERO, "degF": CELSIUS_ZERO - 32.0 * 5.0 / 9.0, "K": 0.0}

AXES = ("x", "y", "z")
RECORDED = tuple(f"accel_{a}" for a in AXES) + tuple(f"gyro_{a}" for a in AXES)
CHANNEL_KINDS: dict[str, tuple[str, ...]] = {
    **{f"accel_{a}": ("acc", "dv") for a in AXES},
    **{f"gyro_{a}": ("rate", "inc") for a in AXES},
    **{f"incl_{a}": ("acc",) for a in AXES},
    **{f"mag_{a}": ("mag",) for a in AXES},
    "temperature": ("temp",),
    "time": ("time",),
    "latency": ("time",),
    "pps": ("any", "time"),
    "aux": ("any",),
}
"""Channels a field may feed, with the unit kinds allowed. ``temperature`` fields are averaged into one."""

FLAG_BITS: dict[str, int] = {**{ch: i for i, ch in enumerate(RECORDED)}, "temperature": 6, "unit": 7}
"""Normalised per-sample status flags (``ImuBlock.status``): bit set = that channel is invalid.
Bits 0–2 accel x/y/z, 3–5 gyro x/y/z, 6 temperature, 7 a unit-level problem; 0 = every channel valid."""

LOW_WORD_FIRST = "big-low-word-first"
"""Field byte order: big-endian 16-bit words, least significant word first (32-bit integer fields only)."""

_POW2 = re.compile(r"^\s*2\s*(\^|\*\*)\s*([-+]?\d+)\s*$")


DESCRIPTION_KEYS: tuple[str, ...] = (
    "name", "title", "notes", "byte_order", "sync", "length", "options", "fields", "counter", "status",
    "checksum", "time", "trailer", "end",
)  # fmt: skip
"""Top-level keys of a single-layout frame description (a multi-layout one adds ``layouts``)."""


def parse_number(v: Any) -> float | None:
    """A finite number, or a power of two written ``2^-14`` / ``2**-14``; None if neither."""
    if isinstance(v, bool):
        return None
    if isinstance(v, (int, float)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, str):
        m = _POW2.match(v)
        if m:
            return math.ldexp(1.0, int(m.group(2)))
        try:
            x = float(v)
        except ValueError:
            return None
        return x if math.isfinite(x) else None
    return None


@dataclass(frozen=True)
class OptionDesc:
    """A configuration option of the unit (not in the frame). ``choices`` None: a positive number."""

    name: str
    default: Any
    choices: tuple[str, ...] | None
    help: str = ""


@dataclass(frozen=True)
class FieldDesc:
    """One field of the frame. ``scale``/``unit`` may be literal, ``{by: OPTION, values: {...}}`` or
    ``{option: NAME}`` (a numeric option); resolved by :func:`compile_format`."""

    name: str
    offset: int
    type: str
    byte_order: str
    channel: str | None
    scale: Any
    unit: Any
    mux: tuple[tuple[int, str, Any, Any], ...] = ()
    mux_selector: str | None = None
    mux_modulus: int = 0
    sim_value: float = 0.0
    path: KeyPath = ()
    add: Any = 0
    """A constant added after scaling, in the field's unit (literal or selected by option, like ``scale``)."""

    @property
    def size(self) -> int:
        return TYPES[self.type][1]

    def dtype(self) -> np.dtype:
        """numpy dtype of the (widened) value."""
        kind = TYPES[self.type][0]
        return np.dtype(("<" if self.byte_order == "little" else ">") + kind)

    @property
    def low_word_first(self) -> bool:
        """A 32-bit value sent as two big-endian 16-bit words, the least significant word first (ADIS
        ``*_LOW`` / ``*_OUT`` register pairs in a 32-bit burst)."""
        return self.byte_order == LOW_WORD_FIRST


@dataclass(frozen=True)
class CounterDesc:
    """The frame counter: ``modulus`` values, advancing by ``step`` per sample (or tick_hz / sample rate)."""

    field: str
    modulus: int
    step: int | None
    tick_hz: float | None


@dataclass(frozen=True)
class StatusDesc:
    """A status field. ``valid``: ``bits_set`` (bit set = channel valid, ``bits`` map channel → bit),
    ``bits_clear`` (bit set = channel invalid, e.g. a clipping flag; ``bits`` map channel → bit),
    ``zero`` (0 = valid, anything else invalidates ``channels``), ``flags`` (the project's flag bits)."""

    field: str
    valid: str
    bits: tuple[tuple[str, int], ...] = ()
    channels: tuple[str, ...] = ()


@dataclass(frozen=True)
class ChecksumDesc:
    """Where the checksum sits and what it covers: bytes [start, end) then ``pad`` zero bytes."""

    spec: CrcSpec
    offset: int
    start: int
    end: int
    pad: int
    byte_order: str


@dataclass(frozen=True)
class FrameDescription:
    """A loaded frame description (validated; scales and units still depend on options)."""

    name: str
    title: str
    path: str
    sync: bytes
    length: int
    byte_order: str
    fields: tuple[FieldDesc, ...]
    counter: CounterDesc | None
    status: tuple[StatusDesc, ...]
    checksum: ChecksumDesc | None
    options: tuple[OptionDesc, ...]
    time_field: str | None = None
    time_modulus: int = 0
    trailer: bytes = b""
    end: bytes = b""
    """Constant bytes closing every frame (inside ``length``), checked like the checksum (Epson's CR)."""
    notes: str = ""
    smap: SourceMap = field(default_factory=lambda: SourceMap("<description>"), repr=False, compare=False)
    alternates: tuple[tuple[str, FrameDescription], ...] = ()
    """Multi-layout descriptions ("length by identifier"): the other layouts as (role, description), role
    ``data`` (decoded into samples like the primary layout, which is this description's own fields) or
    ``bit`` (built-in-test frames: recognised and counted, kept for the caller, never samples) or ``other``
    (another message the unit interleaves, e.g. the HG4930's control message: checked, counted, skipped)."""

    def field_named(self, name: str) -> FieldDesc:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(name)

    def option_named(self, name: str) -> OptionDesc:
        for o in self.options:
            if o.name == name:
                return o
        raise KeyError(name)


# ---- loading ----------------------------------------------------------------------------------------


def shipped_frames() -> list[str]:
    """Names of the shipped frame descriptions (``drivers/imu_unit/frames/*.yaml``)."""
    return sorted(p.stem for p in FRAMES_DIR.glob("*.yaml"))


def frame_path(name_or_path: str, base_dir: str | Path | None = None) -> Path:
    """The description file for a shipped name (``kvh-1750-a``; also the layouts in ``frames/parts/`` that are
    only used inside other descriptions, e.g. ``kvh-1750-bit-aa``) or a path (``.yaml``, relative to base_dir)."""
    s = str(name_or_path)
    if s.endswith((".yaml", ".yml")) or "/" in s or "\\" in s:
        p = Path(s).expanduser()
        if not p.is_absolute() and base_dir is not None:
            p = Path(base_dir) / p
        return p
    for p in (FRAMES_DIR / f"{s}.yaml", FRAMES_DIR / "parts" / f"{s}.yaml"):
        if p.exists():
            return p
    raise KeyError(s)


def load_frame(name_or_path: str, base_dir: str | Path | None = None) -> FrameDescription:
    """Load and validate a frame description by shipped name or path.

    Raises
    ------
    ConfigError
        Unknown name (the message lists the shipped ones) or a bad description (file:line).
    """
    try:
        path = frame_path(name_or_path, base_dir)
    except KeyError:
        raise ConfigError(
            str(name_or_path),
            None,
            f"unknown frame format; shipped: {', '.join(shipped_frames())} (or give a path to a .yaml description)",
        ) from None
    data, smap, _text = load_yaml(path)
    return parse_description(data, smap)


def _int(d: dict, smap: SourceMap, p: KeyPath, key: str, default: Any = None, lo: int = 0, hi: int = 1 << 62) -> int:
    if key not in d or d[key] is None:
        if default is None:
            raise smap.error(p + (key,), "is required (an integer)")
        return int(default)
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, int):
        raise smap.error(p + (key,), f"expected an integer (decimal or 0x hex), got {v!r}")
    if not lo <= v <= hi:
        raise smap.error(p + (key,), f"{v} is out of range; allowed [{lo}, {hi}]")
    return int(v)


class _FrameReader(CoreReader):
    """A frame description's reader (:mod:`core.declare`): core's accessors and messages, integers as this
    format writes them (decimal or 0x hex, with its own messages)."""

    def read(self, f: Field, d: Any, smap: SourceMap, path: KeyPath, default: Any) -> Any:
        if f.kind == "integer":
            dflt = None if default is REQUIRED else default
            return _int(dict(d), smap, path, f.key, dflt, int(f.minimum or 0), int(f.maximum or 0))
        return super().read(f, d, smap, path, default)


FRAME_READER = _FrameReader()
BYTE_ORDERS = ("big", "little")

DESCRIPTION = Section(
    text("name"),
    text("byte_order", "big", choices=BYTE_ORDERS),
    integer("length", REQUIRED, 2, 4096),
    order=DESCRIPTION_KEYS,
    reader=FRAME_READER,
)
"""A single-layout description's own keys; ``sync``, ``trailer``, ``title``, ``notes`` and the sub-sections are
read by :func:`parse_description` (byte lists; free text; sections of their own)."""
FIELD = Section(
    text("name"),
    text("type", choices=list(TYPES)),
    text("byte_order", choices=[*BYTE_ORDERS, LOW_WORD_FIRST]),
    order=["name", "offset", "type", "byte_order", "channel", "scale", "unit", "mux", "sim_value", "add"],
    reader=FRAME_READER,
)
"""One entry of ``fields`` (``byte_order`` defaults to the frame's; ``offset`` is bounded by the frame's length;
``channel``, ``scale``, ``unit``, ``mux``, ``sim_value`` and ``add`` may come from options, read by
:func:`_parse_field`)."""
MUX = Section(text("selector"), integer("modulus", REQUIRED, 1, 256), extra=["slots"], reader=FRAME_READER)
"""A multiplexed field's ``mux``."""
MUX_SLOT = Section(text("channel", choices=list(CHANNEL_KINDS)), extra=["scale", "unit"], reader=FRAME_READER)
"""One slot of a ``mux``."""
COUNTER = Section(
    integer("modulus", REQUIRED, 2, 1 << 64), order=["field", "modulus", "step", "tick_hz"], reader=FRAME_READER
)
"""``counter`` (its ``field`` names a field; ``step`` is bounded by the modulus; ``tick_hz`` a positive number)."""
STATUS = Section(
    text("valid", choices=["bits_set", "bits_clear", "zero", "flags"]),
    order=["field", "valid", "bits", "channels"],
    reader=FRAME_READER,
)
"""One entry of ``status``."""
TIME = Section(integer("modulus", 0, 0, 1 << 64), order=["field", "modulus"], reader=FRAME_READER)
"""``time``: a time-stamp field used as bench time."""


def _bytes(d: dict, smap: SourceMap, p: KeyPath, key: str, required: bool) -> bytes:
    v = d.get(key)
    if v is None:
        if required:
            raise smap.error(p + (key,), "is required (a list of byte values like [0xFE, 0x81])")
        return b""
    if not isinstance(v, list) or not v:
        raise smap.error(p + (key,), f"expected a non-empty list of byte values like [0xFE, 0x81], got {v!r}")
    out = bytearray()
    for i, b in enumerate(v):
        if isinstance(b, bool) or not isinstance(b, int) or not 0 <= b <= 255:
            raise smap.error(p + (key, i), f"expected a byte value 0…255 (e.g. 0x55), got {b!r}")
        out.append(b)
    return bytes(out)


def _check_selectable(v: Any, smap: SourceMap, p: KeyPath, options: dict[str, OptionDesc], what: str) -> None:
    """Validate a literal / {by, values} / {option} scale or unit (recursively)."""
    if isinstance(v, dict):
        if "option" in v:
            check_keys(v, smap, p, ["option"])
            o = options.get(v["option"])
            if o is None or o.choices is not None:
                raise smap.error(p + ("option",), f"{v['option']!r} is not a numeric option of this description")
            if what != "scale":
                raise smap.error(p, "only a scale can come from a numeric option")
            return
        check_keys(v, smap, p, ["by", "values"])
        by = v.get("by")
        o = options.get(by) if isinstance(by, str) else None
        if o is None or o.choices is None:
            raise smap.error(p + ("by",), f"{by!r} is not a choice option of this description ({', '.join(options)})")
        vals = v.get("values")
        if not isinstance(vals, dict):
            raise smap.error(p + ("values",), "expected a mapping choice: value")
        missing = [c for c in o.choices if c not in vals and str(c) not in {str(k) for k in vals}]
        if missing:
            raise smap.error(p + ("values",), f"no value for choice(s) {', '.join(map(str, missing))} of {by!r}")
        for k, sub in vals.items():
            _check_selectable(sub, smap, p + ("values", str(k)), options, what)
        return
    if what == "scale":
        if parse_number(v) is None:
            raise smap.error(p, f"expected a number or a power of two like 2^-14, got {v!r}")
    elif not isinstance(v, str) or v not in UNITS:
        raise smap.error(p, f"unknown unit {v!r}; known: {', '.join(UNITS)}")


def parse_description(data: Any, smap: SourceMap) -> FrameDescription:
    """Validate parsed YAML into a :class:`FrameDescription` (errors name the file and line)."""
    if data is None:
        raise ConfigError(smap.file, None, "the frame description is empty; see drivers/imu_unit/frames/README.md")
    d = get_mapping(data, smap, ())
    if "layouts" in d:
        return _parse_layouts(d, smap)
    top = DESCRIPTION.read(d, smap, ())
    name, order, length = top["name"], top["byte_order"], top["length"]
    sync = _bytes(d, smap, (), "sync", True)
    end = _bytes(d, smap, (), "end", False)
    if len(sync) + len(end) >= length:
        raise smap.error(("sync",), f"{len(sync) + len(end)} sync/end bytes leave nothing of a {length}-byte frame")
    options = _parse_options(d, smap)
    occupied = np.zeros(length, dtype=bool)
    occupied[: len(sync)] = True
    occupied[length - len(end) :] = True
    fields = _parse_fields(d, smap, length, order, options, occupied)
    names = {f.name for f in fields}
    time_field, time_mod = _parse_time(d, smap, fields)
    return FrameDescription(
        name=name,
        title=str(d.get("title", name)),
        path=smap.file,
        sync=sync,
        length=length,
        byte_order=order,
        fields=tuple(fields),
        counter=_parse_counter(d, smap, names),
        status=_parse_status(d, smap, names),
        checksum=_parse_checksum(d, smap, length, order, occupied),
        options=tuple(options.values()),
        time_field=time_field,
        time_modulus=time_mod,
        trailer=_bytes(d, smap, (), "trailer", False),
        end=end,
        notes=str(d.get("notes", "")),
        smap=smap,
    )


def _parse_options(d: dict, smap: SourceMap) -> dict[str, OptionDesc]:
    """``options``: the unit's configuration the output depends on (choices, or a positive number)."""
    options: dict[str, OptionDesc] = {}
    od = d.get("options") or {}
    if not isinstance(od, dict):
        raise smap.error(("options",), "expected a mapping option-name: {default, choices}")
    for oname, spec in od.items():
        p = ("options", str(oname))
        spec = get_mapping(spec, smap, p)
        check_keys(spec, smap, p, ["default", "choices", "help"])
        ch = spec.get("choices")
        if ch is None:
            dv = parse_number(spec.get("default"))
            if dv is None or dv <= 0:
                raise smap.error(p + ("default",), "a numeric option needs a positive default (or give choices)")
            options[str(oname)] = OptionDesc(str(oname), dv, None, str(spec.get("help", "")))
            continue
        if not isinstance(ch, list) or not ch or not all(isinstance(c, (str, int, float)) for c in ch):
            raise smap.error(p + ("choices",), "expected a list of choices like [rate, delta_angle]")
        choices = tuple(str(c) for c in ch)
        default = str(spec.get("default", choices[0]))
        if default not in choices:
            raise smap.error(p + ("default",), f"{default!r} is not one of the choices {', '.join(choices)}")
        options[str(oname)] = OptionDesc(str(oname), default, choices, str(spec.get("help", "")))
    return options


def _parse_fields(
    d: dict, smap: SourceMap, length: int, order: str, options: dict[str, OptionDesc], occupied: NDArray[np.bool_]
) -> list[FieldDesc]:
    """``fields``: each field inside the frame, none overlapping (``occupied`` is updated)."""
    fl = d.get("fields")
    if not isinstance(fl, list) or not fl:
        raise smap.error(("fields",), "is required (a list of {name, offset, type, …})")
    fields: list[FieldDesc] = []
    names: set[str] = set()
    for i, fd in enumerate(fl):
        f = _parse_field(fd, smap, ("fields", i), length, order, options, occupied)
        if f.name in names:
            raise smap.error(f.path + ("name",), f"field name {f.name!r} is used twice")
        names.add(f.name)
        fields.append(f)
    for f in fields:
        if f.mux_selector is not None and f.mux_selector not in names:
            raise smap.error(f.path + ("mux", "selector"), f"no field named {f.mux_selector!r}")
    return fields


def _parse_field(
    fd: Any,
    smap: SourceMap,
    p: KeyPath,
    length: int,
    order: str,
    options: dict[str, OptionDesc],
    occupied: NDArray[np.bool_],
) -> FieldDesc:
    """One entry of ``fields``."""
    fd = get_mapping(fd, smap, p)
    declared = FIELD.read(fd, smap, p, {"byte_order": order})
    fname, ftype, forder = declared["name"], declared["type"], declared["byte_order"]
    off = _int(fd, smap, p, "offset", None, 0, length - 1)
    size = TYPES[ftype][1]
    if off + size > length:
        raise smap.error(p + ("offset",), f"{fname} ({ftype}) at {off} runs past the {length}-byte frame")
    if occupied[off : off + size].any():
        raise smap.error(
            p + ("offset",), f"{fname} at bytes {off}…{off + size - 1} overlaps the sync, end bytes or another field"
        )
    occupied[off : off + size] = True
    if forder == LOW_WORD_FIRST and ftype not in ("int32", "uint32"):
        raise smap.error(p + ("byte_order",), f"{LOW_WORD_FIRST} is for int32/uint32 fields, not {ftype}")
    channel = fd.get("channel")
    if channel is not None and (not isinstance(channel, str) or channel not in CHANNEL_KINDS):
        raise smap.error(p + ("channel",), f"unknown channel {channel!r}; known: {', '.join(CHANNEL_KINDS)}")
    scale = fd.get("scale", 1)
    unit = fd.get("unit", "1")
    mux: list[tuple[int, str, Any, Any]] = []
    selector, modulus = None, 0
    if fd.get("mux") is not None:
        selector, modulus, mux = _parse_mux(fd["mux"], smap, p + ("mux",), options)
    else:
        _check_selectable(scale, smap, p + ("scale",), options, "scale")
        _check_selectable(unit, smap, p + ("unit",), options, "unit")
    add = fd.get("add", 0)
    if add != 0 and (fd.get("mux") is not None or channel is None):
        raise smap.error(p + ("add",), "only a plain field with a channel takes add (the value of a raw 0)")
    _check_selectable(add, smap, p + ("add",), options, "scale")
    sim_value = parse_number(fd.get("sim_value", 0))
    if sim_value is None:
        raise smap.error(p + ("sim_value",), "expected a number")
    return FieldDesc(fname, off, ftype, forder, channel, scale, unit, tuple(mux), selector, modulus, sim_value, p, add)


def _parse_mux(
    m: Any, smap: SourceMap, mp: KeyPath, options: dict[str, OptionDesc]
) -> tuple[str, int, list[tuple[int, str, Any, Any]]]:
    """A multiplexed field's ``mux``: (selector field, modulus, [(slot, channel, scale, unit)])."""
    md = get_mapping(m, smap, mp)
    declared = MUX.read(md, smap, mp)
    selector, modulus = declared["selector"], declared["modulus"]
    slots = get_mapping(md.get("slots"), smap, mp + ("slots",))
    mux: list[tuple[int, str, Any, Any]] = []
    for k, sd in slots.items():
        sp = mp + ("slots", str(k))
        sd = get_mapping(sd, smap, sp)
        MUX_SLOT.reader.check_keys(sd, smap, sp, MUX_SLOT.keys())
        try:
            slot = int(k)
        except ValueError:
            raise smap.error(sp, f"slot {k!r} must be an integer 0…{modulus - 1}") from None
        sch = MUX_SLOT.read(sd, smap, sp, check=False)["channel"]
        mux.append((slot, sch, sd.get("scale", 1), sd.get("unit", "1")))
        _check_selectable(sd.get("scale", 1), smap, sp + ("scale",), options, "scale")
        _check_selectable(sd.get("unit", "1"), smap, sp + ("unit",), options, "unit")
    return selector, modulus, mux


def _parse_counter(d: dict, smap: SourceMap, names: set[str]) -> CounterDesc | None:
    """``counter``: {field, modulus, step} or {field, modulus, tick_hz}."""
    if d.get("counter") is None:
        return None
    p: KeyPath = ("counter",)
    cd = get_mapping(d["counter"], smap, p)
    COUNTER.reader.check_keys(cd, smap, p, COUNTER.keys())
    cf = get_str(cd, smap, p, "field", choices=sorted(names))
    modulus = COUNTER.read(cd, smap, p, check=False)["modulus"]
    if "step" in cd and "tick_hz" in cd:
        raise smap.error(p, "give step or tick_hz, not both")
    step = _int(cd, smap, p, "step", 1, 1, modulus // 2) if "tick_hz" not in cd else None
    tick = parse_number(cd.get("tick_hz")) if "tick_hz" in cd else None
    if "tick_hz" in cd and (tick is None or tick <= 0):
        raise smap.error(p + ("tick_hz",), "expected a positive number of Hz")
    return CounterDesc(cf, modulus, step, tick)


def _parse_status(d: dict, smap: SourceMap, names: set[str]) -> tuple[StatusDesc, ...]:
    """``status``: list of {field, valid: bits_set|bits_clear|zero|flags, bits, channels}."""
    status: list[StatusDesc] = []
    sl = d.get("status") or []
    if not isinstance(sl, list):
        raise smap.error(("status",), "expected a list of {field, valid, …}")
    for i, sd in enumerate(sl):
        p: KeyPath = ("status", i)
        sd = get_mapping(sd, smap, p)
        STATUS.reader.check_keys(sd, smap, p, STATUS.keys())
        sf = get_str(sd, smap, p, "field", choices=sorted(names))
        valid = STATUS.read(sd, smap, p, check=False)["valid"]
        bits: list[tuple[str, int]] = []
        chans: tuple[str, ...] = ()
        if valid in ("bits_set", "bits_clear"):
            bd = get_mapping(sd.get("bits"), smap, p + ("bits",))
            for ch in bd:
                if ch not in FLAG_BITS:
                    raise smap.error(p + ("bits", str(ch)), f"unknown channel {ch!r}; known: {', '.join(FLAG_BITS)}")
                bits.append((str(ch), _int(bd, smap, p + ("bits",), ch, None, 0, 63)))
        elif valid == "zero":
            cl = sd.get("channels")
            if not isinstance(cl, list) or any(c not in FLAG_BITS for c in cl):
                raise smap.error(
                    p + ("channels",), f"expected a list (maybe empty) of channels among {', '.join(FLAG_BITS)}"
                )
            chans = tuple(cl)
        status.append(StatusDesc(sf, valid, tuple(bits), chans))
    return tuple(status)


CHECKSUM_KEYS = [
    "algorithm",
    "width",
    "poly",
    "init",
    "refin",
    "refout",
    "xorout",
    "offset",
    "covers",
    "pad_to",
    "byte_order",
]
CHECKSUM = Section(text("algorithm", "custom"), order=CHECKSUM_KEYS, reader=FRAME_READER)
"""``checksum``: the algorithm here; a custom CRC's parameters (:data:`CRC`), the offset (bounded by the frame),
``covers``, ``pad_to`` and ``byte_order`` (the frame's by default) are read by :func:`_parse_checksum`."""
CRC = Section(
    integer("width", REQUIRED, 8, 32),
    integer("poly", REQUIRED, 1, (1 << 32) - 1),
    integer("init", 0, 0, (1 << 32) - 1),
    integer("xorout", 0, 0, (1 << 32) - 1),
    reader=FRAME_READER,
)
"""A ``custom`` checksum's CRC parameters (``refin``/``refout`` are read as truth values)."""


def _checksum_spec(cd: dict, smap: SourceMap, p: KeyPath) -> CrcSpec:
    """The checksum algorithm: a preset name, or ``custom`` with its CRC parameters."""
    algo = CHECKSUM.read(cd, smap, p, check=False)["algorithm"]
    if algo in SUM_KINDS or algo in PRESETS:
        return CrcSpec.named(algo)
    if algo != "custom":
        known = ", ".join([*SUM_KINDS, "custom", *PRESETS])
        raise smap.error(p + ("algorithm",), f"unknown algorithm {algo!r}; known: {known}")
    crc = CRC.read(cd, smap, p, check=False)
    spec = CrcSpec(
        "custom",
        crc["width"],
        crc["poly"],
        crc["init"],
        bool(cd.get("refin", False)),
        bool(cd.get("refout", False)),
        crc["xorout"],
    )
    if spec.width not in (8, 16, 32) or spec.poly >= (1 << spec.width):
        raise smap.error(p + ("width",), "width must be 8, 16 or 32 with poly < 2^width")
    return spec


def _parse_checksum(
    d: dict, smap: SourceMap, length: int, order: str, occupied: NDArray[np.bool_]
) -> ChecksumDesc | None:
    """``checksum``: {algorithm, offset, covers: [first, end), pad_to, byte_order}."""
    if d.get("checksum") is None:
        return None
    p: KeyPath = ("checksum",)
    cd = get_mapping(d["checksum"], smap, p)
    CHECKSUM.reader.check_keys(cd, smap, p, CHECKSUM.keys())
    spec = _checksum_spec(cd, smap, p)
    off = _int(cd, smap, p, "offset", None, 0, length - 1)
    if off + spec.nbytes > length:
        raise smap.error(p + ("offset",), f"the {spec.nbytes}-byte checksum at {off} runs past the frame")
    if occupied[off : off + spec.nbytes].any():
        raise smap.error(p + ("offset",), "the checksum overlaps a field or the sync bytes")
    cov = cd.get("covers")
    if not (
        isinstance(cov, list) and len(cov) == 2 and all(isinstance(x, int) and not isinstance(x, bool) for x in cov)
    ):
        raise smap.error(p + ("covers",), "expected [first, end) byte offsets like [0, 32]")
    start, end = int(cov[0]), int(cov[1])
    if not 0 <= start < end <= length or (start < off + spec.nbytes and end > off):
        raise smap.error(p + ("covers",), f"[{start}, {end}) must lie inside the frame and exclude the checksum")
    pad_to = _int(cd, smap, p, "pad_to", 1, 1, 64)
    if spec.algorithm.startswith("sum16-words") and (end - start + (-(end - start)) % pad_to) % 2:
        raise smap.error(
            p + ("covers",), f"{spec.algorithm} sums 16-bit words: [{start}, {end}) must cover an even count"
        )
    return ChecksumDesc(
        spec,
        off,
        start,
        end,
        (-(end - start)) % pad_to,
        get_str(cd, smap, p, "byte_order", order, choices=["big", "little"]),
    )


def _parse_time(d: dict, smap: SourceMap, fields: list[FieldDesc]) -> tuple[str | None, int]:
    """``time``: {field, modulus}, a time-stamp field used as bench time."""
    if d.get("time") is None:
        return None, 0
    p: KeyPath = ("time",)
    td = get_mapping(d["time"], smap, p)
    TIME.reader.check_keys(td, smap, p, TIME.keys())
    time_field = get_str(td, smap, p, "field", choices=sorted(f.name for f in fields))
    if dict((f.name, f.channel) for f in fields)[time_field] != "time":
        raise smap.error(p + ("field",), f"field {time_field!r} must have channel: time")
    return time_field, TIME.read(td, smap, p, check=False)["modulus"]


def _parse_layouts(d: dict, smap: SourceMap) -> FrameDescription:
    """A multi-layout description: ``layouts`` lists descriptions (shipped names or paths relative to this
    file) selected by their sync/identifier bytes, each with a ``role`` (``data`` or ``bit``). The file's own
    layout (if it gives ``sync``) is the primary one, else the first ``data`` layout listed."""
    check_keys(
        d,
        smap,
        (),
        [*DESCRIPTION_KEYS, "layouts"],
    )
    name = get_str(d, smap, (), "name")
    entries = d.get("layouts")
    if not isinstance(entries, list) or not entries:
        raise smap.error(("layouts",), "expected a list of frame names/paths or {frame, role: data|bit|other}")
    own = None
    if "sync" in d:
        own = parse_description({k: v for k, v in d.items() if k != "layouts"}, smap)
    elif any(k in d for k in ("length", "fields", "counter", "status", "checksum", "time", "options")):
        raise smap.error(("layouts",), "a layouts-only description has no own fields; give sync: for its own layout")
    base = Path(smap.file).parent
    layouts: list[tuple[str, FrameDescription, KeyPath]] = []
    for i, e in enumerate(entries):
        p: KeyPath = ("layouts", i)
        role = "data"
        if isinstance(e, dict):
            check_keys(e, smap, p, ["frame", "role"])
            ref = get_str(e, smap, p, "frame")
            role = get_str(e, smap, p, "role", "data", choices=["data", "bit", "other"])
        elif isinstance(e, str):
            ref = e
        else:
            raise smap.error(p, f"expected a frame name/path or {{frame, role}}, got {e!r}")
        try:
            path = frame_path(ref, base)
        except KeyError:
            raise smap.error(p, f"unknown frame format {ref!r}; shipped: {', '.join(shipped_frames())}") from None
        if not path.exists():
            raise smap.error(p, f"frame description {path} not found")
        sub_data, sub_smap, _t = load_yaml(path)
        sub = parse_description(sub_data, sub_smap)
        if sub.alternates:
            raise smap.error(p, f"{ref!r} has layouts of its own; list its layouts here instead (no nesting)")
        layouts.append((role, sub, p))
    if own is None:
        first = next((k for k, (r, _d, _p) in enumerate(layouts) if r == "data"), None)
        if first is None:
            raise smap.error(("layouts",), "needs at least one layout with role: data")
        role0, primary, _p0 = layouts.pop(first)
    else:
        primary = own
    seen = {primary.sync: "the primary layout"}
    options = {o.name: o for o in primary.options}
    for role, sub, p in layouts:
        if sub.sync in seen:
            raise smap.error(p, f"{sub.name} has the same sync/identifier bytes as {seen[sub.sync]}")
        seen[sub.sync] = sub.name
        for o in sub.options:
            if o.name in options and (options[o.name].choices, options[o.name].default) != (o.choices, o.default):
                raise smap.error(p, f"{sub.name} defines option {o.name!r} differently from another layout")
            options.setdefault(o.name, o)
        c, c0 = sub.counter, primary.counter
        if role == "data" and (c is None) != (c0 is None):
            raise smap.error(p, f"{sub.name}: every data layout needs a counter, or none")
        if (
            role == "data"
            and c is not None
            and c0 is not None
            and (c.modulus, c.step, c.tick_hz)
            != (
                c0.modulus,
                c0.step,
                c0.tick_hz,
            )
        ):
            raise smap.error(p, f"{sub.name}: its counter (modulus, step) differs from {primary.name}'s")
    trailer = _bytes(d, smap, (), "trailer", False) or primary.trailer
    return replace(
        primary,
        name=name,
        title=str(d.get("title", name)),
        path=smap.file,
        options=tuple(options.values()),
        trailer=trailer,
        notes=str(d.get("notes", primary.notes)),
        alternates=tuple((r, sub) for r, sub, _p in layouts),
    )


# ---- compiling for one configuration ---------------------------------------------------------------------


@dataclass(frozen=True)
class Conversion:
    """raw → SI: ``si = raw * factor + offset``; ``increment``: the raw value is an increment over one sample."""

    channel: str
    factor: float
    offset: float
    increment: bool
    unit: str
    scale: float


@dataclass(frozen=True)
class FrameFormat:
    """A description compiled for one unit configuration and sample rate.

    Attributes
    ----------
    desc : FrameDescription
    options : dict
        Every option's value (defaults filled in).
    sample_rate : float
        Hz; increments are divided by 1 / sample_rate to give rates / specific force.
    conversions : dict
        Field name → :class:`Conversion` (plain fields) or slot → Conversion (multiplexed fields, key
        ``(name, slot)``).
    counter_step : int
        Counter advance per sample (1 if the frame has no counter).
    """

    desc: FrameDescription
    options: dict[str, Any]
    sample_rate: float
    conversions: dict[Any, Conversion]
    counter_step: int
    alternates: tuple[tuple[str, FrameFormat], ...] = ()
    """The description's other layouts compiled for the same configuration (role, format)."""

    @property
    def name(self) -> str:
        return self.desc.name

    @property
    def length(self) -> int:
        return self.desc.length

    def increments(self) -> list[str]:
        """Recorded channels the unit outputs as increments (Δθ, Δv), converted to rates here."""
        return sorted({c.channel for c in self.conversions.values() if c.increment and c.channel in RECORDED})

    def describe(self) -> str:
        """One line: format, options and what is converted (for the recording's events)."""
        opts = ", ".join(f"{k}={v}" for k, v in self.options.items())
        inc = self.increments()
        text = f"frame {self.desc.name} ({self.desc.length} B)" + (f", {opts}" if opts else "")
        if inc:
            text += (
                f"; {'/'.join(inc)} are increments per sample, converted to rate/specific force by dividing by "
                f"the sample interval 1/{self.sample_rate:g} s"
            )
        if self.alternates:
            nd = sum(r == "data" for r, _f in self.alternates)
            no = sum(r == "other" for r, _f in self.alternates)
            nb = len(self.alternates) - nd - no
            skipped = f", {no} skipped message layout(s)" if no else ""
            text += f"; also {nd} other data layout(s){skipped} and {nb} built-in-test layout(s), chosen by identifier"
        return text


def _resolve(v: Any, options: dict[str, Any]) -> Any:
    while isinstance(v, dict):
        if "option" in v:
            return options[v["option"]]
        vals = v["values"]
        key = options[v["by"]]
        v = vals[key] if key in vals else {str(k): x for k, x in vals.items()}[str(key)]
    return v


def _conversion(
    channel: str, scale: Any, unit: Any, options: dict[str, Any], desc: FrameDescription, path: KeyPath, add: Any = 0
) -> Conversion:
    s = parse_number(_resolve(scale, options))
    a = parse_number(_resolve(add, options)) or 0.0
    u = str(_resolve(unit, options))
    assert s is not None
    factor, kind = UNITS[u]
    allowed = CHANNEL_KINDS.get(channel, ("any",))
    if kind not in allowed and "any" not in allowed and kind != "any":
        raise desc.smap.error(path, f"unit {u!r} does not fit channel {channel} (needs a {'/'.join(allowed)} unit)")
    offset = TEMP_OFFSET.get(u, 0.0) + a * factor
    return Conversion(channel, s * factor, offset, kind in ("inc", "dv"), u, s)


def compile_format(
    desc: FrameDescription, options: dict[str, Any] | None, sample_rate: float, where: str = "frame_options"
) -> FrameFormat:
    """Resolve a description for one configuration. Bad options raise ``ValueError`` (the caller locates them).

    Parameters
    ----------
    desc : FrameDescription
    options : dict or None
        Option values (missing ones take the description's defaults).
    sample_rate : float
        Hz.
    where : str
        How the caller names the options in messages.
    """
    opts: dict[str, Any] = {}
    given = dict(options or {})
    known = {o.name: o for o in desc.options}
    for k in given:
        if k not in known:
            raise ValueError(
                f"{where}: unknown option {k!r} for frame {desc.name}; known: {', '.join(known) or '(none)'}"
            )
    for o in desc.options:
        v = given.get(o.name, o.default)
        if o.choices is None:
            x = parse_number(v)
            if x is None or x <= 0:
                raise ValueError(f"{where}.{o.name}: expected a positive number, got {v!r}")
            opts[o.name] = x
        else:
            if str(v) not in o.choices:
                raise ValueError(f"{where}.{o.name}: {v!r} is not allowed; choose one of: {', '.join(o.choices)}")
            opts[o.name] = str(v)
    if not (sample_rate > 0 and math.isfinite(sample_rate)):
        raise ValueError(f"sample rate must be > 0 Hz, got {sample_rate}")
    conv: dict[Any, Conversion] = {}
    for f in desc.fields:
        if f.mux:
            for slot, ch, sc, un in f.mux:
                conv[(f.name, slot)] = _conversion(ch, sc, un, opts, desc, f.path + ("mux", "slots", str(slot)))
        elif f.channel is not None:
            conv[f.name] = _conversion(f.channel, f.scale, f.unit, opts, desc, f.path, f.add)
    step = 1
    c = desc.counter
    if c is not None:
        if c.tick_hz is not None:
            ratio = c.tick_hz / sample_rate
            if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
                raise ValueError(
                    f"frame {desc.name}: the counter counts {c.tick_hz:g} Hz ticks, so the sample rate must divide "
                    f"{c.tick_hz:g} Hz (got {sample_rate:g} Hz)"
                )
            step = int(round(ratio))
        else:
            step = int(c.step or 1)
        if step > c.modulus // 2:
            raise ValueError(f"frame {desc.name}: counter step {step} is too large for modulus {c.modulus}")
    alternates = tuple(
        (role, compile_format(sub, {o.name: opts[o.name] for o in sub.options}, sample_rate, where))
        for role, sub in desc.alternates
    )
    return FrameFormat(desc, opts, float(sample_rate), conv, step, alternates)
