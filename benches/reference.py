"""Reference specific force and body rate for recorded samples, from the table's own readings.

What a real bench knows: the table's reported gimbal angles and rates (one reading per acquisition block,
time-stamped by the controller), the unit's mounting on the inner gimbal (C_b^t, bench file) and the
local gravity of the site (measured, or WGS-84 normal gravity). The simulator's truth is never used.

Frames: ENU navigation frame n; body frame b. f_ref = C_n^b [0, 0, g]ᵀ (m/s², body frame: the specific
force at rest, an upward reading on an up axis); ω = body angular rate relative to the ground (rad/s, body
frame) from the gimbal rates (Earth rate is negligible for the centripetal term, < 1e-8 m/s²).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from analysis.gimbal import body_rate, gravity_in_body


def interpolate_table(
    t: NDArray[np.float64],
    table_time: NDArray[np.float64],
    table_angles: NDArray[np.float64],
    table_rates: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gimbal angles and rates (rad, rad/s) at sample times ``t`` by linear interpolation of readings.

    Angles are unwrapped readings, so interpolation across a spin is exact for a constant rate.
    Outside the span of the readings the nearest reading is held.
    """
    if table_time.size == 0:
        raise ValueError("the recording has no table readings; the reference attitude is unknown")
    order = np.argsort(table_time, kind="stable")
    tt = table_time[order]
    ang = np.column_stack([np.interp(t, tt, table_angles[order, k]) for k in range(3)])
    rat = np.column_stack([np.interp(t, tt, table_rates[order, k]) for k in range(3)])
    return ang, rat


def reference_at(
    angles: NDArray[np.float64], rates: NDArray[np.float64], g: float, mounting: NDArray[np.float64] | None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reference specific force (m/s², body) and body rate (rad/s, body) for gimbal angles/rates (n, 3)."""
    return gravity_in_body(angles, g, mounting), body_rate(angles, rates, mounting)
