"""Procedure files: read, validate and convert to SI (the schema is documented in ``procedures/SCHEMA.md``).

A procedure file is YAML with degrees, °/s and seconds; :func:`load_procedure` returns a
:class:`Procedure` whose step specifications are SI (rad, rad/s, s) and remember their source line.
Every mistake raises :class:`~core.yaml_source.ConfigError` naming file, line, step and what is
allowed. Attitudes are not resolved here (that needs the bench's mounting and limits): see
:mod:`procedures.compiler`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from analysis.gimbal import ENU_DIRECTIONS
from analysis.units import celsius_to_kelvin, from_display
from core.declare import REQUIRED, Field, Section, number
from core.provenance import text_sha256
from core.yaml_source import ConfigError, KeyPath, SourceMap, load_yaml, load_yaml_text

BODY_AXES: tuple[str, ...] = ("x", "y", "z", "+x", "+y", "+z", "-x", "-y", "-z")
TOP_KEYS: tuple[str, ...] = ("name", "description", "version", "defaults", "parameters", "steps")
DEFAULT_KEYS: tuple[str, ...] = ("settle_s", "hold_s", "spin_settle_s")
MAX_COUNT: int = 10_000
"""Largest ``count`` of a repeat or step_rotate (guards against a typo compiling for ever)."""
MAX_SECONDS: float = 1e7
"""Longest duration (warm-up, hold, spin, settling) a step may ask for, s (≈ 116 days): larger is a typo."""
MAX_REVOLUTIONS: float = 1e5
"""Most revolutions one spin may count."""
MAX_RATE_DPS: float = 36_000.0
"""Largest spin rate a procedure may write, °/s (the bench's own limit is checked by the compiler)."""
_PARAM_RE = re.compile(r"^\$\{?([A-Za-z_][A-Za-z0-9_]*)\}?$")


# ---- the loaded (SI) specification -------------------------------------------------------------------


@dataclass(frozen=True)
class Attitude:
    """A requested attitude: body axes along named ENU directions, or explicit gimbal angles (rad).

    ``directions`` maps body axis (``"x"``, ``"y"``, ``"z"``) to a unit ENU vector (n frame); it is always
    complete (a missing third axis is completed right-handed). ``angles`` are (outer ψ, middle θ, inner γ).
    """

    directions: dict[str, tuple[int, int, int]] | None = None
    angles: tuple[float, float, float] | None = None

    def matrix(self) -> np.ndarray | None:
        """C_b^n (3, 3) for a direction attitude (columns: body axes in ENU), else None."""
        if self.directions is None:
            return None
        return np.array([self.directions[a] for a in "xyz"], dtype=float).T

    def words(self) -> str:
        """``"x East, y North, z Up"`` or ``"angles (0, -90, 0) deg"``."""
        if self.directions is not None:
            inv = {v: k for k, v in ENU_DIRECTIONS.items()}
            return ", ".join(f"{a} {inv[self.directions[a]]}" for a in "xyz")
        assert self.angles is not None
        return "angles (" + ", ".join(f"{np.degrees(a):g}" for a in self.angles) + ") deg"


@dataclass(frozen=True)
class StepSpec:
    """Common fields of a step specification: source line, a label for messages, an optional name.

    ``kind`` (a class attribute) is the step's key in the procedure file.
    """

    kind: ClassVar[str] = ""
    line: int | None
    label: str
    name: str | None


@dataclass(frozen=True)
class WarmupSpec(StepSpec):
    """Warm-up record of ``duration`` s at ``at`` (None: the current/initial attitude)."""

    kind: ClassVar[str] = "warmup"
    duration: float = 0.0
    at: Attitude | None = None
    settle: float | None = None


@dataclass(frozen=True)
class OrientSpec(StepSpec):
    """Move to a base orientation."""

    kind: ClassVar[str] = "orient"
    attitude: Attitude = field(default_factory=Attitude)


@dataclass(frozen=True)
class HoldSpec(StepSpec):
    """Static acquisition of ``duration`` s at the current attitude."""

    kind: ClassVar[str] = "hold"
    duration: float = 0.0
    settle: float | None = None


@dataclass(frozen=True)
class StepRotateSpec(StepSpec):
    """``count`` rotations of ``angle`` rad about signed body axis ``axis``, holding ``hold`` s after each."""

    kind: ClassVar[str] = "step_rotate"
    axis: str = "+z"
    angle: float = 0.0
    count: int = 1
    hold: float = 0.0
    settle: float | None = None


@dataclass(frozen=True)
class SpinSpec(StepSpec):
    """Constant-rate spin(s) about signed body axis ``axis``; ``rates`` rad/s (two entries for both directions)."""

    kind: ClassVar[str] = "spin"
    axis: str = "+z"
    rates: tuple[float, ...] = ()
    revolutions: float | None = None
    duration: float | None = None
    settle: float | None = None


@dataclass(frozen=True)
class RepeatSpec(StepSpec):
    """``steps`` repeated ``count`` times."""

    kind: ClassVar[str] = "repeat"
    count: int = 1
    steps: tuple[StepSpec, ...] = ()


@dataclass(frozen=True)
class GroupSpec(StepSpec):
    """Named group of steps (the name prefixes every compiled step name)."""

    kind: ClassVar[str] = "group"
    group: str = ""
    steps: tuple[StepSpec, ...] = ()


@dataclass(frozen=True)
class NoteSpec(StepSpec):
    """Free text, logged in the recording when reached."""

    kind: ClassVar[str] = "note"
    text: str = ""


@dataclass(frozen=True)
class SoakSpec(StepSpec):
    """Chamber set point and the soak criterion of the unit's temperature, SI (K, K/s, s)."""

    kind: ClassVar[str] = "soak"
    setpoint: float = 0.0
    tolerance: float = 0.5
    rate_limit: float = 0.1 / 60.0
    dwell: float = 600.0
    timeout: float = 4 * 3600.0
    self_heating: float = 0.0


@dataclass(frozen=True)
class RampSpec(StepSpec):
    """A set-point ramp ``start`` → ``end`` (K) at ``rate`` (K/s), soaked at ``start`` first, with ``steps`` (the
    table sequence) repeated until the ramp ends."""

    kind: ClassVar[str] = "ramp"
    start: float = 0.0
    end: float = 0.0
    rate: float = 0.0
    soak: SoakSpec | None = None
    steps: tuple[StepSpec, ...] = ()


@dataclass(frozen=True)
class Defaults:
    """Procedure-wide defaults, s (None: not given, the compiler's default applies)."""

    settle: float | None = None
    hold: float | None = None
    spin_settle: float | None = None


@dataclass(frozen=True)
class Procedure:
    """A loaded, validated procedure (SI), not yet compiled against a bench."""

    name: str
    description: str
    version: str
    defaults: Defaults
    steps: tuple[StepSpec, ...]
    text: str
    sha256: str
    path: str | None
    parameters: dict[str, float] = field(default_factory=dict)


SPEC_TYPES: tuple[type[StepSpec], ...] = (
    WarmupSpec,
    OrientSpec,
    HoldSpec,
    StepRotateSpec,
    SpinSpec,
    RepeatSpec,
    GroupSpec,
    NoteSpec,
    SoakSpec,
    RampSpec,
)
"""The step specifications a procedure file may contain (each class' ``kind`` is its key in the file)."""
_KINDS: tuple[str, ...] = tuple(t.kind for t in SPEC_TYPES)


# ---- parsing ---------------------------------------------------------------------------------------


class _Ctx:
    def __init__(self, smap: SourceMap, defaults: Defaults) -> None:
        self.smap = smap
        self.defaults = defaults

    def err(self, path: KeyPath, label: str, message: str) -> ConfigError:
        return ConfigError(self.smap.file, self.smap.line(path), f"step {label!r}: {message}")


def _optional_duration(ctx: _Ctx, body: Mapping[str, Any], bpath: KeyPath, label: str) -> float | None:
    """The step's optional ``duration_s`` (seconds > 0, at most MAX_SECONDS), or None when absent."""
    return _num(
        ctx, body, bpath, label, "duration_s", required=False, positive=True, maximum=MAX_SECONDS, what="seconds > 0"
    )


def _num(
    ctx: _Ctx,
    d: Mapping[str, Any],
    path: KeyPath,
    label: str,
    key: str,
    *,
    required: bool = True,
    minimum: float | None = None,
    positive: bool = False,
    integer: bool = False,
    maximum: float | None = None,
    what: str = "a number",
) -> float | None:
    if key not in d or d[key] is None:
        if required:
            raise ctx.err(path, label, f"{key} is required ({what})")
        return None
    v = d[key]
    where = path + (key,)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v or v in (float("inf"), float("-inf")):
        raise ctx.err(where, label, f"{key}: expected {what}, got {v!r}")
    if integer and float(v) != int(v):
        raise ctx.err(where, label, f"{key}: expected a whole number, got {v!r}")
    if positive and not v > 0:
        raise ctx.err(where, label, f"{key}: {v!r} is not allowed; must be > 0")
    if minimum is not None and v < minimum:
        raise ctx.err(where, label, f"{key}: {v!r} is not allowed; must be >= {minimum:g}")
    if maximum is not None and v > maximum:
        raise ctx.err(where, label, f"{key}: {v!r} is not allowed; must be <= {maximum:g}")
    return float(v)


def _keys(ctx: _Ctx, d: Mapping[str, Any], path: KeyPath, label: str, allowed: tuple[str, ...]) -> None:
    for k in d:
        if k not in allowed:
            raise ctx.err(path + (str(k),), label, f"unknown key {k!r}; allowed here: {', '.join(allowed)}")


def _body_axis(ctx: _Ctx, d: Mapping[str, Any], path: KeyPath, label: str) -> str:
    v = d.get("axis")
    if v is None:
        raise ctx.err(path, label, "axis is required (a body axis: x, y, z, or signed like -y)")
    if not isinstance(v, str) or v.strip() not in BODY_AXES:
        raise ctx.err(path + ("axis",), label, f"axis: {v!r} is not allowed; choose one of: x, y, z, +x, -x, ... -z")
    s = v.strip()
    return s if s[0] in "+-" else "+" + s


def _attitude(ctx: _Ctx, d: Mapping[str, Any], path: KeyPath, label: str) -> Attitude:
    has_dirs = any(k in d for k in ("x", "y", "z"))
    if has_dirs and "angles_deg" in d:
        raise ctx.err(path, label, "give either body-axis directions (x/y/z) or angles_deg, not both")
    if "angles_deg" in d:
        v = d["angles_deg"]
        if not isinstance(v, list) or len(v) != 3:
            raise ctx.err(
                path + ("angles_deg",), label, f"angles_deg: expected 3 gimbal angles [outer, middle, inner], got {v!r}"
            )
        out = []
        for i, item in enumerate(v):
            if isinstance(item, bool) or not isinstance(item, (int, float)) or item != item:
                raise ctx.err(
                    path + ("angles_deg", i), label, f"angles_deg[{i}]: expected a number (deg), got {item!r}"
                )
            out.append(from_display("angle", float(item)))
        return Attitude(angles=(out[0], out[1], out[2]))
    if not has_dirs:
        raise ctx.err(
            path,
            label,
            "an attitude needs body-axis directions like {x: East, y: North, z: Up} or angles_deg: [ψ, θ, γ]",
        )
    words = {w.lower(): w for w in ENU_DIRECTIONS}
    dirs: dict[str, tuple[int, int, int]] = {}
    for ax in "xyz":
        if ax not in d:
            continue
        v = d[ax]
        if not isinstance(v, str) or v.strip().lower() not in words:
            raise ctx.err(path + (ax,), label, f"{ax}: {v!r} is not a direction; allowed: {', '.join(ENU_DIRECTIONS)}")
        dirs[ax] = ENU_DIRECTIONS[words[v.strip().lower()]]
    if len(dirs) < 2:
        raise ctx.err(path, label, "give the directions of at least two body axes (e.g. x: East, z: Up)")
    given = list(dirs)
    for i, a in enumerate(given):
        for b in given[i + 1 :]:
            if int(np.dot(dirs[a], dirs[b])) != 0:
                raise ctx.err(
                    path + (b,),
                    label,
                    f"body axes {a} and {b} cannot both point along the same line; choose perpendicular directions",
                )
    # Complete / check right-handedness: z = x × y, x = y × z, y = z × x.
    cyc = {"z": ("x", "y"), "x": ("y", "z"), "y": ("z", "x")}
    for ax, (p, q) in cyc.items():
        if p in dirs and q in dirs:
            need = tuple(int(c) for c in np.cross(dirs[p], dirs[q]))
            if ax in dirs and dirs[ax] != need:
                inv = {v: k for k, v in ENU_DIRECTIONS.items()}
                raise ctx.err(
                    path + (ax,),
                    label,
                    f"{ax}: {inv[dirs[ax]]} makes a left-handed frame; with {p} {inv[dirs[p]]} and {q} {inv[dirs[q]]} "
                    f"the allowed direction is {inv[need]}",
                )
            dirs.setdefault(ax, need)  # type: ignore[arg-type]
    return Attitude(directions=dirs)


def _leaf_label(prefix: str, kind: str, name: str | None) -> str:
    base = name or kind
    return f"{prefix}/{base}" if prefix else base


def _parse_steps(ctx: _Ctx, items: Any, path: KeyPath, prefix: str) -> tuple[StepSpec, ...]:
    label_here = prefix or "steps"
    if not isinstance(items, list):
        raise ctx.err(path, label_here, f"steps: expected a list of steps (lines starting with '- '), got {items!r}")
    if not items:
        raise ctx.err(path, label_here, "steps: the list is empty; add at least one step")
    return tuple(_parse_step(ctx, item, path + (i,), prefix) for i, item in enumerate(items))


class _StepReader:
    """Reads declared step fields (:mod:`core.declare`) with the loader's messages: ``step 'label': key: …``."""

    def __init__(self, ctx: _Ctx, label: str) -> None:
        self.ctx, self.label = ctx, label

    def check_keys(self, d: Mapping[str, Any], smap: SourceMap, path: KeyPath, allowed: Sequence[str]) -> None:
        _keys(self.ctx, d, path, self.label, tuple(allowed))

    def read(self, f: Field, d: Mapping[str, Any], smap: SourceMap, path: KeyPath, default: Any) -> Any:
        v = _num(
            self.ctx,
            d,
            path,
            self.label,
            f.key,
            required=default is REQUIRED,
            minimum=None if f.exclusive_minimum else f.minimum,
            positive=f.exclusive_minimum,
            integer=f.kind == "integer",
            maximum=f.maximum,
            what=f.what,
        )
        return default if v is None else v * f.unit


_SETTLE = number("settle_s", None, minimum=0.0, maximum=MAX_SECONDS, what="seconds >= 0", attr="settle")
_POSITIVE_SECONDS = {"minimum": 0.0, "exclusive_minimum": True, "maximum": MAX_SECONDS, "what": "seconds > 0"}
_COUNT = {"minimum": 0.0, "exclusive_minimum": True, "maximum": MAX_COUNT, "what": "a whole number >= 1"}

WARMUP = Section(number("duration_s", **_POSITIVE_SECONDS, attr="duration"), _SETTLE,
                 order=("name", "duration_s", "at", "settle_s"))  # fmt: skip
"""``warmup:`` (``at`` is an attitude, read by :func:`_attitude`)."""
HOLD = Section(number("duration_s", None, **_POSITIVE_SECONDS, attr="duration"), _SETTLE,
               order=("name", "duration_s", "settle_s"))  # fmt: skip
"""``hold:`` (``duration_s`` defaults to the procedure's ``defaults.hold_s``)."""
STEP_ROTATE = Section(
    number("angle_deg", what="degrees, non-zero", attr="angle"),
    Field("count", "integer", default=None, **_COUNT),
    number("hold_s", None, minimum=0.0, maximum=MAX_SECONDS, what="seconds >= 0", attr="hold"),
    _SETTLE,
    order=("name", "axis", "angle_deg", "count", "hold_s", "settle_s"),
)
"""``step_rotate:`` (``axis`` is a signed body axis, read by :func:`_body_axis`)."""
SPIN = Section(
    number("rate_dps", minimum=-MAX_RATE_DPS, maximum=MAX_RATE_DPS, what="°/s, non-zero", attr="rate"),
    number("revolutions", None, minimum=0.0, exclusive_minimum=True, maximum=MAX_REVOLUTIONS, what="a number > 0"),
    number("duration_s", None, **_POSITIVE_SECONDS, attr="duration"),
    _SETTLE,
    order=("name", "axis", "rate_dps", "direction", "revolutions", "duration_s", "settle_s"),
)
"""``spin:`` (``axis`` and ``direction`` are read by hand)."""
REPEAT = Section(Field("count", "integer", **_COUNT), order=("count", "steps"))
"""``repeat:`` (``steps`` is a nested list)."""


def _parse_step(ctx: _Ctx, item: Any, path: KeyPath, prefix: str) -> StepSpec:
    line = ctx.smap.line(path)
    label0 = prefix or f"steps[{path[-1]}]"
    if not isinstance(item, dict) or len(item) != 1:
        raise ctx.err(
            path,
            label0,
            f"each step is one 'kind: {{...}}' entry; kinds allowed: {', '.join(_KINDS)}; got {item!r}",
        )
    kind, body = next(iter(item.items()))
    if kind not in _KINDS:
        raise ctx.err(path + (str(kind),), label0, f"unknown step kind {kind!r}; allowed: {', '.join(_KINDS)}")
    bpath = path + (kind,)
    if kind == NoteSpec.kind:
        if isinstance(body, dict):
            _keys(ctx, body, bpath, _leaf_label(prefix, kind, None), ("text",))
            body = body.get("text")
        if not isinstance(body, str) or not body.strip():
            raise ctx.err(bpath, _leaf_label(prefix, kind, None), f"note: expected text, got {body!r}")
        return NoteSpec(line, _leaf_label(prefix, kind, None), None, text=body.strip())
    if body is None:
        body = {}
    if not isinstance(body, dict):
        raise ctx.err(bpath, _leaf_label(prefix, kind, None), f"{kind}: expected a mapping (key: value), got {body!r}")
    name = body.get("name")
    if name is not None and (not isinstance(name, str) or not re.fullmatch(r"[A-Za-z0-9_.+\-]+", name)):
        raise ctx.err(
            bpath + ("name",),
            _leaf_label(prefix, kind, None),
            f"name: {name!r} is not allowed; use letters, digits, _ . + -",
        )
    step = _StepBody(ctx, line, _leaf_label(prefix, kind, name), name, body, bpath, prefix)
    return _STEP_PARSERS[kind](step)


@dataclass(frozen=True)
class _StepBody:
    """One step's mapping with where it is (the per-kind parsers' argument)."""

    ctx: _Ctx
    line: int | None
    label: str
    name: str | None
    body: dict[str, Any]
    path: KeyPath
    prefix: str

    def read(self, section: Section, check: bool = True) -> dict[str, Any]:
        """The section's declared fields of this step (SI), with the loader's messages."""
        reader = _StepReader(self.ctx, self.label)
        return section.read(self.body, self.ctx.smap, self.path, check=check, reader=reader)

    def check_keys(self, section: Section) -> None:
        """Refuse a key the step kind does not take."""
        _keys(self.ctx, self.body, self.path, self.label, tuple(section.keys()))

    def err(self, key: str | None, message: str) -> ConfigError:
        """An error at the step (``key`` None) or at one of its keys."""
        return self.ctx.err(self.path if key is None else self.path + (key,), self.label, message)


def _warmup(s: _StepBody) -> StepSpec:
    s.check_keys(WARMUP)
    at = None
    if "at" in s.body:
        if not isinstance(s.body["at"], dict):
            raise s.err("at", "at: expected an attitude like {x: East, y: North, z: Up}")
        _keys(s.ctx, s.body["at"], s.path + ("at",), s.label, ("x", "y", "z", "angles_deg"))
        at = _attitude(s.ctx, s.body["at"], s.path + ("at",), s.label)
    v = s.read(WARMUP, check=False)
    return WarmupSpec(s.line, s.label, s.name, duration=v["duration"] or 0.0, at=at, settle=v["settle"])


def _orient(s: _StepBody) -> StepSpec:
    _keys(s.ctx, s.body, s.path, s.label, ("name", "x", "y", "z", "angles_deg"))
    return OrientSpec(s.line, s.label, s.name, attitude=_attitude(s.ctx, s.body, s.path, s.label))


def _hold(s: _StepBody) -> StepSpec:
    v = s.read(HOLD)
    if v["duration"] is None:
        if s.ctx.defaults.hold is None:
            raise s.err(None, "duration_s is required (seconds > 0) unless defaults.hold_s is set")
        v["duration"] = s.ctx.defaults.hold
    return HoldSpec(s.line, s.label, s.name, **v)


def _step_rotate(s: _StepBody) -> StepSpec:
    s.check_keys(STEP_ROTATE)
    axis = _body_axis(s.ctx, s.body, s.path, s.label)
    v = s.read(STEP_ROTATE, check=False)
    ang = v["angle"]
    if ang == 0 or abs(ang) > 360:
        raise s.err("angle_deg", f"angle_deg: {ang:g} is not allowed; use a non-zero angle in [-360, 360]")
    if v["hold"] is None:
        if s.ctx.defaults.hold is None:
            raise s.err(None, "hold_s is required (seconds >= 0) unless defaults.hold_s is set")
        v["hold"] = s.ctx.defaults.hold
    return StepRotateSpec(
        s.line, s.label, s.name, axis=axis, angle=from_display("angle", ang), count=int(v["count"] or 1),
        hold=v["hold"], settle=v["settle"],
    )  # fmt: skip


def _spin(s: _StepBody) -> StepSpec:
    s.check_keys(SPIN)
    axis = _body_axis(s.ctx, s.body, s.path, s.label)
    v = s.read(SPIN, check=False)
    rate = v["rate"]
    if rate == 0:
        raise s.err("rate_dps", "rate_dps: 0 is not allowed; a spin needs a non-zero rate")
    direction = s.body.get("direction")
    if direction is not None:
        if direction not in ("positive", "negative", "both"):
            raise s.err("direction", f"direction: {direction!r} is not allowed; choose positive, negative or both")
        if rate < 0:
            raise s.err("rate_dps", "rate_dps must be positive when direction is given (the sign comes from direction)")
    r = from_display("rate", rate)
    rates = {None: (r,), "positive": (r,), "negative": (-r,), "both": (r, -r)}[direction]
    if (v["revolutions"] is None) == (v["duration"] is None):
        raise s.err(None, "give exactly one of revolutions or duration_s")
    return SpinSpec(
        s.line, s.label, s.name, axis=axis, rates=rates, revolutions=v["revolutions"], duration=v["duration"],
        settle=v["settle"],
    )  # fmt: skip


def _repeat(s: _StepBody) -> StepSpec:
    count = s.read(REPEAT)["count"]
    if "steps" not in s.body:
        raise s.err(None, "steps is required (the list of steps to repeat)")
    steps = _parse_steps(s.ctx, s.body["steps"], s.path + ("steps",), s.prefix)
    return RepeatSpec(s.line, s.label, None, count=int(count or 1), steps=steps)


def _group(s: _StepBody) -> StepSpec:
    _keys(s.ctx, s.body, s.path, s.label, ("name", "steps"))
    if s.name is None:
        raise s.err(None, "name is required (e.g. name: A); it prefixes the group's step names")
    if "steps" not in s.body:
        raise s.err(None, "steps is required (the group's list of steps)")
    gname = f"{s.prefix}/{s.name}" if s.prefix else s.name
    steps = _parse_steps(s.ctx, s.body["steps"], s.path + ("steps",), gname)
    return GroupSpec(s.line, s.label, s.name, group=gname, steps=steps)


_STEP_PARSERS: dict[str, Callable[[_StepBody], StepSpec]] = {
    WarmupSpec.kind: _warmup,
    OrientSpec.kind: _orient,
    HoldSpec.kind: _hold,
    StepRotateSpec.kind: _step_rotate,
    SpinSpec.kind: _spin,
    RepeatSpec.kind: _repeat,
    GroupSpec.kind: _group,
    SoakSpec.kind: lambda s: _parse_thermal(s.ctx, SoakSpec.kind, s.body, s.path, s.label, s.line, s.name, s.prefix),
    RampSpec.kind: lambda s: _parse_thermal(s.ctx, RampSpec.kind, s.body, s.path, s.label, s.line, s.name, s.prefix),
}
"""The parser of each step kind (a new kind: its spec class in ``SPEC_TYPES`` and its parser here)."""


SOAK_KEYS = ("tolerance_k", "rate_k_per_min", "dwell_s", "timeout_s", "self_heating_k")
TEMPERATURE_RANGE_C = (-100.0, 300.0)
"""Plausible chamber temperatures, °C (the bench's own limits are checked by the compiler)."""


def _soak_criterion(
    ctx: _Ctx, body: Mapping[str, Any], bpath: KeyPath, label: str, line: int | None, name: str | None, sp: float
) -> SoakSpec:
    tol = _num(ctx, body, bpath, label, "tolerance_k", required=False, positive=True, maximum=50.0, what="kelvin > 0")
    rate = _num(
        ctx, body, bpath, label, "rate_k_per_min", required=False, positive=True, maximum=100.0, what="K/min > 0"
    )
    dwell = _num(ctx, body, bpath, label, "dwell_s", required=False, minimum=0.0, maximum=MAX_SECONDS, what="s >= 0")
    tout = _num(ctx, body, bpath, label, "timeout_s", required=False, positive=True, maximum=MAX_SECONDS, what="s > 0")
    heat = _num(ctx, body, bpath, label, "self_heating_k", required=False, minimum=-50.0, maximum=50.0, what="kelvin")
    d = SoakSpec(line, label, name)
    return SoakSpec(
        line,
        label,
        name,
        setpoint=sp,
        tolerance=d.tolerance if tol is None else tol,
        rate_limit=d.rate_limit if rate is None else rate / 60.0,
        dwell=d.dwell if dwell is None else dwell,
        timeout=d.timeout if tout is None else tout,
        self_heating=0.0 if heat is None else heat,
    )


def _parse_thermal(
    ctx: _Ctx,
    kind: str,
    body: Mapping[str, Any],
    bpath: KeyPath,
    label: str,
    line: int | None,
    name: str | None,
    prefix: str,
) -> StepSpec:
    """``soak: {setpoint_c, tolerance_k, rate_k_per_min, dwell_s, timeout_s, self_heating_k}`` or
    ``ramp: {from_c, to_c, rate_k_per_min, steps, soak: {the soak keys, for the soak at from_c}}``."""
    lo, hi = TEMPERATURE_RANGE_C
    temp = "°C"
    if kind == SoakSpec.kind:
        _keys(ctx, body, bpath, label, ("name", "setpoint_c") + SOAK_KEYS)
        sp = _num(ctx, body, bpath, label, "setpoint_c", minimum=lo, maximum=hi, what=temp)
        assert sp is not None
        return _soak_criterion(ctx, body, bpath, label, line, name, celsius_to_kelvin(sp))
    _keys(ctx, body, bpath, label, ("name", "from_c", "to_c", "rate_k_per_min", "steps", "soak"))
    t0 = _num(ctx, body, bpath, label, "from_c", minimum=lo, maximum=hi, what=temp)
    t1 = _num(ctx, body, bpath, label, "to_c", minimum=lo, maximum=hi, what=temp)
    rate = _num(ctx, body, bpath, label, "rate_k_per_min", positive=True, maximum=100.0, what="K/min > 0")
    assert t0 is not None and t1 is not None and rate is not None
    if t0 == t1:
        raise ctx.err(bpath + ("to_c",), label, "to_c must differ from from_c (a ramp needs a temperature change)")
    if "steps" not in body:
        raise ctx.err(bpath, label, "steps is required (the table sequence repeated during the ramp)")
    steps = _parse_steps(ctx, body["steps"], bpath + ("steps",), prefix)
    sbody = body.get("soak") or {}
    if not isinstance(sbody, dict):
        raise ctx.err(bpath + ("soak",), label, "soak: expected the soak criterion at from_c, e.g. {tolerance_k: 0.5}")
    _keys(ctx, sbody, bpath + ("soak",), label, SOAK_KEYS)
    soak = _soak_criterion(ctx, sbody, bpath + ("soak",), label, line, name, celsius_to_kelvin(t0))
    return RampSpec(
        line,
        label,
        name,
        start=celsius_to_kelvin(t0),
        end=celsius_to_kelvin(t1),
        rate=rate / 60.0,
        soak=soak,
        steps=steps,
    )


def _settle(ctx: _Ctx, body: Mapping[str, Any], bpath: KeyPath, label: str) -> float | None:
    return _num(
        ctx, body, bpath, label, "settle_s", required=False, minimum=0.0, maximum=MAX_SECONDS, what="seconds >= 0"
    )


def _parameters(data: Mapping[str, Any], smap: SourceMap, overrides: Mapping[str, float] | None) -> dict[str, float]:
    params: dict[str, float] = {}
    raw = data.get("parameters")
    if raw is not None:
        if not isinstance(raw, dict):
            raise smap.error(("parameters",), "expected a mapping of name: number")
        for k, v in raw.items():
            if not isinstance(k, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", k):
                raise smap.error(("parameters", str(k)), f"parameter name {k!r} is not allowed; use letters, digits, _")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise smap.error(("parameters", k), f"expected a finite number (the default value), got {v!r}")
            params[k] = float(v)
    for k, v in (overrides or {}).items():
        if k not in params:
            allowed = ", ".join(params) or "none (the file has no parameters: block)"
            raise ConfigError(
                smap.file, smap.lines.get(("parameters",)), f"unknown parameter {k!r}; allowed: {allowed}"
            )
        params[k] = float(v)
    return params


def _substitute(node: Any, path: KeyPath, params: Mapping[str, float], smap: SourceMap) -> Any:
    if isinstance(node, dict):
        return {k: _substitute(v, path + (k,), params, smap) for k, v in node.items()}
    if isinstance(node, list):
        return [_substitute(v, path + (i,), params, smap) for i, v in enumerate(node)]
    if isinstance(node, str):
        m = _PARAM_RE.match(node.strip())
        if m:
            if m.group(1) not in params:
                allowed = ", ".join(f"${p}" for p in params) or "none (add a top-level parameters: block)"
                raise smap.error(path, f"unknown parameter {node!r}; allowed: {allowed}")
            return params[m.group(1)]
    return node


def parse_procedure(
    data: Any, smap: SourceMap, text: str, path: str | Path | None = None, overrides: Mapping[str, float] | None = None
) -> Procedure:
    """Validate parsed YAML ``data`` (with its source map) and convert it to a :class:`Procedure` (SI)."""
    if not isinstance(data, dict):
        raise ConfigError(smap.file, smap.line(()), "a procedure file is a mapping with name, description, steps")
    for key in data:
        if key not in TOP_KEYS:
            raise smap.error((str(key),), f"unknown key {key!r}; allowed at the top level: {', '.join(TOP_KEYS)}")
    name = data.get("name")
    if not isinstance(name, str) or not name.strip():
        raise smap.error(("name",), f"name is required (text), got {name!r}")
    desc = data.get("description", "")
    if desc is None:
        desc = ""
    if not isinstance(desc, str):
        raise smap.error(("description",), f"expected text, got {desc!r}")
    version = data.get("version", "1")
    if isinstance(version, bool) or not isinstance(version, (str, int, float)):
        raise smap.error(("version",), f"expected a version like 1 or '1.2', got {version!r}")
    params = _parameters(data, smap, overrides)
    data = {k: (_substitute(v, (k,), params, smap) if k in ("defaults", "steps") else v) for k, v in data.items()}
    dd = data.get("defaults") or {}
    if not isinstance(dd, dict):
        raise smap.error(("defaults",), "expected a mapping like {settle_s: 5, hold_s: 60}")
    for k, v in dd.items():
        if k not in DEFAULT_KEYS:
            raise smap.error(("defaults", str(k)), f"unknown key {k!r}; allowed here: {', '.join(DEFAULT_KEYS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= MAX_SECONDS:
            raise smap.error(("defaults", k), f"expected seconds in [0, {MAX_SECONDS:g}], got {v!r}")
    defaults = Defaults(
        settle=None if dd.get("settle_s") is None else float(dd["settle_s"]),
        hold=None if dd.get("hold_s") is None else float(dd["hold_s"]),
        spin_settle=None if dd.get("spin_settle_s") is None else float(dd["spin_settle_s"]),
    )
    if "steps" not in data:
        raise ConfigError(smap.file, smap.line(()), "steps is required (the list of steps)")
    ctx = _Ctx(smap, defaults)
    steps = _parse_steps(ctx, data["steps"], ("steps",), "")
    return Procedure(
        name=name.strip(),
        description=desc.strip(),
        version=str(version),
        defaults=defaults,
        steps=steps,
        text=text,
        sha256=text_sha256(text),
        path=None if path is None else str(path),
        parameters=params,
    )


def load_procedure(path: str | Path, overrides: Mapping[str, float] | None = None) -> Procedure:
    """Load and validate a procedure file.

    Parameters
    ----------
    path : str or Path
        The YAML file.
    overrides : mapping, optional
        Values for the file's ``parameters:`` (file units, e.g. ``{"duration_s": 60}``).

    Raises
    ------
    ConfigError
        Naming file, line, step and what is allowed.
    """
    data, smap, text = load_yaml(path)
    return parse_procedure(data, smap, text, path, overrides)


def load_procedure_text(
    text: str, file: str = "<procedure>", overrides: Mapping[str, float] | None = None
) -> Procedure:
    """Like :func:`load_procedure` for YAML text (tests, embedded procedures)."""
    data, smap = load_yaml_text(text, file)
    return parse_procedure(data, smap, text, None, overrides)
