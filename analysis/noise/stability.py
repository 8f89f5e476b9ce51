"""The frequency-stability family on frequency or phase records, several channels at once, gaps allowed.

Estimators (NIST SP 1065 definitions, each equal to allantools 2024.06 with the same ``data_type`` and τ;
τ = m τ₀, x the phase (time error) with N points, y the frequency with N − 1 = N_f samples):

=========  =====================================================================  ==========================
name       definition                                                             terms per τ
=========  =====================================================================  ==========================
adev       non-overlapping Allan: (x_{i+2m} − 2x_{i+m} + x_i)², stride m           ⌈(N − 2m)/m⌉
oadev      overlapping Allan, stride 1                                            N − 2m
mdev       modified Allan: m-sums of the second differences                       N − 3m + 1
tdev       τ/√3 · mdev (seconds of phase)                                          as mdev
hdev       Hadamard: (x_{i+3m} − 3x_{i+2m} + 3x_{i+m} − x_i)², stride m            ⌈(N − 3m)/m⌉
ohdev      overlapping Hadamard, stride 1                                         N − 3m
totdev     total: second differences of the phase reflected (inverted) at both    N − 2
           ends, centred on the N − 2 interior points
mtotdev    modified total: per 3m-point subsequence, linear trend (half means)    N − 3m + 1 subsequences
           removed, extended by even reflection to 9m, 6m modified second
           differences
ttotdev    τ/√3 · mtotdev                                                         as mtotdev
htotdev    Hadamard total: as mtotdev on the frequency (m = 1: ohdev)             N_f − 3m + 1
theo1      Theo1 (SP 1065 eq. 30), even m, reported at τ = m τ₀ like allantools     (N − m) m/2
           (Stable32's printed "Thêo1" is theobr, at the effective τ = 0.75 m τ₀)
theoh      TheoH: overlapping ADEV for τ < k, TheoBR (at 0.75 m τ₀ ≥ k) beyond, k   —
           the largest τ ≤ 20 % of the record (NIST SP 1065; Stable32)
theobr     bias-removed Theo1: Theo1 · mean(AVAR(9+3i)/Theo1(12+4i)), i = 0 … n,   (N − m) m/2
           n = ⌊N/6⌋ − 3 (Stable32's Run; Taylor & Howe 2010 use ⌊0.1N/3⌋ − 3),
           at τ = 0.75 m τ₀
mtie       maximum time-interval error over windows of m + 1 phase points          N − m windows
tierms     rms of x_{i+m} − x_i                                                    N − m
=========  =====================================================================  ==========================

Frequency input is integrated to phase as allantools does (mean removed, x_0 = 0, x_j = x_{j−1} + y_j τ₀);
phase input for ``htotdev`` is differenced to frequency.

Speed. Every estimator costs O(N) or O(N log N) per τ. ADEV/OADEV/HDEV/OHDEV/TIE rms: chunked differences;
MDEV/TDEV: a cumulative sum of the second differences; MTIE: an O(N) running max/min filter; the classic
ADEV/OADEV/MDEV/TOTDEV of gap-free frequency records go through :func:`analysis.noise.allan.allan_variances`
(channel by channel, chunked passes shared by several octaves, plain sums by telescoping, analytic ramp handling;
for one channel the pass also leaves the record's phase, so it is not integrated twice). MTOTDEV/TTOTDEV/HTOTDEV:
the even reflection makes each subsequence's 6m terms one period of a circular filter, i.e. a quadratic form zᵀQz
with Q Toeplitz + Hankel; summed over subsequences it reduces to the record's autocorrelation (one FFT per channel
and record, :func:`~analysis.noise.fftkit.autocorr`) and FFT correlations of the 3m − 1 end samples
(:func:`~analysis.noise.mtot.mtot_fft`: O(N) once plus O(m log m) per τ). Theo1: window sums, one lagged product, a
blocked FFT correlation and two anti-diagonal triangle sums by divide and conquer
(:func:`~analysis.noise.theo1.theo1_fft`, O(N log m + m log² m) per τ). Both closed forms expand squares into
products, so they are used only where their rounding estimate is below 1e-10 of the variance (and for m ≥ 8 / 64);
above it (small m on a long random-walk phase) block by block (:func:`~analysis.noise.closed_forms.blocked_sum`, O(N
log B) per τ); with gaps, the exact direct sums (O(N·m) per τ, vectorised, in chunks). Several channels: the closed
forms run channel by channel over the whole τ grid (:func:`~analysis.noise.closed_forms.prepass`), so one channel's
series and autocorrelation are alive at a time. Memory (benchmarks/bench_noise.py, RESULTS.md): the classic path
about 2× the record; the total family and Theo1 below 4× over the whole grid, longest τ included (N = 10⁷ octave
grid: MTOT/HTOT/TTOT 3.6×, Theo1 3.3×): the autocorrelation is formed in one buffer of N + maxlag points
(:func:`~analysis.noise.fftkit.autocorr`, in-place FFTs, only the lags the grid reads); the total family's detrended
series is formed on demand (:class:`~analysis.noise.fftkit.Detrended`), its end-segment correlations use at most two
in-place FFT buffers of ≈ 6m points, with R released at the grid's largest m; Theo1's long correlations and triangle
squares are blocked (FFTs of ≤ N/8 points, :func:`~analysis.noise.theo1.corr_sum`). A gap-free phase input and a
gap-free frequency input for HTOTDEV are used without copies.

Gaps. NaN samples are gaps. A term is skipped when it touches a gap: for phase input (allantools'
gap-robust ``gradev`` convention) the phase points a point-estimator uses (ADEV, OADEV, HDEV, OHDEV, TIE rms)
must be finite; for the span-estimators (MDEV, TOTDEV, the total family, Theo1, MTIE) and for every
estimator on frequency input, the whole span of the term must be gap-free (with frequency input a missing
sample leaves the phase after it unknown, so a term across it is meaningless). Each estimator reports the
number of terms it used per τ and channel.

Layout: this module holds the driver (:func:`stability`, the estimator table, noise identification and
intervals); the kernels live in :mod:`analysis.noise.record` (input, τ grid), :mod:`analysis.noise.direct`
(direct sums), :mod:`analysis.noise.fftkit` (FFT building blocks), :mod:`analysis.noise.mtot` and
:mod:`analysis.noise.theo1` (closed forms) and :mod:`analysis.noise.closed_forms` (their dispatch). Method:
docs/methods/noise.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.noise.allan import allan_variances
from analysis.noise.closed_forms import prepass, theo1_total, total_sumsq
from analysis.noise.direct import diff_sumsq, mod_sumsq, mtie, oadev_sumsq, tot_sumsq, tot_sumsq_central
from analysis.noise.record import DATA_TYPES, Record, m_grid

__all__ = ["DATA_TYPES", "ESTIMATORS", "Estimate", "StabilityResult", "m_grid", "stability", "theobr_ratio_count"]

ESTIMATORS: tuple[str, ...] = (
    "adev",
    "oadev",
    "mdev",
    "tdev",
    "hdev",
    "ohdev",
    "totdev",
    "mtotdev",
    "ttotdev",
    "htotdev",
    "theo1",
    "theoh",
    "theobr",
    "mtie",
    "tierms",
)
"""Every estimator name accepted by :func:`stability`."""


@dataclass
class Estimate:
    """One estimator of C channels on its τ grid.

    Attributes
    ----------
    tau : ndarray (M,)
        τ = m τ₀, s (Theo1: allantools' convention m τ₀; its effective τ is 0.75 m τ₀).
    m : ndarray (M,) of int
        Averaging factors.
    dev : ndarray (M, C)
        Deviation in the data unit (phase unit for ``tdev``, ``ttotdev``, ``mtie``, ``tierms``), NaN where
        undefined (fewer than two terms).
    n_terms : ndarray (M, C) of int
        Terms (squared differences, subsequences, windows) actually used, gaps skipped.
    """

    tau: NDArray[np.float64]
    m: NDArray[np.int64]
    dev: NDArray[np.float64]
    n_terms: NDArray[np.int64]
    edf: NDArray[np.float64] | None = None
    alpha: NDArray[np.int64] | None = None
    lo: NDArray[np.float64] | None = None
    hi: NDArray[np.float64] | None = None
    bias: NDArray[np.float64] | None = None
    """Variance bias factor B for the identified noise (TOTDEV: 1 − a(α)·τ/T, Howe; HTOTDEV: 1 + a(α) for
    m ≥ 2), as Stable32 applies it; None for estimators reported unbiased."""

    def unbiased(self) -> NDArray[np.float64]:
        """The deviation divided by √B (Stable32's printed TOTDEV/HTOTDEV); ``dev`` where no bias applies."""
        return self.dev if self.bias is None else self.dev / np.sqrt(self.bias)


@dataclass
class StabilityResult:
    """Result of :func:`stability`: the estimates by name, plus record facts."""

    rate: float
    data_type: str
    n_points: int
    estimates: dict[str, Estimate]
    gap_samples: NDArray[np.int64]
    gap_runs: NDArray[np.int64]
    confidence: float = 0.683
    notes: list[str] = field(default_factory=list)
    edf_rules: str = "tablebench"
    """Rule set of the EDFs (:data:`analysis.noise.confidence.EDF_RULES`)."""


# ----------------------------------------------------------------------------------------------- input
# ------------------------------------------------------------------------------------------------ driver

_MAX_M = {
    "adev": lambda n: (n - 1) // 2,
    "oadev": lambda n: (n - 1) // 2,
    "mdev": lambda n: (n + 1) // 3,
    "tdev": lambda n: (n + 1) // 3,
    "hdev": lambda n: (n - 1) // 3,
    "ohdev": lambda n: (n - 1) // 3,
    "totdev": lambda n: (n - 1) // 2,
    "mtotdev": lambda n: n // 3,
    "ttotdev": lambda n: n // 3,
    "htotdev": lambda n: (n - 1) // 3,
    "theo1": lambda n: n - 1,
    "theoh": lambda n: n - 1,
    "theobr": lambda n: n - 1,
    "mtie": lambda n: n - 1,
    "tierms": lambda n: n - 1,
}


def _one(rec: Record, name: str, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """(variance-or-deviation, n_terms) of estimator ``name`` at m for every channel; see :func:`stability`."""
    ts = rec.ts
    tau = m * ts
    if name == "oadev":
        s, k = oadev_sumsq(rec, m, cache)
        return np.sqrt(s / (2.0 * np.maximum(k, 1) * tau * tau)), k
    if name == "adev":
        s, k = diff_sumsq(rec, m, (1.0, -2.0, 1.0), m)
        return np.sqrt(s / (2.0 * np.maximum(k, 1) * tau * tau)), k
    if name in ("hdev", "ohdev"):
        s, k = diff_sumsq(rec, m, (-1.0, 3.0, -3.0, 1.0), m if name == "hdev" else 1)
        return np.sqrt(s / (6.0 * np.maximum(k, 1) * tau * tau)), k
    if name in ("mdev", "tdev"):
        if ("mdev", m) not in cache:
            cache[("mdev", m)] = mod_sumsq(rec, m)
        s, k = cache[("mdev", m)]
        md = np.sqrt(s / (2.0 * m * m * tau * tau * np.maximum(k, 1)))
        return (md if name == "mdev" else tau * md / math.sqrt(3.0)), k
    if name == "totdev":
        s, k = tot_sumsq(rec, m) if rec.has_gaps else tot_sumsq_central(rec, m, cache)
        return np.sqrt(s / (2.0 * tau * tau * np.maximum(k, 1))), k
    if name in ("mtotdev", "ttotdev"):
        if ("mtot", m) not in cache:
            cnt = rec.n - 3 * m + 1
            ok = rec.span_ok(0, cnt, 3 * m - 1) if cnt > 0 else None
            cache[("mtot", m)] = total_sumsq(rec.x, m, ok, cache, "R_phase")
        s, k = cache[("mtot", m)]
        v = np.sqrt(s / (m * m * 6.0 * m * 2.0 * tau * tau * np.maximum(k, 1)))
        return (v if name == "mtotdev" else tau * v / math.sqrt(3.0)), k
    if name == "htotdev":
        if m == 1:
            return _one(rec, "ohdev", 1, cache)
        if "freq" not in cache:
            cache["freq"] = rec.frequency()
        y, bp = cache["freq"]
        cnt = y.shape[1] - 3 * m + 1
        ok = None
        if bp is not None and cnt > 0:
            ok = bp[:, 3 * m : 3 * m + cnt] == bp[:, :cnt]
        s, k = total_sumsq(y, m, ok, cache, "R_freq")
        return np.sqrt(s / (m * m * 36.0 * m * np.maximum(k, 1))), k
    if name == "theo1":
        s, k = theo1_total(rec, m, cache)
        cnt = k // max(m // 2, 1)
        return np.sqrt(s / (0.75 * np.maximum(cnt, 1) * tau * tau)), k
    if name == "mtie":
        return mtie(rec, m)
    if name == "tierms":
        s, k = diff_sumsq(rec, m, (-1.0, 1.0), 1)
        return np.sqrt(s / np.maximum(k, 1)), k
    raise ValueError(f"unknown estimator {name!r}; choose from {', '.join(ESTIMATORS)}")


def stability(
    data: ArrayLike,
    rate: float,
    estimators: tuple[str, ...] | list[str] = ("adev", "oadev", "mdev", "totdev"),
    taus: str | ArrayLike = "octave",
    data_type: str = "freq",
    theoh_split: float = 0.2,
    confidence: float | None = 0.683,
    noise_type: int | list[tuple[float, float, int]] | None = None,
    edf_rules: str = "tablebench",
) -> StabilityResult:
    """Frequency-stability deviations of every channel of a record.

    Parameters
    ----------
    data : array_like (N,) or (N, C)
        Frequency (rate, specific force, fractional frequency) or phase (angle, velocity, time error) record,
        one column per channel, SI; NaN marks a gap.
    rate : float
        Sample rate, Hz.
    estimators : sequence of str
        Names from :data:`ESTIMATORS`.
    taus : {"octave", "decade", "all", "log"} or array_like
        τ grid (:func:`m_grid`); each estimator keeps the m inside its own range.
    data_type : {"freq", "phase"}
        What ``data`` holds.
    theoh_split : float
        TheoH: k = the largest τ ≤ this fraction of the record length (0.2: NIST SP 1065, Stable32); the
        overlapping ADEV below k, TheoBR at effective τ ≥ k.
    confidence : float or None
        Two-sided probability of the χ² intervals (default 0.683); None: no noise identification, EDF or
        intervals (faster).
    noise_type : int or list of (τ_lo, τ_hi, α), optional
        The power-law noise type set by hand, as Stable32 allows (α = 2 white PM, 1 flicker PM, 0 white FM, −1
        flicker FM, −2 random-walk FM): one α for every τ, or α per closed τ range in seconds (the reported τ;
        the first range holding τ wins); τ outside every range keep the identified type. The EDF, intervals and
        the TOTDEV/HTOTDEV bias use it.
    edf_rules : {"tablebench", "stable32"}
        EDF rules of the intervals: tablebench's (default; where Stable32's intervals miss their confidence,
        calibrated by Monte Carlo coverage) or Stable32's own (:func:`analysis.noise.confidence.edf_stable32`:
        with ``noise_type`` set to the α Stable32 printed, its printed bounds are reproduced).

    Returns
    -------
    StabilityResult
    """
    from analysis.noise.confidence import EDF_RULES

    if edf_rules not in EDF_RULES:
        raise ValueError(f"unknown EDF rules {edf_rules!r}; choose from {', '.join(EDF_RULES)}")
    bad = [e for e in estimators if e not in ESTIMATORS]
    if bad:
        raise ValueError(f"unknown estimator(s) {', '.join(bad)}; choose from {', '.join(ESTIMATORS)}")
    if not estimators:
        raise ValueError("no estimator chosen")
    rec = Record(data, rate, data_type)
    if rec.n < 4:
        raise ValueError(f"record too short: {rec.n} phase points (need at least 4)")
    grid = m_grid(rec.n, taus, rate)
    if grid.size == 0:
        raise ValueError(f"no averaging time of the requested grid fits a record of {rec.n} points at {rate} Hz")
    c = rec.channels
    out: dict[str, Estimate] = {}
    cache: dict = {}
    classic = None
    if rec.data_type == "freq" and not rec.has_gaps:
        want = [e for e in ("adev", "oadev", "mdev", "totdev") if e in estimators]
        if want:
            ms = grid[grid <= max(_MAX_M[e](rec.n) for e in want)]
            top = int(ms.max()) if ms.size else 1
            # channel by channel inside (two single-channel arrays); its own older intervals are not wanted here.
            # One channel: the pass also leaves the record's phase (noise identification, other estimators) in
            # the array it ran in — no second integration, no extra memory.
            phase = None
            if c == 1 and (confidence is not None or len(want) < len(estimators)):
                phase = np.empty((1, rec.n))
            classic = allan_variances(rec.freq_raw.T, rate, ms / rate, max_m=top, confidence=None, phase=phase)
            if phase is not None:
                rec.set_phase(phase)
    key = {"adev": "avar", "oadev": "oavar", "mdev": "mvar", "totdev": "totvar"}
    for name in estimators:
        if name in ("theoh", "theobr"):
            continue
        ms = grid[grid <= _MAX_M[name](rec.n)]
        if name == "theo1":
            ms = ms[ms % 2 == 0]
        prepass(rec, name, ms, cache)
        dev = np.full((ms.size, c), np.nan)
        nt = np.zeros((ms.size, c), dtype=np.int64)
        for j, m in enumerate(ms):
            m = int(m)
            if classic is not None and name in key and m in set(classic.m.tolist()):
                jj = int(np.searchsorted(classic.m, m))
                dev[j] = np.sqrt(classic.var[key[name]][jj])
                nt[j] = classic.n_terms[key[name]][jj]
                if name == "adev":  # allantools counts ⌈(N−2m)/m⌉ terms (allan.py: K−1 with K = ⌊N_f/m⌋)
                    nt[j] = classic.n_terms["avar"][jj]
                continue
            dev[j], nt[j] = _one(rec, name, m, cache)
        dev[nt <= 1] = np.nan
        out[name] = Estimate(ms * rec.ts, ms, dev, nt)
    if "theobr" in estimators:
        out["theobr"] = _theobr(rec, grid, cache)
    if "theoh" in estimators:
        out["theoh"] = _theoh(rec, grid, out, cache, theoh_split)
    res = StabilityResult(float(rate), data_type, rec.n, out, rec.gap_samples, rec.gap_runs)
    if confidence is not None:
        if not 0.0 < confidence < 1.0:
            raise ValueError(f"confidence must be in (0, 1), got {confidence}")
        res.confidence = float(confidence)
        res.edf_rules = edf_rules
        _attach_intervals(rec, res, _noise_type_ranges(noise_type))
    return res


def _id_phase(rec: Record, ch: int) -> NDArray[np.float64]:
    """One channel's phase for noise identification: gaps bridged (frequency gaps are zero-filled after the
    mean is removed; missing phase points are interpolated linearly)."""
    x = rec.x[ch]
    if rec.point_ok is not None and not rec.point_ok[ch].all():
        ok = rec.point_ok[ch]
        idx = np.arange(x.size)
        x = np.interp(idx, idx[ok], x[ok])
    return x


def _noise_type_ranges(noise_type: int | list[tuple[float, float, int]] | None) -> list[tuple[float, float, int]]:
    """``noise_type`` of :func:`stability` as a list of (τ_lo, τ_hi, α), checked."""
    if noise_type is None:
        return []
    ranges = [(0.0, math.inf, noise_type)] if isinstance(noise_type, (int, np.integer)) else list(noise_type)
    out = []
    for lo, hi, a in ranges:
        if int(a) != a or not -2 <= int(a) <= 2:
            raise ValueError(f"noise type α must be an integer from -2 (random-walk FM) to 2 (white PM), got {a}")
        if not (lo <= hi) or lo < 0:
            raise ValueError(f"noise-type τ range {lo}..{hi} s is empty or negative")
        out.append((float(lo), float(hi), int(a)))
    return out


def forced_alpha(ranges: list[tuple[float, float, int]], tau: float) -> int | None:
    """The α set by hand for τ (a relative tolerance of 1e-9 on the range ends), or None."""
    for lo, hi, a in ranges:
        if lo * (1 - 1e-9) <= tau <= hi * (1 + 1e-9):
            return a
    return None


def _attach_intervals(rec: Record, res: StabilityResult, ranges: list[tuple[float, float, int]] | None = None) -> None:
    """Noise type, EDF and χ² interval per estimator, τ and channel (see :mod:`analysis.noise.confidence`)."""
    from analysis.noise import confidence as ci

    lag1_cache: dict[tuple[int, int, int], int | None] = {}
    pm_cache: dict[tuple[int, int], int | None] = {}
    pm_test: dict[tuple[int, int], bool | None] = {}
    phases: dict[int, NDArray[np.float64]] = {}
    prev: dict[tuple[str, int], int] = {}

    def alpha_of(name: str, ch: int, m: int, dmax: int, n_terms: int, carry: bool = False) -> int:
        """Lag-1 ACF (≥ 30 decimated points); below, the α carried from the previous τ (Theo1; every estimator
        below 8 points), else the phase-noise test, then B1; a phase-noise result at m ≥ 4 is split into
        white/flicker PM by R(n) where it has terms enough."""
        if ch not in phases:
            phases[ch] = _id_phase(rec, ch)
        x = phases[ch]
        key = (ch, m, dmax)
        if key not in lag1_cache:
            lag1_cache[key] = ci.lag1_alpha(x, m, dmax)
        a = lag1_cache[key]
        if a is None and (carry or x.size // m < ci.PM_TEST_MIN_POINTS):
            a = prev.get((name, ch))
        if a is None:
            if (ch, m) not in pm_test:
                pm_test[(ch, m)] = ci.is_phase_noise(x, m)
            a = 2 if pm_test[(ch, m)] else ci.b1_alpha(x, m, rec.ts, n_terms)
        if a is None:
            a = prev.get((name, ch), 0)
        a = int(min(2, max(-2, a)))
        if a >= 1 and m >= ci.RN_MIN_FACTOR:
            if (ch, m) not in pm_cache:
                pm_cache[(ch, m)] = ci.pm_alpha(x, m)
            a = pm_cache[(ch, m)] or a
        prev[(name, ch)] = a
        return a

    n = rec.n
    for name, est in res.estimates.items():
        if name in ("mtie", "tierms"):
            continue
        mcount, c = est.dev.shape
        alpha = np.zeros((mcount, c), dtype=np.int64)
        e = np.full((mcount, c), np.nan)
        dmax = ci.D_ORDER[name]
        for j, m in enumerate(est.m):
            m = int(m)
            kind = name
            if name == "theoh":
                kind = "theo1" if est.tau[j] < m * rec.ts * 0.99 else "oadev"
            elif name == "theobr":
                kind = "theo1"
            m_id = max(1, int(round(0.75 * m))) if kind == "theo1" else m
            for ch in range(c):
                if not np.isfinite(est.dev[j, ch]):
                    continue
                # B1(N, μ) is the ratio for N averages; Stable32 passes the term count, which for Theo1 is
                # (N − m)·m/2 and would make every long-τ Theo1 look like phase noise: use the averages
                # Beyond the lag-1 range (< 30 decimated points) Theo1 keeps the α identified at the longest τ
                # where the lag-1 method applies: Stable32 gives a Theo1 run one noise type (fixed, or from the
                # TheoBR ratio), and B1 from the handful of averages left at Theo1's τ misidentifies 30–75 %
                # (coverage test)
                n_b1 = (n - 1) // m_id if kind == "theo1" else int(est.n_terms[j, ch])
                a = forced_alpha(ranges or [], float(est.tau[j]))
                if a is None:
                    a = alpha_of(name, ch, m_id, dmax, n_b1, carry=kind == "theo1")
                alpha[j, ch] = a
                e[j, ch] = ci.edf(kind, a, m, n, res.edf_rules)
                if kind == "theo1" and name != "theo1":  # TheoBR = kf·Theo1: add the scatter of kf
                    e[j, ch] = ci.edf_theobr(e[j, ch])
        est.alpha = alpha
        est.edf = e
        if name in ("totdev", "htotdev"):
            t_rec = (n - 1) * rec.ts
            est.bias = ci.bias_factor(name, alpha, est.m, est.tau, t_rec)
        est.lo, est.hi = ci.chi2_interval(est.unbiased(), e, res.confidence)
        if name == "totdev" and res.edf_rules == "tablebench":  # white PM: the reflected end terms skew the law
            for j, ch in zip(*np.nonzero((alpha == 2) & np.isfinite(est.dev)), strict=True):
                shape = ci.totvar_wpm_shape(n, int(est.m[j]))
                if shape is not None and shape[0] > 0:
                    est.lo[j, ch], est.hi[j, ch] = ci.shifted_chi2_interval(est.dev[j, ch], shape, res.confidence)


THEOBR_MAX_RATIOS = 256
"""TheoBR averages at most this many AVAR/Theo1 ratios, evenly spread over i = 0 … n (all of them, as Stable32,
up to N ≈ 1560 points; the ratio varies slowly with i, and each costs one OADEV and one Theo1). Measured on a
white + random-walk FM record of N = 20 000 (3331 ratios): kf within 0.12 % of the all-ratio value (0.5 % with
64), 6 s instead of 76 s."""


def theobr_ratio_count(n_points: int) -> int:
    """Number of AVAR/Theo1 ratios n + 1 of TheoBR on ``n_points`` phase points: n = ⌊N/6⌋ − 3, the value
    with which Stable32's Theo1/TheoH runs reproduce (Sr87: its printed Thêo1 equals Theo1·√kf to 5 digits);
    Taylor & Howe's "Fast TheoBR" (2010) and W. Riley's TheoBR.cpp use the shorter ⌊0.1N/3⌋ − 3 (AVAR up to
    0.1 T only). 0 when the record is too short (N < 24)."""
    return max(0, int(n_points) // 6 - 3 + 1)


def _theobr_factor(rec: Record, cache: dict) -> NDArray[np.float64]:
    """TheoBR's bias factor per channel: the mean of OAVAR(m = 9+3i) / Theo1(m = 12+4i) (equal τ, since Theo1's
    effective τ is 0.75 m τ₀) over i = 0 … n (NIST SP 1065; Howe, Taylor & Tasset, "TheoH bias-removal method",
    2006); NaN when too short."""
    if "theobr_kf" in cache:
        return cache["theobr_kf"]
    c = rec.channels
    count = theobr_ratio_count(rec.n)
    if count == 0:
        kf = np.full(c, np.nan)
    else:
        ii = np.arange(count)
        if count > THEOBR_MAX_RATIOS:
            ii = np.unique(np.rint(np.linspace(0, count - 1, THEOBR_MAX_RATIOS)).astype(np.int64))
        acc = np.zeros(c)
        used = np.zeros(c)
        for i in ii:
            a, ka = _one(rec, "oadev", int(9 + 3 * i), cache)
            t, kt = _one(rec, "theo1", int(12 + 4 * i), cache)
            ok = (ka > 1) & (kt > 1) & (t > 0)
            with np.errstate(divide="ignore", invalid="ignore"):
                acc += np.where(ok, (a / t) ** 2, 0.0)
            used += ok
        with np.errstate(invalid="ignore"):
            kf = np.where(used > 0, acc / np.maximum(used, 1), np.nan)
    cache["theobr_kf"] = kf
    return kf


def _theobr(rec: Record, grid: NDArray[np.int64], cache: dict) -> Estimate:
    """TheoBR = Theo1 · kf (even m), reported at Theo1's effective τ = 0.75 m τ₀.

    Its intervals combine the Theo1 EDF with that of kf (:func:`analysis.noise.confidence.edf_theobr`);
    Stable32 and W. Riley's TheoBR.cpp use the Theo1 EDF alone, which ignores the scatter of kf (set by the
    long-τ AVAR): simulated (N = 1024, 100 records) their 68 % intervals covered 6–52 % of white-FM records."""
    kf = _theobr_factor(rec, cache)
    ms = grid[(grid % 2 == 0) & (grid <= _MAX_M["theobr"](rec.n))]
    c = rec.channels
    dev = np.full((ms.size, c), np.nan)
    nt = np.zeros((ms.size, c), dtype=np.int64)
    for j, m in enumerate(ms):
        d, k = _one(rec, "theo1", int(m), cache)
        dev[j], nt[j] = d * np.sqrt(kf), k
    dev[nt <= 1] = np.nan
    return Estimate(0.75 * ms * rec.ts, ms, dev, nt)


def _theoh(rec: Record, grid: NDArray[np.int64], done: dict, cache: dict, split: float) -> Estimate:
    """TheoH (NIST SP 1065; Howe, Taylor & Tasset 2006): the overlapping ADEV for m < k/τ₀ and TheoBR at
    its effective τ = 0.75 m τ₀ ≥ k (even m), k the largest τ ≤ ``split`` · T (T = (N − 1) τ₀)."""
    t_rec = (rec.n - 1) * rec.ts
    m_split = max(1, int(math.floor(split * t_rec / rec.ts)))
    ms_a = grid[grid < min(m_split, _MAX_M["oadev"](rec.n) + 1)]
    c = rec.channels
    rows_m, rows_tau, rows_dev, rows_n = [], [], [], []
    for m in ms_a:
        d, k = _one(rec, "oadev", int(m), cache)
        rows_m.append(int(m))
        rows_tau.append(m * rec.ts)
        rows_dev.append(d)
        rows_n.append(k)
    ms_t = grid[(grid % 2 == 0) & (0.75 * grid >= m_split) & (grid <= rec.n - 1)]
    if ms_t.size:
        kf = _theobr_factor(rec, cache)
    for m in ms_t:
        d, k = _one(rec, "theo1", int(m), cache)
        rows_m.append(int(m))
        rows_tau.append(0.75 * m * rec.ts)
        rows_dev.append(d * np.sqrt(kf))
        rows_n.append(k)
    if not rows_m:
        return Estimate(np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, c)), np.zeros((0, c), dtype=np.int64))
    dev = np.array(rows_dev)
    nt = np.array(rows_n, dtype=np.int64)
    dev[nt <= 1] = np.nan
    return Estimate(np.array(rows_tau), np.array(rows_m, dtype=np.int64), dev, nt)
