"""``tablebench correct`` with a thermal calibration: the parameters at each sample's own temperature
(docs/methods/thermal.md, "Compensation").

For every sample, the 30 parameters are the thermal model evaluated at the unit's temperature channel
(:meth:`analysis.thermal.model.ThermalModel.evaluate`); the gyro output is compensated first,
ω_ib = (I + M(T))⁻¹ (ω_out − b_g(T)) with M = diag(S_g) + the misalignments τ_g, then the accelerometer's by
the exact inverse model (:func:`analysis.identification.model.correct`, Newton per sample) with the
compensated rates in its size-effect term. The temperature channel is quantised (0.01 K steps), so samples
are grouped by their temperature value and each group is compensated with its parameters: exact, and
vectorised.

Outside the calibrated range (the plateau temperatures' span) the model is an extrapolation: refused unless
the user asks for a warning instead (``--outside-range warn``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from analysis.identification.model import correct as correct_accel
from analysis.thermal.model import ThermalModel
from analysis.units import CELSIUS_ZERO
from benches.thermal.plateau import MISALIGNMENT_PAIRS

OUTSIDE_CHOICES = ("refuse", "warn")


class OutsideRangeError(ValueError):
    """Samples at temperatures outside the calibrated range (and the user asked to refuse)."""


def range_check(model: ThermalModel, temperature: NDArray[np.float64], outside: str) -> str | None:
    """None if every temperature lies in the model's validity range; else the message (raised as
    :class:`OutsideRangeError` when ``outside`` is "refuse", returned as a warning when "warn")."""
    if outside not in OUTSIDE_CHOICES:
        raise ValueError(f"outside must be one of {OUTSIDE_CHOICES}, got {outside!r}")
    t = np.asarray(temperature, dtype=float)
    if not np.all(np.isfinite(t)):
        raise OutsideRangeError(f"{int(np.sum(~np.isfinite(t)))} samples have no valid unit temperature (NaN)")
    bad = ~model.in_range(t)
    if not np.any(bad):
        return None
    lo, hi = (v - CELSIUS_ZERO for v in model.temperature_range)
    msg = (
        f"{int(bad.sum())} of {t.size} samples lie at unit temperatures {t[bad].min() - CELSIUS_ZERO:.2f} to "
        f"{t[bad].max() - CELSIUS_ZERO:.2f} °C, outside the calibrated range {lo:.2f} to {hi:.2f} °C"
    )
    if outside == "refuse":
        raise OutsideRangeError(
            msg + "; the model would be extrapolated there — calibrate over that range, or pass "
            "--outside-range warn to apply it anyway"
        )
    return msg + " (model extrapolated there)"


def gyro_matrices(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(I + M (m, 3, 3), b (m, 3)) of the gyro from the thermal parameters x (m, 30)."""
    g = x[:, 18:]
    m = np.zeros((len(x), 3, 3))
    m[:, [0, 1, 2], [0, 1, 2]] = 1.0 + g[:, 3:6]
    for k, (i, j) in enumerate(MISALIGNMENT_PAIRS):
        m[:, i, j] = g[:, 6 + k]
    return m, g[:, :3]


def thermal_correct(
    model: ThermalModel,
    f_out: NDArray[np.float64],
    gyro_out: NDArray[np.float64],
    temperature: NDArray[np.float64],
    outside: str = "refuse",
) -> tuple[NDArray[np.float64], str | None]:
    """Compensated [f (m/s²), ω_ib (rad/s)] (n, 6), body frame, and the range warning (None if in range).

    Parameters
    ----------
    model : ThermalModel
        The 30-parameter thermal model (``benches.thermal.plateau.THERMAL_PARAM_NAMES``).
    f_out, gyro_out : (n, 3)
        Raw accelerometer (m/s²) and gyro (rad/s) outputs, body frame.
    temperature : (n,)
        The unit's temperature channel, K.
    outside : {"refuse", "warn"}
    """
    f_out = np.asarray(f_out, dtype=float)
    gyro_out = np.asarray(gyro_out, dtype=float)
    t = np.asarray(temperature, dtype=float)
    if f_out.shape != gyro_out.shape or f_out.ndim != 2 or f_out.shape[1] != 3 or t.shape != (len(f_out),):
        raise ValueError(f"expected (n, 3), (n, 3), (n,); got {f_out.shape}, {gyro_out.shape}, {t.shape}")
    warning = range_check(model, t, outside)
    levels, inverse = np.unique(t, return_inverse=True)
    x, _ = model.evaluate(levels)  # (L, 30)
    m, b = gyro_matrices(x)
    rhs = gyro_out - b[inverse]
    omega = np.linalg.solve(m[inverse], rhs[:, :, None])[:, :, 0]
    f = np.empty_like(f_out)
    order = np.argsort(inverse, kind="stable")
    bounds = np.searchsorted(inverse[order], np.arange(len(levels) + 1))
    for k in range(len(levels)):
        idx = order[bounds[k] : bounds[k + 1]]
        f[idx] = correct_accel(x[k, :18], f_out[idx], omega[idx])
    return np.hstack([f, omega]), warning
