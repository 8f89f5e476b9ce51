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
(which a controller reporting on its own clock may take after the next move has started).
"""

from __future__ import annotations

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
    """Gimbal angles and rates (rad, rad/s) at times ``t`` (s) from the table's readings.

    Linear interpolation between readings inside ``span`` = (t_start, t_end) of one step (all readings if
    None). Angles are unwrapped readings, so interpolation across a spin is exact for a constant rate.
    Outside the readings the boundary reading is extrapolated with its reported rate (a hold: held).
    """
    tt_all = np.asarray(table_time, dtype=float)
    if tt_all.size == 0:
        raise ValueError("the recording has no table readings; the reference attitude is unknown")
    ta = np.asarray(table_angles, dtype=float)
    tr = np.asarray(table_rates, dtype=float)
    if span is not None:
        keep = (tt_all >= span[0]) & (tt_all <= span[1])
        if not np.any(keep):  # no reading inside the step: the nearest one before it (same motion state)
            before = np.flatnonzero(tt_all <= span[0])
            keep = np.zeros(tt_all.size, bool)
            keep[before[-1] if before.size else 0] = True
        tt_all, ta, tr = tt_all[keep], ta[keep], tr[keep]
    order = np.argsort(tt_all, kind="stable")
    tt, ta, tr = tt_all[order], ta[order], tr[order]
    tq = np.asarray(t, dtype=float)
    ang = np.column_stack([np.interp(tq, tt, ta[:, k]) for k in range(3)])
    rat = np.column_stack([np.interp(tq, tt, tr[:, k]) for k in range(3)])
    lo, hi = tq < tt[0], tq > tt[-1]
    if np.any(lo):
        ang[lo] += (tq[lo] - tt[0])[:, None] * tr[0]
    if np.any(hi):
        ang[hi] += (tq[hi] - tt[-1])[:, None] * tr[-1]
    return ang, rat


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
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], Trig]:
    """Reference for unit samples stamped ``t`` (s): the table at t − latency, within one step's ``span``.

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
    """
    ang, rat = interpolate_table(np.asarray(t, dtype=float) - latency, table_time, table_angles, table_rates, span)
    trig = angle_trig(ang)
    f_ref, omega = reference_at(ang, rat, g, mounting, trig=trig)
    return f_ref, omega, ang, trig


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
