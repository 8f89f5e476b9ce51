"""Motions of the table found in its readings: the sharp features a time base is measured on.

A reading is *moving* when any reported gimbal rate exceeds ``rate_threshold`` or its angles differ from a
neighbouring reading's by more than ``angle_threshold``. Consecutive moving readings form one motion; a motion
is used only when one gimbal axis moved (a multi-axis re-orientation turns the moving axis in the body frame,
which the single-axis fit does not model). Each motion gives one event window (its readings ± ``window`` s), or
two (start and stop) when it lasts longer than 2 × ``window`` (a long spin). Times here are the table's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class MotionWindow:
    """Readings around one single-axis motion (indices into the reading arrays, sorted)."""

    axis: int
    readings: NDArray[np.int64]
    moving: NDArray[np.bool_]


def moving_readings(
    angles: NDArray[np.float64], rates: NDArray[np.float64], rate_threshold: float, angle_threshold: float
) -> NDArray[np.bool_]:
    """Moving flag per reading (see module docstring). angles (m, 3) rad, rates (m, 3) rad/s."""
    mv = np.any(np.abs(rates) > rate_threshold, axis=1)
    if angles.shape[0] > 1:
        step = np.any(np.abs(np.diff(angles, axis=0)) > angle_threshold, axis=1)
        mv[1:] |= step
        mv[:-1] |= step
    return mv


def _runs(flag: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """[start, end] (inclusive) index ranges of consecutive True values."""
    d = np.diff(np.concatenate([[0], flag.astype(np.int8), [0]]))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def single_axis_motions(
    angles: NDArray[np.float64],
    rates: NDArray[np.float64],
    *,
    rate_threshold: float = 2e-4,
    angle_threshold: float = 1e-4,
    moved_threshold: float = 1e-3,
) -> tuple[NDArray[np.bool_], list[tuple[int, int, int]]]:
    """The time-independent part of :func:`motion_windows`: the moving flag per reading and, per motion (a run of
    moving readings), (first reading, last reading, the gimbal axis that moved, or −1 when not exactly one did)."""
    mv = moving_readings(angles, rates, rate_threshold, angle_threshold)
    m = angles.shape[0]
    out: list[tuple[int, int, int]] = []
    for a, b in _runs(mv):
        lo_i, hi_i = max(0, a - 1), min(m - 1, b + 1)
        span = np.ptp(angles[lo_i : hi_i + 1], axis=0)
        spinning = np.any(np.abs(rates[a : b + 1]) > rate_threshold, axis=0)
        moved = np.flatnonzero((span > moved_threshold) | spinning)
        out.append((a, b, int(moved[0]) if moved.size == 1 else -1))
    return mv, out


def motion_windows(
    times: NDArray[np.float64],
    angles: NDArray[np.float64],
    rates: NDArray[np.float64],
    *,
    window: float = 1.5,
    rate_threshold: float = 2e-4,
    angle_threshold: float = 1e-4,
    moved_threshold: float = 1e-3,
    motions: tuple[NDArray[np.bool_], list[tuple[int, int, int]]] | None = None,
) -> tuple[list[MotionWindow], int]:
    """Event windows around single-axis motions, and the number of multi-axis motions skipped.

    Parameters
    ----------
    times : (m,) s; angles : (m, 3) rad (unwrapped); rates : (m, 3) rad/s — the table's readings in time order.
    window : s, how far an event window reaches before a motion starts and after it ends.
    rate_threshold : rad/s; angle_threshold : rad — the moving test. moved_threshold : rad, an axis whose
        angle changes by more than this over the motion has moved (a spin always has).
    motions : :func:`single_axis_motions` of the same readings and thresholds, when already found (they do not
        depend on ``times``: a caller that maps the times anew reuses them).
    """
    mv, runs = motions if motions is not None else single_axis_motions(
        angles, rates, rate_threshold=rate_threshold, angle_threshold=angle_threshold,
        moved_threshold=moved_threshold,
    )  # fmt: skip
    out: list[MotionWindow] = []
    skipped = 0
    m = times.shape[0]
    for j, (a, b, axis) in enumerate(runs):
        if axis < 0:
            skipped += 1
            continue
        prev_end = runs[j - 1][1] if j > 0 else -1
        next_start = runs[j + 1][0] if j + 1 < len(runs) else m
        ta, tb = times[a], times[b]
        parts = [(ta - window, tb + window)] if tb - ta <= 2 * window else [(ta - window, ta + window),
                                                                              (tb - window, tb + window)]  # fmt: skip
        for t_lo, t_hi in parts:
            idx = np.arange(prev_end + 1, next_start)
            idx = idx[(times[idx] >= t_lo) & (times[idx] <= t_hi)]
            if idx.size:
                out.append(MotionWindow(axis, idx.astype(np.int64), mv[idx]))
    return out, skipped
