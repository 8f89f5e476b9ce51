"""Compiled procedure steps: the flat list of typed motion and acquisition steps the runner executes.

Everything here is SI: angles in rad (gimbal angles (outer ψ, middle θ, inner γ), unwrapped), rates in
rad/s (gimbal rate, signed), times in s. The navigation frame n is ENU, the body frame b the unit's case
axes, and C_b^n = R_z(ψ) R_x(θ) R_y(γ) C_b^t (see :mod:`analysis.gimbal`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from analysis.gimbal import body_to_nav, direction_word
from analysis.units import CELSIUS_ZERO, DEG, format_hms
from drivers.protocols import AXIS_NAMES, AxisLimits

Vec3 = tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class Step:
    """One compiled step; a concrete step is a :class:`Move`, :class:`Warmup`, :class:`Hold`, :class:`Spin` or
    :class:`Note`, and knows its bench time, the table commands it sends and whether it acquires.

    Every step carries the same attributes (neutral values where a kind has none: no angles, no axis, zero
    rate and durations), so the recorder and the observers read any step alike; the runner, the summary, the
    time estimates, the nominal trajectory and the identification dispatch on the type.

    Attributes
    ----------
    index : int
        Position in the compiled list (0-based).
    name : str
        Unique readable name, e.g. ``"A/orient"``, ``"A/hold"``, ``"A/step-3"``, ``"A/hold-3"``, ``"A/spin+"``.
    group : str
        Group path (e.g. ``"A"``; nested groups ``"A/fine"``), ``""`` outside any group.
    line : int or None
        Line of the procedure file the step comes from.
    text : str
        Note text, or a one-line human description.
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
    """

    kind: ClassVar[str] = ""
    """The step's kind as recorded (``steps/kind`` in the recording) and shown."""
    acquires: ClassVar[bool] = False
    """True if samples taken during the step's counted window are data."""

    index: int
    name: str
    group: str = ""
    line: int | None = None
    text: str = ""
    angles: Vec3 | None = None
    axis: int | None = None
    rate: float = 0.0
    duration: float = 0.0
    settle: float = 0.0
    body_axis: str | None = None

    @property
    def acquisition_time(self) -> float:
        """Time during which samples count, s (0 for a step that does not acquire)."""
        return self.duration if self.acquires else 0.0

    def commanded_positions(self) -> tuple[Vec3, ...]:
        """Absolute gimbal angles (rad) this step commands the table to."""
        return () if self.angles is None else (self.angles,)

    def commanded_rates(self) -> tuple[tuple[int, float], ...]:
        """(gimbal axis, rate rad/s) this step commands."""
        return ()

    def bench_time(self, limits: Sequence[AxisLimits], current: np.ndarray | None) -> tuple[float, np.ndarray | None]:
        """Estimated bench time of the step from nominal gimbal angles ``current`` (rad; None: unknown), s,
        and the nominal angles it leaves the table at. Moves are trapezoidal at the limits; an unknown
        start counts as no move."""
        t = 0.0
        if self.angles is not None:
            target = np.asarray(self.angles, dtype=float)
            if current is not None:
                t += move_time(current, target, limits)
            current = target
        return t + self.settle + self.duration, current

    def describe(self, mounting: np.ndarray | None) -> str:
        """What the step does, in words (the summary's last column)."""
        return describe_attitude(self.angles, mounting)


@dataclass(frozen=True, kw_only=True)
class Move(Step):
    """Move to absolute gimbal ``angles`` (an orientation, or one rotation of a step_rotate about ``axis``)."""

    kind: ClassVar[str] = "move"
    angles: Vec3 = field()  # required (field(): the inherited None default does not apply)

    def describe(self, mounting: np.ndarray | None) -> str:
        what = f"→ {describe_attitude(self.angles, mounting)}"
        return what + f"  [{self.text}]" if self.body_axis is not None else what


@dataclass(frozen=True, kw_only=True)
class Warmup(Step):
    """Warm-up record: settle, then acquire ``duration`` s at ``angles`` (None: wherever the table is)."""

    kind: ClassVar[str] = "warmup"
    acquires: ClassVar[bool] = True


@dataclass(frozen=True, kw_only=True)
class Hold(Step):
    """Static acquisition: verify the attitude ``angles``, settle, then acquire ``duration`` s."""

    kind: ClassVar[str] = "hold"
    acquires: ClassVar[bool] = True
    angles: Vec3 = field()  # required (field(): the inherited None default does not apply)


@dataclass(frozen=True, kw_only=True)
class Spin(Step):
    """Constant-rate spin of gimbal ``axis`` at ``rate`` rad/s: ramp up, settle, acquire ``duration`` s, stop."""

    kind: ClassVar[str] = "spin"
    acquires: ClassVar[bool] = True
    axis: int = field()  # required

    def commanded_rates(self) -> tuple[tuple[int, float], ...]:
        return ((self.axis, self.rate),)

    def ramp_time(self, limits: Sequence[AxisLimits]) -> float:
        """Time to reach (or leave) the rate at the axis' acceleration limit, s."""
        return abs(self.rate) / limits[self.axis].accel_max

    def bench_time(self, limits: Sequence[AxisLimits], current: np.ndarray | None) -> tuple[float, np.ndarray | None]:
        """Ramps, settling and acquisition; leaves the gimbal at its nominal end angle (unwrapped)."""
        lim = limits[self.axis]
        t = 2.0 * self.ramp_time(limits) + self.settle + self.duration
        if current is not None:
            current = current.copy()
            current[self.axis] += spin_angle(self.rate, self.duration, self.settle, lim.accel_max)
        return t, current

    def describe(self, mounting: np.ndarray | None) -> str:
        return (
            f"spin about body {self.body_axis} at {abs(self.rate) / DEG:g} °/s "
            f"({AXIS_NAMES[self.axis]} gimbal {self.rate / DEG:+g} °/s)"
        )


@dataclass(frozen=True, kw_only=True)
class Note(Step):
    """Free text logged in the recording when reached; no motion, no time."""

    kind: ClassVar[str] = "note"

    def bench_time(self, limits: Sequence[AxisLimits], current: np.ndarray | None) -> tuple[float, np.ndarray | None]:
        return 0.0, current

    def describe(self, mounting: np.ndarray | None) -> str:
        return f"note: {self.text}"


@dataclass(frozen=True, kw_only=True)
class Soak(Step):
    """Chamber to ``setpoint`` (K), then wait until the unit's own temperature has soaked (docs/methods/thermal.md):
    within ``tolerance`` (K) of ``target`` and changing by less than ``rate_limit`` (K/s) for ``dwell`` s; the
    step fails after ``timeout`` s. The table holds still; samples are recorded but do not count."""

    kind: ClassVar[str] = "soak"
    setpoint: float = 0.0
    target: float = 0.0
    tolerance: float = 0.5
    rate_limit: float = 0.1 / 60.0
    dwell: float = 600.0
    timeout: float = 4 * 3600.0

    def bench_time(self, limits: Sequence[AxisLimits], current: np.ndarray | None) -> tuple[float, np.ndarray | None]:
        """At least the dwell (the lag of the unit is the bench's, unknown here)."""
        return self.dwell, current

    def describe(self, mounting: np.ndarray | None) -> str:
        return (
            f"soak at {self.setpoint - CELSIUS_ZERO:g} °C (unit within {self.tolerance:g} K, "
            f"< {self.rate_limit * 60:g} K/min for {format_hms(self.dwell)}; time-out {format_hms(self.timeout)})"
        )


@dataclass(frozen=True, kw_only=True)
class Ramp(Step):
    """Start a set-point ramp from ``start`` to ``end`` (K) at ``ramp_rate`` (K/s) that runs while the steps after
    it (the repeated table sequence) execute; ``ramp_time`` s long."""

    kind: ClassVar[str] = "ramp"
    start: float = 0.0
    end: float = 0.0
    ramp_rate: float = 0.0
    ramp_time: float = 0.0

    def bench_time(self, limits: Sequence[AxisLimits], current: np.ndarray | None) -> tuple[float, np.ndarray | None]:
        return 0.0, current

    def describe(self, mounting: np.ndarray | None) -> str:
        return (
            f"ramp {self.start - CELSIUS_ZERO:g} → {self.end - CELSIUS_ZERO:g} °C at {self.ramp_rate * 60:g} K/min "
            f"({format_hms(self.ramp_time)}) while the sequence repeats"
        )


THERMAL_STEPS: tuple[type[Step], ...] = (Soak, Ramp)
"""Steps that command the chamber (a bench without one cannot run them)."""


def limit_problems(steps: Sequence[Step], limits: Sequence[AxisLimits]) -> list[str]:
    """Every position and rate the steps command, checked with :class:`AxisLimits`; problems (empty: ok)."""
    problems: list[str] = []
    for s in steps:
        for angles in s.commanded_positions():
            for i, (a, lim) in enumerate(zip(angles, limits, strict=True)):
                if not lim.allows_position(a):
                    problems.append(
                        f"step {s.name!r}: {AXIS_NAMES[i]} gimbal angle {math.degrees(a):.3f}° outside the table's "
                        f"limits {lim.position_range_text()}"
                    )
        for axis, rate in s.commanded_rates():
            if not 0 <= axis <= 2:
                problems.append(f"step {s.name!r}: spin without a valid gimbal axis")
            elif not limits[axis].allows_rate(rate):
                problems.append(
                    f"step {s.name!r}: rate {math.degrees(rate):.3f} °/s exceeds the table's "
                    f"{math.degrees(limits[axis].rate_max):.3f} °/s on the {AXIS_NAMES[axis]} gimbal"
                )
    return problems


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


def describe_attitude(angles: Sequence[float] | None, mounting: np.ndarray | None = None) -> str:
    """Body axes in words for gimbal angles (rad), e.g. ``"x East, y North, z Up"``; ``"(current)"`` if None."""
    if angles is None:
        return "(current)"
    c = body_to_nav(np.asarray(angles, dtype=float), mounting)
    return ", ".join(f"{ax} {direction_word(c[:, i])}" for i, ax in enumerate("xyz"))


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
            t, current = step.bench_time(limits, current)
            times.append(t)
        return times

    def estimated_duration(self, limits: Sequence[AxisLimits]) -> float:
        """Estimated total bench time, s, including moves (trapezoidal at ``limits``), settling and spin ramps."""
        return float(sum(self.step_times(limits)))

    def acquisition_time(self) -> float:
        """Total time during which samples count, s."""
        return float(sum(s.acquisition_time for s in self.steps))

    def summary(self, limits: Sequence[AxisLimits] | None = None) -> str:
        """A readable table of the steps (attitudes in body-axis words, spins, durations) for the CLI."""
        mounting = self._mounting()
        times = self.step_times(limits) if limits is not None else [float("nan")] * len(self.steps)
        rows = [f"procedure {self.name!r}: {self.description.strip().splitlines()[0] if self.description else ''}"]
        head = f"{'#':>3}  {'step':<18} {'kind':<6} {'line':>4}  {'acq s':>7} {'est s':>7}  attitude / motion"
        rows.append(head)
        rows.append("-" * len(head))
        for step, t in zip(self.steps, times, strict=True):
            line = "" if step.line is None else str(step.line)
            acq = f"{step.duration:7.1f}" if step.acquires else " " * 7
            est = f"{t:7.1f}" if t == t else " " * 7
            what = step.describe(mounting)
            rows.append(f"{step.index:>3}  {step.name:<18} {step.kind:<6} {line:>4}  {acq} {est}  {what}")
        rows.append("-" * len(head))
        n_acq = sum(1 for s in self.steps if s.acquires)
        n_spin = sum(1 for s in self.steps if isinstance(s, Spin))
        tail = f"{len(self.steps)} steps, {n_acq} acquisitions ({n_spin} spins)"
        tail += f", acquisition {format_hms(self.acquisition_time())}"
        if limits is not None:
            tail += f", estimated duration {format_hms(self.estimated_duration(limits))} (h:m:s)"
        rows.append(tail)
        return "\n".join(rows)
