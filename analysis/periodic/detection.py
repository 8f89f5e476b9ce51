"""Coarse periodic-term detection with a false-alarm probability that holds at its nominal value (spec step 1).

Statistic
---------
Zero-padded periodogram ``P(f)`` of the mean-removed sample with a 4-term Blackman–Harris window (−92 dB
sidelobes, so a strong tone's leakage is never taken for another tone). Under white noise (locally white
noise, for coloured noise) ``P(f)/μ(f)`` is exponential with mean 1 at every frequency, μ the PSD.

Noise floor
-----------
μ is estimated from periodogram values taken ``INDEPENDENT_BINS`` = 5 unpadded bins apart: the squared
4-term window has cosines up to order 6, so the correlation of two such values is |ρ|² = 1e-5 at 5 bins
(9e-4 at 4, exactly 0 from 7): they are independent. At each floor point the floor is the *mean of two
medians*, of the K = ``FLOOR_POINTS_PER_SIDE`` values on the left and the K on the right, skipping the
``FLOOR_EXCLUDE`` nearest on each side — so the floor of a frequency never contains the value being tested,
and a PSD that varies linearly across the window (a drift or ARMA slope) is still estimated without bias (a
convex slope, like 1/f², is overestimated: conservative). Frequencies without a full window on both sides are
not searched (:func:`search_band`). The median of K independent Exp(μ) values is ``μ Σ_{i<m} E_i/(K−i)``
(m = (K+1)/2, E_i independent Exp(1)); normalised by ``c = Σ_{i<m} 1/(K−i)`` it is unbiased, and the
probability that one bin exceeds γ × floor is exactly (Laplace transform of the sum of the two sides)::

    L(γ) = Π_{i<m} (1 + γ / (2c (K − i)))⁻²

Whole-band false-alarm probability
----------------------------------
The search is over a continuous band (zero-padded), so the number of independent trials is not the number
of bins. For the envelope of the windowed DFT of white noise, Rice's formula gives the expected number of
up-crossings of level u (in units of the mean) per Hz as ``D √u e^{−u}`` with ``D = 2 √(π var_w(t))``,
``var_w(t)`` the variance of time weighted by the squared window (Baluev 2008, A&A 385, 1279, eq. 5 for the
rectangular case, where D = T √(π/3)). Over a band of B Hz, with the floor estimated as above::

    Pfa(γ) ≈ L(γ) · (1 + B · D · √(γ F̃))

with ``F̃ = 2 Σ_{i<m} 1/(2c(K−i) + γ)`` the floor ratio's mean under the tilt e^{−γF}. The threshold γ solves
``Pfa(γ) = false_alarm``; it is verified by simulation (``tests/analysis/periodic/test_periodic_detection.py``).

Post-fit test
-------------
After the exact least-squares fit, a tone is kept when ``u = (A/σ_A)²/2`` exceeds the threshold of the same
whole-band false-alarm probability for the unwindowed least-squares periodogram (D = T √(π/3)) with the
noise level estimated on ν = n − p degrees of freedom: ``(1 + 2γ/ν)^{−ν/2} (1 + B D √γ) = false_alarm``
(:func:`post_fit_threshold`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, signal, stats
from scipy.ndimage import maximum_filter1d

from analysis.periodic.model import PeriodicInputError

__all__ = [
    "PAD",
    "FLOOR_POINTS_PER_SIDE",
    "FLOOR_EXCLUDE",
    "INDEPENDENT_BINS",
    "Peak",
    "padded_periodogram",
    "window_trial_density",
    "median_floor_tail",
    "spectrum_threshold",
    "post_fit_threshold",
    "redetection_probability",
    "coarse_threshold",
    "coarse_redetection_probability",
    "window_processing_loss",
    "search_band",
    "detect",
    "find_peaks_psd",
]

PAD = 4
"""Zero-padding factor of the FFT (at least; the FFT length is the next power of two)."""
FLOOR_POINTS_PER_SIDE = 15
"""K: independent periodogram values in each of the two medians of the noise floor (2 … 16 × 5 unpadded bins
from the tested frequency, i.e. ±10 Hz for an 8 s record)."""
FLOOR_EXCLUDE = 1
"""Floor points skipped on each side of the tested one (so the tested value is never part of its floor)."""
MIN_FLOOR_POINTS = 5
"""Fewest values per side of the floor near DC and Nyquist (with its own threshold, module doc)."""
INDEPENDENT_BINS = 5
"""Spacing (unpadded bins) at which 4-term Blackman–Harris periodogram values are independent (|ρ|² = 1e-5)."""
LOBE_BINS = 4
"""Half-width of the Blackman–Harris main lobe, unpadded bins: one peak per lobe."""
EDGE_PERIODS = 6.0
"""Tones are searched in [6/T, f_s/2 − 6/T]: closer to DC or Nyquist a tone cannot be told from drift or resolved
from its alias."""


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
        Significance threshold at the peak (γ × floor), unit²/Hz.
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


@functools.lru_cache(maxsize=8)
def _window(n: int) -> NDArray[np.float64]:
    w = signal.windows.blackmanharris(n, sym=False)
    w.flags.writeable = False
    return w


def padded_periodogram(
    x: ArrayLike, rate_hz: float, pad: int = PAD
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """Zero-padded Blackman–Harris periodogram of each row of ``x`` (mean removed), one-sided PSD (unit²/Hz).

    Returns
    -------
    freqs : ndarray
        Frequencies, Hz.
    psd : ndarray
        Same leading shape as ``x``, last axis over ``freqs``.
    nfft : int
        FFT length (power of two ≥ ``pad`` × n).
    """
    v = np.asarray(x, dtype=np.float64)
    n = v.shape[-1]
    w = _window(n)
    nfft = 1 << int(math.ceil(math.log2(max(pad, 1) * n)))
    spec = np.fft.rfft((v - v.mean(axis=-1, keepdims=True)) * w, nfft, axis=-1)
    psd = (spec.real**2 + spec.imag**2) * (2.0 / (rate_hz * np.sum(w**2)))
    return np.fft.rfftfreq(nfft, 1.0 / rate_hz), psd, nfft


def window_trial_density(weights: ArrayLike, rate_hz: float) -> float:
    """``D = 2 √(π var_w(t))`` (s): up-crossings per Hz of the windowed periodogram are ``D √u e^{−u}``.

    ``var_w(t)`` is the variance of the sample time weighted by the squared window ``weights²``.
    """
    w2 = np.asarray(weights, dtype=np.float64) ** 2
    t = np.arange(w2.size) / rate_hz
    p = w2 / w2.sum()
    mean = float(p @ t)
    var = float(p @ (t - mean) ** 2)
    return 2.0 * math.sqrt(math.pi * var)


def _median_constants(k: int) -> tuple[NDArray[np.float64], int]:
    """Rates ``c (K − i)``, i < m, of the normalised median's exponential components, and m (1-based order)."""
    m = (k + 1) // 2
    rates = (k - np.arange(m)).astype(np.float64)
    c = float(np.sum(1.0 / rates))
    return c * rates, m


def median_floor_tail(gamma: float, k: int, sides: int = 2) -> tuple[float, float]:
    """``L(γ) = P(E > γ F)`` for E ~ Exp(1) and F the mean of ``sides`` independent normalised medians of ``k``
    Exp(1) values each, and the tilted mean ``F̃`` of F under the weight e^{−γF} (both exact)."""
    rates, _ = _median_constants(k)
    rates = sides * rates
    log_l = -sides * float(np.sum(np.log1p(gamma / rates)))
    return math.exp(log_l), sides * float(np.sum(1.0 / (rates + gamma)))


def _solve_threshold(log_pfa, false_alarm: float, lo: float = 1e-9) -> float:  # noqa: ANN001
    """γ with ``log_pfa(γ) = log(false_alarm)``, ``log_pfa`` decreasing on [lo, ∞)."""
    target = math.log(false_alarm)
    hi = max(1.0, 2.0 * lo)
    while log_pfa(hi) > target:
        hi *= 2.0
        if hi > 1e7:
            return math.inf
    if log_pfa(lo) <= target:
        return lo
    return float(optimize.brentq(lambda g: log_pfa(g) - target, lo, hi, xtol=1e-12, rtol=1e-12))


def spectrum_threshold(
    false_alarm: float, band_hz: float, density_s: float, floor_points: int, sides: int = 2
) -> float:
    """γ such that the whole-band false-alarm probability of ``P(f) > γ × floor(f)`` is ``false_alarm``.

    Parameters
    ----------
    false_alarm : float
        Probability that white noise gives at least one peak above threshold anywhere in the band.
    band_hz : float
        Width of the searched band, Hz.
    density_s : float
        :func:`window_trial_density` of the window, s.
    floor_points : int
        K, the independent values in each median of the floor (``0`` = floor known exactly).
    sides : int
        Number of independent medians averaged in the floor.
    """

    def log_pfa(g: float) -> float:
        if floor_points > 0:
            tail, ft = median_floor_tail(g, floor_points, sides)
            return math.log(tail) + math.log1p(band_hz * density_s * math.sqrt(g * ft))
        return -g + math.log1p(band_hz * density_s * math.sqrt(g))

    return _solve_threshold(log_pfa, false_alarm)


@functools.lru_cache(maxsize=64)
def post_fit_threshold(false_alarm: float, band_hz: float, n: int, rate_hz: float, dof: int) -> float:
    """Threshold on ``u = (A/σ_A)²/2`` of a least-squares tone for the whole-band ``false_alarm`` (module doc).

    ``n`` samples at ``rate_hz`` (unwindowed: D = √(4π var t) = √(π(n²−1)/3)/f_s), σ estimated on ``dof``
    degrees of freedom.
    """
    density = math.sqrt(math.pi * (float(n) ** 2 - 1.0) / 3.0) / rate_hz
    nu = max(int(dof), 1)

    def log_pfa(g: float) -> float:
        return -0.5 * nu * math.log1p(2.0 * g / nu) + math.log1p(band_hz * density * math.sqrt(g))

    return _solve_threshold(log_pfa, false_alarm)


def redetection_probability(u: float, threshold: float) -> float:
    """Probability that a tone with post-fit statistic ``u`` would exceed ``threshold`` in a repeat record.

    ``2u`` is non-central χ² with 2 degrees of freedom and non-centrality ``2u₀`` (u₀ the noise-free value);
    ``u₀`` is estimated without bias as ``max(u − 1, 0)``.
    """
    if not math.isfinite(u):
        return 1.0
    return float(stats.ncx2.sf(2.0 * threshold, 2, 2.0 * max(u - 1.0, 0.0)))


def _nfft(n: int) -> int:
    return 1 << int(math.ceil(math.log2(PAD * n)))


def _floor_layout(n: int, nfft: int, floor_points: int) -> tuple[NDArray[np.int64], int, NDArray[np.int64]]:
    """Padded-bin indices of the independent floor points, their spacing (padded bins), and the K used per side
    at each point: ``floor_points`` in the interior, fewer (odd, ≥ ``MIN_FLOOR_POINTS``) near DC and Nyquist
    where the window must stay symmetric, 0 where even that does not fit."""
    spacing = int(math.ceil(INDEPENDENT_BINS * nfft / n))
    size = nfft // 2 + 1
    idx = np.arange(spacing, size - spacing, spacing)
    c = np.arange(idx.size)
    k = np.minimum(floor_points, np.minimum(c, idx.size - 1 - c) - FLOOR_EXCLUDE)
    k -= 1 - k % 2  # odd
    return idx, spacing, np.where(k >= MIN_FLOOR_POINTS, k, 0)


@functools.lru_cache(maxsize=64)
def search_band(n: int, rate_hz: float, floor_points: int = FLOOR_POINTS_PER_SIDE) -> tuple[float, float]:
    """The searched band, Hz: [6/T, f_s/2 − 6/T] (closer to DC or Nyquist a tone cannot be told from drift or
    resolved from its alias) where the noise floor has a symmetric window of at least ``MIN_FLOOR_POINTS``
    values per side (empty: lo ≥ hi)."""
    duration = n / rate_hz
    nfft = _nfft(n)
    idx, spacing, k = _floor_layout(n, nfft, floor_points)
    ok = np.flatnonzero(k)
    if ok.size == 0:
        return EDGE_PERIODS / duration, EDGE_PERIODS / duration
    df = rate_hz / nfft
    lo = max(EDGE_PERIODS / duration, (idx[ok[0]] - spacing / 2) * df)
    hi = min(rate_hz / 2.0 - EDGE_PERIODS / duration, (idx[ok[-1]] + spacing / 2) * df)
    return float(lo), float(hi)


def _nearest_point(size: int, idx: NDArray[np.int64], spacing: int) -> NDArray[np.int64]:
    return np.clip(np.rint((np.arange(size) - idx[0]) / spacing).astype(np.int64), 0, idx.size - 1)


def _floor(psd: NDArray[np.float64], n: int, nfft: int, floor_points: int) -> tuple[NDArray[np.float64], int]:
    """Two-sided median floor of each row of ``psd`` (module doc) at every padded bin (NaN where no window
    fits); returns (floor, interior K per side, 0 when the record is too short)."""
    idx, spacing, kpts = _floor_layout(n, nfft, floor_points)
    vals = psd[..., idx]
    floor_pts = np.full(vals.shape, np.nan)
    for k in np.unique(kpts[kpts > 0]):
        windows = np.lib.stride_tricks.sliding_window_view(vals, int(k), axis=-1)  # (..., nd − k + 1, k)
        rates, m = _median_constants(int(k))
        med = np.partition(windows, m - 1, axis=-1)[..., m - 1] / (rates[0] / k)  # normalised by c = rates[0]/K
        centres = np.flatnonzero(kpts == k)
        floor_pts[..., centres] = 0.5 * (med[..., centres - FLOOR_EXCLUDE - k] + med[..., centres + FLOOR_EXCLUDE + 1])
    return floor_pts[..., _nearest_point(psd.shape[-1], idx, spacing)], int(kpts.max(initial=0))


@functools.lru_cache(maxsize=64)
def _thresholds(n: int, rate_hz: float, false_alarm: float, floor_points: int) -> tuple[tuple[int, float], ...]:
    """(K, γ_K) for every K per side used by the floor of this record length (module doc)."""
    _, _, kpts = _floor_layout(n, _nfft(n), floor_points)
    ks = [int(k) for k in np.unique(kpts[kpts > 0])]
    if not ks:
        return ()
    lo, hi = search_band(n, rate_hz, floor_points)
    density = window_trial_density(_window(n), rate_hz)
    k_top = ks[-1]
    g_top = spectrum_threshold(false_alarm, max(hi - lo, 0.0), density, k_top)
    if not math.isfinite(g_top):
        return tuple((k, math.inf) for k in ks)

    def log_rate(g: float, k: int) -> float:  # log of the up-crossing density per Hz at threshold g
        tail, ft = median_floor_tail(g, k)
        return math.log(tail) + math.log(density * math.sqrt(g * ft))

    target = log_rate(g_top, k_top)
    return tuple(
        (k, g_top if k == k_top else _solve_threshold(lambda g, k=k: log_rate(g, k), math.exp(target), lo=1.0))
        for k in ks
    )


def coarse_threshold(n: int, rate_hz: float, false_alarm: float, floor_points: int = FLOOR_POINTS_PER_SIDE) -> float:
    """γ of the coarse search in the interior of the band for ``n`` samples at ``rate_hz`` (peak / floor
    threshold; ∞ when the record is too short for a floor)."""
    th = _thresholds(n, rate_hz, false_alarm, floor_points)
    return th[-1][1] if th else math.inf


def _bin_thresholds(n: int, nfft: int, rate_hz: float, false_alarm: float, floor_points: int) -> NDArray[np.float64]:
    """γ at every padded bin (∞ where there is no floor)."""
    idx, spacing, kpts = _floor_layout(n, nfft, floor_points)
    gamma_pts = np.full(idx.size, np.inf)
    for k, g in _thresholds(n, rate_hz, false_alarm, floor_points):
        gamma_pts[kpts == k] = g
    return gamma_pts[_nearest_point(nfft // 2 + 1, idx, spacing)]


def window_processing_loss(n: int) -> float:
    """Equivalent noise bandwidth of the window in bins, N Σw²/(Σw)² (≈ 2.0): the ratio of a tone's
    least-squares statistic ``u`` to its expected windowed peak / floor ratio."""
    w = _window(n)
    return float(n * np.sum(w**2) / np.sum(w) ** 2)


def coarse_redetection_probability(u: float, gamma: float, enbw: float) -> float:
    """Probability that the coarse search finds again a tone with least-squares statistic ``u`` (module doc):
    its peak / floor ratio is ``E`` of a non-central χ²₂/2 with non-centrality ``2 max(u − 1, 0)/enbw``
    (floor taken as exact, peak at a bin centre)."""
    if not math.isfinite(u):
        return 1.0
    if not math.isfinite(gamma):
        return 0.0
    return float(stats.ncx2.sf(2.0 * gamma, 2, 2.0 * max(u - 1.0, 0.0) / enbw))


@dataclass(frozen=True)
class _Scan:
    freqs: NDArray[np.float64]
    psd: NDArray[np.float64]
    floor: NDArray[np.float64]
    candidates: NDArray[np.bool_]
    gamma: NDArray[np.float64]
    nfft: int
    floor_points: int


def _scan(v: NDArray[np.float64], rate_hz: float, false_alarm: float, floor_points: int) -> _Scan:
    n = v.shape[-1]
    freqs, psd, nfft = padded_periodogram(v, rate_hz)
    floor, k = _floor(psd, n, nfft, floor_points)
    lo, hi = search_band(n, rate_hz, floor_points)
    band = (freqs >= lo) & (freqs <= hi)
    lobe = LOBE_BINS * int(math.ceil(nfft / n))
    is_max = (psd >= maximum_filter1d(psd, size=2 * lobe + 1, mode="nearest", axis=-1)) & band & (psd > 0)
    gamma = _bin_thresholds(n, nfft, rate_hz, false_alarm, floor_points)
    return _Scan(freqs, psd, floor, is_max, gamma, nfft, k)


def _check(v: NDArray[np.float64], false_alarm: float) -> None:
    if v.shape[-1] < 64:
        raise PeriodicInputError(f"need at least 64 points for the peak search, got {v.shape[-1]}")
    if not 0 < false_alarm < 1:
        raise PeriodicInputError(f"the false-alarm probability must be in (0, 1), got {false_alarm}")


def detect(
    records: ArrayLike, rate_hz: float, false_alarm: float = 1e-3, floor_points: int = FLOOR_POINTS_PER_SIDE
) -> NDArray[np.bool_]:
    """Whether each record (row) has at least one significant peak: the decision of :func:`find_peaks_psd`,
    vectorised over records (used to verify the false-alarm probability by simulation)."""
    v = np.atleast_2d(np.asarray(records, dtype=np.float64))
    _check(v, false_alarm)
    s = _scan(v, rate_hz, false_alarm, floor_points)
    with np.errstate(invalid="ignore"):
        return np.any(s.candidates & (s.psd > s.gamma * s.floor), axis=-1)


def find_peaks_psd(
    x: ArrayLike,
    rate_hz: float,
    n_terms: int | None = None,
    false_alarm: float = 1e-3,
    max_terms: int = 8,
    floor_points: int = FLOOR_POINTS_PER_SIDE,
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
        Probability that pure white noise yields at least one false peak anywhere in the searched band.
    max_terms : int
        Cap on the number of significant peaks kept when ``n_terms`` is not given (strongest first).
    floor_points : int
        K, values per side of the two-median floor (module doc).

    Returns
    -------
    list of Peak
        Strongest first, frequencies in :func:`search_band`. Each peak's interval D_i is f_i ± 1/T (the main
        lobe of the least-squares cost).
    """
    v = np.asarray(x, dtype=np.float64)
    if v.ndim != 1:
        raise PeriodicInputError(f"need a 1-D sample for the peak search, got shape {v.shape}")
    _check(v, false_alarm)
    if n_terms is not None and n_terms < 0:
        raise PeriodicInputError(f"the number of terms must be ≥ 0, got {n_terms}")
    n = v.size
    s = _scan(v, rate_hz, false_alarm, floor_points)
    psd, floor = s.psd, s.floor
    cand = np.flatnonzero(s.candidates)
    cand = cand[np.argsort(psd[cand])[::-1]]
    if n_terms is not None:
        chosen = list(cand[:n_terms])
    else:
        with np.errstate(invalid="ignore"):
            chosen = [k for k in cand if floor[k] > 0 and psd[k] > s.gamma[k] * floor[k]][:max_terms]
    df = s.freqs[1] - s.freqs[0]
    duration = n / rate_hz
    peaks: list[Peak] = []
    for k in chosen:
        f = s.freqs[k]
        if 0 < k < psd.size - 1 and psd[k - 1] > 0 and psd[k + 1] > 0:
            lm, l0, lp = np.log(psd[k - 1]), np.log(psd[k]), np.log(psd[k + 1])
            den = lm - 2.0 * l0 + lp
            if den < 0:
                f += 0.5 * (lm - lp) / den * df
        peaks.append(Peak(float(f), float(psd[k]), float(floor[k]), float(s.gamma[k] * floor[k]), 1.0 / duration))
    return peaks
