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
(channel by channel, chunked passes shared by several octaves, plain sums by telescoping, analytic ramp
handling; for one channel the pass also leaves the record's phase, so it is not integrated twice).
MTOTDEV/TTOTDEV/HTOTDEV: the even reflection makes each subsequence's 6m terms one period of a
circular filter, i.e. a quadratic form zᵀQz with Q Toeplitz + Hankel; summed over subsequences it reduces to the
record's autocorrelation (one FFT per channel and record, :func:`_autocorr`) and FFT correlations of the 3m − 1
end samples (:func:`_mtot_fft`: O(N) once plus O(m log m) per τ). Theo1: window sums, one lagged product, a
blocked FFT correlation and two anti-diagonal triangle sums by divide and conquer (:func:`_theo1_fft`,
O(N log m + m log² m) per τ). Both closed forms expand squares into products, so they are used only where their
rounding estimate is below 1e-10 of the variance (and for m ≥ 8 / 64); above it (small m on a long random-walk
phase) block by block (:func:`_blocked_sum`, O(N log B) per τ); with gaps, the exact direct sums (O(N·m) per τ,
vectorised, in chunks). Several channels: the closed forms run channel by
channel over the whole τ grid (:func:`_prepass`), so one channel's series and autocorrelation are alive at a
time. Memory (benchmarks/bench_noise.py, RESULTS.md): the classic path about 2× the record; the total family
and Theo1 below 4× over the whole grid, longest τ included (N = 10⁷ octave grid: MTOT/HTOT/TTOT 3.6×, Theo1
3.3×): the autocorrelation is formed in one buffer of N + maxlag points (:func:`_autocorr`, in-place FFTs, only
the lags the grid reads); the total family's detrended series is formed on demand (:class:`_Detrended`), its
end-segment correlations use at most two in-place FFT buffers of ≈ 6m points, with R released at the grid's
largest m; Theo1's long correlations and triangle squares are blocked (FFTs of ≤ N/8 points, :func:`_corr_sum`).
A gap-free phase input and a gap-free frequency input for HTOTDEV are used without copies.

Gaps. NaN samples are gaps. A term is skipped when it touches a gap: for phase input (allantools'
gap-robust ``gradev`` convention) the phase points a point-estimator uses (ADEV, OADEV, HDEV, OHDEV, TIE rms)
must be finite; for the span-estimators (MDEV, TOTDEV, the total family, Theo1, MTIE) and for every
estimator on frequency input, the whole span of the term must be gap-free (with frequency input a missing
sample leaves the phase after it unknown, so a term across it is meaningless). Each estimator reports the
number of terms it used per τ and channel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import fft as sfft

from analysis.noise.allan import allan_variances, sum_of_products

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

DATA_TYPES: tuple[str, ...] = ("freq", "phase")

_CHUNK = 1 << 17
"""Columns per chunk of the O(N) passes."""


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


# ----------------------------------------------------------------------------------------------- input


class _Record:
    """Phase (C, N) with gaps zero-filled, plus gap bookkeeping for term validity."""

    def __init__(self, data: ArrayLike, rate: float, data_type: str) -> None:
        a = np.asarray(data)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2:
            raise ValueError(f"expected a 1-D record or a 2-D array (samples × channels), got shape {a.shape}")
        if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
            raise ValueError(f"expected real numeric data, got dtype {a.dtype}")
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"sample rate must be a positive number of Hz, got {rate}")
        if data_type not in DATA_TYPES:
            raise ValueError(f"data_type must be 'freq' or 'phase', got {data_type!r}")
        a = np.ascontiguousarray(np.asarray(a, dtype=np.float64).T)  # (C, n), a view of 1-D float64 input
        self.ts = 1.0 / rate
        self.data_type = data_type
        c, n_in = a.shape
        self.channels = c
        self.n = n_in + 1 if data_type == "freq" else n_in
        self._raw = a
        self._x: NDArray[np.float64] | None = None
        if np.isfinite(a).all():  # the usual case: one pass, no mask kept
            self.has_gaps = False
            self.gap_samples = np.zeros(c, dtype=np.int64)
            self.gap_runs = np.zeros(c, dtype=np.int64)
            self.bad_prefix = None
            self.point_ok = None
            self.freq_raw = a if data_type == "freq" else None
            return
        if np.any(np.isinf(a)):
            raise ValueError("record contains ±inf; only NaN marks a gap")
        bad = np.isnan(a)
        self.gap_samples = bad.sum(axis=1)
        self.gap_runs = (np.diff(bad.astype(np.int8), axis=1, prepend=0) == 1).sum(axis=1)
        self.has_gaps = True
        if np.all(bad, axis=1).any():
            raise ValueError("a channel holds no finite sample")
        self.bad_prefix = np.zeros((c, n_in + 1), dtype=np.int64)
        np.cumsum(bad, axis=1, out=self.bad_prefix[:, 1:])
        if data_type == "freq":  # bad intervals: prefix count over frequency samples, aligned with phase points
            self.freq_raw = a
            self.point_ok = None
        else:
            self.freq_raw = None
            self.point_ok = ~bad

    @property
    def x(self) -> NDArray[np.float64]:
        """Phase (C, N), gaps zero-filled: frequency input integrated (mean removed, x_0 = 0, chunked cumulative
        sum with carry, no full-size temporary); gap-free phase input is the caller's array itself (read only)."""
        if self._x is None:
            a = self._raw
            c, n_in = a.shape
            if self.data_type == "freq":
                mean = np.nanmean(a, axis=1, keepdims=True) if self.has_gaps else a.mean(axis=1, keepdims=True)
                x = np.empty((c, n_in + 1))
                x[:, 0] = 0.0
                carry = np.zeros((c, 1))
                step = 1 << 16
                buf = np.empty((c, min(step, n_in)))
                for s0 in range(0, n_in, step):
                    e0 = min(n_in, s0 + step)
                    blk = buf[:, : e0 - s0]
                    np.subtract(a[:, s0:e0], mean, out=blk)
                    if self.has_gaps:
                        blk[np.isnan(blk)] = 0.0
                    seg = x[:, s0 + 1 : e0 + 1]
                    np.cumsum(blk, axis=1, out=seg)
                    seg += carry
                    carry = seg[:, -1:].copy()
                    seg *= self.ts  # while in cache (the carry stays unscaled)
            elif self.has_gaps:
                x = np.where(self.point_ok, a, 0.0)
            else:
                x = a
            self._x = x
        return self._x

    def span_ok(self, start: int, count: int, span: int) -> NDArray[np.bool_] | None:
        """Validity of terms i = start … start+count−1 whose phase span is [i, i+span]; None: all valid."""
        if not self.has_gaps:
            return None
        bp = self.bad_prefix
        if self.data_type == "freq":  # frequency samples i … i+span−1 lie between phase points i and i+span
            return bp[:, start + span : start + span + count] == bp[:, start : start + count]
        return bp[:, start + span + 1 : start + span + 1 + count] == bp[:, start : start + count]

    def points_ok(self, start: int, count: int, offsets: tuple[int, ...], stride: int = 1) -> NDArray | None:
        """Validity of terms using phase points i + offsets (phase input); span validity for frequency input."""
        if not self.has_gaps:
            return None
        if self.data_type == "freq":
            ok = self.span_ok(start, count, max(offsets))
            return ok[:, ::stride]
        ok = np.ones((self.channels, len(range(start, start + count, stride))), dtype=bool)
        for o in offsets:
            ok &= self.point_ok[:, start + o : start + o + count : stride]
        return ok

    def frequency(self) -> tuple[NDArray[np.float64], NDArray[np.int64] | None]:
        """Frequency (C, N_f) with gaps zero-filled, and the prefix count of bad frequency samples."""
        if self.data_type == "freq":
            if self.has_gaps:
                return np.where(np.isnan(self.freq_raw), 0.0, self.freq_raw), self.bad_prefix
            return self.freq_raw, None  # the caller's array: read only
        y = np.diff(self.x, axis=1) / self.ts
        if not self.has_gaps:
            return y, None
        bad_y = ~(self.point_ok[:, 1:] & self.point_ok[:, :-1])
        y[bad_y] = 0.0
        bp = np.zeros((y.shape[0], y.shape[1] + 1), dtype=np.int64)
        np.cumsum(bad_y, axis=1, out=bp[:, 1:])
        return y, bp


# ------------------------------------------------------------------------------------------------ τ grid


def m_grid(n_points: int, taus: str | ArrayLike, rate: float) -> NDArray[np.int64]:
    """Candidate averaging factors for a record of ``n_points`` phase points (each estimator keeps its range).

    ``octave``: 1, 2, 4, …; ``decade``: 1, 2, 4, 10, 20, 40, … (Stable32's spacing); ``all``: every m;
    an array: τ in seconds, rounded to the nearest m (as allantools).
    """
    top = max(int(n_points) - 1, 1)
    if isinstance(taus, str):
        kind = taus.lower()
        if kind == "octave":
            m = 2 ** np.arange(int(math.floor(math.log2(top))) + 1, dtype=np.int64)
        elif kind == "decade":
            k = int(math.floor(math.log10(top))) + 1
            m = np.array([f * 10**e for e in range(k) for f in (1, 2, 4)], dtype=np.int64)
        elif kind == "all":
            m = np.arange(1, top + 1, dtype=np.int64)
        elif kind == "log":
            k = int(math.floor(10 * math.log10(top))) if top > 1 else 0
            m = np.unique(np.rint(10.0 ** (np.arange(k + 1) / 10)).astype(np.int64))
        else:
            raise ValueError(f"unknown τ grid {taus!r}; use octave, decade, all, log or a list of τ in seconds")
    else:
        t = np.atleast_1d(np.asarray(taus, dtype=np.float64))
        if t.size == 0 or not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise ValueError("τ values must be positive finite seconds")
        m = np.rint(t * rate).astype(np.int64)
    m = np.unique(m)
    return m[(m >= 1) & (m <= top)]


# --------------------------------------------------------------------------------- point and span sums


def _diff_sumsq(
    rec: _Record, m: int, coeffs: tuple[float, ...], stride: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Σ (Σ_k c_k x_{i+km})² over i = 0, stride, … (i + (len(c)−1) m ≤ N − 1), skipping gap terms."""
    x = rec.x
    n = rec.n
    d = len(coeffs) - 1
    count = n - d * m
    c = x.shape[0]
    s = np.zeros(c)
    k = np.zeros(c, dtype=np.int64)
    if count <= 0:
        return s, k
    offs = tuple(j * m for j in range(d + 1))
    step = max(_CHUNK - _CHUNK % stride, stride)
    width = -(-min(step, count) // stride)
    buf, tmp = np.empty((c, width)), np.empty((c, width))  # reused: no allocation per chunk
    for a in range(0, count, step):
        b = min(count, a + step)
        w = -(-(b - a) // stride)
        v, t = buf[:, :w], tmp[:, :w]
        np.multiply(x[:, a:b:stride], coeffs[0], out=v)
        for j in range(1, d + 1):
            xj = x[:, a + offs[j] : b + offs[j] : stride]
            if coeffs[j] == 1.0:
                np.add(v, xj, out=v)
            elif coeffs[j] == -1.0:
                np.subtract(v, xj, out=v)
            else:
                np.multiply(xj, coeffs[j], out=t)
                np.add(v, t, out=v)
        ok = rec.points_ok(a, b - a, offs, stride)
        if ok is not None:
            v[~ok] = 0.0
            k += ok.sum(axis=1)
        else:
            k += v.shape[1]
        s += np.einsum("ij,ij->i", v, v)
    return s, k


def _mod_sumsq(rec: _Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Modified Allan: Σ_j (Σ_{i=j}^{j+m−1} x_{i+2m} − 2x_{i+m} + x_i)² over j = 0 … N−3m, gaps skipped."""
    x = rec.x
    n = rec.n
    count = n - 3 * m + 1
    c = x.shape[0]
    if count <= 0:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    nd = n - 2 * m
    d = x[:, 2 * m :] - 2.0 * x[:, m : n - m] + x[:, :nd]
    if rec.has_gaps:
        ok_d = rec.span_ok(0, nd, 2 * m)
        d[~ok_d] = 0.0
    cs = np.zeros((c, nd + 1))
    np.cumsum(d, axis=1, out=cs[:, 1:])
    del d
    v = cs[:, m : m + count] - cs[:, :count]
    ok = rec.span_ok(0, count, 3 * m - 1)
    if ok is not None:
        v[~ok] = 0.0
        return np.einsum("ij,ij->i", v, v), ok.sum(axis=1)
    return np.einsum("ij,ij->i", v, v), np.full(c, count, dtype=np.int64)


def _mirror(j: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    """The sample a reflected index −(n−1) ≤ j ≤ 2(n−1) mirrors: −j before the start, 2(n−1) − j after the end."""
    return np.where(j < 0, -j, np.where(j > n - 1, 2 * (n - 1) - j, j))


def _reflected(x: NDArray[np.float64], j: NDArray[np.int64]) -> NDArray[np.float64]:
    """x*_j of the phase x (C, n) extended by inverted reflection at both ends (the total variances'
    extension): x*_{−j} = 2x_0 − x_j, x*_{n−1+j} = 2x_{n−1} − x_{n−1−j}."""
    n = x.shape[1]
    v = x[:, _mirror(j, n)]
    v = np.where(j < 0, 2.0 * x[:, :1] - v, v)
    return np.where(j > n - 1, 2.0 * x[:, n - 1 : n] - v, v)


def _oadev_sumsq(rec: _Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Σ (x_{i+2m} − 2x_{i+m} + x_i)² over i = 0 … N−2m−1 (gap terms skipped), once per m (OADEV, TOTDEV)."""
    if ("osum", m) not in cache:
        cache[("osum", m)] = _diff_sumsq(rec, m, (1.0, -2.0, 1.0), 1)
    return cache[("osum", m)]


def _tot_sumsq_central(rec: _Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`_tot_sumsq` of a gap-free record: its centres m … N−1−m reach no reflected point, so their terms
    are exactly OADEV's (shared through ``cache``); only the ≤ 2(m−1) centres near the ends are formed here."""
    x = rec.x
    n = rec.n
    c = x.shape[0]
    if m > n - 2:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    s = _oadev_sumsq(rec, m, cache)[0].copy() if n - 2 * m > 0 else np.zeros(c)
    ends = np.concatenate([np.arange(1, min(m, n - 1)), np.arange(max(n - m, m), n - 1)])
    if ends.size:
        v = _reflected(x, ends - m) - 2.0 * x[:, ends] + _reflected(x, ends + m)
        s += np.einsum("ij,ij->i", v, v)
    return s, np.full(c, n - 2, dtype=np.int64)


def _tot_sumsq(rec: _Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Total variance: Σ over centres i = 1 … N−2 of (x*_{i−m} − 2x_i + x*_{i+m})², phase reflected
    (inverted) at both ends; gap terms skipped (their mapped points / span)."""
    x = rec.x
    n = rec.n
    c = x.shape[0]
    i = np.arange(1, n - 1)
    lo = i - m
    hi = i + m
    if m > n - 2:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    v = _reflected(x, lo) - 2.0 * x[:, 1 : n - 1] + _reflected(x, hi)
    if not rec.has_gaps:
        return np.einsum("ij,ij->i", v, v), np.full(c, n - 2, dtype=np.int64)
    if rec.data_type == "phase":
        p = rec.point_ok
        ok = p[:, 1 : n - 1].copy()
        for j in (lo, hi):
            ok &= p[:, _mirror(j, n)]
        ok &= np.where(lo < 0, p[:, :1], True)
        ok &= np.where(hi > n - 1, p[:, n - 1 : n], True)
    else:
        a = np.where(lo >= 0, lo, 0)
        b = np.where(hi <= n - 1, hi, n - 1)
        b = np.where(lo < 0, np.maximum(b, np.minimum(-lo, n - 1)), b)
        a = np.where(hi > n - 1, np.minimum(a, np.maximum(2 * (n - 1) - hi, 0)), a)
        bp = rec.bad_prefix
        ok = bp[:, b] == bp[:, a]
    v[~ok] = 0.0
    return np.einsum("ij,ij->i", v, v), ok.sum(axis=1)


# ------------------------------------------------------------------------------------- the total family


def _reflected_reps(m: int) -> list[tuple[float, float, tuple[tuple[int, float], ...], float, float]]:
    """Per evaluated term j of :func:`_reflected_sumsq`: (weight, g_tot, ((p, κ_p), …), Σκ_p, Σκ_p q(p))."""
    L = 3 * m

    def q(p: int) -> float:
        return 0.5 * p * (p - 1)

    def f_parts(a: int) -> tuple[float, float, int]:
        if a <= L:
            return 1.0, -1.0, L - a
        if a <= 2 * L:
            return 1.0, 1.0, a - L
        return 3.0, -1.0, 3 * L - a

    js: list[tuple[int, float]] = [(j, 1.0 if 2 * j == L else 2.0) for j in range(0, L // 2 + 1)]
    js += [(j, 1.0 if 2 * j == 9 * m else 2.0) for j in range(L + 1, (9 * m) // 2 + 1) if 2 * j <= 9 * m]
    out = []
    for j, w in js:
        coef_p: dict[int, float] = {}
        g_tot = 0.0
        for k, sign in ((0, -1.0), (1, 3.0), (2, -3.0), (3, 1.0)):
            gz, sz, pz = f_parts(j + k * m)
            g_tot += sign * gz
            coef_p[pz] = coef_p.get(pz, 0.0) + sign * sz
        items = tuple((p, kp) for p, kp in coef_p.items() if kp != 0.0)
        out.append((w, g_tot, items, sum(coef_p.values()), sum(kp * q(p) for p, kp in coef_p.items())))
    return out


def _reflected_sumsq(
    s: NDArray[np.float64], m: int, ok: NDArray[np.bool_] | None
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Σ over subsequences i and j = 0 … 6m−1 of (S₁ − 2S₂ + S₃)² (m-sums, not averages) of the 3m-point
    subsequence s[i : i+3m], its linear trend (half means) removed, extended by even reflection to 9m points.

    Closed form per j from prefix sums P of s: with Z(p) = P[i+p] − P[i] − b_i p(p−1)/2 the partial sums of
    the detrended subsequence, the prefix sums of the reflected 9m series are F(a) = Z(3m) − Z(3m−a)
    (a ≤ 3m), Z(3m) + Z(a−3m) (a ≤ 6m), 3Z(3m) − Z(9m−a), and S₁ − 2S₂ + S₃ = −F(j) + 3F(j+m) − 3F(j+2m) +
    F(j+3m). The reflected series is one and a half periods of the even 6m-periodic extension and the
    kernel is symmetric, so term j equals term 3m − j (mod 6m): only ⌈3m⌉ of the 6m terms are evaluated.
    O(N·m) per τ, in chunks of subsequences with local prefix sums (memory O(chunk + 3m) per channel).
    """
    c, n_s = s.shape
    L = 3 * m
    count = n_s - L + 1
    if count <= 0:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    h1 = L // 2
    h2 = L - h1
    D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
    qL = 0.5 * L * (L - 1)
    reps = _reflected_reps(m)
    total = np.zeros(c)
    step = max(_CHUNK // 8 // max(1, c), 1024)  # short chunks: partial sums stay small (rounding ∝ chunk^1.5)
    for a in range(0, count, step):
        k = min(count, a + step) - a
        P = np.zeros((c, k + L))
        seg = s[:, a : a + k + L - 1]
        np.cumsum(seg - seg.mean(axis=1, keepdims=True), axis=1, out=P[:, 1:])  # local offset: small partial sums
        P0 = P[:, :k]
        b = ((P[:, L : L + k] - P[:, h2 : h2 + k]) - (P[:, h1 : h1 + k] - P0)) / (h1 * D)
        ztot = P[:, L : L + k] - P0
        ztot -= qL * b
        acc = np.zeros((c, k))
        v = np.empty((c, k))
        for w, g_tot, items, kappa_sum, qsum in reps:
            np.multiply(ztot, g_tot, out=v)
            for p, kp in items:
                v += kp * P[:, p : p + k]
            if kappa_sum != 0.0:
                v -= kappa_sum * P0
            if qsum != 0.0:
                v -= qsum * b
            v *= v
            if w != 1.0:
                v *= w
            acc += v
        if ok is not None:
            acc[~ok[:, a : a + k]] = 0.0
        total += acc.sum(axis=1)
    if ok is not None:
        return total, ok.sum(axis=1)
    return total, np.full(c, count, dtype=np.int64)


def _fast_len(n: int) -> int:
    """A fast real FFT length ≥ n."""
    return int(sfft.next_fast_len(max(int(n), 2), real=True))


_IP_STEP = 1 << 15
"""Chunk (complex values) of the in-place spectrum passes."""
_IP_SMALL = 1 << 18
"""Buffers up to this length are transformed by scipy's real FFT through a temporary (faster when small)."""


def _rfft_ip(buf: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Real FFT of ``buf`` (even length nf) in place: returns the complex view of buf holding X_k, k < nf/2, with
    the two real values packed in slot 0 (X_0 + i X_{nf/2}). A complex FFT of the even/odd sample pairs, then
    the real-FFT split pair by pair (k, nf/2 − k) in chunks: no buffer besides buf."""
    z = buf.view(np.complex128)
    h = z.size
    nf = 2 * h
    if nf <= _IP_SMALL:  # small: scipy's real FFT (a temporary of nf points), packed
        f = sfft.rfft(buf, workers=1)
        z[1:] = f[1:h]
        z[0] = complex(f[0].real, f[h].real)
        return z
    zz = sfft.fft(z, overwrite_x=True, workers=1)
    if not np.shares_memory(zz, z):  # pragma: no cover - scipy transforms a contiguous complex128 array in place
        z[:] = zz
    del zz
    z0 = z[0]
    z[0] = complex(z0.real + z0.imag, z0.real - z0.imag)
    half = h // 2
    for a in range(1, half + 1, _IP_STEP):  # X_k = E − F, X_{h−k} = conj(E + F), F = i W^k O, W = e^{−2πi/nf}
        b = min(half + 1, a + _IP_STEP)
        zk = z[a:b].copy()
        zm = np.conj(z[h - b + 1 : h - a + 1][::-1])
        e = zk + zm
        e *= 0.5
        zk -= zm
        zk *= 0.5j * np.exp(np.arange(a, b) * (-2j * np.pi / nf))
        del zm
        z[a:b] = e - zk
        e += zk
        z[h - b + 1 : h - a + 1] = np.conj(e)[::-1]
    return z


def _irfft_ip(z: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Inverse of :func:`_rfft_ip` in place (packed spectrum → the real series, 1/nf included), returned as the
    float view of the same buffer."""
    h = z.size
    nf = 2 * h
    x0, xh = z[0].real, z[0].imag
    if nf <= _IP_SMALL:
        f = np.empty(h + 1, dtype=np.complex128)
        f[1:h] = z[1:]
        f[0], f[h] = x0, xh
        out = z.view(np.float64)
        out[:] = sfft.irfft(f, nf, workers=1)
        return out
    half = h // 2
    for a in range(1, half + 1, _IP_STEP):  # Z_k = Ev_k + i Od_k, Ev = (X_k + conj X_{h−k})/2, Od = W^{−k}(X_k − …)/2
        b = min(half + 1, a + _IP_STEP)
        xk = z[a:b].copy()
        xm = np.conj(z[h - b + 1 : h - a + 1][::-1])
        ev = xk + xm
        ev *= 0.5
        xk -= xm
        xk *= 0.5j * np.exp(np.arange(a, b) * (2j * np.pi / nf))  # i·Od_k
        del xm
        z[a:b] = ev + xk
        ev -= xk  # Z_{h−k} = conj(Ev_k) + i conj(Od_k) = conj(Ev_k − i Od_k)
        z[h - b + 1 : h - a + 1] = np.conj(ev)[::-1]
    z[0] = complex(0.5 * (x0 + xh), 0.5 * (x0 - xh))
    zz = sfft.ifft(z, overwrite_x=True, workers=1)
    if not np.shares_memory(zz, z):  # pragma: no cover
        z[:] = zz
    del zz
    return z.view(np.float64)


def _spec_update(z: NDArray[np.complex128], op: str, w: NDArray[np.complex128] | None = None) -> None:
    """In place on a packed spectrum (:func:`_rfft_ip`): "pow" |z|², "sq" z², "mulc" z·conj(w), "cmul"
    conj(z)·w (w packed alike)."""
    z0 = z[0]
    w0 = w[0] if w is not None else 0j
    for a in range(1, z.size, 1 << 16):
        b = min(z.size, a + (1 << 16))
        blk = z[a:b]
        if op == "pow":
            blk[:] = blk.real * blk.real + blk.imag * blk.imag
        elif op == "sq":
            blk *= blk
        elif op == "cmul":
            np.conjugate(blk, out=blk)
            blk *= w[a:b]
        else:
            blk *= np.conj(w[a:b])
    if op in ("mulc", "cmul"):
        z[0] = complex(z0.real * w0.real, z0.imag * w0.imag)
    else:
        z[0] = complex(z0.real * z0.real, z0.imag * z0.imag)


def _even_len(n: int) -> int:
    """A fast even FFT length ≥ n (whose half is a fast complex length)."""
    return 2 * int(sfft.next_fast_len(max((int(n) + 1) // 2, 1), real=False))


def _autocorr(s, maxlag: int, step: int = 1) -> NDArray[np.float64]:
    """R_d = Σ_t s_t s_{t+d}, d = 0, step, 2·step … ≤ maxlag, of a 1-D series (zero outside; an array or a
    :class:`_Detrended`, written into the buffer chunk by chunk).

    One buffer of ≈ N + maxlag points holds everything: the series is transformed in place (:func:`_rfft_ip`),
    the power spectrum is written over it and a DCT-I of that (real, even) spectrum, also in place, gives R; the
    buffer is then shrunk to the lags kept. Peak memory: the series plus N + maxlag points."""
    n = s.size
    maxlag = min(int(maxlag), n - 1)
    nf = _even_len(n + maxlag)
    h = nf // 2
    buf = np.empty(nf)
    _fill(buf, s, 0, n)
    z = _rfft_ip(buf)
    _spec_update(z, "pow")
    ph = z[0].imag
    del z
    for a in range(1, h, _IP_STEP):  # compact the real parts: buf[k] = P_k
        b = min(h, a + _IP_STEP)
        buf[a:b] = buf[2 * a : 2 * b : 2]
    buf[h] = ph
    r = sfft.dct(buf[: h + 1], type=1, overwrite_x=True, workers=1)
    if not np.shares_memory(r, buf):  # pragma: no cover - DCT-I of a contiguous view runs in place
        buf[: h + 1] = r
    del r
    keep = maxlag // step + 1
    if step > 1:
        for a in range(1, keep, _IP_STEP):
            b = min(keep, a + _IP_STEP)
            buf[a:b] = buf[step * a : step * b : step]
    buf.resize(keep, refcheck=False)
    buf /= nf
    return buf


def _fill(buf: NDArray[np.float64], s, a: int, b: int, ramp: bool = False) -> None:
    """buf[: b − a] = s[a:b] (times its local index 0 … b − a − 1 if ``ramp``), zeros after; s an array or a
    :class:`_Detrended`, in chunks."""
    k = b - a
    step = 1 << 16
    for c0 in range(0, k, step):
        c1 = min(k, c0 + step)
        blk = buf[c0:c1]
        blk[:] = s[a + c0 : a + c1] if isinstance(s, np.ndarray) else s.seg(a + c0, a + c1)
        if ramp:
            blk *= np.arange(c0, c1, dtype=np.float64)
    buf[k:] = 0.0


class _Detrended:
    """A 1-D series minus its least-squares quadratic, formed on demand (:meth:`seg`) instead of stored; ``a`` is
    the quadratic's coefficient per sample².

    The basis 1, t, t² − mean(t²) with t = (i − (N−1)/2)/N is orthogonal on the sample grid, so each
    coefficient is one projection (chunked sums: no N × 3 design matrix)."""

    def __init__(self, s: NDArray[np.float64]) -> None:
        n = s.size
        self.s = s
        self.size = n
        self.c = 0.5 * (n - 1)
        self.mt2 = float((n * n - 1.0) / (12.0 * n * n))  # mean of t² on the grid
        proj = np.zeros(3)
        norm = np.zeros(3)
        step = 1 << 16
        for a in range(0, n, step):
            b = min(n, a + step)
            t = (np.arange(a, b, dtype=np.float64) - self.c) / n
            q = t * t - self.mt2
            blk = s[a:b]
            proj += (blk.sum(), sum_of_products(blk, t), sum_of_products(blk, q))
            norm += (b - a, sum_of_products(t, t), sum_of_products(q, q))
        self.coef = np.where(norm > 0, proj / np.where(norm > 0, norm, 1.0), 0.0)
        self.a = float(self.coef[2]) / float(n) ** 2

    def total(self) -> float:
        """Σ of every detrended value (computed once)."""
        if not hasattr(self, "_total"):
            step = 1 << 18
            self._total = sum(float(self.seg(a, min(self.size, a + step)).sum()) for a in range(0, self.size, step))
        return self._total

    def seg(self, a: int, b: int, out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """The detrended values a … b − 1 (the same numbers whatever the range)."""
        a, b = max(a, 0), min(b, self.size)
        out = np.empty(max(b - a, 0)) if out is None else out
        coef, n = self.coef, self.size
        for c0 in range(a, b, 1 << 16):
            c1 = min(b, c0 + (1 << 16))
            t = (np.arange(c0, c1, dtype=np.float64) - self.c) / n
            np.subtract(self.s[c0:c1], coef[0] + coef[1] * t + coef[2] * (t * t - self.mt2), out=out[c0 - a : c1 - a])
        return out


def _detrend_quadratic(s: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """A 1-D series minus its least-squares quadratic (stored), and the quadratic's coefficient per sample²."""
    d = _Detrended(s)
    return d.seg(0, s.size), d.a


def _rho_slice(m: int, t0: int, t1: int) -> NDArray[np.float64]:
    """ρ(t) of :func:`_kernel_rho` for t = t0 … t1 − 1 (0 ≤ t0 ≤ t1 ≤ 6m) by its closed form (integers)."""
    t = np.arange(t0, t1)
    t = np.where(t > 3 * m, 6 * m - t, t)
    out = np.empty(t.size)
    a = t < m
    out[a] = 6.0 * (m - t[a]) - 4.0 * t[a]
    b = (t >= m) & (t < 2 * m)
    u = t[b] - m
    out[b] = -4.0 * (m - u) + 1.0 * u
    c = t >= 2 * m
    out[c] = 1.0 * (m - (t[c] - 2 * m))
    return out


def _rho_spectrum(m: int, f0: int, f1: int) -> NDArray[np.float64]:
    """The real FFT of ρ (period 6m) at f = f0 … f1 − 1: ρ is the kernel's circular autocorrelation, so its
    spectrum is |κ̂|² = 16 sin⁶(πf/6) / sin²(πf/6m) (0 at f = 0), sin⁶(πf/6) taken exactly from f mod 6."""
    f = np.arange(f0, f1)
    s6 = np.array([0.0, 1.0 / 64.0, 27.0 / 64.0, 1.0, 27.0 / 64.0, 1.0 / 64.0])[f % 6]
    den = np.sin(f * (np.pi / (6 * m)))
    den *= den
    return np.divide(16.0 * s6, den, out=np.zeros(f.size), where=f > 0)


class _ParityCumsum:
    """RC[j] = Σ ρ(u) over u ≤ j − 2 with u ≡ j (mod 2), j = 0 … 6m + 1 (RC[0] = RC[1] = 0), slice by slice from
    checkpoints: ρ is integer-valued, so these are exactly the numbers of one cumulative sum."""

    CH = 1 << 16

    def __init__(self, m: int) -> None:
        self.m = m
        p = 6 * m
        self.full = None
        if p <= self.CH:  # small: the whole array
            r = _kernel_rho(m)
            self.full = np.zeros(p + 2)
            self.full[2::2] = np.cumsum(r[0::2])
            self.full[3::2] = np.cumsum(r[1::2])
            return
        self.chk = [(0.0, 0.0)]
        e = o = 0.0
        for t0 in range(0, p, self.CH):
            r = _rho_slice(m, t0, min(p, t0 + self.CH))
            e += float(r[0::2].sum())
            o += float(r[1::2].sum())
            self.chk.append((e, o))

    def get(self, j0: int, j1: int) -> NDArray[np.float64]:
        if self.full is not None:
            return self.full[j0:j1]
        q = j0 // self.CH
        base = q * self.CH
        out = np.empty(j1 - base)
        e, o = self.chk[q]
        out[0::2] = e
        out[1::2] = o
        if j1 - 2 > base:
            r = _rho_slice(self.m, base, j1 - 2)
            out[2::2] += np.cumsum(r[0::2])
            out[3::2] += np.cumsum(r[1::2])
        return out[j0 - base :]


class _Prefix:
    """S(j) = Σ_{k<j} v_k of a series of n values given by ``get(a, b)`` = v[a:b], clipped (S = 0 below 0 and
    S(n) above n), slice by slice from checkpoints (no array of n values)."""

    CH = 1 << 16

    def __init__(self, get, n: int) -> None:
        self.get, self.n = get, n
        self.chk = [0.0]
        acc = 0.0
        for a in range(0, n, self.CH):
            acc += float(get(a, min(n, a + self.CH)).sum())
            self.chk.append(acc)

    def at(self, j0: int, j1: int) -> NDArray[np.float64]:
        out = np.empty(j1 - j0)
        a = min(max(0, -j0), out.size)  # indices below 0
        b = max(a, min(out.size, self.n + 1 - j0))  # indices up to n
        out[:a] = 0.0
        if b > a:
            lo, hi = j0 + a, j0 + b  # S over [lo, hi) ⊂ [0, n]
            q = lo // self.CH
            base = q * self.CH
            cs = np.empty(hi - base)
            cs[0] = self.chk[q]
            if hi - 1 > base:
                np.cumsum(self.get(base, hi - 1), out=cs[1:])
                cs[1:] += self.chk[q]
            out[a:b] = cs[lo - base :]
        out[b:] = self.chk[-1]
        return out


def _beta_chunk(p: _Prefix, d0: int, d1: int, L: int, h1: int, D: float) -> NDArray[np.float64]:
    """Σ_k β_k v_{k+d} for d = d0 … d1 − 1, β the half-mean slope kernel (−1/(h1·D) on the first h1 of L = 3m
    points, +1/(h1·D) on the last h1), v zero outside its points: differences of v's prefix sums."""
    res = p.at(d0 + L, d1 + L)
    res -= p.at(d0 + L - h1, d1 + L - h1)
    res -= p.at(d0 + h1, d1 + h1)
    res += p.at(d0, d1)
    res /= h1 * D
    return res


def _q_apply(m: int, v) -> NDArray[np.float64]:
    """Q v with Q_kl = 2[ρ(k−l) + ρ(k+l+1)], k, l < L = 3m, v an array or ``v(a, b)`` = v[a:b]: Q = Eᵀ C E with E
    the even extension of period 6m and C the circulant of ρ, so Q v folds one circular convolution of period 6m,
    done in one buffer of 6m points (:func:`_rfft_ip`, ρ's spectrum in closed form)."""
    L = 3 * m
    p = 2 * L
    get = (lambda a, b: v[a:b]) if isinstance(v, np.ndarray) else v
    buf = np.empty(p)
    step = 1 << 16
    for a in range(0, L, step):
        b = min(L, a + step)
        buf[a:b] = get(a, b)
        buf[p - b : p - a] = buf[a:b][::-1]
    z = _rfft_ip(buf)
    sp = _rho_spectrum(m, L, L + 1)[0]
    z[0] = complex(z[0].real * _rho_spectrum(m, 0, 1)[0], z[0].imag * sp)
    for a in range(1, L, step):
        b = min(L, a + step)
        z[a:b] *= _rho_spectrum(m, a, b)
    del z
    u = _irfft_ip(buf.view(np.complex128))
    del u
    for a in range(0, L, step):  # fold: Q v = u[:L] + u[L:][::-1]
        b = min(L, a + step)
        buf[a:b] += buf[p - b : p - a][::-1]
    buf.resize(L, refcheck=False)
    return buf


def _mtot_fft(s, m: int, R, a: float) -> tuple[float, float]:
    """The sum of :func:`_reflected_sumsq` for one gap-free channel in O(N) + O(m log m) given R, and an
    error scale (≈ ε × the largest summand / E).

    s is the series with its least-squares quadratic removed (an array or a :class:`_Detrended`, a its
    coefficient per sample²) and R its autocorrelation (lags < 3m at least; passed in a one-element list, it is
    released as soon as its terms are summed). Per subsequence the 6m terms are one period of a circular filter
    of the even extension z (period 6m), so Σ_j c_j² = zᵀQz with Q_kl = 2[ρ(k−l) + ρ(k+l+1)], ρ the circular
    autocorrelation of the kernel (1…1, −2…−2, 1…1). With z = X_i − b_i k (X_i the window, b_i = βᵀX_i its
    half-mean slope) and q = Qk: Σ_i zᵀQz = Σ_i X_iᵀQX_i − 2 Σ_i (βᵀX_i)(qᵀX_i) + kᵀQk Σ_i (βᵀX_i)². Every sum
    over windows Σ_{i<M} (uᵀX_i)(vᵀX_i) is Σ_d c_uv(d) R_|d| (c_uv the kernels' cross-correlation) less the
    partial windows hanging over the first and last 3m − 1 samples (FFT correlations of those segments). The
    Toeplitz part of X_iᵀQX_i weighs R_d by the window count less head and tail corrections (weighted
    autocorrelations of the end segments); the Hankel part sums, for each pair (u, v), ρ over t = u + v + 1 − 2i
    of every window i holding both, which in the interior depends only on |u − v| (same-parity cumulative sums
    of ρ) and at the two ends on u + v (self-convolutions of the end segments). The quadratic a t² removed from
    the record adds the same vector r = a(k² − βk) to every detrended window; its terms 2 Σ_i rᵀQz_i + M rᵀQr
    are exact.

    Memory: the weights (ρ, its parity sums, the kernels' correlations) are formed slice by slice and every
    sum of products is reduced as it is formed, so besides s and R at most two in-place FFT buffers of ≈ 6m
    points are alive (:func:`_rfft_ip`; R released before them when owned).
    """
    own = isinstance(R, list)
    Rv = R.pop() if own else R
    seg = (lambda i, j: s[i:j]) if isinstance(s, np.ndarray) else s.seg
    ls = s.size
    L = 3 * m
    M = ls - L + 1
    n = L - 1  # end-segment length
    h1 = L // 2
    h2 = L - h1
    D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
    rho0 = 6.0 * m  # ρ(0)
    r0 = abs(float(Rv[0]))
    rc = _ParityCumsum(m)
    step = 1 << 16
    rho_all = _kernel_rho(m)[:L] if L <= step else None

    def weights(d0: int, d1: int) -> tuple[NDArray, NDArray, NDArray]:  # wr(d) = w_d ρ(d), rc_hi(d), rc_lo(d)
        wr = 2.0 * (rho_all[d0:d1] if rho_all is not None else _rho_slice(m, d0, d1))
        if d0 == 0:
            wr[0] *= 0.5
        return wr, rc.get(2 * L + 2 - d1, 2 * L + 2 - d0)[::-1], rc.get(1 + d0, 1 + d1)

    # Toeplitz part's interior: Σ_d R_d [2(Rc(2L−1−d) − Rc(d−1)) + w_d ρ(d)(L − d)]
    T1 = 0.0
    for d0 in range(0, L, step):
        d1 = min(L, d0 + step)
        wr, hi, lo = weights(d0, d1)
        wa = np.subtract(hi, lo)
        wa *= 2.0
        if d0 == 0:
            wa[0] *= 0.5
        wa += wr * np.arange(L - d0, L - d1, -1, dtype=np.float64)
        T1 += 2.0 * sum_of_products(Rv[d0:d1], wa)
    E_quad = scale_quad = 0.0
    if a != 0.0:  # the removed quadratic's exact terms: r1 = k² − β_s k, Q r1, and Σ_i z_i
        kk = np.arange(L, dtype=np.float64)
        beta_s = ((kk[h2:] ** 2).mean() - (kk[:h1] ** 2).mean()) / D
        del kk

        def r1(i: int, j: int) -> NDArray[np.float64]:
            k = np.arange(i, j, dtype=np.float64)
            return k * k - beta_s * k

        qr1 = _q_apply(m, r1)
        square = M * a * a * sum(sum_of_products(r1(i, min(L, i + step)), qr1[i : i + step]) for i in range(0, L, step))
        if isinstance(s, np.ndarray):  # Σ_{i<M} s[i + k] at k = 0
            w0 = float(s[:M].sum())
        else:
            w0 = s.total() - float(seg(M, ls).sum())
        carry = w0
        wq = kq = w_lo = w_hi = 0.0
        for i in range(0, L, step):
            j = min(L, i + step)
            win = np.empty(j - i)
            if i == 0:
                win[0] = w0
                win[1:] = np.cumsum(seg(M, M + j - 1) - seg(0, j - 1)) + w0
            else:
                np.cumsum(seg(M + i - 1, M + j - 1) - seg(i - 1, j - 1), out=win)
                win += carry
            carry = float(win[-1])
            wq += sum_of_products(win, qr1[i:j])
            kq += sum_of_products(np.arange(i, j, dtype=np.float64), qr1[i:j])
            w_lo += float(win[: max(0, min(j, h1) - i)].sum())
            w_hi += float(win[max(0, h2 - i) :].sum())
        del qr1
        bsum = (w_hi - w_lo) / (h1 * D)
        cross = 2.0 * a * (wq - bsum * kq)
        E_quad = cross + square
        scale_quad = 8.0 * (abs(cross) + abs(square))
    # detrend terms: β the half-mean slope, q = Qk; Σ_{i<M} (βᵀX_i)(vᵀX_i) = Σ_d c_βv(d) R_|d| − partial windows
    q = _q_apply(m, np.arange(L, dtype=np.float64))
    kqk = sum(
        sum_of_products(np.arange(i, min(L, i + step), dtype=np.float64), q[i : i + step]) for i in range(0, L, step)
    )

    def full(p: _Prefix, rv: NDArray) -> tuple[float, float]:  # Σ_d c(d) R_|d|, c = β ⋆ v, d = −(L−1) … L−1; Σ|c| R_0
        c0 = float(_beta_chunk(p, 0, 1, L, h1, D)[0])
        tot, ab = c0 * float(rv[0]), abs(c0)
        for d0 in range(1, L, step):
            d1 = min(L, d0 + step)
            cp = _beta_chunk(p, d0, d1, L, h1, D)
            cn = _beta_chunk(p, 1 - d1, 1 - d0, L, h1, D)[::-1]
            ab += float(np.abs(cp).sum() + np.abs(cn).sum())
            cp += cn
            tot += sum_of_products(cp, rv[d0:d1])
        return tot, r0 * ab

    def beta(i: int, j: int) -> NDArray[np.float64]:
        k = np.arange(i, j)
        return np.where(k < h1, -1.0 / (h1 * D), np.where(k >= h2, 1.0 / (h1 * D), 0.0))

    s_bu, sc_bu = full(_Prefix(lambda i, j, q=q: q[i:j], L), Rv)
    s_bb, sc_bb = full(_Prefix(beta, L), Rv)
    del Rv  # every R term is summed
    nf = _even_len(2 * n)  # ≥ 2n − 1 (self-convolutions) and ≥ n + L − 1 (the correlations with q)
    # partial windows over the head and the tail: Σ_i sb_i sq_i with sq = q ⋆ segment (one FFT of q for both)
    bq = np.empty(nf)
    _fill(bq, q, 0, L)
    del q
    qz = _rfft_ip(bq)
    for s0, lo, hi in ((0, -(L - 1), 0), (M, 0, L - 1)):
        bs = np.empty(nf)
        _fill(bs, s, s0, s0 + n)
        sz = _rfft_ip(bs)
        _spec_update(sz, "mulc", qz)
        out = _irfft_ip(sz)  # out[i mod nf] = Σ_k q_k seg_{i+k}
        del sz
        pre = _Prefix(lambda i, j, s0=s0: seg(s0 + i, s0 + j), n)
        for i0 in range(lo, hi, step):
            i1 = min(hi, i0 + step)
            sb = _beta_chunk(pre, i0, i1, L, h1, D)
            sq = out[i0 % nf : i0 % nf + (i1 - i0)]
            s_bu -= sum_of_products(sb, sq)
            sc_bu += sum_of_products(np.abs(sb), np.abs(sq))
            bb = sum_of_products(sb, sb)
            s_bb -= bb
            sc_bb += bb
            del sb, sq
        del out, bs, pre
    del qz, bq
    # head and tail segments: the Toeplitz part's window-count corrections (Σ wa_d A_d with A the segment's
    # autocorrelation, Σ wb_d B_d with B_d = Σ_t t h_t h_{t+d}) and the Hankel part's end terms (Σ wc_σ C_σ, C the
    # self-convolution), from the segment's spectrum (two buffers)
    for s0, sign in ((0, 1.0), (M, -1.0)):
        b1 = np.empty(nf)
        _fill(b1, s, s0, s0 + n)
        hz = _rfft_ip(b1)
        b2 = np.empty(nf)
        _fill(b2, s, s0, s0 + n, ramp=True)
        tz = _rfft_ip(b2)
        _spec_update(tz, "cmul", hz)  # conj(TH)·H
        out = _irfft_ip(tz)
        del tz
        for d0 in range(0, n, step):
            d1 = min(n, d0 + step)
            T1 += 2.0 * sign * sum_of_products(out[d0:d1], weights(d0, d1)[0])
        np.copyto(b2, b1)
        cz = b2.view(np.complex128)
        _spec_update(cz, "sq")
        out = _irfft_ip(cz)
        del cz
        for c0 in range(0, 2 * n - 1, step):
            c1 = min(2 * n - 1, c0 + step)
            T1 += 2.0 * sign * sum_of_products(out[c0:c1], rc.get(3 + c0, 3 + c1))
        del out, b2
        _spec_update(hz, "pow")
        out = _irfft_ip(hz)
        del hz
        for d0 in range(0, n, step):
            d1 = min(n, d0 + step)
            wr, hi, lo = weights(d0, d1)
            if s0 == 0:  # −2[2 Rc(2L−1−d) (Rc(2L−1) at d = 0) + w_d ρ(d)(L − 1 − d)]
                wa = np.multiply(hi, 2.0)
                if d0 == 0:
                    wa[0] = hi[0]
                wa += wr * np.arange(L - 1 - d0, L - 1 - d1, -1, dtype=np.float64)
                wa *= -2.0
            else:  # 2[2 Rc(d − 1) (Rc(−1) at d = 0) − w_d ρ(d)]
                wa = np.multiply(lo, 2.0)
                if d0 == 0:
                    wa[0] = lo[0]
                wa -= wr
                wa *= 2.0
            T1 += sum_of_products(out[d0:d1], wa)
        del out, b1
    E = T1 - 2.0 * s_bu + kqk * s_bb + E_quad
    scale = 4.0 * L * abs(rho0) * r0 + 2.0 * sc_bu + abs(kqk) * sc_bb + scale_quad
    err = 1.1e-16 * scale / abs(E) if E != 0.0 else math.inf
    return E, err


_FFT_MIN_M = 8
"""Below this m the direct O(N·m) evaluation is cheap and exact; above it the O(N log N) form is tried."""
_FFT_MAX_ERR = 1e-10
"""Largest estimated relative rounding error of the variance accepted from the FFT form (else the direct sum is
used). The estimate can be ~5× short of the actual error: at 1e-9, MTOTDEV at m = 2048 on the N = 10⁷ benchmark
record was accepted 3e-9 (variance) off the blocked sum; at 1e-10 that τ goes block by block (+0.3 s) and every
value agrees with a 1e-11 bar."""


def _kernel_rho(m: int) -> NDArray[np.float64]:
    """Circular autocorrelation (period 6m) of the modified-total kernel (1…1, −2…−2, 1…1): the box's triangle
    max(m − |t|, 0) combined with the second difference's (1, −4, 6, −4, 1) at spacing m (closed form, O(m)):
    ρ(t) = (m − t)·(6, −4, 1 at t in [0, m), [m, 2m), [2m, 3m)) + t'·(−4, 1) ramps, mirrored to period 6m."""
    p = 6 * m
    out = np.empty(p)
    t = np.arange(m, dtype=np.float64)  # position inside each m-block
    # triangle sums on the blocks [km, (k+1)m): f_k(t) = Σ_j c_j max(m − |km + t − jm|, 0)
    out[:m] = 6.0 * (m - t) - 4.0 * t
    out[m : 2 * m] = -4.0 * (m - t) + 1.0 * t
    out[2 * m : 3 * m] = 1.0 * (m - t)
    out[3 * m] = 0.0
    out[3 * m + 1 :] = out[3 * m - 1 : 0 : -1]
    return out


def _series_cache(
    s: NDArray[np.float64], ch: int, cache: dict, key: str, need: int
) -> tuple[NDArray, NDArray, float]:
    """(series minus its least-squares quadratic, its autocorrelation, the quadratic coefficient) of one
    channel, computed once per record and kept in ``cache``.

    The autocorrelation holds the lags up to ``need`` at least, or up to ``cache[("maxlag", key)]`` (the largest
    lag of the estimator's τ grid, set by :func:`_prepass`) when that is larger; every lag without that hint or
    when a cached one falls short (TheoBR's ratios ask for growing m); ``R_theo`` (Theo1) keeps the even lags
    only (r[j] = R_2j), the only ones Theo1 reads."""
    ck = (key, ch)
    step = 2 if key == "R_theo" else 1
    if ck not in cache or (cache[ck][1].size - 1) * step < need:
        hint = cache.get(("maxlag", key))
        lag = max(need, hint) if hint is not None and ck not in cache else s.shape[1] - 1  # else: every lag
        cache.pop(ck, None)
        d = _Detrended(s[ch])  # formed on demand: R's buffer is filled from it
        r = _autocorr(d, lag, step)
        # Theo1 reads the whole series many times: stored (after R's buffer is shrunk); the total family reads
        # its two end segments and a few sums: kept on demand
        cache[ck] = (d.seg(0, d.size) if key == "R_theo" else d, r, d.a)
    return cache[ck]


_BLOCK_MIN = 1 << 16
"""Fewest windows per block of :func:`_blocked_sum`."""


def _blocked_sum(s: NDArray[np.float64], m: int, kind: str) -> float:
    """The closed form evaluated block by block: windows i ∈ [b₀, b₁) use only s[b₀ : b₁ + span], so their sum
    is the closed form of that segment (its own quadratic removed, its own autocorrelation). A short segment's
    autocorrelation is small next to the record's (a random-walk phase: R₀ ∝ length²), which keeps the
    expansion's rounding below :data:`_FFT_MAX_ERR` where the record-wide form is not; a block still above it
    is summed directly. O(N log B) per τ for blocks of B ≈ max(2¹⁶, 16·span) windows."""
    if kind == "mtot":
        span, count, fn = 3 * m - 1, s.size - 3 * m + 1, _mtot_fft
    else:
        span, count, fn = m, s.size - m, _theo1_fft
    block = max(_BLOCK_MIN, 16 * span)
    total = 0.0
    for b0 in range(0, count, block):
        b1 = min(count, b0 + block)
        seg = s[b0 : b1 + span]
        sd, a = _detrend_quadratic(seg)
        r = _autocorr(sd, min(seg.size - 1, span + 1), 1 if kind == "mtot" else 2)
        v, err = fn(sd, m, r, a)
        del sd, r
        if err >= _FFT_MAX_ERR:
            if kind == "mtot":
                v = float(_reflected_sumsq(seg[None, :], m, None)[0][0])
            else:
                v = float(_theo1_sumsq(seg[None, :], m, None)[0][0])
        total += v
    return total


def _total_sumsq(
    s: NDArray[np.float64], m: int, ok: NDArray[np.bool_] | None, cache: dict, key: str
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`_reflected_sumsq` through :func:`_mtot_fft` (channel by channel) when the record has no gaps,
    m ≥ :data:`_FFT_MIN_M` and its rounding estimate is below :data:`_FFT_MAX_ERR`; otherwise directly.

    For the dynamic range the record's least-squares quadratic is removed first: each subsequence is
    detrended, so the line changes nothing and the quadratic's exact terms are added back."""
    c, n_s = s.shape
    count = n_s - 3 * m + 1
    if ok is None and m >= _FFT_MIN_M and count > 0:
        pre = cache.get(("pre", key, m))
        e = np.zeros(c)
        for ch in range(c):
            if pre is not None:
                v, err = pre[ch], 0.0 if np.isfinite(pre[ch]) else math.inf
            else:
                sd, r, a = _series_cache(s, ch, cache, key, 3 * m - 1)
                if 3 * m - 1 >= cache.get(("maxlag", key), math.inf):  # the grid's largest m: R's last use
                    del cache[(key, ch)]
                    r = [r]  # owned: released inside once its terms are summed
                v, err = _mtot_fft(sd, m, r, a)
                del sd, r
            e[ch] = v if err < _FFT_MAX_ERR else _blocked_sum(s[ch], m, "mtot")
        return e, np.full(c, count, dtype=np.int64)
    return _reflected_sumsq(s, m, ok)


def _prepass(rec: _Record, name: str, ms: NDArray[np.int64], cache: dict) -> None:
    """Gap-free records: the O(N log N) forms of one estimator for every m of its grid, channel by channel, so
    that only one channel's detrended series and autocorrelation are alive at a time (memory a few × one
    channel instead of × all channels). Stored as ``cache[("pre", key, m)]`` (NaN: rounding estimate too
    large, the direct sum is used)."""
    if rec.has_gaps:
        return
    if name in ("mtotdev", "ttotdev"):
        key, fn, src = "R_phase", _mtot_fft, rec.x
        todo = [int(m) for m in ms if m >= _FFT_MIN_M and rec.n - 3 * m + 1 > 0]
    elif name == "htotdev":
        if "freq" not in cache:
            cache["freq"] = rec.frequency()
        key, fn, src = "R_freq", _mtot_fft, cache["freq"][0]
        todo = [int(m) for m in ms if m >= _FFT_MIN_M and src.shape[1] - 3 * m + 1 > 0]
    elif name == "theo1":
        key, fn, src = "R_theo", _theo1_fft, rec.x
        todo = [int(m) for m in ms if m >= 64 and m % 2 == 0 and rec.n - m > 0]
    else:
        return
    if todo:  # the largest lag the grid reads: R_d, d < 3m (total family); R_2δ, δ < m/2 (Theo1)
        need = max(todo) - 2 if fn is _theo1_fft else 3 * max(todo) - 1
        cache[("maxlag", key)] = max(need, cache.get(("maxlag", key), 0))
    if rec.channels == 1:  # one channel: the τ loop computes each m in turn, with the same cached series
        return
    todo = [m for m in todo if ("pre", key, m) not in cache]
    if not todo:
        return
    vals = {m: np.full(rec.channels, np.nan) for m in todo}
    for ch in range(rec.channels):
        sd, r, a = _series_cache(src, ch, cache, key, cache[("maxlag", key)])
        del cache[(key, ch)]
        rr = [r]  # the total family releases R at the last m (see _mtot_fft)
        del r
        bad = []
        for j, m in enumerate(todo):
            v, err = fn(sd, m, rr if fn is _mtot_fft and j == len(todo) - 1 else rr[0], a)
            if err < _FFT_MAX_ERR:
                vals[m][ch] = v
            else:
                bad.append(m)
        del sd, rr
        for m in bad:  # record-wide rounding too large: block by block (see _blocked_sum)
            vals[m][ch] = _blocked_sum(src[ch], m, "theo1" if fn is _theo1_fft else "mtot")
    for m in todo:
        cache[("pre", key, m)] = vals[m]


def _theo1_sumsq(
    x: NDArray[np.float64], m: int, ok: NDArray[np.bool_] | None
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Σ_i Σ_{δ<m/2} [(x_i − x_{i+m/2−δ}) + (x_{i+m} − x_{i+m/2+δ})]² / (m/2 − δ), i = 0 … N−m−1, per channel
    of the phase x (C, N), terms with ok False skipped (O(N·m), in chunks of i)."""
    c, n = x.shape
    count = n - m
    h = m // 2
    if count <= 0 or m % 2:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    total = np.zeros(c)
    step = max(_CHUNK // max(1, c), 1024)
    e = np.empty((c, min(step, count)))
    for a0 in range(0, count, step):
        b0 = min(count, a0 + step)
        k = b0 - a0
        base = x[:, a0:b0] + x[:, a0 + m : b0 + m]
        acc = np.zeros((c, k))
        ek = e[:, :k]
        for dlt in range(h):
            np.subtract(base, x[:, a0 + h - dlt : b0 + h - dlt], out=ek)
            ek -= x[:, a0 + h + dlt : b0 + h + dlt]
            ek *= ek
            ek *= 1.0 / (h - dlt)
            acc += ek
        if ok is not None:
            acc[~ok[:, a0:b0]] = 0.0
        total += acc.sum(axis=1)
    if ok is not None:
        return total, ok.sum(axis=1) * h
    return total, np.full(c, count * h, dtype=np.int64)

_LEAN_MIN = 1 << 16
"""Smallest FFT length of the blocked correlations (:func:`_fft_cap`)."""
_LEAN_DIV = 8
"""The blocked correlations of a series of N points use FFTs of at most about N / this many points, so each of
their few buffers costs a fraction of the series (see :func:`_corr_sum`)."""


def _fft_cap(n: int) -> int:
    """Largest FFT length (even) of the blocked correlations of a series of n points."""
    cap = _fast_len(max(_LEAN_MIN, n // _LEAN_DIV))
    return cap + cap % 2


def _corr_sum(get_a, na: int, get_b, nb: int, kern, lo: int, hi: int, cap: int) -> float:
    """Σ_{u<na, v<nb} a_u b_v K(v − u) for a kernel K that is zero outside the lags [lo, hi).

    ``get_a(i, j)`` and ``get_b(i, j)`` return a[i:j] and b[i:j] (so a series can be formed block by block),
    ``kern(l0, l1)`` K over the lags l0 … l1 − 1. One FFT cross-correlation when na + nb − 1 ≤ cap; otherwise
    blocks of cap/2 points of a against blocks of b whose lags meet [lo, hi), one FFT of cap points per pair
    (memory O(cap), a few buffers, instead of O(na + nb))."""
    if na <= 0 or nb <= 0 or hi <= lo:
        return 0.0
    if na + nb - 1 <= cap:
        nf, blk = _fast_len(na + nb - 1), max(na, nb)
    else:
        nf, blk = cap, cap // 2
    tot = 0.0
    for j0 in range(0, na, blk):
        j1 = min(na, j0 + blk)
        fa = None
        for k0 in range(0, nb, blk):
            k1 = min(nb, k0 + blk)
            base = k0 - j0  # lag of a_{j0} with b_{k0}; the pair covers base − (j1 − j0 − 1) … base + k1 − k0 − 1
            if base + (k1 - k0) <= lo or base - (j1 - j0 - 1) >= hi:
                continue
            if fa is None:
                fa = sfft.rfft(get_a(j0, j1), nf)
                np.conjugate(fa, out=fa)
            f = sfft.rfft(get_b(k0, k1), nf)
            f *= fa
            cc = sfft.irfft(f, nf, overwrite_x=True)  # cc[δ mod nf] = Σ_u a_{j0+u} b_{k0+u+δ}
            del f
            tot += sum_of_products(cc[: k1 - k0], kern(base, base + k1 - k0))
            if j1 - j0 > 1:
                tot += sum_of_products(cc[nf - (j1 - j0) + 1 :], kern(base - (j1 - j0) + 1, base))
            del cc
        del fa
    return tot


_TRI_BASE = 256
"""Triangle size below which :func:`_tri` sums directly."""
_TRI_IDX: dict[int, tuple[NDArray, NDArray]] = {}


def _tri(a: NDArray, b: NDArray, gk, off: int, n: int, cap: int) -> float:
    """Σ over u, v ∈ [0, n) with u + v < n of a_u b_v G(v − u + off), 1-D a and b zero beyond their length and
    ``gk(e0, e1)`` G over e0 … e1 − 1 (zero outside [0, ∞)), in O(n log² n).

    Divide and conquer on the anti-diagonal triangle: the square [0, n/2)² is a cross-correlation
    (:func:`_corr_sum`, blocked beyond ``cap``), the two remaining strips are triangles of half the size
    (recursion, on views: a strip's missing half is a's or b's end), and for odd n the centre point.
    """
    a = a[:n]
    b = b[:n]
    if n <= 0 or a.size == 0 or b.size == 0:
        return 0.0
    if n <= _TRI_BASE:
        if n not in _TRI_IDX:
            u = np.arange(n)
            _TRI_IDX[n] = ((u[None, :] - u[:, None]) + (n - 1), (u[:, None] + u[None, :]) < n)
        idx, mask = _TRI_IDX[n]
        g = gk(off - (n - 1), off + n)
        wmat = g[idx] * mask
        return float(np.einsum("u,uv,v->", a, wmat[: a.size, : b.size], b))
    k = n // 2
    tot = _corr_sum(
        lambda i, j: a[i:j], min(a.size, k), lambda i, j: b[i:j], min(b.size, k),
        lambda l0, l1: gk(l0 + off, l1 + off), -off, 1 << 62, cap,
    )
    r = n - k
    tot += _tri(a[:k], b[k:n], gk, off + k, r, cap)
    tot += _tri(a[k:n], b[:k], gk, off - k, r, cap)
    if n % 2 and k < a.size and k < b.size:
        tot += float(a[k] * b[k] * gk(off, off + 1)[0])
    return tot


def _window_sum_chunks(f: NDArray[np.float64], count: int, top: int, sq: bool):
    """Yield (o₀, W[o₀ : o₁]) for W(o) = Σ_{c<count} f_{c+o} (or f²), o = 0 … top, in ascending chunks: one direct
    sum and a running cumulative sum of the O(top) end differences (no array as long as top)."""
    w0 = sum_of_products(f[:count], f[:count]) if sq else float(f[:count].sum())
    yield 0, np.array([w0])
    carry = w0
    step = 1 << 16
    for o0 in range(1, top + 1, step):
        o1 = min(top + 1, o0 + step)
        tail = f[count + o0 - 1 : count + o1 - 1]
        head = f[o0 - 1 : o1 - 1]
        c = np.cumsum(tail * tail - head * head if sq else tail - head)
        c += carry
        carry = float(c[-1])
        yield o0, c


def _fold_windows(chunks, h: int, coef) -> tuple[float, float, float]:
    """(Σ_{δ<h} c_δ (W[h − δ] + W[h + δ]), W[0], W[2h]) over the chunks of :func:`_window_sum_chunks` (top = 2h),
    ``coef(d0, d1)`` giving c_δ for δ = d0 … d1 − 1."""
    tot = w_lo = w_hi = 0.0
    for o0, v in chunks:
        o1 = o0 + v.size
        if o0 == 0:
            w_lo = float(v[0])
        if o1 > 2 * h:
            w_hi = float(v[2 * h - o0])
        lo, hi = max(o0, 1), min(o1, h + 1)  # o = h − δ
        if hi > lo:
            tot += sum_of_products(v[lo - o0 : hi - o0][::-1], coef(h - hi + 1, h - lo + 1))
        lo, hi = max(o0, h), min(o1, 2 * h)  # o = h + δ
        if hi > lo:
            tot += sum_of_products(v[lo - o0 : hi - o0], coef(lo - h, hi - h))
    return tot, w_lo, w_hi


def _theo1_fft(x: NDArray[np.float64], m: int, r: NDArray[np.float64], a: float) -> tuple[float, float]:
    """Theo1's double sum of one gap-free channel in O(N log m + m log² m) given the even-lag autocorrelation
    r (r[j] = R_2j) of x, and a rounding-error scale (see :func:`_theo1_sumsq`).

    With c = i + m/2 and A_c = x_{c−m/2} + x_{c+m/2}, each term is (A_c − x_{c−δ} − x_{c+δ})²/(m/2 − δ); summed
    over δ it is W A_c² − 2 A_c (k∗x)_c + (k∗x²)_c + 2 Σ_δ w_δ x_{c−δ} x_{c+δ} with k the symmetric kernel of the
    weights w_δ = 1/(m/2 − δ). Σ A_c² and Σ (k∗x²)_c are window sums of x² (in chunks) plus one lagged dot
    product; Σ A_c (k∗x)_c is a blocked (overlap-save) FFT correlation, the kernel itself cut into pieces when
    it is long; the last sum over c is Σ_δ w_δ R_{2δ} less two anti-diagonal triangles of the first and of the
    reversed last m − 1 samples (:func:`_tri`). x has its least-squares quadratic removed (a its coefficient per
    sample², whose exact terms 2a(h² − δ²) per term are added back). Memory: the weights (m/2 points) and FFT
    buffers of at most :func:`_fft_cap` points, whatever m.
    """
    n = x.size
    h = m // 2
    count = n - m
    cap = _fft_cap(n)
    w = 1.0 / (h - np.arange(h))
    wsum = float(w.sum())
    t3, w2_0, w2_m = _fold_windows(_window_sum_chunks(x, count, m, True), h, lambda d0, d1: w[d0:d1])
    t1 = wsum * (w2_0 + w2_m + 2.0 * sum_of_products(x[:count], x[m : m + count]))
    # Σ_c A_c (k∗x)_c, (k∗x)_c = Σ_{j<m−1} kern_j x_{c+1+j}, kern_j = w_{|j − h + 1|} (2 w_0 at j = h − 1)
    kl = m - 1

    def kern(j0: int, j1: int) -> NDArray[np.float64]:
        out = np.empty(j1 - j0)
        p1 = min(j1, h - 1)
        if p1 > j0:
            out[: p1 - j0] = w[h - p1 : h - j0][::-1]
        if j0 <= h - 1 < j1:
            out[h - 1 - j0] = 2.0 * w[0]
        p2 = max(j0, h)
        if j1 > p2:
            out[p2 - j0 :] = w[p2 - h + 1 : j1 - h + 1]
        return out

    piece = kl if 4 * kl <= cap else cap // 2
    t2 = 0.0
    for j0 in range(0, kl, piece):  # kernel pieces j0 … j1 − 1, each an overlap-save pass over c
        j1 = min(kl, j0 + piece)
        kp = j1 - j0
        nf = min(_fast_len(max(4 * kp, 1 << 16) if piece == kl else 2 * kp), _fast_len(count + kp - 1))
        blk = nf - kp + 1
        kf = sfft.rfft(kern(j0, j1)[::-1], nf)
        for c0 in range(0, count, blk):
            c1 = min(count, c0 + blk)
            f = sfft.rfft(x[c0 + 1 + j0 : c1 + j1], nf)
            f *= kf
            kc = sfft.irfft(f, nf, overwrite_x=True)[kp - 1 : kp - 1 + c1 - c0]
            del f
            t2 += sum_of_products(x[c0:c1] + x[c0 + m : c1 + m], kc)
            del kc
        del kf
    t2 *= 2.0
    s4 = sum_of_products(r[:h], w)

    def gk(e0: int, e1: int) -> NDArray[np.float64]:  # G(e) = w_{e/2} at even e ∈ [0, m − 2], else 0
        out = np.zeros(e1 - e0)
        s = max(e0, 0)
        s += s & 1
        t = min(e1, 2 * h - 1)
        if t > s:
            out[s - e0 : t - e0 : 2] = w[s // 2 : (t + 1) // 2]
        return out

    s4 -= _tri(x[: m - 1], x[: m - 1], gk, 0, m - 1, cap)
    tail = x[::-1][: m - 1]
    s4 -= _tri(tail, tail, gk, 0, m - 1, cap)
    v = t1 - t2 + t3 + 2.0 * s4
    scale = 8.0 * (t1 + abs(t2) + t3 + 2.0 * wsum * abs(float(r[0])))
    if a != 0.0:
        # Theo1 is blind to a line in the phase, and a quadratic a t² adds exactly 2a(h² − δ²) to every term

        def wq(d0: int, d1: int) -> NDArray[np.float64]:  # w_δ · 2(h² − δ²)
            d = np.arange(d0, d1, dtype=np.float64)
            return w[d0:d1] * (2.0 * (h * h - d * d))

        s1, s1_0, s1_m = _fold_windows(_window_sum_chunks(x, count, m, False), h, wq)
        step = 1 << 16
        wq_sum = wq_sq = 0.0
        for d0 in range(0, h, step):
            c = wq(d0, min(h, d0 + step))
            d = np.arange(d0, d0 + c.size, dtype=np.float64)
            wq_sum += float(c.sum())
            wq_sq += sum_of_products(c, 2.0 * (h * h - d * d))
        cross = 2.0 * a * ((s1_0 + s1_m) * wq_sum - s1)
        square = count * a * a * wq_sq
        v += cross + square
        scale += 8.0 * (abs(cross) + abs(square))
    err = 1.1e-16 * scale / abs(v) if v != 0.0 else math.inf
    return v, err


def _theo1_total(rec: _Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Theo1 sums: :func:`_theo1_fft` channel by channel for gap-free records with m ≥ 64 when its rounding
    estimate is below :data:`_FFT_MAX_ERR`, else :func:`_theo1_sumsq`."""
    n = rec.n
    if not rec.has_gaps and m >= 64 and m % 2 == 0 and n - m > 0:
        c = rec.channels
        out = np.zeros(c)
        pre = cache.get(("pre", "R_theo", m))
        for ch in range(c):
            if pre is not None:
                v, err = pre[ch], 0.0 if np.isfinite(pre[ch]) else math.inf
            else:
                xd, r, a = _series_cache(rec.x, ch, cache, "R_theo", m - 2)
                v, err = _theo1_fft(xd, m, r, a)
            out[ch] = v if err < _FFT_MAX_ERR else _blocked_sum(rec.x[ch], m, "theo1")
        return out, np.full(c, (n - m) * (m // 2), dtype=np.int64)
    return _theo1_sumsq(rec.x, m, rec.span_ok(0, n - m, m) if n - m > 0 else None)



def _mtie(rec: _Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Largest max − min of the phase over windows of m + 1 points (O(N) running max/min filter)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    x = rec.x
    n = rec.n
    c = x.shape[0]
    w = m + 1
    count = n - m
    if count <= 0:
        return np.full(c, np.nan), np.zeros(c, dtype=np.int64)
    xx = x
    if rec.has_gaps:
        ok_pt = rec.point_ok if rec.point_ok is not None else np.ones(x.shape, dtype=bool)
        xx_hi = np.where(ok_pt, x, -np.inf)
        xx_lo = np.where(ok_pt, x, np.inf)
    else:
        xx_hi = xx_lo = xx
    hi = maximum_filter1d(xx_hi, size=w, axis=1, mode="nearest")
    lo = minimum_filter1d(xx_lo, size=w, axis=1, mode="nearest")
    # the centred filter at index k covers [k − w//2, k + (w−1)//2]; a full window [i, i+m] sits at k = i + w//2
    k0 = w // 2
    tie = hi[:, k0 : k0 + count] - lo[:, k0 : k0 + count]
    ok = rec.span_ok(0, count, m)
    if ok is not None:
        tie = np.where(ok, tie, -np.inf)
        used = ok.sum(axis=1)
        return np.where(used > 0, tie.max(axis=1), np.nan), used
    return tie.max(axis=1), np.full(c, count, dtype=np.int64)


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


def _one(rec: _Record, name: str, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """(variance-or-deviation, n_terms) of estimator ``name`` at m for every channel; see :func:`stability`."""
    ts = rec.ts
    tau = m * ts
    if name == "oadev":
        s, k = _oadev_sumsq(rec, m, cache)
        return np.sqrt(s / (2.0 * np.maximum(k, 1) * tau * tau)), k
    if name == "adev":
        s, k = _diff_sumsq(rec, m, (1.0, -2.0, 1.0), m)
        return np.sqrt(s / (2.0 * np.maximum(k, 1) * tau * tau)), k
    if name in ("hdev", "ohdev"):
        s, k = _diff_sumsq(rec, m, (-1.0, 3.0, -3.0, 1.0), m if name == "hdev" else 1)
        return np.sqrt(s / (6.0 * np.maximum(k, 1) * tau * tau)), k
    if name in ("mdev", "tdev"):
        if ("mdev", m) not in cache:
            cache[("mdev", m)] = _mod_sumsq(rec, m)
        s, k = cache[("mdev", m)]
        md = np.sqrt(s / (2.0 * m * m * tau * tau * np.maximum(k, 1)))
        return (md if name == "mdev" else tau * md / math.sqrt(3.0)), k
    if name == "totdev":
        s, k = _tot_sumsq(rec, m) if rec.has_gaps else _tot_sumsq_central(rec, m, cache)
        return np.sqrt(s / (2.0 * tau * tau * np.maximum(k, 1))), k
    if name in ("mtotdev", "ttotdev"):
        if ("mtot", m) not in cache:
            cnt = rec.n - 3 * m + 1
            ok = rec.span_ok(0, cnt, 3 * m - 1) if cnt > 0 else None
            cache[("mtot", m)] = _total_sumsq(rec.x, m, ok, cache, "R_phase")
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
        s, k = _total_sumsq(y, m, ok, cache, "R_freq")
        return np.sqrt(s / (m * m * 36.0 * m * np.maximum(k, 1))), k
    if name == "theo1":
        s, k = _theo1_total(rec, m, cache)
        cnt = k // max(m // 2, 1)
        return np.sqrt(s / (0.75 * np.maximum(cnt, 1) * tau * tau)), k
    if name == "mtie":
        return _mtie(rec, m)
    if name == "tierms":
        s, k = _diff_sumsq(rec, m, (-1.0, 1.0), 1)
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

    Returns
    -------
    StabilityResult
    """
    bad = [e for e in estimators if e not in ESTIMATORS]
    if bad:
        raise ValueError(f"unknown estimator(s) {', '.join(bad)}; choose from {', '.join(ESTIMATORS)}")
    if not estimators:
        raise ValueError("no estimator chosen")
    rec = _Record(data, rate, data_type)
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
                rec._x = phase
    key = {"adev": "avar", "oadev": "oavar", "mdev": "mvar", "totdev": "totvar"}
    for name in estimators:
        if name in ("theoh", "theobr"):
            continue
        ms = grid[grid <= _MAX_M[name](rec.n)]
        if name == "theo1":
            ms = ms[ms % 2 == 0]
        _prepass(rec, name, ms, cache)
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
        _attach_intervals(rec, res)
    return res


def _id_phase(rec: _Record, ch: int) -> NDArray[np.float64]:
    """One channel's phase for noise identification: gaps bridged (frequency gaps are zero-filled after the
    mean is removed; missing phase points are interpolated linearly)."""
    x = rec.x[ch]
    if rec.point_ok is not None and not rec.point_ok[ch].all():
        ok = rec.point_ok[ch]
        idx = np.arange(x.size)
        x = np.interp(idx, idx[ok], x[ok])
    return x


def _attach_intervals(rec: _Record, res: StabilityResult) -> None:
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
                a = alpha_of(name, ch, m_id, dmax, n_b1, carry=kind == "theo1")
                alpha[j, ch] = a
                e[j, ch] = ci.edf(kind, a, m, n)
                if kind == "theo1" and name != "theo1":  # TheoBR = kf·Theo1: add the scatter of kf
                    e[j, ch] = ci.edf_theobr(e[j, ch])
        est.alpha = alpha
        est.edf = e
        if name in ("totdev", "htotdev"):
            t_rec = (n - 1) * rec.ts
            est.bias = ci.bias_factor(name, alpha, est.m, est.tau, t_rec)
        est.lo, est.hi = ci.chi2_interval(est.unbiased(), e, res.confidence)
        if name == "totdev":  # white PM: the reflected end terms skew the law, three cumulants (exact B)
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


def _theobr_factor(rec: _Record, cache: dict) -> NDArray[np.float64]:
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


def _theobr(rec: _Record, grid: NDArray[np.int64], cache: dict) -> Estimate:
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


def _theoh(rec: _Record, grid: NDArray[np.int64], done: dict, cache: dict, split: float) -> Estimate:
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
