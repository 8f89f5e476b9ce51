"""Per-plateau identification of both triads from the calibration sequence's windows (docs/methods/thermal.md).

Accelerometers: the 18-parameter batch least squares of :mod:`analysis.identification.batch` on every sample
of the held and spun windows. Gyros: per axis i, the linear least squares

    ω_out,i − ω_i = b_i + Σ_j M_ij ω_j,   ω = table rate + Earth rate, body frame b

(M_ii = scale factor S_i, M_ij = misalignment τ_ij), whose covariance is σ_i² (AᵀA)⁻¹ with σ_i² the
configured white-noise variance per sample. The 30 parameters of a plateau are returned with their
covariance (the two triads' noises are independent, so it is block diagonal).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from analysis.identification.batch import batch_identify
from analysis.identification.model import PARAM_NAMES

MISALIGNMENT_PAIRS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
GYRO_PARAM_NAMES: tuple[str, ...] = ("gb_x", "gb_y", "gb_z", "gS_x", "gS_y", "gS_z") + tuple(
    f"gtau_{'xyz'[i]}{'xyz'[j]}" for i, j in MISALIGNMENT_PAIRS
)
"""Gyro parameters: bias (rad/s), scale factor, misalignment (rad), in the accelerometer model's order."""
THERMAL_PARAM_NAMES: tuple[str, ...] = tuple(PARAM_NAMES) + GYRO_PARAM_NAMES
"""The 30 parameters of a thermal model: 18 accelerometer (analysis.identification.model) + 12 gyro."""


@dataclass
class PlateauData:
    """Samples of one plateau's calibration sequence (body frame, SI).

    Attributes
    ----------
    accel, gyro : lists of (n, 3) arrays — the unit's outputs, m/s² and rad/s.
    f_ref, omega : lists of (n, 3) — reference specific force (m/s²) and table body rate w.r.t. the Earth
        (rad/s) from the table's angles and rates.
    earth : list of (n, 3) — Earth rate in the body frame, rad/s.
    temperature, time : lists of (n,) — unit temperature (K) and bench time (s).
    """

    accel: list[NDArray[np.float64]] = field(default_factory=list)
    gyro: list[NDArray[np.float64]] = field(default_factory=list)
    f_ref: list[NDArray[np.float64]] = field(default_factory=list)
    omega: list[NDArray[np.float64]] = field(default_factory=list)
    earth: list[NDArray[np.float64]] = field(default_factory=list)
    temperature: list[NDArray[np.float64]] = field(default_factory=list)
    time: list[NDArray[np.float64]] = field(default_factory=list)

    def stacked(self) -> dict[str, NDArray[np.float64]]:
        """Every list concatenated."""
        return {k: np.concatenate(getattr(self, k)) for k in self.__dataclass_fields__}


def identify_gyro(
    gyro: NDArray[np.float64], omega: NDArray[np.float64], variance: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Gyro bias, scale and misalignment (12, ``GYRO_PARAM_NAMES`` order) and their covariance (12, 12).

    Parameters
    ----------
    gyro : (n, 3) rad/s, body frame — the gyro outputs.
    omega : (n, 3) rad/s, body frame — the true angular rate w.r.t. inertial space (table + Earth).
    variance : (3,) (rad/s)² — white-noise variance per sample and axis.
    """
    x = np.zeros(12)
    cov = np.zeros((12, 12))
    a = np.column_stack([np.ones(len(omega)), omega])
    info = a.T @ a
    inv = np.linalg.inv(info)
    for i in range(3):
        beta = inv @ (a.T @ (gyro[:, i] - omega[:, i]))
        # beta = [b_i, M_i0, M_i1, M_i2]
        idx = [i, 3 + i] + [6 + k for k, (r, c) in enumerate(MISALIGNMENT_PAIRS) if r == i]
        cols = [0, 1 + i] + [1 + c for (r, c) in MISALIGNMENT_PAIRS if r == i]
        x[idx] = beta[cols]
        cov[np.ix_(idx, idx)] = variance[i] * inv[np.ix_(cols, cols)]
    return x, cov


def identify_plateau(
    data: PlateauData, accel_variance: NDArray[np.float64], gyro_variance: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """(x (30,), covariance (30, 30), mean unit temperature K, mean rate K/s) of one plateau."""
    s = data.stacked()
    acc = batch_identify(s["accel"], s["f_ref"], s["omega"], accel_variance)
    if acc.rank < 18:
        raise ValueError(
            f"the plateau's calibration sequence identifies only {acc.rank} of 18 accelerometer parameters"
        )
    gx, gcov = identify_gyro(s["gyro"], s["omega"] + s["earth"], gyro_variance)
    x = np.concatenate([acc.x, gx])
    cov = np.zeros((30, 30))
    cov[:18, :18] = acc.covariance
    cov[18:, 18:] = gcov
    t, temp = s["time"], s["temperature"]
    rate = float(np.polyfit(t - t.mean(), temp, 1)[0]) if np.ptp(t) > 0 else 0.0
    return x, cov, float(np.mean(temp)), rate
