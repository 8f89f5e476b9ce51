"""Piecewise-analytic motion of one simulated gimbal axis (pure maths, vectorised over sample times).

An :class:`AxisPlan` is a list of constant-acceleration segments (start time, angle, rate, acceleration),
the last one extending to +∞, plus an optional settling transient after a position move:

    e(τ) = A exp(−τ/τ_s) sin(ω_d τ),  τ = t − t_end ≥ 0

(a small overshoot in the direction of motion). :meth:`AxisPlan.evaluate` returns angle (rad), rate (rad/s)
and angular acceleration (rad/s²) of the axis at any array of times at once. Plans are built by the
``plan_*`` functions from the axis state at the command time, so every command re-plans from an exact,
analytic state and the result does not depend on how sample generation is split.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.protocols import AxisLimits, AxisMode


@dataclass(frozen=True)
class AxisPlan:
    """Motion of one axis from ``t[0]`` on.

    Attributes
    ----------
    t, p, v, a : (m,) segment start times (s), start angles (rad), start rates (rad/s), accelerations (rad/s²).
    mode : the commanded mode.
    target : rad, commanded angle (position mode) else None.
    rate_cmd : rad/s, commanded rate (rate mode) else 0.
    settle_t0 : s, start of the settling transient (None: none). settle_amp : rad, its amplitude A.
    settle_omega : rad/s, ω_d. settle_tau : s, τ_s.
    t_still : s, time from which the axis is not moving (within tolerance, or at rest); inf if never.
    t_done : s, time from which IN_POSITION (position mode) or AT_RATE (rate mode) holds.
    """

    t: NDArray[np.float64]
    p: NDArray[np.float64]
    v: NDArray[np.float64]
    a: NDArray[np.float64]
    mode: AxisMode
    target: float | None = None
    rate_cmd: float = 0.0
    settle_t0: float | None = None
    settle_amp: float = 0.0
    settle_omega: float = 0.0
    settle_tau: float = 1.0
    t_still: float = 0.0
    t_done: float = 0.0

    @functools.cached_property  # (asked for at every block: computed once per plan; the plan is immutable)
    def settle_end(self) -> float:
        """Time after which the settling transient is cut (envelope below 1e-13 rad: exactly at rest)."""
        if self.settle_t0 is None or abs(self.settle_amp) <= 1e-13:
            return -math.inf
        return self.settle_t0 + self.settle_tau * math.log(abs(self.settle_amp) / 1e-13)

    def evaluate(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Angle (rad), rate (rad/s) and angular acceleration (rad/s²) at times ``t`` (s, 1-D array ≥ t[0])."""
        t = np.asarray(t, dtype=float)
        if len(self.t) == 1 or t[0] >= self.t[-1]:  # last segment only (holds, constant rates)
            j = len(self.t) - 1
            dt = t - self.t[j]
            a0, v0 = float(self.a[j]), float(self.v[j])
            v = v0 + a0 * dt
            p = self.p[j] + v0 * dt + 0.5 * a0 * dt * dt
            acc = np.full(t.shape, a0)
        else:
            i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1)
            dt = t - self.t[i]
            a = self.a[i]
            v = self.v[i] + a * dt
            p = self.p[i] + self.v[i] * dt + 0.5 * a * dt * dt
            acc = np.array(a, dtype=float)
        if self.settle_t0 is not None and self.settle_amp != 0.0 and t[0] < self.settle_end:
            tau = t - self.settle_t0
            on = (tau > 0.0) & (tau < self.settle_end - self.settle_t0)
            if np.any(on):
                tau = np.where(on, tau, 0.0)
                env = self.settle_amp * np.exp(-tau / self.settle_tau) * on
                w, k = self.settle_omega, 1.0 / self.settle_tau
                s, c = np.sin(w * tau), np.cos(w * tau)
                p = p + env * s
                v = v + env * (w * c - k * s)
                acc = acc + env * ((k * k - w * w) * s - 2.0 * w * k * c)
        return p, v, acc

    def state(self, t: float) -> tuple[float, float]:
        """(angle rad, rate rad/s) at scalar time ``t`` (same arithmetic as :meth:`evaluate`, same bits).

        Without a settling transient at ``t`` it is computed on Python floats (a controller reading asks for
        one time per block: the array machinery cost more than the arithmetic); the operations and their order
        are those of :meth:`evaluate`, so the result is identical."""
        t = float(t)
        if self.settle_t0 is not None and self.settle_amp != 0.0 and t < self.settle_end:
            p, v, _ = self.evaluate(np.array([t]))
            return float(p[0]), float(v[0])
        ts = self.t
        j = len(ts) - 1
        if j > 0 and t < ts[-1]:
            j = min(max(bisect.bisect_right(ts, t) - 1, 0), j)
        dt = t - float(ts[j])
        a0, v0 = float(self.a[j]), float(self.v[j])
        return float(self.p[j]) + v0 * dt + 0.5 * a0 * dt * dt, v0 + a0 * dt


def _segments(rows: list[tuple[float, float, float, float]]) -> tuple[NDArray[np.float64], ...]:
    arr = np.array(rows, dtype=float)
    return arr[:, 0].copy(), arr[:, 1].copy(), arr[:, 2].copy(), arr[:, 3].copy()


def plan_hold(t0: float, angle: float, mode: AxisMode = AxisMode.STOP, target: float | None = None) -> AxisPlan:
    """Axis at rest at ``angle`` (rad) from ``t0`` (an abrupt halt when the axis was moving)."""
    t, p, v, a = _segments([(t0, angle, 0.0, 0.0)])
    return AxisPlan(t, p, v, a, mode=mode, target=target, t_still=t0, t_done=t0)


def _brake(t0: float, p0: float, v0: float, accel: float, rows: list) -> tuple[float, float]:
    """Append a deceleration to rest at ``accel`` (rad/s²); return (time, angle) at rest."""
    if v0 == 0.0:
        return t0, p0
    dur = abs(v0) / accel
    a = -math.copysign(accel, v0)
    rows.append((t0, p0, v0, a))
    return t0 + dur, p0 + v0 * dur + 0.5 * a * dur * dur


def plan_stop(t0: float, p0: float, v0: float, limits: AxisLimits) -> AxisPlan:
    """Controlled deceleration at the axis acceleration limit to rest, then hold (mode STOP)."""
    rows: list[tuple[float, float, float, float]] = []
    t1, p1 = _brake(t0, p0, v0, limits.accel_max, rows)
    rows.append((t1, p1, 0.0, 0.0))
    t, p, v, a = _segments(rows)
    return AxisPlan(t, p, v, a, mode=AxisMode.STOP, t_still=t1, t_done=t1)


def plan_rate(
    t0: float, p0: float, v0: float, rate: float, limits: AxisLimits, realised: float | None = None
) -> AxisPlan:
    """Ramp from rate ``v0`` to ``rate`` (rad/s, the command) at the acceleration limit, then hold the rate.

    ``realised`` (rad/s, default ``rate``) is the rate the axis really turns at: a table with a rate error ε
    turns at (1 + ε) × its command (docs/methods/simulation.md); ``rate_cmd`` keeps the command.
    """
    rows: list[tuple[float, float, float, float]] = []
    cmd = rate
    rate = cmd if realised is None else float(realised)
    dv = rate - v0
    t1, p1 = t0, p0
    if dv != 0.0:
        dur = abs(dv) / limits.accel_max
        a = math.copysign(limits.accel_max, dv)
        rows.append((t0, p0, v0, a))
        t1, p1 = t0 + dur, p0 + v0 * dur + 0.5 * a * dur * dur
    rows.append((t1, p1, rate, 0.0))
    t, p, v, a = _segments(rows)
    still = t1 if rate == 0.0 else math.inf
    return AxisPlan(t, p, v, a, mode=AxisMode.RATE, rate_cmd=cmd, t_still=still, t_done=t1)


def plan_position(
    t0: float,
    p0: float,
    v0: float,
    target: float,
    limits: AxisLimits,
    *,
    slew_fraction: float,
    overshoot: float,
    settle_frequency_hz: float,
    settle_time_constant: float,
    tolerance: float,
    in_position_time: float,
) -> AxisPlan:
    """Trapezoidal move to the absolute angle ``target`` (rad), then a settling transient.

    A moving axis first brakes to rest at the acceleration limit; the move then cruises at
    ``slew_fraction·rate_max`` (triangular if too short). The transient amplitude is ``overshoot`` in the
    direction of motion; the axis counts as within tolerance once the transient's envelope is below
    ``tolerance``, and IN_POSITION holds ``in_position_time`` later.
    """
    rows: list[tuple[float, float, float, float]] = []
    t1, p1 = _brake(t0, p0, v0, limits.accel_max, rows)
    d = target - p1
    acc = limits.accel_max
    vmax = slew_fraction * limits.rate_max
    sgn = 1.0 if d >= 0 else -1.0
    dist = abs(d)
    if dist > 0.0:
        if dist >= vmax * vmax / acc:
            ta, tc, vp = vmax / acc, (dist - vmax * vmax / acc) / vmax, vmax
        else:
            vp = math.sqrt(dist * acc)
            ta, tc = vp / acc, 0.0
        rows.append((t1, p1, 0.0, sgn * acc))
        pa = p1 + sgn * 0.5 * acc * ta * ta
        rows.append((t1 + ta, pa, sgn * vp, 0.0))
        pc = pa + sgn * vp * tc
        rows.append((t1 + ta + tc, pc, sgn * vp, -sgn * acc))
        t_end = t1 + 2 * ta + tc
    else:
        t_end = t1
    rows.append((t_end, target, 0.0, 0.0))
    t, p, v, a = _segments(rows)
    amp = sgn * overshoot if dist > 0.0 else 0.0
    env_time = settle_time_constant * math.log(abs(amp) / tolerance) if abs(amp) > tolerance > 0 else 0.0
    t_still = t_end + env_time
    return AxisPlan(
        t,
        p,
        v,
        a,
        mode=AxisMode.POSITION,
        target=target,
        settle_t0=t_end if amp != 0.0 else None,
        settle_amp=amp,
        settle_omega=2.0 * math.pi * settle_frequency_hz,
        settle_tau=settle_time_constant,
        t_still=t_still,
        t_done=t_still + in_position_time,
    )
