"""Linear least squares at fixed frequencies (spec step 2): offset, amplitudes and phases of the tones.

Columns ``[1, cos 2πf_i t, sin 2πf_i t]``; a_i = A_i cos φ_i, b_i = −A_i sin φ_i, A_i = √(a_i² + b_i²),
φ_i = atan2(−b_i, a_i). Shared by the refinement methods and the comparison.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["design_matrix", "solve_lsq", "fit_fixed_frequencies", "tones"]


def design_matrix(t: NDArray[np.float64], freqs: Sequence[float]) -> NDArray[np.float64]:
    """Columns ``[1, cos 2πf_1 t, sin 2πf_1 t, …]`` at times ``t`` (s) for frequencies ``freqs`` (Hz)."""
    cols = [np.ones_like(t)]
    for f in freqs:
        arg = 2.0 * np.pi * f * t
        cols += [np.cos(arg), np.sin(arg)]
    return np.stack(cols, axis=1)


def solve_lsq(design: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least-squares coefficients: normal equations when well conditioned (fast), else SVD ``lstsq``."""
    gram = design.T @ design
    d = np.sqrt(np.diag(gram))
    if np.all(d > 0):
        gs = gram / np.outer(d, d)
        # normal equations lose cond(Gram) = cond(X)² in accuracy: accept only near-orthogonal columns
        # (separated tones: cond ≈ 1–2), so the relative error stays ≤ 1e4 ε ≈ 2e-12
        if np.linalg.cond(gs) < 1e4:
            return np.linalg.solve(gs, (design.T @ v) / d) / d
    return np.linalg.lstsq(design, v, rcond=None)[0]


def fit_fixed_frequencies(
    x: ArrayLike, rate_hz: float, frequencies_hz: Sequence[float]
) -> tuple[float, NDArray[np.float64], NDArray[np.float64], float]:
    """Linear least squares for offset, amplitudes and phases at fixed frequencies.

    Parameters
    ----------
    x : array_like
        1-D samples (channel SI unit), sample 0 at t = 0.
    rate_hz : float
        Sample rate, Hz.
    frequencies_hz : sequence of float
        The tone frequencies, Hz.

    Returns
    -------
    offset : float
        c₀ (channel SI unit).
    amplitudes, phases : ndarray
        A_i ≥ 0 (channel SI unit) and φ_i (rad, in (−π, π]) of ``A_i cos(2π f_i t + φ_i)``.
    rss : float
        Residual sum of squares (unit²).
    """
    v = np.asarray(x, dtype=np.float64)
    t = np.arange(v.size) / rate_hz
    design = design_matrix(t, frequencies_hz)
    coef = solve_lsq(design, v)
    res = v - design @ coef
    a, b = coef[1::2], coef[2::2]
    return float(coef[0]), np.hypot(a, b), np.arctan2(-b, a), float(res @ res)


def tones(t: NDArray[np.float64], freqs: ArrayLike, amps: ArrayLike, phases: ArrayLike) -> NDArray[np.float64]:
    """``Σ A_i cos(2π f_i t + φ_i)`` at times ``t`` (s)."""
    out = np.zeros_like(t)
    for f, a, ph in zip(np.atleast_1d(freqs), np.atleast_1d(amps), np.atleast_1d(phases), strict=True):
        out += a * np.cos(2.0 * np.pi * f * t + ph)
    return out
