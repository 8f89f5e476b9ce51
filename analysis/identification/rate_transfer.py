"""Gyro rate-transfer test: scale factor, scale-factor nonlinearity and asymmetry per axis (pure maths).

Definitions (IEEE Std 952-1997 § 3 and § 9.3, IEEE Std 1431-2004 the same; docs/methods/gyro-calibration.md):

* **scale factor** K: the slope of the least-squares straight line of the output against the input rate over
  the input range (here: the mean gyro output of each constant-rate spin, whole revolutions, and of the
  holds, against the reference ω_ib along the axis — the table rate from its encoder angles over time plus
  the Earth rate's component);
* **nonlinearity**: the largest deviation of the points from that line, as a fraction of the full-scale
  output (the line's output at the largest |input|), in ppm;
* **asymmetry**: the difference between the scale factor over positive inputs and over negative inputs,
  as a fraction of the average, in ppm. Both are fitted together with one common bias
  (y = b + K₊ ω for ω > 0, y = b + K₋ ω for ω ≤ 0), so the bias does not leak into either slope.

Uncertainties: every point's mean carries the white-noise variance of its window (ARW² × rate / n) plus,
when given, a bias-instability variance common to nothing (independent per window); the three figures are
linear (K, asymmetry) or first-order (nonlinearity: the residual at the point of the largest deviation) in
the means, so their standard uncertainties follow by the law of propagation (GUM 5.1.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class AxisRateTransfer:
    """Rate-transfer result of one gyro axis (SI unless a name says ppm).

    Attributes
    ----------
    axis : str
        Body axis ("x", "y", "z").
    rate_in, rate_out, u_out : ndarray (k,)
        Reference input rate, mean output and the standard uncertainty of the mean per point, rad/s.
    scale_factor, u_scale_factor : float
        K (output per input, 1 + S) and its u.
    bias : float
        Intercept of the line, rad/s.
    residuals : ndarray (k,)
        Deviation of each point from the line, rad/s.
    full_scale : float
        |K| × max |input|, rad/s.
    nonlinearity_ppm, u_nonlinearity_ppm : float
        max |residual| / full scale, ppm, and its u.
    asymmetry_ppm, u_asymmetry_ppm : float
        (K₊ − K₋) / ((K₊ + K₋)/2), ppm, and its u.
    """

    axis: str
    rate_in: NDArray[np.float64]
    rate_out: NDArray[np.float64]
    u_out: NDArray[np.float64]
    scale_factor: float
    u_scale_factor: float
    bias: float
    residuals: NDArray[np.float64]
    full_scale: float
    nonlinearity_ppm: float
    u_nonlinearity_ppm: float
    asymmetry_ppm: float
    u_asymmetry_ppm: float

    def as_dict(self) -> dict[str, object]:
        """JSON-ready mapping (SI arrays as lists)."""
        return {
            "axis": self.axis,
            "rate_in": self.rate_in.tolist(),
            "rate_out": self.rate_out.tolist(),
            "u_out": self.u_out.tolist(),
            "scale_factor": self.scale_factor,
            "u_scale_factor": self.u_scale_factor,
            "bias": self.bias,
            "residuals": self.residuals.tolist(),
            "full_scale": self.full_scale,
            "nonlinearity_ppm": self.nonlinearity_ppm,
            "u_nonlinearity_ppm": self.u_nonlinearity_ppm,
            "asymmetry_ppm": self.asymmetry_ppm,
            "u_asymmetry_ppm": self.u_asymmetry_ppm,
        }


def _wls(a: NDArray[np.float64], y: NDArray[np.float64], w: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Weighted least squares: the estimate and the linear map L (estimate = L y)."""
    aw = a * w[:, None]
    lin = np.linalg.solve(a.T @ aw, aw.T)
    return lin @ y, lin


def rate_transfer_axis(axis: str, rate_in: ArrayLike, rate_out: ArrayLike, u_out: ArrayLike) -> AxisRateTransfer:
    """Scale factor, nonlinearity and asymmetry of one axis from its points (module docstring).

    Parameters
    ----------
    axis : str
        Body axis name.
    rate_in : array_like (k,)
        Reference input rate along the axis per point (ω_ib: table rate + Earth rate component), rad/s.
    rate_out : array_like (k,)
        Mean gyro output of the axis per point, rad/s.
    u_out : array_like (k,)
        Standard uncertainty of each mean, rad/s (> 0).
    """
    x = np.asarray(rate_in, dtype=float).reshape(-1)
    y = np.asarray(rate_out, dtype=float).reshape(-1)
    u = np.asarray(u_out, dtype=float).reshape(-1)
    if not (x.shape == y.shape == u.shape) or x.size < 4 or np.any(u <= 0) or not np.all(np.isfinite(x + y + u)):
        raise ValueError("rate transfer needs at least 4 finite points with positive uncertainties")
    if not (np.any(x > 0) and np.any(x < 0)):
        raise ValueError("rate transfer needs input rates of both signs (spins in both directions)")
    w = 1.0 / u**2
    cov_y = np.diag(u**2)
    line = np.column_stack([np.ones_like(x), x])
    (b, k), lin = _wls(line, y, w)
    res_map = np.eye(x.size) - line @ lin  # residuals = (I − A L) y
    res = res_map @ y
    u_k = float(np.sqrt(lin[1] @ cov_y @ lin[1]))
    fs = abs(k) * float(np.max(np.abs(x)))
    j = int(np.argmax(np.abs(res)))
    u_res = float(np.sqrt(res_map[j] @ cov_y @ res_map[j]))
    split = np.column_stack([np.ones_like(x), np.where(x > 0, x, 0.0), np.where(x > 0, 0.0, x)])
    (_, kp, kn), lin2 = _wls(split, y, w)
    kbar = 0.5 * (kp + kn)
    asym = (kp - kn) / kbar
    grad = (lin2[1] - lin2[2]) / kbar - asym * 0.5 * (lin2[1] + lin2[2]) / kbar  # ∂asym/∂y
    u_asym = float(np.sqrt(grad @ cov_y @ grad))
    return AxisRateTransfer(
        axis=axis, rate_in=x, rate_out=y, u_out=u, scale_factor=float(k), u_scale_factor=u_k, bias=float(b),
        residuals=res, full_scale=fs, nonlinearity_ppm=float(abs(res[j]) / fs * 1e6),
        u_nonlinearity_ppm=u_res / fs * 1e6, asymmetry_ppm=float(asym * 1e6), u_asymmetry_ppm=u_asym * 1e6,
    )  # fmt: skip


__all__ = ["AxisRateTransfer", "rate_transfer_axis"]
