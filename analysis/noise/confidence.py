"""Noise identification, equivalent degrees of freedom and χ² confidence intervals of stability estimates.

What Stable32 does (W. Riley, *Handbook of Frequency Stability Analysis*, NIST SP 1065; C. Greenhall and
W. Riley, "Uncertainty of stability variances based on finite differences", PTTI 2003; W. Riley and
C. Greenhall, "Power law noise identification using the lag 1 autocorrelation", EFTF 2004), per estimator and τ:

1. Noise type α (S_y ∝ f^α: 2 white PM, 1 flicker PM, 0 white FM, −1 flicker FM, −2 random-walk FM) by the
   lag-1 autocorrelation of the phase decimated by m (quadratic removed), differenced d times until
   ρ = r₁/(1 + r₁) < 0.25 or d = d_max (2 for the Allan family, 3 for the Hadamard family);
   α = 2 − round(2ρ) − 2d. With fewer than 30 decimated points: the B1 ratio (standard variance of the
   m-averaged frequency over the Allan variance) against Barnes' theoretical B1(N, μ), the phase-noise
   case split by R(n) = MVAR/AVAR; with too few points even for that, the α of the previous τ.

   Where tablebench departs from Stable32, each measured by the slow coverage test (1000 records of 1024
   points per noise type; white / flicker PM were misidentified at 15–85 % of the long τ before):
   r₁ is averaged over the m decimation phases (:func:`lag1_alpha`); below 30 points a phase-noise test on
   that r₁ comes before B1 (:func:`is_phase_noise`); every phase-noise result at m ≥ 4 is split into
   white / flicker PM by R(n) with overlapping variances (:func:`pm_alpha`: the lag-1 method reads short
   records of flicker PM as white at m ≥ 8); below 8 decimated points the previous τ's α is kept (B1 on 4
   averages read white PM as white FM in 60 % of the records).
2. EDF: Greenhall's combined algorithm (modelling the phase as the first difference of a continuous-time
   power-law process) for ADEV, OADEV, MDEV, TDEV, HDEV, OHDEV — for ADEV/OADEV/HDEV/OHDEV with phase noise
   the exact EDF of discrete-time PM instead (:func:`edf_discrete_pm`: equal to Greenhall's for white PM,
   10–25 % higher and right for flicker PM); the published fits for the total family —
   TOTVAR b·N/m − c (SP 1065 Table 7), at most OAVAR's EDF scaled by the term count (OAVAR's at m = 1,
   where TOTVAR has no reflected term); for white PM the exact EDF of the reflected estimator, for flicker PM
   Table 5's AVAR formula; MTOT/TTOT b·N/m − c (Howe's revised coefficients as in Stable32, the MVAR
   EDF for m ≤ 8), HTOT (N/m)/(b₀ + b₁ m/N) (Howe et al. 2000, HDEV's EDF below m = 16; for phase noise, which no
   published fit covers, OHDEV's EDF times tablebench's Monte Carlo ratio ``_HTOT_PM_RATIO``), and Theo1 / TheoBR
   (Howe & Peppler 2003, at the effective factor 0.75 m; beyond the lag-1 range Theo1 keeps the last lag-1 α).
3. χ² interval of the deviation: σ √(EDF/χ²_{1−p/2}) … σ √(EDF/χ²_{p/2}).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy import special, stats

from analysis.noise.allan import sum_of_products

ONE_SIGMA = math.erf(1.0 / math.sqrt(2.0))
"""Two-sided probability of ±1σ, 0.6827 (Stable32's "0.683")."""

D_ORDER = {"adev": 2, "oadev": 2, "mdev": 2, "tdev": 2, "hdev": 3, "ohdev": 3, "totdev": 2, "mtotdev": 2,
            "ttotdev": 2, "htotdev": 3, "theo1": 2, "theoh": 2, "theobr": 2}
"""Differencing order d of each estimator (noise identification's d_max)."""

# ------------------------------------------------------------------------------------ noise identification


def lag1(z: NDArray[np.float64]) -> float:
    """Lag-1 autocorrelation as Stable32 computes it, Σ z̃_i z̃_{i+1} / Σ z̃_i² · (n − 1)/n with z̃ = z − mean,
    of each column of z (n, k), averaged over the columns."""
    z = z - z.mean(axis=0)
    den = np.einsum("ij,ij->j", z, z)  # einsum, not BLAS: its threads cost more than this sum on a busy machine
    num = np.einsum("ij,ij->j", z[:-1], z[1:])
    ok = den > 0
    return float(np.mean(num[ok] / den[ok])) * (z.shape[0] - 1) / z.shape[0] if ok.any() else 0.0


LAG1_MIN_POINTS = 30
"""Fewest decimated points for the lag-1 method (Riley & Greenhall: "at least 30")."""
PM_TEST_MIN_POINTS = 8
"""Fewest decimated points for the phase-noise test below the lag-1 range (see :func:`is_phase_noise`); below
it the previous τ's α is kept."""
_DECIMATION_POINTS = 1 << 16
"""The lag-1 statistics average the m decimation phases up to about this many points in all (one phase when
the decimated record alone is longer: r₁'s scatter is then ≤ 0.004, far inside the bands)."""


LAG1_MAX_POINTS = 1 << 18
"""The lag-1 statistics use at most this many decimated points per phase (r₁'s standard error is then
≈ 1/√n = 0.002, far inside its classification bands of width 0.5)."""


def _decimations(x_phase: NDArray[np.float64], m: int) -> NDArray[np.float64]:
    """The phase decimated by m at offsets 0 … k − 1 as the columns of an (n, k) view, n = ⌊N/m⌋ (at most
    :data:`LAG1_MAX_POINTS`)."""
    n = min(x_phase.size // m, LAG1_MAX_POINTS)
    k = min(m, max(1, _DECIMATION_POINTS // max(n, 1)))
    return np.asarray(x_phase[: n * m], dtype=np.float64).reshape(n, m)[:, :k]


def lag1_alpha(x_phase: NDArray[np.float64], m: int, dmax: int = 2) -> int | None:
    """α by the lag-1 autocorrelation method on the phase decimated by m (Riley & Greenhall 2004, as in
    Stable32: no trend removal — remove drift before the analysis); None below 30 decimated points.

    Where Stable32 takes one decimation (offset 0), r₁ here is the mean over the m decimation phases
    (offsets 0 … m − 1, up to ≈ 2¹⁶ points in all): the same expectation, a smaller scatter — at N = 1024 the
    single-phase r₁ read white PM as flicker at m = 8–32 in 2–15 % of records, the averaged one in none."""
    z = _decimations(x_phase, m)
    if z.shape[0] < LAG1_MIN_POINTS:
        return None
    d = 0
    while True:
        r1 = lag1(z)
        rho = r1 / (1.0 + r1)
        if rho < 0.25 or d >= dmax:
            return int(-round(2.0 * rho) - 2 * d + 2)
        z = np.diff(z, axis=0)
        d += 1


@lru_cache(maxsize=64)
def expected_lag1(n: int, random_walk: bool) -> float:
    """E[Σ z̃_i z̃_{i+1}] / E[Σ z̃_i²] · (n − 1)/n on n points of white noise (−(n − 1)/n²) or of a random walk
    (covariance min(i, j) + 1), z̃ the points less their mean."""
    if not random_walk:
        return -(n - 1.0) / (n * n)
    i = np.arange(n)
    cov = np.minimum.outer(i, i) + 1.0
    c = np.eye(n) - 1.0 / n
    cm = c @ cov @ c
    return float(np.trace(cm, 1) / np.trace(cm)) * (n - 1.0) / n


def is_phase_noise(x_phase: NDArray[np.float64], m: int) -> bool | None:
    """Below the lag-1 range: is the noise at factor m phase noise (white or flicker PM)? None below 8 points.

    The m-decimated phase of PM noise is white-like (r₁ ≈ −1/n; flicker PM's drifts towards it at large m),
    that of FM noise a random walk or steeper (white FM: exactly a random walk). PM when the r₁ averaged over
    the decimation phases is below the midpoint of the white and the random-walk expectations at n points
    (0.15 at n = 8, 0.30 at n = 16, Riley & Greenhall's 1/3 from 24 points). tablebench's addition, not
    Stable32's: the B1 ratio it replaces there read 18–35 % of white-PM records as white FM at N/m = 8–16
    (N = 1024). Its own error: white FM is called phase noise in 9–12 % of records at 16 points and 26 % at 8
    (a short random walk can look flat); B1 misidentified 32–60 % of white FM at those lengths."""
    z = _decimations(x_phase, m)
    n = z.shape[0]
    if n < PM_TEST_MIN_POINTS:
        return None
    cut = min(1.0 / 3.0, 0.5 * (expected_lag1(n, False) + expected_lag1(n, True)))
    return lag1(z) < cut


RN_MIN_FACTOR = 4
"""Smallest averaging factor at which R(n) splits white from flicker PM (at m = 2 both give R ≈ 0.5)."""


def pm_alpha(x_phase: NDArray[np.float64], m: int) -> int | None:
    """White (2) or flicker (1) PM from R(n) = MVAR/AVAR at factor m ≥ 2 (SP 1065 §5.6): 1/m for white PM,
    3.37/(1.04 + 3 ln(πm)) for flicker PM, split at their geometric mean. Both variances overlapping (Stable32's
    AVAR here is non-overlapping: ~N/m terms, which mis-split 25–45 % of white-PM records at N/m ≤ 16);
    computed on the first 2¹⁶·m phase points at most; None with fewer than 3m + 2 points (MVAR needs m + 1
    terms at least to mean anything)."""
    x = np.asarray(x_phase[: _DECIMATION_POINTS * m + 2 * m], dtype=np.float64)
    if x.size < 3 * m + 2:
        return None
    dd = x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]
    avar = sum_of_products(dd) / dd.size
    cs = np.concatenate([[0.0], np.cumsum(dd)])
    s = cs[m:] - cs[:-m]
    mvar = sum_of_products(s) / s.size / (m * m)
    if avar <= 0:
        return 2
    r_fpm = 3.37 / (1.04 + 3.0 * math.log(math.pi * m))
    return 1 if mvar / avar > math.sqrt(r_fpm / m) else 2


def _b1_theory(n: float, mu: int) -> float:
    """Barnes' expected B1(N, r = 1) for phase-noise exponent μ."""
    if mu == 2:
        return n * (n + 1.0) / 6.0
    if mu == 1:
        return n / 2.0
    if mu == 0:
        return n * math.log(n) / (2.0 * (n - 1.0) * math.log(2.0))
    if mu == -1:
        return 1.0
    return (n * n - 1.0) / (1.5 * n * (n - 1.0))


_MU_TO_ALPHA = {2: -3, 1: -2, 0: -1, -1: 0, -2: 1}


def b1_alpha(x_phase: NDArray[np.float64], m: int, ts: float, n_terms: int) -> int | None:
    """α from the B1 ratio (standard variance of the m-averaged frequency over the non-overlapping AVAR),
    classified against B1(N = the estimator's term count, μ) as Stable32 does; phase noise (μ = −2) is split
    into white/flicker PM by R(n) (:func:`pm_alpha`) for every estimator — Stable32 splits only for the
    modified and total ones and calls the rest flicker PM, which misreads white PM at long τ (coverage test).
    None when fewer than two averages or two terms exist."""
    k = (x_phase.size - 1) // m
    if k < 2 or n_terms < 2:
        return None
    # the mean of m consecutive frequency values telescopes to a phase difference: O(N/m), no full-length pass
    ya = (x_phase[m : k * m + 1 : m] - x_phase[: (k - 1) * m + 1 : m]) / (m * ts)
    svar = float(np.var(ya, ddof=1))
    d = x_phase[2 * m :: m] - 2.0 * x_phase[m:-m:m] + x_phase[: -2 * m : m]
    nd = min(d.size, (x_phase.size - 1) // m - 1)
    d = d[:nd] if nd > 0 else d
    if d.size == 0:
        return None
    avar = float(np.mean(d * d)) / (2.0 * (m * ts) ** 2)
    if avar <= 0:
        return None
    b1 = svar / avar
    n = float(n_terms)
    mu = -2
    for hi_mu in (2, 1, 0, -1):
        th_hi, th_lo = _b1_theory(n, hi_mu), _b1_theory(n, hi_mu - 1)
        bound = 0.5 * (th_hi + th_lo) if hi_mu == 2 else math.sqrt(th_hi * th_lo)
        if b1 > bound:
            mu = hi_mu
            break
    return _MU_TO_ALPHA[mu] if mu != -2 else pm_alpha(x_phase, m) or 1


# --------------------------------------------------------------------------------------- Greenhall EDF


def _sw(t: float, alpha: int) -> float:
    t = abs(t)
    if alpha == 2:
        return -t
    if alpha == 1:
        return t * t * math.log(t) if t else 0.0
    if alpha == 0:
        return t**3
    if alpha == -1:
        return -(t**4) * math.log(t) if t else 0.0
    if alpha == -2:
        return -(t**5)
    if alpha == -3:
        return t**6 * math.log(t) if t else 0.0
    if alpha == -4:
        return t**7
    raise ValueError(f"noise type α = {alpha} outside −4 … 2")


def _sx(t: float, f: float, alpha: int) -> float:
    if math.isinf(f):
        return _sw(t, alpha + 2)
    return f * f * (2.0 * _sw(t, alpha) - _sw(t - 1.0 / f, alpha) - _sw(t + 1.0 / f, alpha))


_BINOM = {1: (2, -1), 2: (6, -4, 1), 3: (20, -15, 6, -1)}


def _sz(t: float, f: float, alpha: int, d: int) -> float:
    c = _BINOM[d]
    s = c[0] * _sx(t, f, alpha)
    for k in range(1, d + 1):
        s += c[k] * (_sx(t - k, f, alpha) + _sx(t + k, f, alpha))
    return s


def _basic_sum(j_: float, m_: float, s_: float, f: float, alpha: int, d: int) -> float:
    tot = _sz(0.0, f, alpha, d) ** 2 + (1.0 - j_ / m_) * _sz(j_ / s_, f, alpha, d) ** 2
    for j in range(1, int(j_)):
        tot += 2.0 * (1.0 - j / m_) * _sz(j / s_, f, alpha, d) ** 2
    return tot


_T1 = {2: {1: (2 / 3, 1 / 3), 2: (7 / 9, 1 / 2), 3: (22 / 25, 2 / 3)},
       1: {1: (0.840, 0.345), 2: (0.997, 0.616), 3: (1.141, 0.843)},
       0: {1: (1.079, 0.368), 2: (1.033, 0.607), 3: (1.184, 0.848)},
       -1: {2: (1.048, 0.534), 3: (1.180, 0.816)},
       -2: {2: (1.302, 0.535), 3: (1.175, 0.777)},
       -3: {3: (1.194, 0.703)},
       -4: {3: (1.489, 0.702)}}
_T2 = {2: {1: (3 / 2, 1 / 2), 2: (35 / 18, 1.0), 3: (231 / 100, 3 / 2)},
       1: {1: (78.6, 25.2), 2: (790.0, 410.0), 3: (9950.0, 6520.0)},
       0: {1: (2 / 3, 1 / 6), 2: (2 / 3, 1 / 3), 3: (7 / 9, 1 / 2)},
       -1: {2: (0.852, 0.375), 3: (0.997, 0.617)},
       -2: {2: (1.079, 0.368), 3: (1.033, 0.607)},
       -3: {3: (1.053, 0.553)},
       -4: {3: (1.302, 0.535)}}
_T3 = {1: (6.0, 4.0), 2: (15.23, 12.0), 3: (47.8, 40.0)}
_JMAX = 100


@lru_cache(maxsize=4096)
def edf_greenhall(alpha: int, d: int, m: int, n: int, overlapping: bool, modified: bool) -> float:
    """Greenhall & Riley (2003) combined EDF of a d-th difference variance at averaging factor m on n phase points.

    d = 2: (O)AVAR / MVAR (TVAR); d = 3: (O)HVAR. ``overlapping``: stride 1 instead of m; ``modified``: the
    modified (m-averaged) form. Requires α + 2d > 1.
    """
    if alpha + 2 * d <= 1:
        raise ValueError(f"a d = {d} variance cannot resolve noise type α = {alpha}")
    f = 1 if modified else m
    s = m if overlapping else 1
    length = m // f + m * d
    if n < length:
        return float("nan")
    mm = 1 + math.floor(s * (n - length) / m)
    jj = min(mm, (d + 1) * s)
    r = mm / s
    if f == 1:  # modified variances (and unmodified at m = 1)
        if jj <= _JMAX:
            inv = _basic_sum(jj, mm, s, 1, alpha, d) / (mm * _sz(0.0, 1, alpha, d) ** 2)
        elif r > d + 1:
            a0, a1 = _T1[alpha][d]
            inv = (a0 - a1 / r) / r
        else:
            mp = _JMAX / r
            inv = _basic_sum(_JMAX, _JMAX, mp, 1, alpha, d) / (_JMAX * _sz(0.0, 1, alpha, d) ** 2)
    elif alpha <= 0:
        if jj <= _JMAX:
            fp = m if m * (d + 1) <= _JMAX else math.inf
            inv = _basic_sum(jj, mm, s, fp, alpha, d) / (mm * _sz(0.0, fp, alpha, d) ** 2)
        elif r > d + 1:
            a0, a1 = _T2[alpha][d]
            inv = (a0 - a1 / r) / r
        else:
            mp = _JMAX / r
            inv = _basic_sum(_JMAX, _JMAX, mp, math.inf, alpha, d) / (_JMAX * _sz(0.0, math.inf, alpha, d) ** 2)
    elif alpha == 1:
        if jj <= _JMAX:
            inv = _basic_sum(jj, mm, s, m, 1, d) / (mm * _sz(0.0, m, 1, d) ** 2)
        elif r > d + 1:
            a0, a1 = _T2[1][d]
            b0, b1 = _T3[d]
            inv = (a0 - a1 / r) / (r * (b0 + b1 * math.log(m)) ** 2)
        else:
            mp = _JMAX / r
            b0, b1 = _T3[d]
            inv = _basic_sum(_JMAX, _JMAX, mp, mp, 1, d) / (_JMAX * (b0 + b1 * math.log(m)) ** 2)
    else:  # white PM, unmodified
        k = math.ceil(r)
        if k <= d:
            acc = sum((1.0 - kk / r) * special.binom(2 * d, d - kk) ** 2 for kk in range(1, k))
            inv = (1.0 + 2.0 * acc / special.binom(2 * d, d) ** 2) / mm
        else:
            a0, a1 = _T2[2][d]
            inv = (a0 - a1 / r) / mm
    return 1.0 / inv


# ------------------------------------------------------------------------------- published EDF fits


def _pm_structure(j: NDArray[np.float64], alpha: int) -> NDArray[np.float64]:
    """Structure function D(j) = E[(x_{t+j} − x_t)²] of discrete phase noise with unit innovations: white PM
    2 (j ≠ 0); flicker PM (2/π)(ψ(j + ½) − ψ(½)), the d → ½ limit of fractionally integrated noise (Kasdin &
    Walter's flicker phase, whose γ(0) − γ(j) → (ψ(j + ½) − ψ(½))/π)."""
    if alpha >= 2:
        return np.where(j > 0, 2.0, 0.0)
    return (2.0 / math.pi) * (special.digamma(j + 0.5) - special.digamma(0.5))


_PM_LAGS = 8
"""The discrete PM EDF sums the terms' covariances out to 8m (overlapping) or 8 terms (non-overlapping): beyond,
flicker PM's fall as (m/k)⁴ — 3e-8 of the EDF at N = 10⁶."""


@lru_cache(maxsize=4096)  # a pure function of integers, asked again for every channel of one record (issue 32)
def edf_discrete_pm(alpha: int, d: int, m: int, n: int, overlapping: bool) -> float:
    """EDF of the (overlapping) Allan (d = 2) or Hadamard (d = 3) variance of discrete white (α = 2) or flicker
    (α = 1) PM on n phase points: K²R(0)² / Σ_{|k|<K} (K − |k|) R(k)², R the covariance of the d-th differences
    at lag m (from the structure function, :func:`_pm_structure`), K the term count — the definition the χ²
    approximation uses, exact for Gaussian phase noise sampled at τ₀.

    For white PM it equals Greenhall's algorithm; for flicker PM Greenhall's continuous-time model gives an EDF
    10–25 % lower than Kasdin–Walter discrete flicker PM's measured one at m = 4–64 (N = 1024: 68 % OADEV
    intervals covered 71.8 %); this one agrees with the measurement within its ±4.5 % and with Stable32's Sr87
    OADEV/OHDEV bounds within 1 % (tests)."""
    c = np.array([1.0, -2.0, 1.0]) if d == 2 else np.array([-1.0, 3.0, -3.0, 1.0])
    w = np.convolve(c, c[::-1])  # weights of D at lags (−d … d)·m
    if overlapping:
        terms, step = n - d * m, 1
        kmax = min(terms - 1, _PM_LAGS * m)
    else:
        terms, step = (n - 1) // m - d + 1, m
        kmax = min(terms - 1, _PM_LAGS) * m
    if terms < 1:
        return float("nan")
    dj = _pm_structure(np.arange(kmax + d * m + 1, dtype=np.float64), alpha)
    k = np.arange(0, kmax + 1, step)
    r = np.zeros(k.size)
    for i, wu in enumerate(w):
        r += wu * _lagged(dj, k, (i - d) * m, step)
    r *= -0.5
    lag = k // step
    weight = np.where(lag == 0, terms, 2.0 * (terms - lag))
    return float(terms * terms * r[0] ** 2 / np.sum(weight * r * r))


def _lagged(dj: NDArray[np.float64], k: NDArray[np.int64], offset: int, step: int) -> NDArray[np.float64]:
    """``dj[|k + offset|]``; for consecutive k (``step`` 1) as slices, not a gather: the same values at a fraction
    of the cost (the overlapping estimators' k run to 8m; the noise report's EDFs were 3/4 of its time, issue
    32)."""
    if step != 1:
        return dj[np.abs(k + offset)]
    top = int(k[-1])
    if offset >= 0:
        return dj[offset : offset + top + 1]
    if -offset <= top:
        return np.concatenate([dj[-offset:0:-1], dj[0 : top + offset + 1]])
    return dj[-offset : -offset - top - 1 : -1]  # -offset > top here: the stop index is ≥ 0


def edf_avar_simple(n: int, m: int, alpha: int) -> float:
    """SP 1065 Table 5 approximations for the overlapping AVAR (n phase points)."""
    nn, mm = float(n), float(m)
    if alpha >= 2:
        return (nn + 1) * (nn - 2 * mm) / (2 * (nn - mm))
    if alpha == 1:
        return math.exp(math.sqrt(math.log((nn - 1) / (2 * mm)) * math.log((2 * mm + 1) * (nn - 1) / 4)))
    if alpha == 0:
        return (3 * (nn - 1) / (2 * mm) - 2 * (nn - 2) / nn) * 4 * mm * mm / (4 * mm * mm + 5)
    if alpha == -1:
        return 2 * (nn - 2) ** 2 / (2.3 * nn - 4.9) if m == 1 else 5 * nn * nn / (4 * mm * (nn + 3 * mm))
    return (nn - 2) / (mm * (nn - 3) ** 2) * ((nn - 1) ** 2 - 3 * mm * (nn - 1) + 4 * mm * mm)


_TOT = {0: (1.50, 0.0), -1: (1.17, 0.22), -2: (0.93, 0.36)}
_MTOT = {2: (2.16, 2.28), 1: (1.73, 2.99), 0: (1.33, 1.89), -1: (0.92, 0.76), -2: (0.79, 0.37)}
"""MTOTVAR (and TTOTVAR) EDF = b·N/m − c for m > 8 (N phase points): D. Howe's revised coefficients of 2000-05-20
as Stable32 uses them (W. Riley's edf test program, k2hrt/edf ``edf4.c`` ``ModTotvarEDF``, which keeps the older
SP 1065 Table 8 values 1.90/2.10 … 0.75/0.31 as comments); for m ≤ 8 Stable32 switches to the MVAR EDF. With these
the Sr87 MTOTDEV/TTOTDEV bounds agree with Stable32's within 2 % (Table 8's were 6–37 % narrower)."""
_MTOT_MVAR_BELOW = 8
"""Largest m at which the MTOT/TTOT EDF is the MVAR EDF (Stable32)."""
_HTOT = {0: (0.559, 1.004), -1: (0.868, 1.140), -2: (0.938, 1.696), -3: (0.974, 2.554), -4: (1.276, 3.149)}
"""HTOTVAR EDF = (N/m)/(b₀ + b₁ m/N) for white, flicker, random-walk, flicker-walk, random-run FM (Howe et al.
2000, Table 1; the same rows as Stable32's ``HadTotvarEDF``, k2hrt/edf ``edf4.c``). Stable32's Sr87 intervals
confirm this row order (allantoolkit's table labels the same rows α = 2 … −2)."""

_HTOT_PM_RATIO = {2: (1.47, 1.90), 1: (1.43, 2.11)}
"""HTOTVAR EDF over Greenhall's OHVAR EDF for white (2) and flicker (1) PM, at m = 2–3 and m ≥ 4 (HTOTVAR is
OHVAR at m = 1). No published fit exists (Howe et al. 2000 cover FM noise; Stable32 uses the Hadamard EDF,
which made the coverage test's 68 % HTOTDEV intervals cover 81–83 %). tablebench's own Monte Carlo calibration:
geometric-mean ratio of the measured EDF 2E[σ̂²]²/Var[σ̂²] over 400 Kasdin–Walter records at N = 256, 4096 and
16 384, octave m (3 + 25 points per α; single ratios 1.3–2.7, rising towards 3m → N), from
``python scripts/calibrate_htot_pm_edf.py``; N = 1024, the coverage test's length, was left out."""


def edf_theo1(n: int, m: int, alpha: int) -> float:
    """Theo1 EDF (Howe & Peppler 2003) on n phase points at averaging factor m (effective t = 0.75 m)."""
    nn = float(n)
    t = 0.75 * m
    if alpha >= 2:
        return 0.86 * (nn + 1) * (nn - 4 * t / 3) / (nn - t) * t / (t + 1.14)
    if alpha == 1:
        return (4.798 * nn**2 - 6.374 * nn * t + 12.387 * t) / (math.sqrt(t + 36.6) * (nn - t)) * t / (t + 0.3)
    if alpha == 0:
        return ((4.1 * nn + 0.8) / t - (3.1 * nn + 6.5) / nn) * t**1.5 / (t**1.5 + 5.2)
    if alpha == -1:
        return (2 * nn**2 - 1.3 * nn * t - 3.5 * t) / (nn * t) * t**3 / (t**3 + 2.3)
    a = 4.4 * nn
    return (a - 2) / (2.9 * t) * ((a - 1) ** 2 - 8.6 * t * (a - 1) + 11.4 * t * t) / (a - 3) ** 2


THEOBR_KF_EDF = 20.0
"""EDF of TheoBR's bias-removal factor kf = mean OAVAR(9 + 3i)/Theo1(12 + 4i), i = 0 … N/6 − 3. The ratios span
m up to N/2, so kf's scatter does not shrink with N: measured EDF of TheoBR at short τ (where Theo1's own is in
the hundreds) over 60–100 simulated records: white FM 24 (N = 1024) and 22–26 (N = 4096), flicker FM 26,
random-walk FM 29 (N = 1024); taken as 20, below every measurement (their sampling error is ±15–18 %). No
published value; for phase noise TheoBR itself is biased (E[TheoBR²]/AVAR 0.3–1.1 with white PM: kf from short τ
does not hold at long τ) and no EDF makes its interval cover."""


def edf_theobr(theo1_edf: float) -> float:
    """EDF of TheoBR = kf·Theo1 from Theo1's EDF at that τ: 1/EDF adds (relative variances of the product)."""
    return 1.0 / (1.0 / theo1_edf + 1.0 / THEOBR_KF_EDF)


_WPM_EXACT_MAX_N = 1 << 21
"""Longest record for which :func:`edf_totvar_wpm` builds the coefficient matrix (O(N), ~3 s at this length);
beyond, SP 1065 Table 5's AVAR EDF (optimistic at large m)."""


def totvar_wpm_b(n: int, m: int):  # noqa: ANN202 (scipy.sparse matrix)
    """B = AᵀA, A (N − 2 × N) the map from the phase to TOTVAR's reflected second differences at factor m."""
    from scipy import sparse

    i = np.arange(1, n - 1)
    r = np.arange(i.size)
    lo, hi = i - m, i + m
    left, right = lo < 0, hi > n - 1
    rows = [r[~left], r[left], r[left], r, r[~right], r[right], r[right]]
    cols = [lo[~left], np.zeros(left.sum(), dtype=np.int64), -lo[left], i, hi[~right],
            np.full(right.sum(), n - 1), 2 * (n - 1) - hi[right]]
    vals = [np.ones((~left).sum()), np.full(left.sum(), 2.0), np.full(left.sum(), -1.0), np.full(i.size, -2.0),
            np.ones((~right).sum()), np.full(right.sum(), 2.0), np.full(right.sum(), -1.0)]
    a = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(i.size, n))
    return (a.T @ a).tocsr()


@lru_cache(maxsize=4096)
def edf_totvar_wpm(n: int, m: int) -> float:
    """EDF of TOTVAR for white PM on n phase points: 2 E[S]²/Var[S] = (tr B)²/‖B‖²_F exactly, S = Σ v_i² the sum
    of the N − 2 (reflected) second differences v = A x, B = AᵀA, x i.i.d. Gaussian — the definition the χ²
    approximation uses (Greenhall's algorithm computes the same for the Allan/Hadamard family). No published
    TOTVAR fit covers phase noise (Stable32 uses the AVAR EDF); the inverted reflection makes the 2(m − 1) end
    terms share 2x₁ and 2x_N, so the EDF falls far below the AVAR's at large m (N = 1024, m = 128: 84 vs 439;
    measured over 400 simulated records: 68)."""
    if n > _WPM_EXACT_MAX_N:
        return edf_avar_simple(n, m, 2)
    b = totvar_wpm_b(n, m)
    tr = float(b.diagonal().sum())
    return tr * tr / float(b.multiply(b).sum())


_WPM_SHAPE_MAX = 1 << 22
"""Largest N·m for which :func:`totvar_wpm_shape` forms B² (the reflected end rows make it dense in blocks:
0.2 s and ≈ 200 MB at N = 4096, m = 1024; beyond, the interval is the χ² of the exact EDF, conservative at
68 %)."""


@lru_cache(maxsize=4096)
def totvar_wpm_shape(n: int, m: int) -> tuple[float, float, float] | None:
    """Three-cumulant law of TOTVAR's σ̂²/σ² for white PM: a + b·χ²_ν with the exact cumulants of S = xᵀBx
    (κ_r ∝ 2^{r−1}(r − 1)! tr B^r): b = k₃/(4k₂), ν = 8k₂³/k₃², a = 1 − bν (a = 0 is the scaled χ² of the
    EDF). The end terms sharing 2x₁ and 2x_N make S more skewed than a χ² of its EDF; the χ² interval then
    covered 73–78 % instead of 68 % at m ≥ 64 (N = 1024). None where N·m > 2²² (B² too large)."""
    if n > _WPM_EXACT_MAX_N or n * m > _WPM_SHAPE_MAX:
        return None
    b = totvar_wpm_b(n, m)
    tr1 = float(b.diagonal().sum())
    b2 = b @ b
    tr2 = float(b2.diagonal().sum())
    tr3 = float(b2.multiply(b).sum())
    k2, k3 = 2.0 * tr2 / tr1**2, 8.0 * tr3 / tr1**3
    scale = k3 / (4.0 * k2)
    nu = 8.0 * k2**3 / k3**2
    return 1.0 - scale * nu, scale, nu


def shifted_chi2_interval(dev: float, shape: tuple[float, float, float], confidence: float) -> tuple[float, float]:
    """Interval (lo, hi) of a deviation whose σ̂²/σ² follows a + b·χ²_ν (see :func:`totvar_wpm_shape`)."""
    a, b, nu = shape
    p = 0.5 * (1.0 - confidence)
    q_lo, q_hi = a + b * stats.chi2.ppf(p, nu), a + b * stats.chi2.ppf(1.0 - p, nu)
    return dev / math.sqrt(q_hi), dev / math.sqrt(q_lo)


EDF_RULES = ("tablebench", "stable32")
"""Rule sets of :func:`edf`: tablebench's (the module docstring; calibrated by Monte Carlo coverage where
Stable32's are known to miss) and Stable32's own (:func:`edf_stable32`, to reproduce a Stable32 printout)."""

STABLE32_TOTAL_EXTRA_EDF = 2.0
"""Stable32's EDF of TOTDEV for phase noise and of HTOTDEV where Howe's fit does not apply (phase noise, m < 16)
is SP 1065 Table 5's simple AVAR EDF plus this constant. Not published: read off Stable32's printouts. With it
the bounds of all 52 such rows we have (allantools' reference files: PHASE.DAT HTOTDEV α = 2, 1, 0 at m = 1–256,
TOTDEV of the GPS, OCXO and counter records, α = 2, 1, N = 2·10⁴–2.4·10⁵; the Sr87 tables: HTOTDEV α = 1, 0, −1,
−2 at m = 1–100, TOTDEV α = 1) equal Stable32's within 0.03 % (χ² exact); without it the flicker-PM rows are up
to 1.4 % apart (PHASE.DAT HTOTDEV m = 256: EDF 16.5 against Stable32's 18.55; m = 128: 48.6 / 50.6; Sr87
m = 100: 90.2 / 92.2; GPS TOTDEV m = 65 536: 41.6 / 43.6). W. Riley's edf program (k2hrt/edf ``edf4.c``) names
the simple AVAR EDF (``CalcDegFree``) as Stable32's fallback for phase noise; 2 is also the difference between
Howe's TOTVAR fit 1.5 N/m and that formula for white FM at large N and m."""


def edf_stable32(estimator: str, alpha: int, m: int, n: int) -> float:
    """EDF of ``estimator`` as Stable32 computes it (NaN: none defined), for reproducing its printed bounds:
    Greenhall's combined algorithm for the Allan/Hadamard family at every α (no discrete-time PM EDF); TOTDEV
    Howe's fit b·N/m − c for FM noise (not capped at OAVAR's EDF) and the simple AVAR EDF +
    :data:`STABLE32_TOTAL_EXTRA_EDF` for phase noise; HTOTDEV Howe's fit for FM noise at m ≥ 16, else the same
    simple AVAR EDF + 2; MTOT/TTOT and Theo1 as tablebench. With the α Stable32 printed, the bounds of every
    row of allantools' Stable32 reference files agree within 0.03 % (except where Stable32 read another copy of the
    record) — Stable32's χ² quantiles are an approximation above EDF 100 whose effect on the bounds is
    ~0.02 %. The intervals are not calibrated: for white and flicker PM Stable32's TOTDEV/HTOTDEV intervals are
    too wide (the default rules' coverage test)."""
    a = int(alpha)
    family = {"adev": (2, False), "oadev": (2, True), "hdev": (3, False), "ohdev": (3, True)}
    if estimator in family:
        d, overlapping = family[estimator]
        return edf_greenhall(min(2, max(a, 2 - 2 * d)), d, m, n, overlapping, False)
    if estimator == "totdev" and a in _TOT:
        b, c = _TOT[a]
        return b * n / m - c
    if estimator == "htotdev" and a <= 0 and m >= 16:
        b0, b1 = _HTOT[max(-4, a)]
        return (n / m) / (b0 + b1 * m / n)
    if estimator in ("totdev", "htotdev") and -2 <= a:
        return edf_avar_simple(n, m, min(a, 2)) + STABLE32_TOTAL_EXTRA_EDF
    return edf(estimator, a, m, n)


def edf(estimator: str, alpha: int, m: int, n: int, rules: str = "tablebench") -> float:
    """EDF of ``estimator`` at averaging factor m on n phase points for noise type α (NaN: none defined), by
    tablebench's rules or, ``rules="stable32"``, by Stable32's (:func:`edf_stable32`)."""
    if rules == "stable32":
        return edf_stable32(estimator, alpha, m, n)
    a = int(alpha)
    unmodified = {"adev": (2, False), "oadev": (2, True), "hdev": (3, False), "ohdev": (3, True)}
    if estimator in unmodified:
        d, overlapping = unmodified[estimator]
        if a >= 1:  # phase noise: the exact discrete-time EDF (Greenhall's for white PM; see edf_discrete_pm)
            return edf_discrete_pm(min(a, 2), d, m, n, overlapping)
        return edf_greenhall(max(a, 2 - 2 * d), d, m, n, overlapping, False)
    if estimator in ("mdev", "tdev"):
        return edf_greenhall(max(a, -2), 2, m, n, True, True)
    if estimator == "totdev":
        if a >= 2:
            return edf_totvar_wpm(n, m)
        if a not in _TOT:
            return edf_avar_simple(n, m, a)
        # the fit b·N/m − c is Howe's large-T/τ form; TOTVAR is OAVAR's N − 2m terms plus 2(m − 1) reflected
        # ones (none at m = 1, where the fit doubles the EDF): not more than OAVAR's EDF scaled by the term count
        b, c = _TOT[a]
        oavar = edf_greenhall(a, 2, m, n, True, False) * (n - 2.0) / (n - 2.0 * m)
        return min(b * n / m - c, oavar)
    if estimator in ("mtotdev", "ttotdev"):
        if m <= _MTOT_MVAR_BELOW:
            return edf_greenhall(max(a, -2), 2, m, n, True, True)
        b, c = _MTOT[max(-2, min(2, a))]
        return b * n / m - c
    if estimator == "htotdev":
        if a > 0:  # phase noise: no published HTOT fit; OHDEV's EDF scaled by tablebench's calibration
            if m == 1:  # HTOTVAR is OHVAR at m = 1
                return edf("ohdev", a, m, n)
            return _HTOT_PM_RATIO[min(a, 2)][0 if m < 4 else 1] * edf_greenhall(min(a, 2), 3, m, n, True, False)
        if m < 16:  # short τ: the OHDEV EDF (Stable32)
            return edf_greenhall(max(a, -4), 3, m, n, True, False)
        b0, b1 = _HTOT[max(-4, a)]
        return (n / m) / (b0 + b1 * m / n)
    if estimator == "theo1":
        return edf_theo1(n, m, max(-2, min(2, a)))
    return float("nan")


_TOT_BIAS = {0: 0.0, -1: 1.0 / (3.0 * math.log(2.0)), -2: 0.75}
_HTOT_BIAS = {0: -0.005, -1: -0.149, -2: -0.229}


def bias_factor(estimator: str, alpha: NDArray, m: NDArray, tau: NDArray, record_time: float) -> NDArray:
    """Variance bias B (E[estimate] = B·σ²) of TOTVAR (1 − a·τ/T: a = 0, 1/(3 ln 2), 3/4 for white, flicker,
    random-walk FM; Howe 1999) and HTOTVAR (1 + a: a = −0.005, −0.149, −0.229, m ≥ 2; Howe et al. 2000);
    1 for phase noise. Shape of ``alpha`` (M, C)."""
    a = np.asarray(alpha)
    out = np.ones(a.shape)
    for al, coef in (_TOT_BIAS if estimator == "totdev" else _HTOT_BIAS).items():
        if estimator == "totdev":
            val = 1.0 - coef * (np.asarray(tau, dtype=np.float64)[:, None] / record_time)
        else:
            val = np.where(np.asarray(m)[:, None] >= 2, 1.0 + coef, 1.0)
        out = np.where(a == al, val, out)
    return out


def chi2_interval(dev: NDArray, edf_: NDArray, confidence: float) -> tuple[NDArray, NDArray]:
    """Two-sided χ² interval (lo, hi) of a deviation with ``edf_`` degrees of freedom (NaN where EDF ≤ 0)."""
    e = np.where(np.isfinite(edf_) & (edf_ > 0), edf_, np.nan)
    p = 0.5 * (1.0 - confidence)
    with np.errstate(invalid="ignore"):
        lo = dev * np.sqrt(e / stats.chi2.ppf(1.0 - p, e))
        hi = dev * np.sqrt(e / stats.chi2.ppf(p, e))
    return lo, hi
