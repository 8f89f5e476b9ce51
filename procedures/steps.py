"""Compiled procedure steps: the flat, plain list of motion and acquisition commands the runner executes.

Everything here is SI: angles in rad (gimbal angles (outer ψ, middle θ, inner γ), unwrapped), rates in
rad/s (gimbal rate, signed), times in s. The navigation frame n is ENU, the body frame b the unit's case
axes, and C_b^n = R_z(ψ) R_x(θ) R_y(γ) C_b^t (see :mod:`analysis.gimbal`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from analysis.gimbal import body_to_nav
from analysis.units import DEG
from drivers.protocols import AXIS_NAMES, AxisLimits

ACQUISITION_KINDS: tuple[str, ...] = ("warmup", "hold", "spin")
"""Compiled kinds during which samples count."""

COMPILED_KINDS: tuple[str, ...] = ("warmup", "move", "hold", "spin", "note")

_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "East": (1.0, 0.0, 0.0),
    "West": (-1.0, 0.0, 0.0),
    "North": (0.0, 1.0, 0.0),
    "South": (0.0, -1.0, 0.0),
    "Up": (0.0, 0.0, 1.0),
    "Down": (0.0, 0.0, -1.0),
}


@dataclass(frozen=True)
class Step:
    """One compiled step.

    Attributes
    ----------
    index : int
        Position in the compiled list (0-based).
    name : str
        Unique readable name, e.g. ``"A/orient"``, ``"A/hold"``, ``"A/step-3"``, ``"A/hold-3"``, ``"A/spin+"``.
    kind : str
        ``"warmup"`` | ``"move"`` | ``"hold"`` | ``"spin"`` | ``"note"``.
    group : str
        Group path (e.g. ``"A"``; nested groups ``"A/fine"``), ``""`` outside any group.
    angles : tuple of 3 float or None
        Gimbal angles (outer, middle, inner), rad, unwrapped: the target of a move, the attitude held during
        a warmup/hold (None for a spin or note, and for a warmup at the table's unknown initial attitude).
    axis : int or None
        Gimbal axis of a spin (0 outer, 1 middle, 2 inner); for a move produced by a body-axis step, the
        gimbal that realises it (informative); None otherwise.
    rate : float
        Commanded gimbal rate of a spin, rad/s, signed; 0 otherwise.
    duration : float
        Acquisition time that counts, s (warmup/hold; spin at rate); 0 for move/note.
    settle : float
        Time to wait after IN_POSITION / AT_RATE before acquisition counts, s.
    body_axis : str or None
        Signed body axis u (``"+x"``, ``"-y"``, ...) such that the spin's angular velocity points along +u,
        or the step's rotation is a positive rotation about u; None otherwise.
    line : int or None
        Line of the procedure file the step comes from.
    text : str
        Note text, or a one-line human description.
    """

    index: int
    name: str
    kind: str
    group: str
    angles: tuple[float, float, float] | None
    axis: int | None
    rate: float
    duration: float
    settle: float
    body_axis: str | None
    line: int | None
    text: str


def trapezoid_time(distance: float, rate_max: float, accel_max: float) -> float:
    """Time of a rest-to-rest trapezoidal (or triangular) profile over ``distance`` rad at the limits, s."""
    d = abs(float(distance))
    if d == 0.0:
        return 0.0
    v, a = float(rate_max), float(accel_max)
    if d < v * v / a:
        return 2.0 * math.sqrt(d / a)
    return d / v + v / a


def move_time(start: Sequence[float], target: Sequence[float], limits: Sequence[AxisLimits]) -> float:
    """Time for the slowest gimbal to move from ``start`` to ``target`` (rad, unwrapped), s."""
    return max(
        trapezoid_time(float(b) - float(a), lim.rate_max, lim.accel_max)
        for a, b, lim in zip(start, target, limits, strict=True)
    )


def spin_angle(rate: float, duration: float, settle: float, accel_max: float) -> float:
    """Nominal gimbal angle travelled by a spin, rad (signed): ramp up, settle + acquisition, ramp down."""
    ramp = rate * rate / accel_max  # both ramps together: 2 × rate²/(2 a)
    return math.copysign(ramp, rate) + rate * (settle + duration)


def _axis_word(v: np.ndarray) -> str:
    for word, d in _DIRECTIONS.items():
        if np.allclose(v, d, atol=1e-6):
            return word
    # Not cardinal: name the ENU components, e.g. "(E 0.71, U -0.71)"
    parts = [f"{lab} {c:+.2f}" for lab, c in zip("ENU", v, strict=True) if abs(c) > 5e-3]
    return "(" + ", ".join(parts) + ")"


def describe_attitude(angles: Sequence[float] | None, mounting: np.ndarray | None = None) -> str:
    """Body axes in words for gimbal angles (rad), e.g. ``"x East, y North, z Up"``; ``"(current)"`` if None."""
    if angles is None:
        return "(current)"
    c = body_to_nav(np.asarray(angles, dtype=float), mounting)
    return ", ".join(f"{ax} {_axis_word(c[:, i])}" for i, ax in enumerate("xyz"))


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600:d}:{(s % 3600) // 60:02d}:{s % 60:02d}"


@dataclass(frozen=True)
class CompiledProcedure:
    """A procedure compiled against a table's limits and the unit's mounting.

    Attributes
    ----------
    name, description : str
    steps : tuple of Step
    text : str
        The procedure file's text, verbatim (recorded with every run).
    sha256 : str
        SHA-256 of ``text`` (hex).
    path : str or None
    start_angles : tuple
        Nominal gimbal angles (rad) at the start of each step (parallel to ``steps``); None where unknown
        (before the first attitude is set). For a spin, the attitude it starts from.
    mounting : tuple of tuple or None
        C_b^t used to compile (None: identity).
    parameters : dict
        Procedure parameters after overrides (file units, as written in the file).
    """

    name: str
    description: str
    steps: tuple[Step, ...]
    text: str
    sha256: str
    path: str | None
    start_angles: tuple[tuple[float, float, float] | None, ...] = ()
    mounting: tuple[tuple[float, float, float], ...] | None = None
    parameters: dict[str, float] = field(default_factory=dict)

    def _mounting(self) -> np.ndarray | None:
        return None if self.mounting is None else np.asarray(self.mounting, dtype=float)

    def step_times(self, limits: Sequence[AxisLimits]) -> list[float]:
        """Estimated wall (bench) time of each step, s: moves at the limits (trapezoidal), settling, ramps.

        A spin leaves its gimbal at its nominal end angle (unwrapped), so the next move's time includes
        unwinding it; an initial attitude that is unknown counts as no move.
        """
        times: list[float] = []
        current: np.ndarray | None = None
        for step, start in zip(self.steps, self.start_angles or (None,) * len(self.steps), strict=True):
            if current is None and start is not None:
                current = np.asarray(start, dtype=float)
            t = 0.0
            if step.kind in ("move", "hold", "warmup") and step.angles is not None:
                target = np.asarray(step.angles, dtype=float)
                if current is not None:
                    t += move_time(current, target, limits)
                current = target
            if step.kind in ("hold", "warmup"):
                t += step.settle + step.duration
            elif step.kind == "spin" and step.axis is not None:
                lim = limits[step.axis]
                t += 2.0 * abs(step.rate) / lim.accel_max + step.settle + step.duration
                if current is not None:
                    current = current.copy()
                    current[step.axis] += spin_angle(step.rate, step.duration, step.settle, lim.accel_max)
            times.append(t)
        return times

    def estimated_duration(self, limits: Sequence[AxisLimits]) -> float:
        """Estimated total bench time, s, including moves (trapezoidal at ``limits``), settling and spin ramps."""
        return float(sum(self.step_times(limits)))

    def acquisition_time(self) -> float:
        """Total time during which samples count, s."""
        return float(sum(s.duration for s in self.steps if s.kind in ACQUISITION_KINDS))

    def summary(self, limits: Sequence[AxisLimits] | None = None) -> str:
        """A readable table of the steps (attitudes in body-axis words, spins, durations) for the CLI."""
        mounting = self._mounting()
        times = self.step_times(limits) if limits is not None else [float("nan")] * len(self.steps)
        rows = [f"procedure {self.name!r}: {self.description.strip().splitlines()[0] if self.description else ''}"]
        head = f"{'#':>3}  {'step':<18} {'kind':<6} {'line':>4}  {'acq s':>7} {'est s':>7}  attitude / motion"
        rows.append(head)
        rows.append("-" * len(head))
        for step, t in zip(self.steps, times, strict=True):
            if step.kind == "spin":
                what = (
                    f"spin about body {step.body_axis} at {abs(step.rate) / DEG:g} °/s "
                    f"({AXIS_NAMES[step.axis or 0]} gimbal {step.rate / DEG:+g} °/s)"
                )
            elif step.kind == "note":
                what = f"note: {step.text}"
            elif step.kind == "move":
                what = f"→ {describe_attitude(step.angles, mounting)}"
                if step.body_axis is not None:
                    what += f"  [{step.text}]"
            else:
                what = describe_attitude(step.angles, mounting)
            line = "" if step.line is None else str(step.line)
            acq = f"{step.duration:7.1f}" if step.kind in ACQUISITION_KINDS else " " * 7
            est = f"{t:7.1f}" if t == t else " " * 7
            rows.append(f"{step.index:>3}  {step.name:<18} {step.kind:<6} {line:>4}  {acq} {est}  {what}")
        rows.append("-" * len(head))
        n_acq = sum(1 for s in self.steps if s.kind in ACQUISITION_KINDS)
        n_spin = sum(1 for s in self.steps if s.kind == "spin")
        tail = f"{len(self.steps)} steps, {n_acq} acquisitions ({n_spin} spins)"
        tail += f", acquisition {_hms(self.acquisition_time())}"
        if limits is not None:
            tail += f", estimated duration {_hms(self.estimated_duration(limits))} (h:m:s)"
        rows.append(tail)
        return "\n".join(rows)
