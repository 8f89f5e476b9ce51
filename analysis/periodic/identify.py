"""Identification of the periodic terms of a calibration sample (spec steps 1–4): detection → refinement →
covariance → post-fit significance test.

1. **Coarse** (:func:`~analysis.periodic.detection.find_peaks_psd`): significant periodogram peaks at a
   whole-band false-alarm probability that holds at its nominal value.
2. **Refinement**: Levenberg–Marquardt on the exact model (:func:`~analysis.periodic.refine.refine_lm`,
   ``method="lm"``, the default) or the published grid search (:func:`~analysis.periodic.grid.refine_frequencies`,
   ``method="grid"``). When LM does not converge inside the tones' intervals, the grid search is used and
   the model says so (``report.fallback``).
3. **Refit and uncertainties**: c₀, A_i, φ_i at the final frequencies; the covariance of (c₀, A_i, φ_i, f_i)
   is σ̂² (JᵀJ)⁻¹ with the model Jacobian J and σ̂² = RSS/(n − p) — for white noise and separated tones this
   is the Cramér–Rao bound ``var f ≥ 24σ² / ((2π)² A² T_s² n (n² − 1))``. When the residual PSD near a tone
   differs significantly from the white level (coloured noise: drift, ARMA), that tone's (A, φ, f) block is
   rescaled by the local level. The offset's standard error stays the white-noise one (optimistic under
   flicker or random-walk drift).
4. **Post-fit significance**: a tone whose ``u = (A/σ_A)²/2`` is below the whole-band threshold
   (:func:`~analysis.periodic.detection.post_fit_threshold`) is dropped and the rest refitted (unless the
   number of terms was forced). Each kept tone gets the probability that a repeat record would find it again
   (the smaller of the coarse search's and the post-fit test's, from its fitted amplitude); below 0.95 it is
   reported as near the detection limit.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import median_filter

from analysis.periodic.detection import (
    coarse_redetection_probability,
    coarse_threshold,
    find_peaks_psd,
    padded_periodogram,
    post_fit_threshold,
    redetection_probability,
    search_band,
    window_processing_loss,
)
from analysis.periodic.grid import refine_frequencies
from analysis.periodic.linear import fit_fixed_frequencies, tones
from analysis.periodic.model import (
    DroppedTone,
    FitReport,
    PeriodicInputError,
    PeriodicModel,
    PeriodicTerm,
    crb_frequency_sigma,
)
from analysis.periodic.refine import refine_lm

__all__ = ["METHODS", "identify_periodic", "local_noise_ratios"]

METHODS = ("lm", "grid")
"""Refinement methods: Levenberg–Marquardt on the exact model (default), the published grid search."""

LOCAL_FLOOR_BINS = 257
"""Running-median width (independent periodogram bins) of the local noise level at each tone."""


def _running_floor(psd: NDArray[np.float64], step: int, width: int) -> NDArray[np.float64]:
    """Running-median level (mean of exponential bins) on every ``step``-th bin, interpolated."""
    idx = np.arange(0, psd.size, max(step, 1))
    coarse = median_filter(psd[idx], size=min(width, max(3, idx.size | 1)), mode="mirror") / math.log(2.0)
    return np.interp(np.arange(psd.size), idx, coarse)


def local_noise_ratios(
    residual: NDArray[np.float64], rate_hz: float, freqs: NDArray[np.float64], sigma: float
) -> NDArray[np.float64]:
    """Local residual PSD at each tone over the white level 2σ̂²/f_s, or 1 where not significantly different.

    The running median over ``LOCAL_FLOOR_BINS`` bins of a Blackman–Harris periodogram (≈2 correlated bins per
    independent one) estimates the level with a log-standard deviation ≈ √(4.2/K) ≈ 0.13; the local level is
    used only when it differs from white by more than 3 of those (factor outside [0.68, 1.47]), so white
    noise keeps the more precise band-average σ̂.
    """
    if freqs.size == 0 or sigma <= 0:
        return np.ones(freqs.size)
    fgrid, psd, nfft = padded_periodogram(residual, rate_hz, 4)
    k = max(nfft // residual.size, 1)
    n_bins = min(LOCAL_FLOOR_BINS, max(3, (psd.size // k) | 1))
    floor = _running_floor(psd, k, n_bins)
    white = 2.0 * sigma**2 / rate_hz
    ratios = np.interp(freqs, fgrid, floor) / white
    tol = 3.0 * math.sqrt(4.2 / n_bins)
    significant = np.abs(np.log(np.maximum(ratios, 1e-300))) > tol
    return np.where(significant & (ratios > 0), ratios, 1.0)


def _refine(
    v: NDArray[np.float64],
    rate_hz: float,
    f0: list[float],
    half: list[float],
    method: str,
    m_parts: int,
    sigma_e_rel: float,
    crb_fraction: float,
) -> tuple[NDArray[np.float64], FitReport]:
    if method == "lm":
        freqs, report = refine_lm(v, rate_hz, f0, half)
        if report.converged:
            return freqs, report
        why = report.message
        freqs, report = refine_frequencies(
            v, rate_hz, f0, half, m_parts=m_parts, sigma_e_rel=sigma_e_rel, crb_fraction=crb_fraction
        )
        report.fallback = True
        report.message = f"{report.message} (after Levenberg–Marquardt: {why})"
        return freqs, report
    return refine_frequencies(v, rate_hz, f0, half, m_parts=m_parts, sigma_e_rel=sigma_e_rel, crb_fraction=crb_fraction)


def _covariance(
    v: NDArray[np.float64], rate_hz: float, freqs: NDArray[np.float64]
) -> tuple[float, NDArray, NDArray, float, NDArray, NDArray]:
    """Refit at ``freqs``; returns c₀, A, φ, σ̂, covariance of (c₀, A_i, φ_i, f_i), local noise ratios."""
    n = v.size
    c0, amps, phases, rss = fit_fixed_frequencies(v, rate_hz, freqs)
    k = freqs.size
    sigma = math.sqrt(rss / max(n - (1 + 3 * k), 1))
    t = np.arange(n) / rate_hz
    cols = [np.ones(n)]
    for f, a, ph in zip(freqs, amps, phases, strict=True):
        th = 2.0 * np.pi * f * t + ph
        s = np.sin(th)
        cols += [np.cos(th), -a * s, -2.0 * np.pi * t * a * s]
    jac = np.stack(cols, axis=1)
    scale = np.linalg.norm(jac, axis=0)
    scale[scale == 0] = 1.0
    js = jac / scale
    cov = sigma**2 * np.linalg.pinv(js.T @ js) / np.outer(scale, scale)
    ratios = local_noise_ratios(v - c0 - tones(t, freqs, amps, phases), rate_hz, freqs, sigma)
    d = np.concatenate([[1.0], np.repeat(np.sqrt(ratios), 3)])
    return c0, amps, phases, sigma, cov * np.outer(d, d), ratios


def identify_periodic(
    x: ArrayLike,
    rate_hz: float,
    n_terms: int | None = None,
    false_alarm: float = 1e-3,
    max_terms: int = 8,
    method: str = "lm",
    m_parts: int = 12,
    sigma_e_rel: float = 1e-10,
    crb_fraction: float = 0.05,
) -> PeriodicModel:
    """Identify the periodic terms of a calibration sample (module doc).

    Parameters
    ----------
    x : array_like
        1-D calibration samples of one channel (SI unit), sample 0 at t = 0 (phase reference).
    rate_hz : float
        Sample rate, Hz.
    n_terms : int, optional
        Force this number of terms (default: the significant peaks, at most ``max_terms``; no post-fit drop).
    false_alarm : float
        Whole-band false-alarm probability of the detection and of the post-fit test.
    max_terms : int
        Cap on the number of detected peaks.
    method : {"lm", "grid"}
        Refinement: Levenberg–Marquardt (default) or the published grid search.
    m_parts, sigma_e_rel, crb_fraction : see :func:`~analysis.periodic.grid.refine_frequencies`.

    Returns
    -------
    PeriodicModel
    """
    v = np.asarray(x, dtype=np.float64)
    if method not in METHODS:
        raise PeriodicInputError(f"unknown refinement method {method!r}; use one of {', '.join(METHODS)}")
    if v.ndim != 1:
        raise PeriodicInputError(f"expected a 1-D channel, got shape {v.shape}")
    if not math.isfinite(rate_hz) or rate_hz <= 0:
        raise PeriodicInputError(f"the sample rate must be a positive number of Hz, got {rate_hz}")
    if not np.all(np.isfinite(v)):
        raise PeriodicInputError("the calibration sample contains NaN/inf values; remove or interpolate them")
    if not 6 <= m_parts <= 30:
        raise PeriodicInputError(f"the number of grid parts M must be between 6 and 30, got {m_parts}")
    n = v.size
    peaks = find_peaks_psd(v, rate_hz, n_terms=n_terms, false_alarm=false_alarm, max_terms=max_terms)
    if n_terms is not None and len(peaks) < n_terms:
        raise PeriodicInputError(
            f"asked for {n_terms} terms but the spectrum has only {len(peaks)} separable peaks; ask for fewer terms"
        )
    snr = [p.snr_db for p in peaks]
    f0 = [p.frequency_hz for p in peaks]
    half = [p.halfwidth_hz for p in peaks]
    lo, hi = search_band(n, rate_hz)
    gamma_coarse, enbw = coarse_threshold(n, rate_hz, false_alarm), window_processing_loss(n)
    dropped: list[DroppedTone] = []
    while True:
        freqs, report = _refine(v, rate_hz, f0, half, method, m_parts, sigma_e_rel, crb_fraction)
        c0, amps, phases, sigma, cov, ratios = _covariance(v, rate_hz, freqs)
        k = freqs.size
        gamma = post_fit_threshold(false_alarm, max(hi - lo, 0.0), n, rate_hz, n - (1 + 3 * k))
        sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
        sa = sd[1::3]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(sa > 0, 0.5 * (amps / sa) ** 2, np.inf)
        weak = np.flatnonzero(u <= gamma) if n_terms is None else np.array([], dtype=int)
        if weak.size == 0:
            break
        # drop the least significant tone only, then refit the rest from their refined frequencies
        i = int(weak[np.argmin(u[weak])])
        dropped.append(DroppedTone(float(freqs[i]), float(amps[i]), float(sa[i]), float(u[i]), float(gamma)))
        keep = [j for j in range(k) if j != i]
        f0 = [float(freqs[j]) for j in keep]
        half = [half[j] for j in keep]
        snr = [snr[j] for j in keep]
    terms = [
        PeriodicTerm(
            frequency_hz=float(freqs[i]),
            frequency_sigma_hz=float(sd[3 + 3 * i]),
            amplitude=float(amps[i]),
            amplitude_sigma=float(sd[1 + 3 * i]),
            phase_rad=float(phases[i]),
            phase_sigma_rad=float(sd[2 + 3 * i]),
            frequency_crb_sigma_hz=crb_frequency_sigma(sigma * math.sqrt(ratios[i]), float(amps[i]), rate_hz, n),
            snr_db=snr[i],
            noise_psd_ratio=float(ratios[i]),
            significance=float(u[i]),
            significance_threshold=float(gamma),
            detection_probability=min(
                redetection_probability(float(u[i]), gamma),
                coarse_redetection_probability(float(u[i]), gamma_coarse, enbw),
            ),
        )
        for i in range(freqs.size)
    ]
    return PeriodicModel(terms, c0, float(sd[0]), float(rate_hz), n, sigma, cov, report, false_alarm, dropped, (lo, hi))
