"""Compile a loaded procedure to typed steps (:mod:`procedures.steps`) for one table and one unit mounting (pure).

Attitudes follow :mod:`analysis.gimbal`: gimbal angles (outer ψ about n-Up, middle θ, inner γ), rad,
C_t^n = R_z(ψ) R_x(θ) R_y(γ) in ENU, and C_b^n = C_t^n C_b^t with the bench's mounting C_b^t.

A rotation about a *body* axis (``step_rotate``, ``spin``) is realised by the one gimbal whose rotation
axis coincides with that body axis at the current attitude: the gimbal axes expressed in the body frame
are

- outer: C_n^b e_z (n-Up),
- middle: C_n^b R_z(ψ) e_x,
- inner: C_t^b e_y,

and turning gimbal j by +δ turns the body by +δ about gimbal axis j (a body-frame rotation, since that
axis is fixed in the body while j turns). The gimbal is picked numerically (|cos| > 1 − 1e-9) and the sign
of the command is the sign of the cosine. Successive steps accumulate on that gimbal, unwrapped. Every
target is checked against the position limits, every spin rate against ``rate_max``.

When an ``orient`` attitude has several gimbal solutions (the two ZXY Euler branches, the one-parameter
family at gimbal lock |θ| = 90°, 2π shifts on limited axes), the compiler takes the first one, in the
order [principal ``euler_from_body_to_nav`` solution, other branch, lock family], that is within the
position limits and, if the next rotation before another orient is about a body axis, has a gimbal aligned
with that axis. Continuous axes are given in (−180°, 180°].
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.gimbal import body_to_nav, euler_from_body_to_nav, table_to_nav
from analysis.units import DEG
from core.yaml_source import ConfigError
from drivers.protocols import AXIS_NAMES, AxisLimits

from .loader import (
    Attitude,
    GroupSpec,
    HoldSpec,
    NoteSpec,
    OrientSpec,
    Procedure,
    RampSpec,
    RepeatSpec,
    SoakSpec,
    SpinSpec,
    StepRotateSpec,
    StepSpec,
    WarmupSpec,
)
from .steps import (
    CompiledProcedure,
    Hold,
    Move,
    Note,
    Ramp,
    Soak,
    Spin,
    Step,
    Warmup,
    describe_attitude,
    spin_angle,
)

ALIGN_TOL = 1e-9
"""Gimbal/body axis alignment tolerance on 1 − |cos| (≈ 0.009°)."""
MAX_STEPS = 100_000
"""Largest number of leaf steps after expanding repeats."""
DEFAULT_SETTLE = 2.0
"""Default settling time after IN_POSITION / AT_RATE, s, when neither the step nor the file says."""

_BODY_VEC = {"x": np.array([1.0, 0.0, 0.0]), "y": np.array([0.0, 1.0, 0.0]), "z": np.array([0.0, 0.0, 1.0])}
_GIMBAL_PREFERENCE = (2, 1, 0)  # inner first: least moving mass, usually the fastest axis


@dataclass(frozen=True)
class _Leaf:
    spec: StepSpec
    group: str
    suffix: str


def gimbal_axes_in_body(angles: Sequence[float], mounting: np.ndarray | None = None) -> np.ndarray:
    """Unit rotation axes of the (outer, middle, inner) gimbals in body frame b at ``angles`` (rad): rows of (3, 3)."""
    a = np.asarray(angles, dtype=float)
    c_bn = body_to_nav(a, mounting)
    c_tn = table_to_nav(a)
    psi = a[0]
    axes_n = np.array([[0.0, 0.0, 1.0], [math.cos(psi), math.sin(psi), 0.0], c_tn[:, 1]])
    return axes_n @ c_bn  # row i: (C_n^b a_i)ᵀ = a_iᵀ C_b^n


def aligned_gimbals(
    angles: Sequence[float], body_axis: str, mounting: np.ndarray | None = None
) -> list[tuple[int, float]]:
    """Gimbals whose axis lies along signed body axis ``body_axis`` (e.g. ``"-y"``) at ``angles`` (rad).

    Returns
    -------
    list of (gimbal index, sign)
        In order of preference (inner, middle, outer); ``sign`` = +1 if a positive gimbal rotation is a
        positive rotation about ``body_axis``, −1 if negative.
    """
    u = _BODY_VEC[body_axis[-1]] * (-1.0 if body_axis.startswith("-") else 1.0)
    g = gimbal_axes_in_body(angles, mounting)
    out = []
    for j in _GIMBAL_PREFERENCE:
        c = float(g[j] @ u)
        if 1.0 - abs(c) < ALIGN_TOL:
            out.append((j, math.copysign(1.0, c)))
    return out


def _wrap(a: float) -> float:
    w = math.remainder(a, 2 * math.pi)
    return math.pi if w <= -math.pi + 1e-12 else w


def _fit_limits(angles: np.ndarray, limits: Sequence[AxisLimits]) -> np.ndarray | None:
    """Shift each angle by multiples of 2π into the axis' limits (continuous axes: into (−π, π]); None if impossible."""
    out = np.empty(3)
    for i, (a, lim) in enumerate(zip(angles, limits, strict=True)):
        w = _wrap(float(a))
        if lim.continuous:
            out[i] = w
            continue
        fits = [w + 2 * math.pi * k for k in (0, -1, 1, -2, 2) if lim.allows_position(w + 2 * math.pi * k)]
        if not fits:
            return None
        out[i] = fits[0]
    return out


def attitude_candidates(c_bn: np.ndarray, mounting: np.ndarray | None = None) -> list[np.ndarray]:
    """Every distinct gimbal-angle solution (rad, wrapped) realising body attitude C_b^n, principal first."""
    p = euler_from_body_to_nav(c_bn, mounting)
    cands = [p, np.array([p[0] + math.pi, math.pi - p[1], p[2] + math.pi])]
    if abs(math.cos(p[1])) < 1e-9:
        s = math.copysign(1.0, math.sin(p[1]))  # at lock only ψ + s γ matters
        for g in (0.0, math.pi / 2, -math.pi / 2, math.pi):
            cands.append(np.array([p[0] + s * p[2] - s * g, p[1], g]))
    out: list[np.ndarray] = []
    for c in cands:
        w = np.array([_wrap(float(x)) for x in c])
        if not np.allclose(body_to_nav(w, mounting), c_bn, atol=1e-9):
            continue
        if not any(np.allclose(w, o, atol=1e-12) for o in out):
            out.append(w)
    return out


class _Compiler:
    def __init__(
        self,
        proc: Procedure,
        limits: Sequence[AxisLimits],
        mounting: np.ndarray | None,
        settle: float,
        chamber: tuple[float, float] | None = None,
    ) -> None:
        self.chamber = chamber
        self.proc = proc
        self.file = proc.path or "<procedure>"
        self.limits = tuple(limits)
        self.mounting = mounting
        self.settle = settle
        self.steps: list[Step] = []
        self.starts: list[tuple[float, float, float] | None] = []
        self.current: np.ndarray | None = None
        self.spun_axis: int | None = None  # gimbal whose angle is only nominal after a spin
        self.names: set[str] = set()

    # ---- helpers -------------------------------------------------------------------------------------
    def err(self, line: int | None, name: str, message: str) -> ConfigError:
        return ConfigError(self.file, line, f"step {name!r}: {message}")

    def unique(self, name: str) -> str:
        if name not in self.names:
            self.names.add(name)
            return name
        k = 2
        while f"{name}#{k}" in self.names:
            k += 1
        self.names.add(f"{name}#{k}")
        return f"{name}#{k}"

    def full(self, group: str, base: str, suffix: str) -> str:
        return self.unique(f"{group}/{base}{suffix}" if group else f"{base}{suffix}")

    def add(self, step_type: type[Step], **kw: Any) -> None:
        if len(self.steps) >= 2 * MAX_STEPS:
            raise self.err(
                kw.get("line"),
                str(kw.get("name")),
                f"the procedure compiles to more than {2 * MAX_STEPS} steps; reduce counts",
            )
        self.starts.append(
            None if self.current is None else (float(self.current[0]), float(self.current[1]), float(self.current[2]))
        )
        self.steps.append(step_type(index=len(self.steps), **kw))

    def settle_of(self, spec_settle: float | None) -> float:
        if spec_settle is not None:
            return spec_settle
        if self.proc.defaults.settle is not None:
            return self.proc.defaults.settle
        return self.settle

    def check_position(self, angles: np.ndarray, line: int | None, name: str, fix: str) -> None:
        for i, (a, lim) in enumerate(zip(angles, self.limits, strict=True)):
            if not lim.allows_position(a):
                raise self.err(
                    line,
                    name,
                    f"the {AXIS_NAMES[i]} gimbal would go to {a / DEG:.3f}°, outside the table's limits "
                    f"{lim.position_range_text()}; allowed: targets within the limits ({fix})",
                )

    def known_attitude(self, line: int | None, name: str, what: str) -> np.ndarray:
        if self.current is None:
            raise self.err(
                line, name, f"{what} needs a known attitude; allowed: put an orient step (or warmup with at:) before it"
            )
        if self.spun_axis is not None:
            raise self.err(
                line,
                name,
                f"{what} after a spin: the {AXIS_NAMES[self.spun_axis]} gimbal stopped at an unknown angle; "
                "allowed: put an orient step after the spin",
            )
        return self.current

    def resolve_attitude(self, att: Attitude, line: int | None, name: str, next_axis: str | None) -> np.ndarray:
        if att.angles is not None:
            target = np.asarray(att.angles, dtype=float)
            self.check_position(target, line, name, "change angles_deg")
            return target
        c_bn = att.matrix()
        assert c_bn is not None
        cands = attitude_candidates(c_bn, self.mounting)
        fitted = [f for f in (_fit_limits(c, self.limits) for c in cands) if f is not None]
        if not fitted:
            first = cands[0]
            self.check_position(first, line, name, "this attitude is not reachable on this table")
            raise self.err(line, name, f"attitude {att.words()} is not reachable within the table's position limits")
        if next_axis is not None:
            for f in fitted:
                if aligned_gimbals(f, next_axis, self.mounting):
                    return f
        return fitted[0]

    # ---- kinds ---------------------------------------------------------------------------------------
    def compile(self) -> CompiledProcedure:
        leaves: list[_Leaf] = []
        self.flatten(self.proc.steps, "", "", leaves)
        for i, leaf in enumerate(leaves):
            spec, group, suffix = leaf.spec, leaf.group, leaf.suffix
            if isinstance(spec, NoteSpec):
                self.add(Note, name=self.full(group, "note", suffix), group=group, line=spec.line, text=spec.text)
            elif isinstance(spec, WarmupSpec):
                self.warmup(spec, group, suffix, self.next_rotation_axis(leaves, i + 1))
            elif isinstance(spec, OrientSpec):
                self.orient(spec, group, suffix, self.next_rotation_axis(leaves, i + 1))
            elif isinstance(spec, HoldSpec):
                self.hold(spec, group, suffix)
            elif isinstance(spec, StepRotateSpec):
                self.step_rotate(spec, group, suffix)
            elif isinstance(spec, SpinSpec):
                self.spin(spec, group, suffix)
            elif isinstance(spec, SoakSpec):
                self.soak(spec, group, suffix)
            elif isinstance(spec, RampSpec):
                self.ramp(spec, group, suffix)
            else:  # pragma: no cover - the loader allows no other leaf kinds
                raise self.err(spec.line, spec.label, f"cannot compile step kind {spec.kind!r}")
        m = None if self.mounting is None else tuple(tuple(float(x) for x in row) for row in self.mounting)
        return CompiledProcedure(
            name=self.proc.name,
            description=self.proc.description,
            steps=tuple(self.steps),
            text=self.proc.text,
            sha256=self.proc.sha256,
            path=self.proc.path,
            start_angles=tuple(self.starts),
            mounting=m,  # type: ignore[arg-type]
            parameters=dict(self.proc.parameters),
        )

    def flatten(self, specs: Sequence[StepSpec], group: str, suffix: str, out: list[_Leaf]) -> None:
        for spec in specs:
            if isinstance(spec, GroupSpec):
                self.flatten(spec.steps, spec.group, suffix, out)
            elif isinstance(spec, RepeatSpec):
                for k in range(1, spec.count + 1):
                    self.flatten(spec.steps, group, f"{suffix}@{k}" if spec.count > 1 else suffix, out)
            elif isinstance(spec, RampSpec):
                out.append(_Leaf(spec, group, suffix))
                count = self.ramp_repeats(spec)
                for k in range(1, count + 1):
                    self.flatten(spec.steps, group, f"{suffix}~{k}", out)
            else:
                out.append(_Leaf(spec, group, suffix))
                if len(out) > MAX_STEPS:
                    raise self.err(
                        spec.line,
                        spec.label,
                        f"the procedure expands to more than {MAX_STEPS} steps; reduce repeat counts",
                    )

    @staticmethod
    def next_rotation_axis(leaves: Sequence[_Leaf], start: int) -> str | None:
        for leaf in leaves[start:]:
            if isinstance(leaf.spec, (StepRotateSpec, SpinSpec)):
                return leaf.spec.axis
            if isinstance(leaf.spec, OrientSpec) or (isinstance(leaf.spec, WarmupSpec) and leaf.spec.at is not None):
                return None
        return None

    # ---- chamber steps (docs/methods/thermal.md) -------------------------------------------------------
    def check_temperature(self, t: float, line: int | None, name: str) -> None:
        if self.chamber is None:
            raise self.err(
                line, name, "this step needs a temperature chamber; the bench has none (add a chamber: section)"
            )
        lo, hi = self.chamber
        if not lo - 1e-9 <= t <= hi + 1e-9:
            raise self.err(
                line,
                name,
                f"{t - 273.15:g} °C is outside the chamber's set-point limits [{lo - 273.15:g}, {hi - 273.15:g}] °C "
                "of the bench; allowed: a temperature inside them",
            )

    def soak(self, spec: SoakSpec, group: str, suffix: str, base: str | None = None) -> None:
        name = self.full(group, base or spec.name or "soak", suffix)
        self.check_temperature(spec.setpoint, spec.line, name)
        self.add(
            Soak,
            name=name,
            group=group,
            line=spec.line,
            text=f"soak at {spec.setpoint - 273.15:g} °C",
            setpoint=spec.setpoint,
            target=spec.setpoint + spec.self_heating,
            tolerance=spec.tolerance,
            rate_limit=spec.rate_limit,
            dwell=spec.dwell,
            timeout=spec.timeout,
        )

    def ramp_repeats(self, spec: RampSpec) -> int:
        """How many times the ramp's table sequence runs to cover the ramp (its bench time estimated)."""
        from dataclasses import replace

        sub = _Compiler(replace(self.proc, steps=spec.steps), self.limits, self.mounting, self.settle, self.chamber)
        seq = sub.compile()
        t, cur = 0.0, None
        for st in seq.steps:
            dt, cur = st.bench_time(self.limits, cur)
            t += dt
        if t <= 0:
            raise self.err(spec.line, spec.label, "the ramp's steps take no time; give a table sequence that acquires")
        return max(1, math.ceil(abs(spec.end - spec.start) / spec.rate / t))

    def ramp(self, spec: RampSpec, group: str, suffix: str) -> None:
        base = spec.name or "ramp"
        self.check_temperature(spec.end, spec.line, self.full(group, base, suffix))
        assert spec.soak is not None
        self.soak(spec.soak, group, suffix, base=f"{base}-soak")
        self.add(
            Ramp,
            name=self.full(group, f"{base}-start", suffix),
            group=group,
            line=spec.line,
            text=f"ramp to {spec.end - 273.15:g} °C",
            start=spec.start,
            end=spec.end,
            ramp_rate=spec.rate,
            ramp_time=abs(spec.end - spec.start) / spec.rate,
        )

    def warmup(self, spec: WarmupSpec, group: str, suffix: str, next_axis: str | None) -> None:
        name = self.full(group, spec.name or "warmup", suffix)
        if spec.at is not None:
            target = self.resolve_attitude(spec.at, spec.line, name, next_axis)
            self.current, self.spun_axis = target, None
            where = spec.at.words()
        else:
            where = "the current attitude"
        angles = None if self.current is None or self.spun_axis is not None else tuple(float(x) for x in self.current)
        self.add(
            Warmup,
            name=name,
            group=group,
            angles=angles,
            duration=spec.duration,
            settle=self.settle_of(spec.settle),
            line=spec.line,
            text=f"warm up {spec.duration:g} s at {where}",
        )

    def orient(self, spec: OrientSpec, group: str, suffix: str, next_axis: str | None) -> None:
        name = self.full(group, spec.name or "orient", suffix)
        target = self.resolve_attitude(spec.attitude, spec.line, name, next_axis)
        self.add(
            Move,
            name=name,
            group=group,
            angles=tuple(float(x) for x in target),
            line=spec.line,
            text=f"orient {spec.attitude.words()}",
        )
        self.current, self.spun_axis = target, None

    def add_hold(
        self, name: str, group: str, angles: Iterable[float], duration: float, settle: float | None, line: int | None
    ) -> None:
        """Append a static hold of ``duration`` s at gimbal ``angles`` (rad)."""
        self.add(
            Hold,
            name=name,
            group=group,
            angles=tuple(float(x) for x in angles),
            duration=duration,
            settle=self.settle_of(settle),
            line=line,
            text=f"hold {duration:g} s",
        )

    def hold(self, spec: HoldSpec, group: str, suffix: str) -> None:
        name = self.full(group, spec.name or "hold", suffix)
        cur = self.known_attitude(spec.line, name, "a hold")
        self.add_hold(name, group, cur, spec.duration, spec.settle, spec.line)

    def pick_gimbal(self, angles: np.ndarray, body_axis: str, line: int | None, name: str) -> tuple[int, float]:
        found = aligned_gimbals(angles, body_axis, self.mounting)
        if not found:
            ang = ", ".join(f"{a / DEG:.3f}".replace("-0.000", "0.000") for a in angles)
            raise self.err(
                line,
                name,
                f"body axis {body_axis[-1]} is not aligned with any gimbal axis at attitude ({ang})° "
                f"[{describe_attitude(angles, self.mounting)}]; allowed: rotate about a body axis that lies along "
                "a gimbal axis (orient first so that it does)",
            )
        return found[0]

    def step_rotate(self, spec: StepRotateSpec, group: str, suffix: str) -> None:
        base = spec.name or "step"
        hold_base = f"{spec.name}-hold" if spec.name else "hold"
        label = f"{group}/{base}" if group else base
        cur = self.known_attitude(spec.line, label, "a step_rotate")
        j, sign = self.pick_gimbal(cur, spec.axis, spec.line, label)
        body_axis = spec.axis if spec.angle > 0 else ("-" if spec.axis[0] == "+" else "+") + spec.axis[1]
        for k in range(1, spec.count + 1):
            name = self.full(group, f"{base}-{k}", suffix)
            target = cur.copy()
            target[j] += sign * spec.angle
            self.check_position(target, spec.line, name, "fewer or smaller steps, or another base orientation")
            self.add(
                Move,
                name=name,
                group=group,
                angles=tuple(float(x) for x in target),
                axis=j,
                body_axis=body_axis,
                line=spec.line,
                text=f"{spec.angle / DEG:+g}° about body {spec.axis} ({AXIS_NAMES[j]} gimbal), "
                f"{k * spec.angle / DEG:+g}° in all",
            )
            self.current = cur = target
            if spec.hold > 0:
                self.add_hold(
                    self.full(group, f"{hold_base}-{k}", suffix), group, target, spec.hold, spec.settle, spec.line
                )

    def spin(self, spec: SpinSpec, group: str, suffix: str) -> None:
        base = spec.name or "spin"
        label = f"{group}/{base}" if group else base
        if self.current is None:
            raise self.err(spec.line, label, "a spin needs a known attitude; allowed: put an orient step before it")
        j, sign = self.pick_gimbal(self.current, spec.axis, spec.line, label)
        if self.spun_axis is not None and self.spun_axis != j:
            self.known_attitude(spec.line, label, "a spin about another gimbal")
        lim = self.limits[j]
        if spec.settle is not None:
            settle = spec.settle
        elif self.proc.defaults.spin_settle is not None:
            settle = self.proc.defaults.spin_settle
        else:
            settle = self.settle_of(None)
        for r in spec.rates:
            name = self.full(group, f"{base}{'+' if r > 0 else '-'}", suffix)
            if not lim.allows_rate(r):
                raise self.err(
                    spec.line,
                    name,
                    f"spin rate {abs(r) / DEG:g} °/s about body {spec.axis} needs the {AXIS_NAMES[j]} gimbal, whose "
                    f"limit is {lim.rate_max / DEG:g} °/s; allowed: |rate_dps| <= {lim.rate_max / DEG:g}",
                )
            duration = spec.duration if spec.duration is not None else (spec.revolutions or 0.0) * 2 * math.pi / abs(r)
            gimbal_rate = sign * r
            travel = spin_angle(gimbal_rate, duration, settle, lim.accel_max)
            assert self.current is not None
            end = self.current.copy()
            end[j] += travel
            if not lim.continuous:
                lo = min(self.current[j], end[j])
                hi = max(self.current[j], end[j])
                self.check_position(
                    np.where(np.arange(3) == j, lo, self.current), spec.line, name, "spin only on a continuous axis"
                )
                self.check_position(
                    np.where(np.arange(3) == j, hi, self.current), spec.line, name, "spin only on a continuous axis"
                )
            body_axis = spec.axis if r > 0 else ("-" if spec.axis[0] == "+" else "+") + spec.axis[1]
            revs = duration * abs(r) / (2 * math.pi)
            self.add(
                Spin,
                name=name,
                group=group,
                axis=j,
                rate=float(gimbal_rate),
                duration=float(duration),
                settle=settle,
                body_axis=body_axis,
                line=spec.line,
                text=f"spin {abs(r) / DEG:g} °/s about body {body_axis} ({AXIS_NAMES[j]} gimbal), {revs:g} rev counted",
            )
            self.current = end
            self.spun_axis = j


def compile_procedure(
    proc: Procedure,
    *,
    limits: Sequence[AxisLimits],
    mounting: np.ndarray | None = None,
    settle: float = DEFAULT_SETTLE,
    chamber: tuple[float, float] | None = None,
) -> CompiledProcedure:
    """Compile a loaded procedure for a table and a unit mounting (pure: no I/O).

    Parameters
    ----------
    proc : Procedure
        From :func:`procedures.loader.load_procedure`.
    limits : (AxisLimits, AxisLimits, AxisLimits)
        The table's per-axis limits (outer, middle, inner), SI; position limits None for continuous axes.
    mounting : ndarray (3, 3), optional
        C_b^t, the unit's body frame expressed in the inner-gimbal frame (identity if None).
    settle : float
        Settling time after IN_POSITION / AT_RATE, s, used where neither the step nor ``defaults`` sets one.
    chamber : (float, float) or None
        The bench chamber's set-point limits (K); None: the bench has no chamber (``soak`` / ``ramp`` refused).

    Returns
    -------
    CompiledProcedure

    Raises
    ------
    ConfigError
        ``FILE:LINE: step 'NAME': ... allowed ...`` for an unreachable attitude, a position-limit violation,
        a rate above the table's limit, a body axis not aligned with any gimbal, or an unknown attitude.
    """
    if len(limits) != 3:
        raise ValueError(f"limits: expected 3 AxisLimits (outer, middle, inner), got {len(limits)}")
    m = None
    if mounting is not None:
        m = np.asarray(mounting, dtype=float)
        if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0:
            raise ValueError("mounting: expected a proper rotation matrix C_b^t (3×3, orthonormal, det +1)")
    if not settle >= 0:
        raise ValueError(f"settle: expected seconds >= 0, got {settle!r}")
    return _Compiler(proc, limits, m, float(settle), chamber).compile()
