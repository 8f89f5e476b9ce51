"""Frequency-drift removal before the stability deviations (as Stable32's "Drift" function offers).

Frequency data: the least-squares line (``linear``) or parabola (``quadratic``) in time t = i/rate is fitted to
the samples and subtracted. Phase data: the same drift seen in the phase, one order higher — a linear frequency
drift is a quadratic phase, so ``linear`` removes the least-squares quadratic of the phase and ``quadratic`` its
cubic. NaN samples (gaps) are left out of the fit and stay NaN. The removed polynomial is reported (coefficients
of t⁰, t¹, … in the data unit per sᵏ; for phase data, the frequency drift they mean is their derivative).
See docs/methods/noise.md.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

DRIFT_MODELS: dict[str, int] = {"linear": 1, "quadratic": 2}
"""Drift model → polynomial order in the frequency."""


def remove_drift(
    data: ArrayLike, rate: float, model: str, data_type: str = "freq"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The record with its least-squares drift polynomial removed, and the polynomial's coefficients.

    Parameters
    ----------
    data : array_like (N,)
        Frequency (rate) or phase (angle) record, SI; NaN marks a gap.
    rate : float
        Sample rate, Hz.
    model : {"linear", "quadratic"}
        Drift of the frequency.
    data_type : {"freq", "phase"}
        What ``data`` holds (phase: the polynomial is one order higher).

    Returns
    -------
    residual : ndarray (N,)
    coefficients : ndarray (order + 1,)
        c_k of Σ c_k t^k, t = i/rate in s, lowest order first.
    """
    if model not in DRIFT_MODELS:
        raise ValueError(f"drift model must be one of {', '.join(DRIFT_MODELS)}, got {model!r}")
    y = np.asarray(data, dtype=np.float64).ravel()
    order = DRIFT_MODELS[model] + (1 if data_type == "phase" else 0)
    ok = np.isfinite(y)
    if np.count_nonzero(ok) <= order + 1:
        raise ValueError(f"too few finite samples to fit a {model} drift")
    t = np.arange(y.size, dtype=np.float64) / rate
    poly = np.polynomial.Polynomial.fit(t[ok], y[ok], order)  # scaled domain: well conditioned
    residual = y - poly(t)
    return residual, poly.convert().coef
