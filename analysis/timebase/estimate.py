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
   * accelerometers only: every unit sample inside the readings' constant-acceleration intervals (where the
     trapezoid rule reproduces the reported angle change: no profile corner inside) against gravity's
     projection at the table time it sees, the angle the interval's exact quadratic through its end readings:
     f(s) = b + M f_ref(c(s − δ)) + k_ω ω² + k_α α, with bias b, a full 3 × 3 matrix M (scale, misalignment),
     centripetal and tangential coefficients (lever arms) per accelerometer as nuisances. Only a change of rate
     carries timing here: at a constant rate a time shift is a constant rotation, which M absorbs, so the
     accelerating and braking phases of moves are what the estimate rests on.

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
from analysis.timebase.events import MotionWindow, motion_windows, single_axis_motions
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
    """(t₀, ε) from the reading times against the unit time of the sample before each reading (to ~ms).

    A reading is requested once the samples before it have arrived, so its time is the mapped unit time plus a
    delay that is never negative and is smallest for a reading requested right after a block arrived: the line
    is the *lower envelope* of the points (refitted on the lowest tenth of the residuals), so a link that
    delivers the frames in bursts of seconds (the readings after a burst's first block wait for nothing but
    are stamped seconds after their samples) does not shift it by half a burst.
    """
    if sig.sample_index is None or sig.t.size == 0:
        return 0.0, 0.0
    k = np.clip(np.asarray(sig.sample_index, dtype=np.int64) - 1, 0, sig.t.size - 1)
    tu = sig.t[k]
    c = sig.table_time
    ok = np.isfinite(c) & np.isfinite(tu)
    if np.count_nonzero(ok) < 2 or np.ptp(tu[ok]) <= 0:
        return float(np.min(c[ok] - tu[ok])) if np.any(ok) else 0.0, 0.0
    x, y = tu[ok], c[ok]
    slope, icpt = np.polyfit(x, y, 1)
    for _ in range(4):
        r = y - (icpt + slope * x)
        low = r <= np.quantile(r, 0.1)
        if np.count_nonzero(low) < 2 or np.ptp(x[low]) <= 0.25 * np.ptp(x):
            break  # the lowest points bunch together: keep the last line
        slope, icpt = np.polyfit(x[low], y[low], 1)
    return float(icpt), float(slope - 1.0)


def _unit_times(sig: RunSignals, t0: float, eps: float, idx: NDArray[np.int64]) -> NDArray[np.float64]:
    """Sample time stamp that sees each reading: (c − t₀)/(1 + ε) + latency."""
    return (sig.table_time[idx] - t0) / (1.0 + eps) + sig.latency


_EPS = float(np.finfo(float).eps)


def _solve(x: NDArray[np.float64], y: NDArray[np.float64], col: int) -> tuple[NDArray[np.float64], float, float]:
    """Least squares y ≈ x·p; returns p, σ of p[col] (residual-scaled; robust to nuisance rank deficiency), RMS.

    One SVD gives the minimum-norm solution, the rank (numpy's tolerance: σ_max · max(n, k) · eps, as ``lstsq``
    and ``matrix_rank``) and, at full rank, σ²(p[col]) = s² [(XᵀX)⁻¹]_col,col = s² Σ_j (V_col,j / σ_j)². Only a
    rank-deficient design projects the nuisance columns out of the δ column explicitly."""
    u, sv, vt = np.linalg.svd(x, full_matrices=False)
    tol = (float(sv[0]) if sv.size else 0.0) * max(x.shape) * _EPS
    keep = sv > tol
    rank, p = int(np.count_nonzero(keep)), vt[keep].T @ ((u[:, keep].T @ y) / sv[keep])
    r = y - x @ p
    dof = x.shape[0] - rank
    if dof < 2:
        return p, math.nan, math.nan
    rr = float(r @ r)
    s2 = rr / dof
    rms = math.sqrt(rr / r.size)
    if rank == x.shape[1]:
        return p, math.sqrt(s2 * float(np.sum((vt[:, col] / sv) ** 2))), rms
    others = np.delete(x, col, axis=1)
    q, *_ = np.linalg.lstsq(others, x[:, col], rcond=None)
    xc = x[:, col] - others @ q  # the δ column with the nuisances projected out
    info = float(xc @ xc)
    return p, (math.sqrt(s2 / info) if info > 0 else math.nan), math.sqrt(float(r @ r) / r.size)


def excess_jitter(r: NDArray[np.float64], moving: NDArray[np.bool_], speed: float) -> float:
    """Timing jitter (s) shown by a fit's residuals ``r`` ((n,) or (n, k)): the excess of their variance while
    the table moves over their variance at rest, over ``speed`` (the signal's RMS rate of change while moving).

    At rest only the unit's and the encoder's noise is in the residuals; while moving a jittering time stamp
    adds speed × jitter. 0 when the excess is not significant (the moving variance within 3σ of the resting one,
    σ of a variance ratio ≈ √(2/n_moving + 2/n_rest)) or either part has fewer than 3 points.
    """
    r2 = np.asarray(r, float) ** 2
    r2 = r2.sum(axis=1) if r2.ndim == 2 else r2
    n_m, n_r = int(np.count_nonzero(moving)), int(np.count_nonzero(~moving))
    if n_m < 3 or n_r < 3 or not speed > 0:
        return 0.0
    vm, vr = float(np.mean(r2[moving])), float(np.mean(r2[~moving]))
    if vm <= vr * (1.0 + 3.0 * math.sqrt(2.0 / n_m + 2.0 / n_r)):
        return 0.0
    return math.sqrt(vm - vr) / speed


def _gyro_event(
    sig: RunSignals, w: MotionWindow, t0: float, eps: float, axes: dict[tuple[int, int], NDArray[np.float64]]
) -> TimingEvent | None:
    """Local offset from the gyro angle about the moving axis (module docstring); ``axes`` caches that axis in
    the body frame per (gimbal axis, first reading) across the passes."""
    idx = w.readings
    if idx.size < 6:
        return None
    key = (w.axis, int(idx[0]))
    if key not in axes:
        e = np.zeros(3)
        e[w.axis] = 1.0
        u_b = body_rate(sig.angles[idx[0]], e, sig.mounting)
        axes[key] = u_b / np.linalg.norm(u_b)
    u_b = axes[key]
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
    x = np.empty((idx.size, 4))  # the design [1, A(s), s − s̄, ∂A/∂s], filled in place per iteration
    x[:, 0] = 1.0
    t_lo, t_hi = float(ts[0]), float(ts[-1])
    for _ in range(6):
        s = s0 + delta
        if s[0] < t_lo or s[-1] > t_hi:
            return None
        a_i = np.interp(s, ts, ang)
        grad = np.interp(s, ts, gr)
        x[:, 1] = a_i
        np.subtract(s, np.add.reduce(s) / s.size, out=x[:, 2])  # s.mean(), without its wrapper
        x[:, 3] = grad
        p, sd, rms = _solve(x, theta - a_i, 3)
        delta += float(p[3])
        if abs(p[3]) < 1e-9:
            break
    if not math.isfinite(sd) or abs(float(p[1])) > MAX_SCALE_MISMATCH:
        return None  # the gyros' angle disagrees with the table's: saturated, or a misconfigured output
    any_moving = bool(np.any(w.moving))
    speed = float(np.sqrt(np.mean(grad[w.moving] ** 2))) if any_moving else 0.0
    resid = theta - a_i - x @ p
    return TimingEvent(
        t_unit=float(np.mean(s0[w.moving] if any_moving else s0)),
        offset=t0 - (1.0 + eps) * delta,
        u=(1.0 + eps) * sd,
        axis=w.axis,
        readings=int(idx.size),
        rms_time=rms / speed if speed > 0 else math.nan,
        jitter=excess_jitter(resid, w.moving, speed),
    )


CONSTANT_ACCEL_TOL = 1e-5
"""rad: a reading interval is taken as one of constant angular acceleration when the trapezoid rule reproduces
its angle change to within this (a switch of the profile inside it, or a settling transient, does not)."""


INTERVAL_MARGIN = 0.03
"""s: samples this close to a reading interval's ends are not used (the unit's anti-alias filter rings for a few
of its time constants after the profile's corner at an interval's end)."""

MAX_EVENT_SIGMA = 0.005
"""s: a motion whose local offset comes out less certain than this carries no useful timing (not used)."""


def constant_acceleration_intervals(
    times: NDArray[np.float64],
    angles: NDArray[np.float64],
    rates: NDArray[np.float64],
    idx: NDArray[np.int64],
    axis: int,
    tol: float = CONSTANT_ACCEL_TOL,
) -> list[tuple[int, float]]:
    """Intervals between consecutive readings ``idx`` over which gimbal ``axis`` moved with one angular
    acceleration: (index of the interval's first reading, that acceleration in rad/s²).

    A table's profile is piecewise constant in acceleration; over such an interval the angle is exactly the
    quadratic through the end readings' angles and rates, so θ₁ − θ₀ = ½ (ω₀ + ω₁) Δt (the trapezoid rule) holds,
    and where it fails a switch (a profile's corner, a settling transient) lies inside.
    """
    out: list[tuple[int, float]] = []
    for i, j in zip(idx[:-1].tolist(), idx[1:].tolist(), strict=True):
        dt = float(times[j] - times[i])
        if j != i + 1 or not dt > 0:
            continue
        w0, w1 = float(rates[i, axis]), float(rates[j, axis])
        if abs(float(angles[j, axis] - angles[i, axis]) - 0.5 * (w0 + w1) * dt) <= tol:
            out.append((i, (w1 - w0) / dt))
    return out


def _shared_shift(
    x0: NDArray[np.float64], y: NDArray[np.float64], d: NDArray[np.float64]
) -> tuple[float, float, float, NDArray[np.float64]]:
    """y[:, a] ≈ x0 · q_a + d[:, a] · δ for a = x, y, z (own nuisances q_a per accelerometer, one shift δ).

    The nuisances are projected out per column (one least-squares solve of the shared design for all six
    right-hand sides), then δ is the pooled regression of what remains. Returns δ, its σ (residual-scaled), the
    RMS residual and the residuals (n, 3).
    """
    coef, _res, rank, _sv = np.linalg.lstsq(x0, np.column_stack([y, d]), rcond=None)
    rest = np.column_stack([y, d]) - x0 @ coef
    yr, dr = rest[:, :3], rest[:, 3:]
    info = float(np.sum(dr * dr))
    if info <= 0:
        return 0.0, math.nan, math.nan, yr
    delta = float(np.sum(dr * yr)) / info
    r = yr - dr * delta
    dof = 3 * (x0.shape[0] - int(rank)) - 1
    if dof < 2:
        return delta, math.nan, math.nan, r
    ss = float(np.sum(r * r))
    return delta, math.sqrt(ss / dof / info), math.sqrt(ss / r.size), r


def _accel_reference(
    sig: RunSignals, c: NDArray[np.float64], seg: NDArray[np.int64], alpha: NDArray[np.float64], axis: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Gravity in body (n, 3), its rate of change ∂f/∂t (n, 3) and the rate of the moving axis (n,) at table times
    ``c`` inside the constant-acceleration intervals starting at readings ``seg``."""
    dt = c - sig.table_time[seg]
    # the rate at the interval's start from the two angles and α (a rate latched apart from the angle would
    # otherwise bend the quadratic): the quadratic passes through both end readings' angles exactly
    span = sig.table_time[seg + 1] - sig.table_time[seg]
    w0 = (sig.angles[seg + 1, axis] - sig.angles[seg, axis]) / span - 0.5 * alpha * span
    ang = sig.angles[seg].copy()
    ang[:, axis] += w0 * dt + 0.5 * alpha * dt * dt
    om = w0 + alpha * dt
    h = 1e-4
    up, dn = ang.copy(), ang.copy()
    up[:, axis] += h
    dn[:, axis] -= h
    f = gravity_in_body(ang, sig.g, sig.mounting)
    dfdth = (gravity_in_body(up, sig.g, sig.mounting) - gravity_in_body(dn, sig.g, sig.mounting)) / (2 * h)
    return f, dfdth * om[:, None], om


def _accel_event(sig: RunSignals, w: MotionWindow, t0: float, eps: float) -> TimingEvent | None:
    """Local offset from the specific force over the readings' constant-acceleration intervals (module docstring).

    Every unit sample inside such an interval (``INTERVAL_MARGIN`` clear of its ends) is compared with gravity's
    projection at the table time it sees, c = t₀ + (1 + ε)(s − latency − δ), the angle exactly the interval's quadratic:
    f(s) = b + M f_ref(c) + k_ω ω(c)² + k_α α, per accelerometer a bias, a full 3 × 3 matrix (scale,
    misalignment), a centripetal and a tangential coefficient (lever arms) as nuisances; δ by Gauss–Newton with
    ∂f_ref/∂t as its Jacobian.
    """
    ivs = constant_acceleration_intervals(sig.table_time, sig.angles, sig.rates, w.readings, w.axis)
    if len(ivs) < 3:
        return None
    starts = np.array([i for i, _ in ivs], dtype=np.int64)
    alphas = np.array([a for _, a in ivs])
    alphas[np.abs(alphas) < 1e-3] = 0.0  # the readings' rate jitter: at rest or at constant rate
    lo_t = sig.table_time[starts] + INTERVAL_MARGIN
    hi_t = sig.table_time[starts + 1] - INTERVAL_MARGIN
    u_b = body_rate(sig.angles[w.readings[0]], np.eye(3)[w.axis], sig.mounting)
    u_b = u_b / np.linalg.norm(u_b)
    delta, sd, rms, step, speed = 0.0, math.nan, math.nan, 0.0, 0.0
    resid, mv = np.zeros((0, 3)), np.zeros(0, bool)
    for _ in range(4):
        c_all = t0 + (1.0 + eps) * (sig.t - sig.latency - delta)
        k = np.searchsorted(hi_t, c_all)  # the interval each sample could fall in
        inside = k < starts.size
        inside[inside] &= c_all[inside] >= lo_t[k[inside]]
        if np.count_nonzero(inside) < 30:
            return None
        c, seg_k = c_all[inside], k[inside]
        f_ref, fdot, om = _accel_reference(sig, c, starts[seg_k], alphas[seg_k], w.axis)
        om = np.where(np.abs(om) < 2e-4, 0.0, om)  # at rest (the readings' rate jitter)
        om_b = om[:, None] * u_b
        w2 = np.sum(om_b * om_b, axis=1)
        x0 = np.column_stack([np.ones_like(c), f_ref, w2, alphas[seg_k]])
        x0 = x0[:, np.any(x0 != 0.0, axis=0)]  # no tangential/centripetal column where the table never turned
        dcol = -(1.0 + eps) * fdot  # ∂f/∂δ per accelerometer (M ≈ 1)
        step, sd, rms, resid = _shared_shift(x0, sig.accel[inside], dcol)
        delta += step
        mv = np.abs(om) > 0
        speed = float(np.sqrt(np.mean(np.sum(fdot[mv] ** 2, axis=1)))) if np.any(mv) else 0.0
        if abs(step) < 1e-8:
            break
    if not math.isfinite(sd) or speed <= 0 or sd > MAX_EVENT_SIGMA or abs(step) > 1e-6:
        return None  # δ not determined: no change of rate inside the intervals (a constant-rate spin's shift is a
        # rotation the misalignment nuisances absorb), or the fit did not converge
    tm = sig.table_time[w.readings[w.moving]] if np.any(w.moving) else sig.table_time[w.readings]
    return TimingEvent(
        t_unit=float(np.mean((tm - t0) / (1.0 + eps))),
        offset=t0 - (1.0 + eps) * delta,
        u=(1.0 + eps) * sd,
        axis=w.axis,
        readings=len(ivs) + 1,
        rms_time=rms / speed,
        jitter=excess_jitter(resid, mv, speed),
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
    use_gyro: bool | None = None,
    initial: tuple[float, float] | None = None,
) -> TimeBase:
    """The run's time base from its data (module docstring).

    Parameters
    ----------
    sig : RunSignals
    window : s, event window before/after each motion.
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
    motions = single_axis_motions(sig.angles, sig.rates)  # the readings' motions: the same in both passes
    axes: dict[tuple[int, int], NDArray[np.float64]] = {}  # the gyro's sensitive axis per (axis, first reading)
    for _ in range(2):  # the second pass re-measures every motion on the corrected mapping
        tw = (sig.table_time - t0) / (1.0 + eps)  # windows found on the unit's time axis
        wins, skipped = motion_windows(tw, sig.angles, sig.rates, window=window, motions=motions)
        events = []
        for w in wins:
            ev = _gyro_event(sig, w, t0, eps, axes) if use_gyro else _accel_event(sig, w, t0, eps)
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
            f"{unused} motion window(s) not used: "
            + (
                "too few readings, or the unit's signal does not follow the table's (a gyro angle off by more than "
                "1 %: a saturated or misconfigured output?)"
                if use_gyro
                else "no change of rate between two "
                "readings of constant acceleration (a constant-rate spin's start or stop, a multi-axis slew)"
            )
        )
    if len(events) == 1:
        notes.append("one motion only: the rate is taken from the reading times, without a stated uncertainty")
    evs = [TimingEvent(e.t_unit, e.offset, e.u, e.axis, e.readings, e.rms_time, float(r), e.jitter)
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
