"""Periodic error identification for high-rate inertial data (spec: ``periodic-error.md``).

Model of one channel (any SI unit, e.g. rad/s for a gyro axis in the body frame)::

    v_j = c₀ + Σ_{i=1}^{N} A_i cos(2π f_i t_j + φ_i) + e_j,   t_j = j T_s,   j = 0 … n−1

with the phase reference at sample 0 of the calibration record. Algorithm (the published grid-refinement
method, made unit-independent):

1. **Coarse** (:func:`find_peaks_psd`): zero-padded periodogram of the calibration sample with a 4-term
   Blackman–Harris window (−92 dB sidelobes, so a strong tone's leakage is never taken for another tone);
   the noise floor is a running median; a peak is *significant* when its power exceeds the floor by the
   exponential (χ²₂) quantile for a whole-spectrum false-alarm probability ``false_alarm`` (Bonferroni over
   the searched bins). All significant peaks are kept (at most ``max_terms``) unless ``n_terms`` overrides the
   count. Each peak gives a coarse f_i (parabolic interpolation of log power) and an interval
   D_i = f_i ± 1/T (the main lobe of the least-squares cost).
2. **Linear fit** (:func:`fit_fixed_frequencies`): at fixed frequencies, ``[1, cos 2πf_i t, sin 2πf_i t]``
   by least squares; a_i = A_i cos φ_i, b_i = −A_i sin φ_i.
3. **Fine search** (:func:`refine_frequencies`): one tone at a time, the others fixed, the interval is split
   into ``M`` parts (6 ≤ M ≤ 30) and the RMS residual e_m of a full linear refit is evaluated at the M+1
   grid points (all at once, by projection on the complement of the fixed columns). While the spread
   std(e_m) exceeds σ_E (relative: ``sigma_e_rel`` × the residual RMS) *and* the grid step is above
   ``crb_fraction`` × the Cramér–Rao σ_f, the interval is zoomed to [f_{m*−1}, f_{m*+1}]; a minimum on the
   interval edge shifts the interval (centred on that edge) instead. Sweeps over the tones repeat until no
   frequency moves by more than its final grid step.
4. **Refit and uncertainties** (:func:`identify_periodic`): c₀, A_i, φ_i at the final frequencies; the
   covariance of (c₀, A_i, φ_i, f_i) is σ̂² (JᵀJ)⁻¹ with the model Jacobian J and σ̂² = RSS/(n − p) — the
   white-noise Gauss–Newton covariance, which for separated tones equals the Cramér–Rao bound
   ``var f ≥ 24σ² / ((2π)² A² T_s² n (n² − 1))``. When the residual PSD near a tone differs significantly
   from the white level (coloured noise: drift, ARMA), that tone's (A, φ, f) block is rescaled by the local
   level — for separated tones only the noise near f_i matters. The offset's standard error stays the
   white-noise one (it is optimistic under flicker or random-walk drift).
Online compensation is in :mod:`analysis.periodic.compensator`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.ndimage import maximum_filter1d, median_filter

from analysis.periodic.compensator import PeriodicCompensator, dirichlet_gain
from core.errors import UserError

__all__ = [
    "PeriodicInputError",
    "Peak",
    "PeriodicTerm",
    "PeriodicModel",
    "crb_frequency_sigma",
    "find_peaks_psd",
    "fit_fixed_frequencies",
    "refine_frequencies",
    "identify_periodic",
    "welch_psd",
    "smoothing_comparison",
    "ChannelAnalysis",
    "analyse_channel",
    "analyse_periodic",
]


class PeriodicInputError(UserError, ValueError):
    """The data cannot be analysed as asked (too short, bad rate, bad parameter); the message says the fix."""


def crb_frequency_sigma(sigma: float, amplitude: float, rate_hz: float, n: int) -> float:
    """Cramér–Rao bound on the standard deviation of a real tone's frequency estimate, Hz.

    ``var f̂ ≥ 24 σ² / ((2π)² A² T_s² n (n² − 1))`` for white noise of standard deviation ``sigma`` and a tone of
    amplitude ``amplitude`` (same unit) sampled ``n`` times at ``rate_hz``.
    """
    if amplitude <= 0 or n < 2:
        return math.inf
    ts = 1.0 / rate_hz
    var = 24.0 * sigma**2 / ((2.0 * math.pi) ** 2 * amplitude**2 * ts**2 * n * (float(n) ** 2 - 1.0))
    return math.sqrt(var)


# --------------------------------------------------------------------------------------------------- coarse


@dataclass(frozen=True)
class Peak:
    """A spectral peak of the coarse search.

    Attributes
    ----------
    frequency_hz : float
        Interpolated peak frequency, Hz.
    power : float
        Periodogram level at the peak (one-sided PSD, unit²/Hz).
    floor : float
        Running-median noise floor at the peak (mean level), unit²/Hz.
    threshold : float
        Significance threshold at the peak, unit²/Hz.
    halfwidth_hz : float
        Half-width of the fine-search interval D_i, Hz.
    """

    frequency_hz: float
    power: float
    floor: float
    threshold: float
    halfwidth_hz: float

    @property
    def significant(self) -> bool:
        """Whether the peak exceeds its false-alarm threshold."""
        return self.power > self.threshold

    @property
    def snr_db(self) -> float:
        """Peak level above the noise floor, dB."""
        return 10.0 * math.log10(self.power / self.floor) if self.floor > 0 else math.inf


def _padded_periodogram(x: NDArray[np.float64], rate_hz: float, pad: int) -> tuple[NDArray, NDArray, int]:
    n = x.size
    w = signal.windows.blackmanharris(n, sym=False)
    nfft = 1 << int(math.ceil(math.log2(max(pad, 1) * n)))
    spec = np.fft.rfft((x - x.mean()) * w, nfft)
    psd = (np.abs(spec) ** 2) * (2.0 / (rate_hz * np.sum(w**2)))
    freqs = np.fft.rfftfreq(nfft, 1.0 / rate_hz)
    return freqs, psd, nfft


def _noise_floor(psd: NDArray[np.float64], step: int, width: int = 129) -> NDArray[np.float64]:
    """Running-median floor (mean level of exponential-distributed bins) on every ``step``-th bin, interpolated."""
    idx = np.arange(0, psd.size, max(step, 1))
    coarse = median_filter(psd[idx], size=min(width, max(3, idx.size | 1)), mode="mirror") / math.log(2.0)
    return np.interp(np.arange(psd.size), idx, coarse)


def find_peaks_psd(
    x: ArrayLike,
    rate_hz: float,
    n_terms: int | None = None,
    false_alarm: float = 1e-3,
    max_terms: int = 8,
    pad: int = 4,
) -> list[Peak]:
    """Coarse periodic-term search: significant peaks of a zero-padded Blackman–Harris periodogram.

    Parameters
    ----------
    x : array_like
        1-D calibration sample (channel SI unit), uniformly sampled.
    rate_hz : float
        Sample rate, Hz.
    n_terms : int, optional
        Take exactly this many of the strongest peaks, significant or not (override of the significance rule).
    false_alarm : float
        Probability that pure white noise yields at least one false peak anywhere in the spectrum.
    max_terms : int
        Cap on the number of significant peaks kept when ``n_terms`` is not given (strongest first).
    pad : int
        Zero-padding factor of the FFT.

    Returns
    -------
    list of Peak
        Strongest first. Frequencies lie in [6/T, f_s/2 − 6/T] (T = record length): closer to DC or Nyquist a
        tone cannot be told from drift or resolved from its alias.
    """
    v = np.asarray(x, dtype=np.float64)
    n = v.size
    if v.ndim != 1 or n < 64:
        raise PeriodicInputError(f"need a 1-D sample of at least 64 points for the peak search, got shape {v.shape}")
    if not 0 < false_alarm < 1:
        raise PeriodicInputError(f"false_alarm must be in (0, 1), got {false_alarm}")
    freqs, psd, nfft = _padded_periodogram(v, rate_hz, pad)
    step = max(nfft // n, 1)
    floor = _noise_floor(psd, step)
    duration = n / rate_hz
    band = (freqs >= 6.0 / duration) & (freqs <= rate_hz / 2.0 - 6.0 / duration)
    n_search = max(int(band.sum()), 1)
    factor = math.log(n_search / false_alarm)  # exponential quantile, Bonferroni over searched bins
    halfwidth_bins = 4 * step  # Blackman–Harris main lobe: ±4 bins of the unpadded FFT
    is_max = (psd >= maximum_filter1d(psd, size=2 * halfwidth_bins + 1, mode="nearest")) & band & (psd > 0)
    cand = np.flatnonzero(is_max)
    cand = cand[np.argsort(psd[cand])[::-1]]
    if n_terms is not None:
        if n_terms < 0:
            raise PeriodicInputError(f"the number of terms must be ≥ 0, got {n_terms}")
        chosen = cand[:n_terms]
    else:
        chosen = [k for k in cand if floor[k] > 0 and psd[k] > factor * floor[k]][:max_terms]
    df = freqs[1] - freqs[0]
    peaks: list[Peak] = []
    for k in chosen:
        f = freqs[k]
        if 0 < k < psd.size - 1 and psd[k - 1] > 0 and psd[k + 1] > 0:
            lm, l0, lp = np.log(psd[k - 1]), np.log(psd[k]), np.log(psd[k + 1])
            den = lm - 2.0 * l0 + lp
            if den < 0:
                f += 0.5 * (lm - lp) / den * df
        peaks.append(Peak(float(f), float(psd[k]), float(floor[k]), float(factor * floor[k]), 1.0 / duration))
    return peaks


# --------------------------------------------------------------------------------------------------- linear fit


def _design(t: NDArray[np.float64], freqs: Sequence[float]) -> NDArray[np.float64]:
    cols = [np.ones_like(t)]
    for f in freqs:
        arg = 2.0 * np.pi * f * t
        cols += [np.cos(arg), np.sin(arg)]
    return np.stack(cols, axis=1)


def _lsq(design: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
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
        c₀.
    amplitudes, phases : ndarray
        A_i ≥ 0 and φ_i (rad, in (−π, π]) of ``A_i cos(2π f_i t + φ_i)``.
    rss : float
        Residual sum of squares.
    """
    v = np.asarray(x, dtype=np.float64)
    t = np.arange(v.size) / rate_hz
    design = _design(t, frequencies_hz)
    coef = _lsq(design, v)
    res = v - design @ coef
    a, b = coef[1::2], coef[2::2]
    return float(coef[0]), np.hypot(a, b), np.arctan2(-b, a), float(res @ res)


def _grid_rss(
    r0: NDArray[np.float64], q: NDArray[np.float64], t: NDArray[np.float64], grid: NDArray[np.float64]
) -> NDArray[np.float64]:
    """RSS of the full linear refit with one tone at each grid frequency, the other columns fixed (basis ``q``)."""
    # columns e^{i2π g_m t} by exact start + short recurrence over the uniform grid (≤ 31 steps, ~1e-15)
    w = 2.0 * np.pi * t
    z = np.empty((t.size, grid.size), dtype=np.complex128)
    z[:, 0] = np.exp(1j * w * grid[0])
    if grid.size > 1:
        rot = np.exp(1j * w * (grid[1] - grid[0]))
        for m in range(1, grid.size):
            np.multiply(z[:, m - 1], rot, out=z[:, m])
    cc, cs = np.ascontiguousarray(z.real), np.ascontiguousarray(z.imag)
    cc -= q @ (q.T @ cc)
    cs -= q @ (q.T @ cs)
    g11, g22, g12 = np.einsum("ij,ij->j", cc, cc), np.einsum("ij,ij->j", cs, cs), np.einsum("ij,ij->j", cc, cs)
    h1, h2 = cc.T @ r0, cs.T @ r0
    det = g11 * g22 - g12**2
    det = np.where(det > 0, det, np.inf)
    b1 = (g22 * h1 - g12 * h2) / det
    b2 = (g11 * h2 - g12 * h1) / det
    res = r0[:, None] - cc * b1 - cs * b2
    return np.einsum("ij,ij->j", res, res)


@dataclass
class RefineReport:
    """Diagnostics of the fine search.

    Attributes
    ----------
    sweeps : int
        Sweeps over all tones performed.
    converged : bool
        True when a sweep moved no frequency by more than its final grid step.
    final_step_hz : list of float
        Final grid step of each tone, Hz.
    edge_limited : list of bool
        Tones whose minimum stayed on an interval edge after the allowed shifts.
    evaluations : int
        Number of grid-point refits.
    """

    sweeps: int = 0
    converged: bool = False
    final_step_hz: list[float] = field(default_factory=list)
    edge_limited: list[bool] = field(default_factory=list)
    evaluations: int = 0


def refine_frequencies(
    x: ArrayLike,
    rate_hz: float,
    frequencies_hz: Sequence[float],
    halfwidths_hz: Sequence[float] | None = None,
    m_parts: int = 12,
    sigma_e_rel: float = 1e-10,
    crb_fraction: float = 0.05,
    max_sweeps: int = 12,
    max_zooms: int = 80,
    max_shifts: int = 20,
) -> tuple[NDArray[np.float64], RefineReport]:
    """Grid-refinement fine frequency search, one tone at a time (spec step 3).

    Parameters
    ----------
    x : array_like
        1-D calibration samples (channel SI unit), sample 0 at t = 0.
    rate_hz : float
        Sample rate, Hz.
    frequencies_hz : sequence of float
        Coarse frequencies, Hz.
    halfwidths_hz : sequence of float, optional
        Half-widths of the initial intervals D_i, Hz (default 1/T).
    m_parts : int
        Number of grid parts M (6 ≤ M ≤ 30).
    sigma_e_rel : float
        σ_E relative to the residual RMS: zooming stops when std(e_m) ≤ σ_E.
    crb_fraction : float
        Zooming also stops when the grid step is below this fraction of the Cramér–Rao σ_f of the tone.
    max_sweeps, max_zooms, max_shifts : int
        Safety caps (sweeps over tones, zooms per tone search, edge shifts per tone search).

    Returns
    -------
    frequencies : ndarray
        Refined frequencies, Hz.
    report : RefineReport
    """
    if not 6 <= m_parts <= 30:
        raise PeriodicInputError(f"M (grid parts) must be between 6 and 30, got {m_parts}")
    v = np.asarray(x, dtype=np.float64)
    n = v.size
    t = np.arange(n) / rate_hz
    freqs = np.array(frequencies_hz, dtype=np.float64)
    k = freqs.size
    duration = n / rate_hz
    half = np.full(k, 1.0 / duration) if halfwidths_hz is None else np.array(halfwidths_hz, dtype=np.float64)
    report = RefineReport(final_step_hz=[0.0] * k, edge_limited=[False] * k)
    if k == 0:
        report.converged = True
        return freqs, report
    rms_scale = float(np.std(v)) or 1.0
    nyq = rate_hz / 2.0
    for sweep in range(max_sweeps):
        report.sweeps = sweep + 1
        moved = False
        for i in range(k):
            others = [freqs[j] for j in range(k) if j != i]
            q, _ = np.linalg.qr(_design(t, others))
            r0 = v - q @ (q.T @ v)
            # current σ̂ and A_i for the Cramér–Rao step limit
            c0, amps, _, rss = fit_fixed_frequencies(v, rate_hz, freqs)
            sigma = math.sqrt(rss / max(n - (1 + 3 * k), 1))
            sf = crb_frequency_sigma(sigma, float(amps[i]), rate_hz, n)
            if sweep == 0 or not math.isfinite(sf):
                width = 2.0 * half[i]
            else:
                width = min(2.0 * half[i], max(20.0 * sf, 4.0 * report.final_step_hz[i]))
            lo, hi = freqs[i] - width / 2.0, freqs[i] + width / 2.0
            shifts = 0
            best = freqs[i]
            step = width / m_parts
            for _ in range(max_zooms):
                lo, hi = max(lo, 1e-9 * nyq), min(hi, nyq * (1 - 1e-9))
                grid = np.linspace(lo, hi, m_parts + 1)
                step = (hi - lo) / m_parts
                e = np.sqrt(np.maximum(_grid_rss(r0, q, t, grid), 0.0) / n)
                report.evaluations += grid.size
                m = int(np.argmin(e))
                best = grid[m]
                at_floor = step <= 8e-16 * max(best, 1.0)  # frequency resolution of float64: nothing finer
                if (
                    m in (0, m_parts)
                    and not at_floor
                    and shifts < max_shifts
                    and lo > 1e-9 * nyq * 1.0001
                    and hi < nyq * 0.9999
                ):
                    shifts += 1
                    lo, hi = best - (hi - lo) / 2.0, best + (hi - lo) / 2.0
                    continue
                report.edge_limited[i] = m in (0, m_parts)
                # σ_E relative to the residual, floored at 1e-12 of the data RMS (the numerical resolution of e)
                sigma_e = max(sigma_e_rel * float(e[m]), 1e-12 * rms_scale)
                if float(np.std(e)) <= sigma_e or step <= crb_fraction * sf or at_floor:
                    break
                lo, hi = grid[max(m - 1, 0)], grid[min(m + 1, m_parts)]
            if abs(best - freqs[i]) > max(step, 1.6e-14 * max(abs(best), 1.0)):
                moved = True
            freqs[i] = best
            report.final_step_hz[i] = float(step)
        if not moved:
            report.converged = True
            break
    return freqs, report


# --------------------------------------------------------------------------------------------------- model


@dataclass(frozen=True)
class PeriodicTerm:
    """One identified term ``A cos(2π f t + φ)``, t from sample 0 of the calibration record.

    Attributes
    ----------
    frequency_hz, frequency_sigma_hz : float
        Frequency and its standard error, Hz.
    amplitude, amplitude_sigma : float
        Amplitude and its standard error, channel SI unit (e.g. rad/s).
    phase_rad, phase_sigma_rad : float
        Phase at t = 0 and its standard error, rad.
    frequency_crb_sigma_hz : float
        Cramér–Rao σ_f for this tone at the estimated σ and A, Hz.
    snr_db : float
        Coarse peak level above the periodogram floor, dB.
    noise_psd_ratio : float
        Local residual PSD at the tone / white level of σ̂; ≠ 1 only when the noise is significantly coloured,
        in which case the tone's standard errors use the local level (see :func:`identify_periodic`).
    """

    frequency_hz: float
    frequency_sigma_hz: float
    amplitude: float
    amplitude_sigma: float
    phase_rad: float
    phase_sigma_rad: float
    frequency_crb_sigma_hz: float
    snr_db: float = math.nan
    noise_psd_ratio: float = 1.0

    def to_json(self) -> dict[str, float]:
        """JSON-ready dict (SI)."""
        return {
            "frequency_hz": self.frequency_hz,
            "frequency_sigma_hz": self.frequency_sigma_hz,
            "amplitude": self.amplitude,
            "amplitude_sigma": self.amplitude_sigma,
            "phase_rad": self.phase_rad,
            "phase_sigma_rad": self.phase_sigma_rad,
            "frequency_crb_sigma_hz": self.frequency_crb_sigma_hz,
            "snr_db": self.snr_db,
            "noise_psd_ratio": self.noise_psd_ratio,
        }


@dataclass
class PeriodicModel:
    """Identified periodic error model of one channel.

    Attributes
    ----------
    terms : list of PeriodicTerm
    offset, offset_sigma : float
        c₀ and its standard error (channel SI unit).
    rate_hz : float
        Sample rate, Hz.
    n_samples : int
        Calibration sample length.
    noise_sigma : float
        σ̂ of the calibration residual (channel SI unit).
    covariance : ndarray
        Covariance of (c₀, A_1, φ_1, f_1, …, A_N, φ_N, f_N).
    report : RefineReport
        Fine-search diagnostics.
    """

    terms: list[PeriodicTerm]
    offset: float
    offset_sigma: float
    rate_hz: float
    n_samples: int
    noise_sigma: float
    covariance: NDArray[np.float64]
    report: RefineReport

    def _jacobian(self, indices: ArrayLike) -> NDArray[np.float64]:
        j = np.asarray(indices, dtype=np.float64).reshape(-1)
        t = j / self.rate_hz
        cols = [np.ones_like(t)]
        for term in self.terms:
            th = 2.0 * np.pi * term.frequency_hz * t + term.phase_rad
            s = np.sin(th)
            cols += [np.cos(th), -term.amplitude * s, -2.0 * np.pi * t * term.amplitude * s]
        return np.stack(cols, axis=1)

    def evaluate(self, indices: ArrayLike, include_offset: bool = False) -> NDArray[np.float64]:
        """Model at raw sample indices (relative to calibration sample 0), phase-accurate; channel SI unit."""
        comp = PeriodicCompensator.from_model(self)
        value = comp.model(np.asarray(indices, dtype=np.int64))
        return value + self.offset if include_offset else value

    def prediction_sigma(self, indices: ArrayLike) -> NDArray[np.float64]:
        """Standard deviation of the model's periodic part at raw sample indices, from the parameter covariance.

        Inside the calibration window it stays near σ̂·√(p/n); beyond it the frequency errors dominate and it
        grows like 2π t A_i σ_f,i — the spec's extrapolation bound.
        """
        g = self._jacobian(indices)[:, 1:]
        cov = self.covariance[1:, 1:]
        return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", g, cov, g), 0.0))

    def compensator(self, start_index: int = 0, decimation: int = 1) -> PeriodicCompensator:
        """An online :class:`~analysis.periodic.compensator.PeriodicCompensator` for this model."""
        return PeriodicCompensator.from_model(self, start_index=start_index, decimation=decimation)


def _tones(
    t: NDArray[np.float64], freqs: NDArray[np.float64], amps: NDArray[np.float64], phases: NDArray[np.float64]
) -> NDArray[np.float64]:
    out = np.zeros_like(t)
    for f, a, ph in zip(freqs, amps, phases, strict=True):
        out += a * np.cos(2.0 * np.pi * f * t + ph)
    return out


LOCAL_FLOOR_BINS = 257
"""Running-median width (independent periodogram bins) of the local noise level at each tone."""


def _local_noise_ratios(
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
    fgrid, psd, nfft = _padded_periodogram(residual, rate_hz, 4)
    k = max(nfft // residual.size, 1)
    n_bins = min(LOCAL_FLOOR_BINS, max(3, (psd.size // k) | 1))
    floor = _noise_floor(psd, k, width=n_bins)
    white = 2.0 * sigma**2 / rate_hz
    ratios = np.interp(freqs, fgrid, floor) / white
    tol = 3.0 * math.sqrt(4.2 / n_bins)
    significant = np.abs(np.log(np.maximum(ratios, 1e-300))) > tol
    return np.where(significant & (ratios > 0), ratios, 1.0)


def identify_periodic(
    x: ArrayLike,
    rate_hz: float,
    n_terms: int | None = None,
    false_alarm: float = 1e-3,
    max_terms: int = 8,
    m_parts: int = 12,
    sigma_e_rel: float = 1e-10,
    crb_fraction: float = 0.05,
) -> PeriodicModel:
    """Identify the periodic terms of a calibration sample (spec steps 1–4).

    Parameters
    ----------
    x : array_like
        1-D calibration samples of one channel (SI unit), sample 0 at t = 0 (phase reference).
    rate_hz : float
        Sample rate, Hz.
    n_terms : int, optional
        Force this number of terms (default: the significant peaks, at most ``max_terms``).
    false_alarm, max_terms : see :func:`find_peaks_psd`.
    m_parts, sigma_e_rel, crb_fraction : see :func:`refine_frequencies`.

    Returns
    -------
    PeriodicModel
    """
    v = np.asarray(x, dtype=np.float64)
    if v.ndim != 1:
        raise PeriodicInputError(f"expected a 1-D channel, got shape {v.shape}")
    if not math.isfinite(rate_hz) or rate_hz <= 0:
        raise PeriodicInputError(f"sample rate must be a positive number of Hz, got {rate_hz}")
    if not np.all(np.isfinite(v)):
        raise PeriodicInputError("the calibration sample contains NaN/inf values; remove or interpolate them")
    n = v.size
    peaks = find_peaks_psd(v, rate_hz, n_terms=n_terms, false_alarm=false_alarm, max_terms=max_terms)
    if n_terms is not None and len(peaks) < n_terms:
        raise PeriodicInputError(
            f"asked for {n_terms} terms but the spectrum has only {len(peaks)} separable peaks; use fewer --terms"
        )
    f0 = [p.frequency_hz for p in peaks]
    freqs, report = refine_frequencies(
        v, rate_hz, f0, [p.halfwidth_hz for p in peaks], m_parts=m_parts, sigma_e_rel=sigma_e_rel,
        crb_fraction=crb_fraction,
    )  # fmt: skip
    c0, amps, phases, rss = fit_fixed_frequencies(v, rate_hz, freqs)
    k = freqs.size
    p = 1 + 3 * k
    sigma = math.sqrt(rss / max(n - p, 1))
    # Gauss–Newton covariance of (c0, A_i, φ_i, f_i), with column scaling for conditioning
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
    ratios = _local_noise_ratios(v - jac[:, 0] * c0 - _tones(t, freqs, amps, phases), rate_hz, freqs, sigma)
    d = np.concatenate([[1.0], np.repeat(np.sqrt(ratios), 3)])
    cov = cov * np.outer(d, d)
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    terms = [
        PeriodicTerm(
            frequency_hz=float(freqs[i]),
            frequency_sigma_hz=float(sd[3 + 3 * i]),
            amplitude=float(amps[i]),
            amplitude_sigma=float(sd[1 + 3 * i]),
            phase_rad=float(phases[i]),
            phase_sigma_rad=float(sd[2 + 3 * i]),
            frequency_crb_sigma_hz=crb_frequency_sigma(sigma * math.sqrt(ratios[i]), float(amps[i]), rate_hz, n),
            snr_db=peaks[i].snr_db,
            noise_psd_ratio=float(ratios[i]),
        )
        for i in range(k)
    ]
    return PeriodicModel(terms, c0, float(sd[0]), float(rate_hz), n, sigma, cov, report)


# --------------------------------------------------------------------------------------------------- evaluation


def welch_psd(x: ArrayLike, rate_hz: float, seconds: float = 4.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One-sided Welch PSD (Hann, 50 % overlap, segments of ≈``seconds``), unit²/Hz, after removing the mean."""
    v = np.asarray(x, dtype=np.float64)
    nper = int(min(v.size, max(64, 1 << int(round(math.log2(max(seconds * rate_hz, 2.0)))))))
    return signal.welch(v - v.mean(), fs=rate_hz, nperseg=nper, detrend=False)


def _tone_rms(v: NDArray[np.float64], rate_hz: float, freqs: Sequence[float], times: NDArray[np.float64]) -> float:
    """RMS of the tones at ``freqs`` (aliased as the sampling demands) fitted to ``v`` sampled at ``times``."""
    if len(freqs) == 0 or v.size < 3 + 2 * len(freqs):
        return 0.0
    design = _design(times, freqs)
    coef, *_ = np.linalg.lstsq(design, v, rcond=None)
    return float(np.sqrt(np.sum(coef[1:] ** 2) / 2.0))


def smoothing_comparison(
    x: ArrayLike,
    rate_hz: float,
    model: PeriodicModel,
    start_index: int,
    averages: Sequence[int] = (5, 10, 20),
    lowpass_order: int = 4,
) -> list[dict[str, float | str]]:
    """Compare compensation with n-sample averaging and a low-pass filter on the same data (spec).

    Parameters
    ----------
    x : array_like
        Samples after the calibration window (channel SI unit); sample 0 is raw index ``start_index``.
    rate_hz : float
        Raw sample rate, Hz.
    model : PeriodicModel
        The identified model.
    start_index : int
        Raw index of ``x[0]`` relative to the model's phase reference.
    averages : sequence of int
        Block-average lengths.
    lowpass_order : int
        Order of the causal Butterworth low-pass, cut at half the lowest identified tone frequency (so every
        tone is attenuated; f_s/4 when there is none).

    Returns
    -------
    list of dict
        One row per method: ``method``, ``output_rate_hz``, ``bandwidth_hz`` (−3 dB, capped at the output
        Nyquist), ``bandwidth_lost`` (fraction of the raw Nyquist band), ``residual_rms`` (about the offset,
        channel SI unit) and ``periodic_rms`` (RMS of the tones still present, fitted at the identified
        frequencies).
    """
    v = np.asarray(x, dtype=np.float64) - model.offset
    n = v.size
    freqs = [tm.frequency_hz for tm in model.terms]
    t = (start_index + np.arange(n)) / rate_hz
    nyq = rate_hz / 2.0
    rows: list[dict[str, float | str]] = []

    def row(method: str, out_rate: float, bw: float, data: NDArray, times: NDArray) -> None:
        rows.append(
            {
                "method": method,
                "output_rate_hz": out_rate,
                "bandwidth_hz": bw,
                "bandwidth_lost": max(0.0, 1.0 - bw / nyq),
                "residual_rms": float(np.sqrt(np.mean(data**2))) if data.size else math.nan,
                "periodic_rms": _tone_rms(data, rate_hz, freqs, times),
            }
        )

    row("none", rate_hz, nyq, v, t)
    comp = model.compensator(start_index=start_index)
    row("compensation", rate_hz, nyq, comp.process(v), t)
    for m in averages:
        nb = n // m
        if nb < 4:
            continue
        avg = v[: nb * m].reshape(nb, m).mean(axis=1)
        tc = t[: nb * m].reshape(nb, m).mean(axis=1)
        # −3 dB point of the m-sample boxcar, capped at the output Nyquist frequency
        fgrid = np.linspace(0.0, nyq, 20001)
        g = np.abs(dirichlet_gain(fgrid / rate_hz, m))
        f3 = float(fgrid[np.argmax(g < 1.0 / math.sqrt(2.0))])
        row(f"average {m}", rate_hz / m, min(f3, rate_hz / (2 * m)), avg, tc)
    fc = 0.5 * min(freqs) if freqs else rate_hz / 4.0
    sos = signal.butter(lowpass_order, fc, fs=rate_hz, output="sos")
    low = signal.sosfilt(sos, v - v[: min(n, 64)].mean()) + v[: min(n, 64)].mean()
    skip = min(n // 2, int(math.ceil(10.0 * rate_hz / fc)))  # drop the filter's start-up transient
    row(f"low-pass {lowpass_order}th-order Butterworth", rate_hz, fc, low[skip:], t[skip:])
    return rows


@dataclass
class ChannelAnalysis:
    """Everything ``tablebench periodic`` reports for one channel.

    Attributes
    ----------
    model : PeriodicModel
    calibration_samples : int
        Samples used for identification (raw indices 0 … n_cal−1).
    before, after : ndarray
        The rest of the record (raw indices n_cal …) before and after compensation, offset removed.
    comparison : list of dict
        :func:`smoothing_comparison` rows.
    """

    model: PeriodicModel
    calibration_samples: int
    before: NDArray[np.float64]
    after: NDArray[np.float64]
    comparison: list[dict[str, float | str]]

    def to_json(self, rate_hz: float) -> dict:
        """The per-channel JSON structure of ``periodic.json`` (SI)."""
        m = self.model
        fb, pb = welch_psd(self.before, rate_hz)
        _, pa = welch_psd(self.after, rate_hz)
        df = fb[1] - fb[0]
        psd_rows = []
        for term in m.terms:
            k = int(round(term.frequency_hz / df))
            sl = slice(max(k - 1, 0), min(k + 2, fb.size))
            psd_rows.append(
                {"frequency_hz": term.frequency_hz, "before": float(pb[sl].max()), "after": float(pa[sl].max())}
            )
        return {
            "terms": [t.to_json() for t in m.terms],
            "offset": m.offset,
            "offset_sigma": m.offset_sigma,
            "noise_sigma": m.noise_sigma,
            "residual_rms_before": float(np.sqrt(np.mean(self.before**2))),
            "residual_rms_after": float(np.sqrt(np.mean(self.after**2))),
            "psd_at_terms": psd_rows,
            "psd_median_after": float(np.median(pa[1:])),
            "comparison": self.comparison,
            "identification": {
                "calibration_samples": self.calibration_samples,
                "sweeps": m.report.sweeps,
                "converged": m.report.converged,
                "grid_evaluations": m.report.evaluations,
                "edge_limited": any(m.report.edge_limited),
            },
        }


def analyse_channel(
    x: ArrayLike, rate_hz: float, calibrate_seconds: float, terms: int | None = None, false_alarm: float = 1e-3
) -> ChannelAnalysis:
    """Identify on the first ``calibrate_seconds``, compensate the rest, compare with averaging / low-pass.

    Parameters
    ----------
    x : array_like
        1-D record of one channel (SI unit).
    rate_hz : float
        Sample rate, Hz.
    calibrate_seconds : float
        Length of the calibration sample, s (the spec: 5–20 s).
    terms : int, optional
        Force the number of terms.
    false_alarm : float
        Whole-spectrum false-alarm probability of the peak significance rule.
    """
    v = np.asarray(x, dtype=np.float64)
    if not math.isfinite(calibrate_seconds) or calibrate_seconds <= 0:
        raise PeriodicInputError(f"--calibrate-seconds must be a positive number, got {calibrate_seconds}")
    n_cal = int(round(calibrate_seconds * rate_hz))
    if n_cal < 64:
        raise PeriodicInputError(
            f"--calibrate-seconds {calibrate_seconds} gives only {n_cal} samples at {rate_hz} Hz; use at least "
            f"{math.ceil(64 / rate_hz * 100) / 100} s"
        )
    if v.size < n_cal + 64:
        raise PeriodicInputError(
            f"the record has {v.size} samples ({v.size / rate_hz:.3g} s), not enough to calibrate on "
            f"{calibrate_seconds} s and compensate at least 64 more samples; shorten --calibrate-seconds"
        )
    model = identify_periodic(v[:n_cal], rate_hz, n_terms=terms, false_alarm=false_alarm)
    rest = v[n_cal:]
    before = rest - model.offset
    after = model.compensator(start_index=n_cal).process(before)
    comparison = smoothing_comparison(rest, rate_hz, model, n_cal)
    return ChannelAnalysis(model, n_cal, before, after, comparison)


def analyse_periodic(
    channels: Mapping[str, ArrayLike], rate: float, calibrate_seconds: float = 8.0, terms: int | None = None
) -> dict:
    """Periodic error analysis of several channels, as the ``periodic.json`` structure (SI).

    Parameters
    ----------
    channels : mapping of str to array_like
        Channel name → 1-D record (SI unit: rad/s for gyro axes, m/s² for accelerometer axes, body frame).
    rate : float
        Sample rate, Hz.
    calibrate_seconds : float
        Calibration sample length, s.
    terms : int, optional
        Force the number of terms per channel.

    Returns
    -------
    dict
        ``{"rate_hz", "calibrate_seconds", "channels": {NAME: {"terms": [{"frequency_hz", "frequency_sigma_hz",
        "amplitude", "phase_rad", ...}], "offset", "residual_rms_before", "residual_rms_after", ...}}}``.
    """
    out: dict = {"rate_hz": float(rate), "calibrate_seconds": float(calibrate_seconds), "channels": {}}
    for name, data in channels.items():
        try:
            res = analyse_channel(data, rate, calibrate_seconds, terms)
        except PeriodicInputError as exc:
            raise PeriodicInputError(f"channel {name}: {exc}") from None
        out["channels"][name] = res.to_json(rate)
    return out
