"""Correlated bias drift between the steps of a calibration: flicker (bias instability) propagated honestly.

The datasheet gives the unit's bias instability B (the flicker floor of the Allan deviation, σ_A ≈ 0.664 B,
IEEE 952 / IEEE 1293 noise model). Over a calibration lasting an hour, flicker noise is not white: the
offsets of the steps are correlated, and a slow wander across the eight positions of a step sequence
aliases into scale and misalignment. This module gives the covariance of the step-mean offsets and its
effect on the estimate, for the pre-run plan and for the reported uncertainty alike.

Model (documented assumption). Flicker noise of floor B is represented, as is standard (Keshner 1982), by
a sum of first-order Gauss–Markov processes with corner frequencies spaced two per decade over a band
[f_lo, f_hi], each of variance B² Δ/π with Δ = ln(10)/2 (the log spacing): the sum has a one-sided PSD
≈ B²/(π f)·(2/π)·… ≈ the flicker PSD B²/(2π f)·(4 ln 2)/… whose Allan deviation floor is ≈ 0.664 B. The
default band [1e-4, 1] Hz spans the calibration's time scales: slower wander is common to every step (it
is the bias b), faster wander averages out within a hold like extra white noise (and is included here).

For a Gauss–Markov component of variance σ² and β = 2π f_c, the covariance of its means over two
windows [a_i, a_i + L_i] and [a_j, a_j + L_j] (a_i + L_i ≤ a_j) is

    σ² (1 − e^{−βL_i})(1 − e^{−βL_j}) e^{−β(a_j − a_i − L_i)} / (β² L_i L_j),

and the variance of one window mean is 2σ² (βL − 1 + e^{−βL}) / (β² L²).

Effect on the estimate x̂ = A⁻¹(P0⁻¹x0 + Σ HᵀR⁻¹z) of a per-step offset β_s (constant within step s,
body axis by axis): x̂ − x ∋ A⁻¹ Σ_s G_s β_s with G_s = Σ_{n∈s} w_n H_nᵀ R⁻¹ (18×3), so the systematic
covariance is A⁻¹ (Σ_axis G_aᵀ C_a G_a) A⁻¹ with C_a the (K×K) step-offset covariance of axis a.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

DEFAULT_BAND: tuple[float, float] = (1e-4, 1.0)
"""Default corner-frequency band of the flicker representation, Hz."""


def flicker_components(
    b: float, band: tuple[float, float] = DEFAULT_BAND, per_decade: int = 2
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Corner frequencies (Hz) and variances of the Gauss–Markov sum representing flicker of floor ``b``.

    Parameters
    ----------
    b : float
        Bias instability B (same unit as the signal, e.g. m/s²).
    band : (f_lo, f_hi)
        Corner-frequency band, Hz.
    per_decade : int
        Components per decade (2 gives a PSD ripple of a few %).
    """
    f_lo, f_hi = band
    if not (0 < f_lo < f_hi):
        raise ValueError(f"flicker band must satisfy 0 < f_lo < f_hi, got {band}")
    k = max(int(math.ceil(per_decade * math.log10(f_hi / f_lo))) + 1, 1)
    corners = np.logspace(math.log10(f_lo), math.log10(f_hi), k)
    var = np.full(k, b * b * (math.log(10.0) / per_decade) / math.pi)
    return corners, var


def window_mean_covariance(
    starts: ArrayLike, ends: ArrayLike, corners: ArrayLike, variances: ArrayLike
) -> NDArray[np.float64]:
    """Covariance (K, K) of the means of a Gauss–Markov sum over K non-overlapping windows (times in s)."""
    a = np.asarray(starts, dtype=float)
    e = np.asarray(ends, dtype=float)
    length = np.maximum(e - a, 1e-12)
    order = np.argsort(a)
    if np.any(a[order][1:] < e[order][:-1] - 1e-9):
        raise ValueError("acquisition windows overlap; give each step's own window")
    cov = np.zeros((a.size, a.size))
    for fc, var in zip(np.asarray(corners, float), np.asarray(variances, float), strict=True):
        beta = 2 * math.pi * fc
        bl = beta * length
        # same window: 2σ²(βL − 1 + e^{−βL})/(βL)², with a series near βL → 0 (→ σ²)
        same = np.where(bl > 1e-6, 2.0 * (bl + np.expm1(-bl)) / np.maximum(bl, 1e-300) ** 2, 1.0 - bl / 3.0)
        # window factors (1 − e^{−βL})/(βL) → 1 as βL → 0
        fac = np.where(bl > 1e-12, -np.expm1(-bl) / np.maximum(bl, 1e-300), 1.0)
        gap = a[None, :] - e[:, None]  # start of j minus end of i (valid where j after i)
        gap = np.where(gap >= 0, gap, (a[:, None] - e[None, :]))  # symmetric: the later one's start
        c = var * fac[:, None] * fac[None, :] * np.exp(-beta * np.maximum(gap, 0.0))
        np.fill_diagonal(c, var * same)
        cov += c
    return 0.5 * (cov + cov.T)


def systematic_covariance(gains: ArrayLike, a_inv: ArrayLike, offset_cov: ArrayLike) -> NDArray[np.float64]:
    """A⁻¹ (Σ_axis G_aᵀ C_a G_a) A⁻¹.

    Parameters
    ----------
    gains : (K, P, 3)
        G_s = Σ_{n∈s} w_n H_nᵀ R⁻¹ per step (P parameters, 3 body axes).
    a_inv : (P, P)
        The estimator's A⁻¹ (posterior covariance with the prior, or the data-only inverse information).
    offset_cov : (3, K, K)
        Covariance of the step offsets per body axis.
    """
    g = np.asarray(gains, dtype=float)
    ai = np.asarray(a_inv, dtype=float)
    c = np.asarray(offset_cov, dtype=float)
    m = np.zeros((g.shape[1], g.shape[1]))
    for axis in range(3):
        ga = g[:, :, axis]  # (K, P)
        m += ga.T @ c[axis] @ ga
    out = ai @ m @ ai
    return 0.5 * (out + out.T)
