"""Estimate t_table = t₀ + (1 + ε) t_unit from a run's data (docs/methods/time-base.md).

1. **Coarse**: each reading was requested after a known block of samples; a straight line through
   (t_unit of that block's last sample, reading time) gives t₀ and ε to within the link latencies (ms).
2. **Per motion** (:mod:`analysis.timebase.events`): the unit's own view of the motion is compared with the
   table's readings, with a local time shift δ as the unknown (Gauss–Newton, δ's Jacobian the signal's rate of
   change):

   * gyros: the angle the gyros measure about the moving gimbal axis, A(t) = ∫ u_bᵀ ω_meas dt (trapezoids: exact
     for the table's constant-acceleration segments), against the table's reported angle of that axis:
     θ_i = K + (1 + s) A(s_i + δ) + b (s_i − s̄), with the event's own offset K, scale s and rate offset b
     (gyro bias, Earth rate) as nuisances. The angle is used rather than the rate because it is smooth: a
     rate profile's corners would bias any smoothing.
   * accelerometers only: the specific force (local quadratic fit over ±``accel_half_window`` s, value and
     slope at s_i) against gravity's projection computed from the reading: f̂(s_i + δ) = b + M f_ref,i +
     c |ω_i|², per event, with bias b, a full 3 × 3 matrix M (scale, misalignment) and the centripetal term c
     (lever arms) as nuisances.

   Each event's δ has its σ from the fit's residuals; it gives the local offset of the table clock.
3. **Across the run**: a weighted straight line through the events' offsets gives t₀ and the rate correction
   (ε) with their covariance, scaled by the Birge ratio √(χ²/dof) when that exceeds 1 (an honest σ when the
   events scatter more than their own σ say).

Pure maths: arrays in, :class:`~analysis.timebase.model.TimeBase` out. Frames: body frame b for the unit's
signals; gimbal angles (ψ, θ, γ) as in ``analysis.gimbal``. SI throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from analysis.gimbal import body_rate, gravity_in_body
from analysis.timebase.events import MotionWindow, motion_windows
from analysis.timebase.model import TimeBase, TimingEvent

MAX_SCALE_MISMATCH = 0.01
"""A motion whose gyro angle differs from the table's by more than this fraction is not used (saturated gyros,
a wrong output configuration): its shape, not only its size, would be wrong."""


@dataclass(frozen=True)
class RunSignals:
    """What the estimate needs from a run (SI; body frame b; the table's readings in time order).

    Attributes
    ----------
    t : (n,) unit sample time stamps, s (sorted).
    accel : (n, 3) specific force, m/s². gyro : (n, 3) angular rate, rad/s, or None (no gyro triad).
    table_time : (m,) reading time stamps, s. angles : (m, 3) rad, unwrapped. rates : (m, 3) rad/s.
    sample_index : (m,) samples recorded before each reading, or None (not recorded).
    g : local gravity, m/s². mounting : (3, 3) C_b^t. latency : unit output latency, s.
    """

    t: NDArray[np.float64]
    accel: NDArray[np.float64]
    gyro: NDArray[np.float64] | None
    table_time: NDArray[np.float64]
    angles: NDArray[np.float64]
    rates: NDArray[np.float64]
    sample_index: NDArray[np.int64] | None
    g: float
    mounting: NDArray[np.float64]
    latency: float = 0.0


def coarse_mapping(sig: RunSignals) -> tuple[float, float]:
    """(t₀, ε) from the reading times against the unit time of the sample before each reading (to ~ms)."""
    if sig.sample_index is None or sig.t.size == 0:
        return 0.0, 0.0
    k = np.clip(np.asarray(sig.sample_index, dtype=np.int64) - 1, 0, sig.t.size - 1)
    tu = sig.t[k]
    c = sig.table_time
    ok = np.isfinite(c) & np.isfinite(tu)
    if np.count_nonzero(ok) < 2 or np.ptp(tu[ok]) <= 0:
        return float(np.median(c[ok] - tu[ok])) if np.any(ok) else 0.0, 0.0
    slope, icpt = np.polyfit(tu[ok], c[ok], 1)
    return float(icpt), float(slope - 1.0)


def _unit_times(sig: RunSignals, t0: float, eps: float, idx: NDArray[np.int64]) -> NDArray[np.float64]:
    """Sample time stamp that sees each reading: (c − t₀)/(1 + ε) + latency."""
    return (sig.table_time[idx] - t0) / (1.0 + eps) + sig.latency


def _solve(x: NDArray[np.float64], y: NDArray[np.float64], col: int) -> tuple[NDArray[np.float64], float, float]:
    """Least squares y ≈ x·p; returns p, σ of p[col] (residual-scaled; robust to nuisance rank deficiency), RMS."""
    p, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ p
    dof = x.shape[0] - np.linalg.matrix_rank(x)
    if dof < 2:
        return p, math.nan, math.nan
    s2 = float(r @ r) / dof
    others = np.delete(x, col, axis=1)
    q, *_ = np.linalg.lstsq(others, x[:, col], rcond=None)
    xc = x[:, col] - others @ q  # the δ column with the nuisances projected out
    info = float(xc @ xc)
    return p, (math.sqrt(s2 / info) if info > 0 else math.nan), math.sqrt(float(r @ r) / r.size)


def _gyro_event(sig: RunSignals, w: MotionWindow, t0: float, eps: float) -> TimingEvent | None:
    idx = w.readings
    if idx.size < 6:
        return None
    e = np.zeros(3)
    e[w.axis] = 1.0
    u_b = body_rate(sig.angles[idx[0]], e, sig.mounting)
    u_b = u_b / np.linalg.norm(u_b)
    s0 = _unit_times(sig, t0, eps, idx)
    lo = np.searchsorted(sig.t, s0[0] - 0.25)
    hi = np.searchsorted(sig.t, s0[-1] + 0.25)
    if hi - lo < 10:
        return None
    ts = sig.t[lo:hi]
    assert sig.gyro is not None
    gr = sig.gyro[lo:hi] @ u_b
    ang = np.concatenate([[0.0], np.cumsum(0.5 * (gr[1:] + gr[:-1]) * np.diff(ts))])
    theta = sig.angles[idx, w.axis]
    delta, sd, rms, grad = 0.0, math.nan, math.nan, np.zeros(idx.size)
    for _ in range(6):
        s = s0 + delta
        if s[0] < ts[0] or s[-1] > ts[-1]:
            return None
        a_i = np.interp(s, ts, ang)
        grad = np.interp(s, ts, gr)
        x = np.column_stack([np.ones_like(s), a_i, s - s.mean(), grad])
        p, sd, rms = _solve(x, theta - a_i, 3)
        delta += float(p[3])
        if abs(p[3]) < 1e-9:
            break
    if not math.isfinite(sd) or abs(float(p[1])) > MAX_SCALE_MISMATCH:
        return None  # the gyros' angle disagrees with the table's: saturated, or a misconfigured output
    speed = float(np.sqrt(np.mean(grad[w.moving] ** 2))) if np.any(w.moving) else 0.0
    return TimingEvent(
        t_unit=float(np.mean(s0[w.moving] if np.any(w.moving) else s0)),
        offset=t0 - (1.0 + eps) * delta,
        u=(1.0 + eps) * sd,
        axis=w.axis,
        readings=int(idx.size),
        rms_time=rms / speed if speed > 0 else math.nan,
    )


def _local_quadratic(
    t: NDArray[np.float64], y: NDArray[np.float64], at: NDArray[np.float64], h: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Value and slope (per component) of a quadratic fitted to ``y`` (n, 3) over ±h s around each of ``at``."""
    val = np.empty((at.size, y.shape[1]))
    der = np.empty_like(val)
    lo = np.searchsorted(t, at - h)
    hi = np.searchsorted(t, at + h)
    for i, (a, b) in enumerate(zip(lo, hi, strict=True)):
        if b - a < 5:
            val[i] = der[i] = math.nan
            continue
        dt = t[a:b] - at[i]
        v = np.column_stack([np.ones_like(dt), dt, dt * dt])
        c, *_ = np.linalg.lstsq(v, y[a:b], rcond=None)
        val[i], der[i] = c[0], c[1]
    return val, der


def _accel_event(sig: RunSignals, w: MotionWindow, t0: float, eps: float, half_window: float) -> TimingEvent | None:
    idx = w.readings
    if idx.size < 8:
        return None
    f_ref = gravity_in_body(sig.angles[idx], sig.g, sig.mounting)
    om = body_rate(sig.angles[idx], sig.rates[idx], sig.mounting)
    w2 = np.sum(om * om, axis=1)
    s0 = _unit_times(sig, t0, eps, idx)
    m = idx.size
    nuis = np.zeros((3 * m, 15))
    for a in range(3):
        rows = slice(a * m, (a + 1) * m)
        nuis[rows, a] = 1.0
        nuis[rows, 3 + 3 * a : 6 + 3 * a] = f_ref
        nuis[rows, 12 + a] = w2
    delta, sd, rms, der = 0.0, math.nan, math.nan, np.zeros((m, 3))
    for _ in range(4):
        val, der = _local_quadratic(sig.t, sig.accel, s0 + delta, half_window)
        if not np.all(np.isfinite(val)):
            return None
        x = np.column_stack([nuis, der.T.reshape(-1)])
        p, sd, rms = _solve(x, val.T.reshape(-1), 15)
        delta -= float(p[15])
        if abs(p[15]) < 1e-8:
            break
    if not math.isfinite(sd):
        return None
    mv = w.moving if np.any(w.moving) else np.ones(m, bool)
    speed = float(np.sqrt(np.mean(np.sum(der[mv] ** 2, axis=1))))
    return TimingEvent(
        t_unit=float(np.mean(s0[mv])),
        offset=t0 - (1.0 + eps) * delta,
        u=(1.0 + eps) * sd,
        axis=w.axis,
        readings=int(m),
        rms_time=rms / speed if speed > 0 else math.nan,
    )


def _line_fit(events: list[TimingEvent]) -> tuple[NDArray[np.float64], NDArray[np.float64], float, NDArray[np.float64]]:
    """Weighted line offset = t₀ + dε · t_unit through the events: (p, cov, Birge ratio, residuals)."""
    t = np.array([e.t_unit for e in events])
    y = np.array([e.offset for e in events])
    u = np.array([e.u for e in events])
    if len(events) == 1:
        return np.array([y[0], 0.0]), np.diag([u[0] ** 2, math.inf]), 1.0, np.zeros(1)
    x = np.column_stack([np.ones_like(t), t])
    wts = 1.0 / u**2
    info = x.T @ (x * wts[:, None])
    cov = np.linalg.inv(info)
    p = cov @ (x.T @ (wts * y))
    r = y - x @ p
    dof = len(events) - 2
    birge = math.sqrt(float(np.sum(wts * r * r)) / dof) if dof > 0 else 1.0
    return p, cov * max(1.0, birge) ** 2, birge, r


def estimate_time_base(
    sig: RunSignals,
    *,
    window: float = 1.5,
    accel_half_window: float = 0.015,
    use_gyro: bool | None = None,
    initial: tuple[float, float] | None = None,
) -> TimeBase:
    """The run's time base from its data (module docstring).

    Parameters
    ----------
    sig : RunSignals
    window : s, event window before/after each motion.
    accel_half_window : s, half-width of the local quadratic fit of the specific force (accelerometer method).
    use_gyro : None (the gyros when the unit has them: a non-zero finite gyro record), True or False.
    initial : (t₀, ε) to start from (None: :func:`coarse_mapping` of ``sig``).
    """
    t0, eps = coarse_mapping(sig) if initial is None else initial
    if use_gyro is None:
        use_gyro = sig.gyro is not None and bool(np.all(np.isfinite(sig.gyro))) and bool(np.any(sig.gyro != 0))
    method = "gyro" if use_gyro else "accelerometer"
    notes: list[str] = []
    events: list[TimingEvent] = []
    cov = np.full((2, 2), math.nan)
    birge = math.nan
    resid = np.zeros(0)
    for _ in range(2):  # the second pass re-measures every motion on the corrected mapping
        tw = (sig.table_time - t0) / (1.0 + eps)  # windows found on the unit's time axis
        wins, skipped = motion_windows(tw, sig.angles, sig.rates, window=window)
        events = []
        for w in wins:
            ev = _gyro_event(sig, w, t0, eps) if use_gyro else _accel_event(sig, w, t0, eps, accel_half_window)
            if ev is not None and math.isfinite(ev.u) and ev.u > 0:
                events.append(ev)
        unused = len(wins) - len(events)
        if not events:
            break
        p, cov, birge, resid = _line_fit(events)
        if len(events) == 1:
            t0 = float(p[0] - eps * events[0].t_unit)
        else:
            t0, eps = float(p[0]), eps + float(p[1])
    if not events:
        notes.append("no single-axis motion to measure the time base on: the coarse mapping from the reading times "
                     "is used, without a stated uncertainty")  # fmt: skip
        return TimeBase(t0, eps, math.nan, math.nan, np.full((2, 2), math.nan), "coarse", [], math.nan, {}, notes)
    if skipped:
        notes.append(f"{skipped} multi-axis motion(s) not used")
    if unused:
        notes.append(
            f"{unused} motion window(s) not used: too few readings, or the unit's signal does not follow the "
            "table's (a gyro angle off by more than 1 %: a saturated or misconfigured output?)"
        )
    if len(events) == 1:
        notes.append("one motion only: the rate is taken from the reading times, without a stated uncertainty")
    evs = [TimingEvent(e.t_unit, e.offset, e.u, e.axis, e.readings, e.rms_time, float(r))
           for e, r in zip(events, resid, strict=True)]  # fmt: skip
    return TimeBase(
        offset=t0,
        rate=eps,
        u_offset=float(math.sqrt(cov[0, 0])),
        u_rate=float(math.sqrt(cov[1, 1])) if math.isfinite(cov[1, 1]) else math.nan,
        covariance=cov,
        method=method,
        events=evs,
        misfit=float(birge),
        notes=notes,
    )
