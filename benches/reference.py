"""THE reference specific force and body rate for recorded samples, from the table's own readings.

One function, :func:`reference_for_window`, serves the identification (offline and live), the uncertainty
budget and the certificate's plots, so they cannot diverge.

What a real bench knows: the table's reported gimbal angles and rates (time-stamped by the controller), the
unit's mounting on the inner gimbal (C_b^t, bench file), its output latency (the sample stamped t measures
the specific force of t − latency) and the local gravity of the site (measured, or WGS-84 normal gravity).
The simulator's truth is never used.

Frames: ENU navigation frame n; body frame b. f_ref = C_n^b [0, 0, g]ᵀ (m/s², body frame: the specific
force at rest, an upward reading on an up axis); ω = body angular rate relative to the ground (rad/s, body
frame) from the gimbal rates (Earth rate is negligible for the centripetal term, < 1e-8 m/s²).

Motion boundaries: the readings used for a step are only those the controller took during that step
(``span``). A sample time after the step's last reading (or before its first) is **extrapolated from that
boundary reading with its own reported rate** — never interpolated towards a reading of the next motion
(which a controller reporting on its own clock may take after the next move has started). That rule is written
once, in :func:`interpolate_windows` (many windows in one pass: the time base's sensitivities); one window is
:func:`interpolate_table`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from analysis.earth import earth_rate_enu
from analysis.gimbal import Trig, angle_trig, body_rate, gravity_in_body, nav_to_body


def interpolate_table(
    t: NDArray[np.float64],
    table_time: NDArray[np.float64],
    table_angles: NDArray[np.float64],
    table_rates: NDArray[np.float64],
    span: tuple[float, float] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gimbal angles and rates (rad, rad/s) at times ``t`` (s) from the table's readings: one window of
    :func:`interpolate_windows` (THE rule: linear between the readings inside ``span`` = (t_start, t_end) of one
    step, all readings if None; outside them the boundary reading extrapolated with its reported rate)."""
    return interpolate_windows([t], [span], table_time, table_angles, table_rates)


def interpolate_windows(
    times: Sequence[NDArray[np.float64]],
    spans: Sequence[tuple[float, float] | None],
    table_time: NDArray[np.float64],
    table_angles: NDArray[np.float64],
    table_rates: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gimbal angles and rates (rad, rad/s; (n, 3), the windows' rows one after the other) at every window's
    sample times ``times[i]`` (s, table clock) from the table's readings within the window's ``spans[i]``.

    THE interpolation rule of the reference (the one place it is written; :func:`interpolate_table` is its
    one-window form):

    - a window's readings are those taken inside its span (t_start ≤ time ≤ t_end), all if the span is None;
      with no reading inside the span, the last one at or before its start (same motion state), the table's
      first if none is;
    - between two of them: linear interpolation (angles are unwrapped readings, so across a spin it is exact
      for a constant rate);
    - before the first of them or after the last: that boundary reading extrapolated with its own reported
      rate (a hold: held) — never interpolated towards a reading of the next motion;
    - exactly at a reading's time: that reading;
    - readings are taken in time order (stable for equal times); a reading with a NaN time is no reading; a NaN
      sample time gives NaN angles and rates.

    All windows are interpolated in one pass per column over the readings any of them uses (between two
    readings of a span an interpolation uses only those two, whichever other readings lie around them), then
    each window's rows outside its span's readings are replaced by the extrapolation.
    """
    tt = np.asarray(table_time, dtype=float)
    ta = np.asarray(table_angles, dtype=float)
    tr = np.asarray(table_rates, dtype=float)
    if not np.all(tt[1:] >= tt[:-1]):  # out of order, or NaN times: ordered, NaN-timed readings dropped
        known = np.flatnonzero(~np.isnan(tt))
        order = known[np.argsort(tt[known], kind="stable")]
        tt, ta, tr = tt[order], ta[order], tr[order]
    if tt.size == 0 or np.isnan(tt[0]):
        raise ValueError("the recording has no table readings; the reference attitude is unknown")
    tq = [np.asarray(t, dtype=float).reshape(-1) for t in times]
    q = np.concatenate(tq) if len(tq) > 1 else tq[0] if tq else np.empty(0)
    starts = [s[0] if s is not None else -np.inf for s in spans]
    lo = np.searchsorted(tt, starts, side="left")  # each window's readings: [lo, hi)
    hi = np.searchsorted(tt, [s[1] if s is not None else np.inf for s in spans], side="right")
    alone = lo >= hi  # no reading inside the span: the last one at or before its start (the table's first if none)
    if np.any(alone):
        last = np.maximum(np.searchsorted(tt, starts, side="right") - 1, 0)
        lo, hi = np.where(alone, last, lo), np.where(alone, last + 1, hi)
    # one interpolation per column over the readings any window uses (between two readings of a span it uses
    # only those two, whichever other readings lie between the windows)
    used = slice(int(lo.min()), int(hi.max())) if lo.size else slice(0, 1)
    ang = np.column_stack([np.interp(q, tt[used], ta[used, k]) for k in range(3)])
    rat = np.column_stack([_interp(q, tt[used], tr[used, k]) for k in range(3)])
    start = 0
    for t, a, b, one in zip(tq, lo.tolist(), hi.tolist(), alone.tolist(), strict=True):
        rows0 = start
        start += t.size
        if one:  # at its time: that reading, not another one of the same time
            at = np.flatnonzero(t == tt[a]) + rows0
            ang[at] = ta[a]
            rat[at] = tr[a]
        for j, side in ((a, t < tt[a]), (b - 1, t > tt[b - 1])):
            if np.any(side):  # outside the span's readings: the boundary reading, extrapolated with its rate
                rows = np.flatnonzero(side) + rows0
                rat[rows] = tr[j]
                ang[rows] = ta[j]
                ang[rows] += (t[side] - tt[j])[:, None] * tr[j]
    if q.size and np.isnan(q.min()):  # a NaN time: NaN (np.interp gives a finite value with a single reading)
        nan = np.isnan(q)
        ang[nan] = np.nan
        rat[nan] = np.nan
    return ang, rat


def _interp(x: NDArray[np.float64], xp: NDArray[np.float64], fp: NDArray[np.float64]) -> NDArray[np.float64]:
    """``np.interp(x, xp, fp)``, bit for bit; readings of one value (a hold's reported rate) filled with it.

    np.interp gives exactly that value at every x then: the reading itself at and beyond the readings' times,
    between two of them slope·(x − x_j) + f_j with slope (f − f)/Δx = +0 (0/0 for equal times falls back to
    f_j), so +0 + f_j = f_j. Interpolated as np.interp does: f_j = −0.0 (+0 + −0 is +0), NaN readings, and any
    NaN x (what np.interp gives for it depends on the number of readings). A test compares it with np.interp on
    such columns (tests/benches/test_reference_shortcuts.py)."""
    bits = fp.view(np.int64)
    v = fp[0] if fp.size else np.nan
    mixed = np.any(bits != bits[0])
    if not np.isfinite(v) or (v == 0.0 and np.signbit(v)) or mixed or np.isnan(np.min(x, initial=0.0)):
        return np.interp(x, xp, fp)
    return np.full(np.shape(x), v)


def reference_at(
    angles: NDArray[np.float64],
    rates: NDArray[np.float64],
    g: float,
    mounting: NDArray[np.float64] | None,
    *,
    trig: Trig | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reference specific force (m/s², body) and body rate (rad/s, body) for gimbal angles/rates (n, 3)
    (``trig``: their :func:`analysis.gimbal.angle_trig`, when the caller has them)."""
    return gravity_in_body(angles, g, mounting, trig=trig), body_rate(angles, rates, mounting, trig=trig)


def reference_for_window(
    t: NDArray[np.float64],
    table_time: NDArray[np.float64],
    table_angles: NDArray[np.float64],
    table_rates: NDArray[np.float64],
    *,
    g: float,
    mounting: NDArray[np.float64] | None,
    latency: float = 0.0,
    span: tuple[float, float] | None = None,
    gimbal_rates: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], Trig, NDArray[np.float64]]:
    """Reference for unit samples stamped ``t`` (s): the table at t − latency, within one step's ``span``.

    ``gimbal_rates``: the gimbal rates (3,) or (n, 3), rad/s, the body rate is formed from instead of the
    readings' reported rates (a spin's rate from its encoder angles, :func:`benches.identify.angle_over_time`);
    the same body rate as forming it again from them afterwards, once instead of twice.

    Returns
    -------
    f_ref : (n, 3)
        Reference specific force, body frame, m/s².
    omega : (n, 3)
        Body angular rate, body frame, rad/s.
    angles : (n, 3)
        Gimbal angles used (ψ, θ, γ), rad (for attitude sensitivities and plots).
    trig : Trig
        The angles' cosines and sines (:func:`analysis.gimbal.angle_trig`), for the caller's further rotations
        of the same samples (:func:`earth_in_body`, a spin's body rate): each computed once per window instead
        of once per rotation (the same values bit for bit).
    rates : (n, 3)
        The gimbal rates the table's readings give at the same times, rad/s (interpolated with the angles, by the
        same rule, whatever ``gimbal_rates`` says; the step geometry of the uncertainty budget keeps them): the
        window is interpolated once for both.
    """
    ang, rates = interpolate_table(np.asarray(t, dtype=float) - latency, table_time, table_angles, table_rates, span)
    trig = angle_trig(ang)
    rat = rates if gimbal_rates is None else np.broadcast_to(np.asarray(gimbal_rates, dtype=float), ang.shape)
    f_ref, omega = reference_at(ang, rat, g, mounting, trig=trig)
    return f_ref, omega, ang, trig, rates


def earth_in_body(
    angles: NDArray[np.float64], latitude: float, mounting: NDArray[np.float64] | None, *, trig: Trig | None = None
) -> NDArray[np.float64]:
    """Earth rate in the body frame at gimbal angles (n, 3), rad/s: C_n^b Ω [0, cos φ, sin φ] (ENU).

    The constant navigation-frame rate rotated into the body frame sample by sample
    (:func:`analysis.gimbal.nav_to_body`), not through a (n, 3, 3) C_b^n per sample (issue 32); ``trig``: the
    angles' :func:`analysis.gimbal.angle_trig`, when the caller has them."""
    return nav_to_body(angles, earth_rate_enu(latitude), mounting, trig=trig)


def acquisition_span(t_first: float, t_last: float, latency: float, sample_rate: float) -> tuple[float, float]:
    """Bench-time span (s) of the table readings that belong to an acquisition window's own motion state.

    From 1.5 sample periods before the first sample's reference time (t_first − latency) to 1.5 sample
    periods after the last sample: the reading the runner takes with each block is stamped at the next
    sample, so it closes the window (the half period covers the unit's time-stamp jitter); a reading later
    than that may already belong to the next motion and is never used
    (:func:`benches.reference.interpolate_table` extrapolates with the reported rate instead).
    """
    dt = 1.5 / sample_rate
    return (t_first - latency - dt, t_last + dt)
