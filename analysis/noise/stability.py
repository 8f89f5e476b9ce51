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

Speed. Every estimator costs O(N) or O(N log N) per τ, all channels at once. ADEV/OADEV/HDEV/OHDEV/TIE rms:
chunked differences; MDEV/TDEV: a cumulative sum of the second differences; MTIE: an O(N) running max/min
filter; the classic ADEV/OADEV/MDEV/TOTDEV of gap-free frequency records go through
:func:`analysis.noise.allan.allan_variances` (one chunked pass per τ, analytic ramp handling).
MTOTDEV/TTOTDEV/HTOTDEV: the even reflection makes each subsequence's 6m terms one period of a circular
filter, i.e. a quadratic form zᵀQz with Q Toeplitz + Hankel; summed over subsequences it reduces to the
record's autocorrelation and FFT correlations of the 3m − 1 end samples (:func:`_reflected_sumsq_fft`,
O(N log N) per τ). Theo1: FFT convolutions plus two anti-diagonal triangle sums by divide and conquer
(:func:`_theo1_sumsq_fft`, O(N log N + m log² m)). Both closed forms expand squares into products, so they are
used only where their rounding estimate is below 1e-9 of the variance (and for m ≥ 8 / 64); otherwise, and
with gaps, the exact direct sums (O(N·m) per τ, vectorised) are used. Memory: the classic path about twice the
record; the FFT forms hold a few complex spectra of twice the record length (measured in
benchmarks/bench_noise.py).

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
from numpy.fft import irfft, rfft
from numpy.typing import ArrayLike, NDArray

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
        a = np.ascontiguousarray(np.asarray(a, dtype=np.float64).T)  # (C, n)
        if np.any(np.isinf(a)):
            raise ValueError("record contains ±inf; only NaN marks a gap")
        self.ts = 1.0 / rate
        self.data_type = data_type
        bad = np.isnan(a)
        self.gap_samples = bad.sum(axis=1)
        self.gap_runs = (np.diff(bad.astype(np.int8), axis=1, prepend=0) == 1).sum(axis=1)
        self.has_gaps = bool(bad.any())
        if np.all(bad, axis=1).any():
            raise ValueError("a channel holds no finite sample")
        c = a.shape[0]
        if data_type == "freq":
            self.freq_raw = a
            y = a - np.nanmean(a, axis=1, keepdims=True)
            y[bad] = 0.0
            x = np.empty((c, a.shape[1] + 1))
            x[:, 0] = 0.0
            np.cumsum(y, axis=1, out=x[:, 1:])
            x *= self.ts
            self.x = x
            # bad intervals: prefix count over frequency samples, aligned with phase points
            self.bad_prefix = np.zeros((c, a.shape[1] + 1), dtype=np.int64) if self.has_gaps else None
            if self.has_gaps:
                np.cumsum(bad, axis=1, out=self.bad_prefix[:, 1:])
            self.point_ok = None
        else:
            x = a.copy()
            x[bad] = 0.0
            self.x = x
            self.freq_raw = None
            self.bad_prefix = np.zeros((c, a.shape[1] + 1), dtype=np.int64) if self.has_gaps else None
            if self.has_gaps:
                np.cumsum(bad, axis=1, out=self.bad_prefix[:, 1:])
            self.point_ok = ~bad if self.has_gaps else None
        self.n = self.x.shape[1]

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
        ok = np.ones((self.x.shape[0], len(range(start, start + count, stride))), dtype=bool)
        for o in offsets:
            ok &= self.point_ok[:, start + o : start + o + count : stride]
        return ok

    def frequency(self) -> tuple[NDArray[np.float64], NDArray[np.int64] | None]:
        """Frequency (C, N_f) with gaps zero-filled, and the prefix count of bad frequency samples."""
        if self.data_type == "freq":
            y = self.freq_raw.copy()
            if self.has_gaps:
                y[np.isnan(y)] = 0.0
                return y, self.bad_prefix
            return y, None
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
    for a in range(0, count, step):
        b = min(count, a + step)
        v = coeffs[0] * x[:, a:b:stride]
        for j in range(1, d + 1):
            v += coeffs[j] * x[:, a + offs[j] : b + offs[j] : stride]
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


def _tot_sumsq(rec: _Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Total variance: Σ over centres i = 1 … N−2 of (x*_{i−m} − 2x_i + x*_{i+m})², phase reflected
    (inverted) at both ends; gap terms skipped (their mapped points / span)."""
    x = rec.x
    n = rec.n
    c = x.shape[0]
    i = np.arange(1, n - 1)
    lo = i - m
    hi = i + m

    def refl(j: NDArray[np.int64]) -> NDArray[np.float64]:
        out = np.empty((c, j.size))
        left = j < 0
        right = j > n - 1
        mid = ~(left | right)
        out[:, mid] = x[:, j[mid]]
        out[:, left] = 2.0 * x[:, :1] - x[:, -j[left]]
        out[:, right] = 2.0 * x[:, n - 1 : n] - x[:, 2 * (n - 1) - j[right]]
        return out

    if m > n - 2:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    v = refl(lo) - 2.0 * x[:, 1 : n - 1] + refl(hi)
    if not rec.has_gaps:
        return np.einsum("ij,ij->i", v, v), np.full(c, n - 2, dtype=np.int64)
    if rec.data_type == "phase":
        p = rec.point_ok
        ok = p[:, 1 : n - 1].copy()
        for j in (lo, hi):
            jj = np.where(j < 0, -j, np.where(j > n - 1, 2 * (n - 1) - j, j))
            ok &= p[:, jj]
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
    """
    c, n_s = s.shape
    L = 3 * m
    count = n_s - L + 1
    if count <= 0:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    P = np.zeros((c, n_s + 1))
    np.cumsum(s - s.mean(axis=1, keepdims=True), axis=1, out=P[:, 1:])
    h1 = L // 2
    h2 = L - h1  # ceil
    D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
    P0 = P[:, :count]
    b = ((P[:, L : L + count] - P[:, h2 : h2 + count]) - (P[:, h1 : h1 + count] - P0)) / (h1 * D)

    def q(p: int) -> float:
        return 0.5 * p * (p - 1)

    # F(a) = gz·Ztot + sz·Z(pz); Z(p) = P[p] − P0 − b q(p); Ztot = Z(L)
    def f_parts(a: int) -> tuple[float, float, int]:
        if a <= L:
            return 1.0, -1.0, L - a
        if a <= 2 * L:
            return 1.0, 1.0, a - L
        return 3.0, -1.0, 3 * L - a

    reps: list[tuple[int, float]] = []
    for j in range(0, L // 2 + 1):
        reps.append((j, 1.0 if 2 * j == L else 2.0))
    for j in range(L + 1, (9 * m) // 2 + 1):
        if 2 * j == 9 * m:
            reps.append((j, 1.0))
        elif 2 * j < 9 * m:
            reps.append((j, 2.0))
    ztot = P[:, L : L + count] - P0 - b * q(L)
    acc = np.zeros((c, count))
    for j, w in reps:
        coef_p: dict[int, float] = {}
        g_tot = 0.0
        for k, sign in ((0, -1.0), (1, 3.0), (2, -3.0), (3, 1.0)):
            gz, sz, pz = f_parts(j + k * m)
            g_tot += sign * gz
            coef_p[pz] = coef_p.get(pz, 0.0) + sign * sz
        # Σ_p κ_p Z(p) = Σ κ_p P[p] − (Σκ_p) P0 − b Σ κ_p q(p)
        kappa_sum = sum(coef_p.values())
        qsum = sum(kp * q(p) for p, kp in coef_p.items())
        v = g_tot * ztot
        for p, kp in coef_p.items():
            if kp != 0.0:
                v += kp * P[:, p : p + count]
        if kappa_sum != 0.0:
            v -= kappa_sum * P0
        if qsum != 0.0:
            v -= qsum * b
        acc += w * (v * v)
    if ok is not None:
        acc[~ok] = 0.0
        return acc.sum(axis=1), ok.sum(axis=1)
    return acc.sum(axis=1), np.full(c, count, dtype=np.int64)


def _nfft(n: int) -> int:
    return 1 << int(np.ceil(np.log2(max(n, 2))))

def _xcorr(a: NDArray, b: NDArray, maxlag: int) -> NDArray[np.float64]:
    """Σ_t a_t b_{t+d}, d = 0..maxlag (last axis), zero outside."""
    n = a.shape[-1] + b.shape[-1]
    nf = _nfft(n)
    r = irfft(np.conj(rfft(a, nf)) * rfft(b, nf), nf)
    return r[..., : maxlag + 1]

def _conv(a: NDArray, b: NDArray, nout: int) -> NDArray[np.float64]:
    """Linear convolution along the last axis, first ``nout`` values."""
    nf = _nfft(a.shape[-1] + b.shape[-1])
    return irfft(rfft(a, nf) * rfft(b, nf), nf)[..., :nout]

def _reflected_sumsq_fft(
    s: NDArray[np.float64], m: int, R: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The sum of :func:`_reflected_sumsq` in O(N log N), and an error scale (≈ ε × the largest summand / E).

    Per subsequence the 6m terms are one period of a circular filter of the even extension z (period 6m), so
    Σ_j c_j² = zᵀQz with Q_kl = 2[ρ(k−l) + ρ(k+l+1)], ρ the circular autocorrelation of the kernel
    (1…1, −2…−2, 1…1). With z = X_i − b_i k (X_i the window, b_i its half-mean slope):
    Σ_i zᵀQz = Σ_i X_iᵀQX_i − 2 Σ_i b_i (Qk)·X_i + kᵀQk Σ_i b_i². The Toeplitz part of the first sum is
    Σ_d ρ(d) × (the record's autocorrelation R_d times the window count, less head and tail corrections that
    are weighted autocorrelations of the first and last 3m − 1 samples); the Hankel part sums, for each pair
    (u, v), ρ over t = u + v + 1 − 2i of every window i holding both, which in the interior depends only on
    |u − v| (same-parity cumulative sums of ρ) and at the two ends on u + v (self-convolutions of the end
    segments). Everything is FFT correlation: O(N log N) per τ given R.
    """
    c, ls = s.shape
    L = 3 * m
    M = ls - L + 1
    P = 6 * m
    s = s - s.mean(axis=1, keepdims=True)
    w = np.zeros(P)
    w[:m] = 1.0
    w[m : 2 * m] = -2.0
    w[2 * m : 3 * m] = 1.0
    W = rfft(w)
    rho = irfft(W * np.conj(W), P)
    # same-parity cumulative sums, RC[t+2] = Rc(t)
    RC = np.zeros(P + 2)
    RC[2::2] = np.cumsum(rho[0::2])
    RC[3::2] = np.cumsum(rho[1::2])

    def Rc(t: NDArray | int) -> NDArray:  # noqa: N802 - the paper's R_c
        return RC[np.asarray(t) + 2]

    d = np.arange(L)
    Hd = Rc(2 * L - 1 - d) - Rc(d - 1)
    wd = np.where(d == 0, 1.0, 2.0)
    Rd = R[:, :L]
    h = s[:, : L - 1]
    g = s[:, M:]
    t = np.arange(L - 1, dtype=float)
    A = _xcorr(h, h, L - 1)
    B = _xcorr(t * h, h, L - 1)
    A2 = _xcorr(g, g, L - 1)
    B2 = _xcorr(t * g, g, L - 1)
    for arr in (A, B, A2, B2):
        arr[:, L - 1 :] = 0.0  # lags beyond the segment
    Td = (L - d) * Rd - ((L - 1 - d) * A - B) - (B2 + A2)
    TT = 2.0 * (Td * (wd * rho[:L])).sum(axis=1)
    ch = _conv(h, h, 2 * L - 3) if L >= 2 else np.zeros((c, 0))
    cg = _conv(g, g, 2 * L - 3) if L >= 2 else np.zeros((c, 0))
    sig = np.arange(ch.shape[1])
    head = (A * (wd * Rc(2 * L - 1 - d))).sum(axis=1) - (ch * Rc(sig + 1)).sum(axis=1)
    tail = (cg * Rc(sig + 1)).sum(axis=1) - (A2 * (wd * Rc(d - 1))).sum(axis=1)
    HK = 2.0 * ((Rd * (wd * Hd)).sum(axis=1) - head - tail)
    T1 = TT + HK
    # detrend terms
    Ps = np.zeros((c, ls + 1))
    np.cumsum(s, axis=1, out=Ps[:, 1:])
    h1 = L // 2
    h2 = L - h1
    D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
    b = ((Ps[:, L:L+M] - Ps[:, h2:h2+M]) - (Ps[:, h1:h1+M] - Ps[:, :M])) / (h1 * D)
    lv = np.arange(L, dtype=float)
    kern = rho[np.abs(np.arange(2 * L - 1) - (L - 1))]
    t1 = _conv(kern, lv, 2 * L - 1)[L - 1 : 2 * L - 1]
    rr = rho[1 : 2 * L] if 2 * L <= P else np.concatenate([rho[1:], rho[:2*L-P]])
    t2 = _conv(rr, lv[::-1], 2 * L - 1)[L - 1 : 2 * L - 1]
    q = 2.0 * (t1 + t2)
    kqk = float(lv @ q)
    u = _conv(s, q[::-1][None, :], ls)[:, L - 1 : L - 1 + M]
    E = T1 - 2.0 * (b * u).sum(axis=1) + kqk * (b * b).sum(axis=1)
    scale = 4.0 * L * abs(rho[0]) * R[:, 0] + 2.0 * np.abs(b * u).sum(axis=1) + abs(kqk) * (b * b).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        err = 1.1e-16 * scale / np.abs(E)
    return E, err


_FFT_MIN_M = 8
"""Below this m the direct O(N·m) evaluation is cheap and exact; above it the O(N log N) form is tried."""
_FFT_MAX_ERR = 1e-9
"""Largest estimated relative rounding error of the variance accepted from the FFT form (else the direct sum is
used): far below any confidence interval (a relative half-width of 1e-9 would need EDF ≈ 1e18)."""


def _kernel_rho(m: int) -> NDArray[np.float64]:
    """Circular autocorrelation (period 6m) of the modified-total kernel (1…1, −2…−2, 1…1)."""
    p = 6 * m
    w = np.zeros(p)
    w[:m] = 1.0
    w[m : 2 * m] = -2.0
    w[2 * m : 3 * m] = 1.0
    wf = rfft(w)
    return irfft(wf * np.conj(wf), p)


def _q_apply(rho: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Q v with Q_kl = 2[ρ(k−l) + ρ(k+l+1)], k, l < L = len(v) (FFT products)."""
    L = v.size
    kern = rho[np.abs(np.arange(2 * L - 1) - (L - 1))]
    t1 = _conv(kern, v, 2 * L - 1)[L - 1 : 2 * L - 1]
    t2 = _conv(rho[1 : 2 * L], v[::-1], 2 * L - 1)[L - 1 : 2 * L - 1]
    return 2.0 * (t1 + t2)


def _total_sumsq(
    s: NDArray[np.float64], m: int, ok: NDArray[np.bool_] | None, cache: dict, key: str
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`_reflected_sumsq` through the O(N log N) form when the record has no gaps, m ≥ 8 and its
    rounding estimate is below :data:`_FFT_MAX_ERR`; otherwise directly.

    For the dynamic range the record's least-squares quadratic a t² + … is removed first: each subsequence is
    detrended, so the line changes nothing and the quadratic adds the same vector r = a(k² − βk) to every
    detrended window (β its half-mean slope); its terms 2 Σ_i rᵀQz_i + M rᵀQr are added back exactly."""
    c, n_s = s.shape
    count = n_s - 3 * m + 1
    if ok is None and m >= _FFT_MIN_M and count > 0:
        if key not in cache:
            t = (np.arange(n_s, dtype=np.float64) - 0.5 * (n_s - 1)) / max(n_s, 1)
            basis = np.vstack([np.ones(n_s), t, t * t - np.mean(t * t)])
            coef = np.linalg.lstsq(basis.T, s.T, rcond=None)[0]  # (3, C)
            sd = s - coef.T @ basis
            a = coef[2] / max(n_s, 1) ** 2  # quadratic coefficient per sample²
            cache[key] = (sd, _xcorr(sd, sd, n_s - 1), a)
        sd, r, a = cache[key]
        e, err = _reflected_sumsq_fft(sd, m, r)
        if np.any(a != 0.0):
            L = 3 * m
            k = np.arange(L, dtype=np.float64)
            h1 = L // 2
            h2 = L - h1
            D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
            beta = ((k[h2:] ** 2).mean() - (k[:h1] ** 2).mean()) / D
            r1 = k * k - beta * k
            qr1 = _q_apply(_kernel_rho(m), r1)
            ps = np.zeros((c, n_s + 1))
            np.cumsum(sd, axis=1, out=ps[:, 1:])
            win = ps[:, count : count + L] - ps[:, :L]  # Σ_i sd[i + k]
            bsum = (
                (ps[:, L : L + count] - ps[:, h2 : h2 + count]) - (ps[:, h1 : h1 + count] - ps[:, :count])
            ).sum(axis=1) / (h1 * D)
            zsum = win - np.outer(bsum, k)
            cross = 2.0 * a * (zsum @ qr1)
            square = count * a * a * float(r1 @ qr1)
            e = e + cross + square
            with np.errstate(divide="ignore", invalid="ignore"):
                err = err + 1.1e-16 * 8.0 * (np.abs(cross) + np.abs(square)) / np.abs(e)
        if np.all(err < _FFT_MAX_ERR):
            return e, np.full(c, count, dtype=np.int64)
    return _reflected_sumsq(s, m, ok)


def _theo1_sumsq(rec: _Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Σ_i Σ_{δ<m/2} [(x_i − x_{i+m/2−δ}) + (x_{i+m} − x_{i+m/2+δ})]² / (m/2 − δ), i = 0 … N−m−1."""
    x = rec.x
    n = rec.n
    c = x.shape[0]
    count = n - m
    h = m // 2
    if count <= 0 or m % 2:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    base = x[:, :count] + x[:, m : m + count]
    acc = np.zeros((c, count))
    for dlt in range(h):
        e = base - x[:, h - dlt : h - dlt + count]
        e -= x[:, h + dlt : h + dlt + count]
        e *= e
        acc += e * (1.0 / (h - dlt))
    ok = rec.span_ok(0, count, m)
    if ok is not None:
        acc[~ok] = 0.0
        return acc.sum(axis=1), ok.sum(axis=1) * h
    return acc.sum(axis=1), np.full(c, count * h, dtype=np.int64)

_TRI_BASE = 96
"""Triangle size below which :func:`_tri` sums directly."""


def _tri(a: NDArray, b: NDArray, g: NDArray, off: int, n: int, gz: int) -> NDArray[np.float64]:
    """Σ over u, v ∈ [0, n) with u + v < n of a_u b_v g[v − u + off + gz], per channel, in O(n log² n).

    Divide and conquer on the anti-diagonal triangle: the square [0, n/2)² is a cross-correlation (FFT), the
    two remaining strips are triangles of half the size (recursion), and for odd n the centre point.
    """
    if n <= 0:
        return np.zeros(a.shape[0])
    if n <= _TRI_BASE:
        u = np.arange(n)
        wmat = g[(u[None, :] - u[:, None]) + off + gz] * ((u[:, None] + u[None, :]) < n)
        return np.einsum("cu,uv,cv->c", a[:, :n], wmat, b[:, :n])
    k = n // 2
    nf = _nfft(2 * k)
    cc = irfft(np.conj(rfft(a[:, :k], nf)) * rfft(b[:, :k], nf), nf)
    d = np.arange(-(k - 1), k)
    tot = (cc[:, d % nf] * g[d + off + gz]).sum(axis=1)
    r = n - k
    a2 = np.zeros((a.shape[0], r))
    a2[:, :k] = a[:, :k]
    tot += _tri(a2, b[:, k:n], g, off + k, r, gz)
    b2 = np.zeros((b.shape[0], r))
    b2[:, :k] = b[:, :k]
    tot += _tri(a[:, k:n], b2, g, off - k, r, gz)
    if n % 2:
        tot += a[:, k] * b[:, k] * g[off + gz]
    return tot


def _theo1_sumsq_fft(
    x: NDArray[np.float64], m: int, r: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Theo1's double sum in O(N log N + m log² m), and a rounding-error scale (see :func:`_theo1_sumsq`).

    With c = i + m/2 and A_c = x_{c−m/2} + x_{c+m/2}, each term is (A_c − x_{c−δ} − x_{c+δ})²/(m/2 − δ); summed
    over δ it is W A_c² − 2 A_c (k∗x)_c + (k∗x²)_c + 2 Σ_δ w_δ x_{c−δ} x_{c+δ} with k the symmetric kernel of the
    weights w_δ = 1/(m/2 − δ). The convolutions are FFTs; the last sum over c is Σ_δ w_δ R_{2δ} (the record's
    autocorrelation) less two anti-diagonal triangles of the first and of the reversed last m − 1 samples
    (:func:`_tri`).
    """
    c, n = x.shape
    h = m // 2
    count = n - m
    dl = np.arange(h)
    w = 1.0 / (h - dl)
    wsum = float(w.sum())
    a_c = x[:, :count] + x[:, m : m + count]
    kern = np.zeros(m - 1)
    kern[h - 1 - dl] = w
    kern[h - 1 + dl] = w
    kern[h - 1] = 2.0 * w[0]
    k_c = _conv(x, kern[None, :], n + m - 2)[:, 2 * h - 1 : 2 * h - 1 + count]
    q_c = _conv(x * x, kern[None, :], n + m - 2)[:, 2 * h - 1 : 2 * h - 1 + count]
    t1 = wsum * np.einsum("ij,ij->i", a_c, a_c)
    t2 = 2.0 * np.einsum("ij,ij->i", a_c, k_c)
    t3 = q_c.sum(axis=1)
    s4 = (r[:, 2 * dl] * w).sum(axis=1)
    gz = 2 * m + 2
    g = np.zeros(4 * m + 5)
    g[gz + 2 * dl] = w
    head = x[:, : m - 1]
    tail = x[:, ::-1][:, : m - 1]
    s4 -= _tri(head, head, g, 0, m - 1, gz) + _tri(tail, tail, g, 0, m - 1, gz)
    v = t1 - t2 + t3 + 2.0 * s4
    with np.errstate(divide="ignore", invalid="ignore"):
        err = 1.1e-16 * 8.0 * (t1 + np.abs(t2) + t3 + 2.0 * wsum * r[:, 0]) / np.abs(v)
    return v, err


def _theo1_total(rec: _Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Theo1 sums: the O(N log N) form for gap-free records with m ≥ 64 when its rounding estimate is below
    :data:`_FFT_MAX_ERR`, else :func:`_theo1_sumsq`."""
    n = rec.n
    if not rec.has_gaps and m >= 64 and m % 2 == 0 and n - m > 0:
        if "R_theo" not in cache:
            # Theo1 is blind to a line in the phase, and a quadratic a t² adds exactly 2a(h² − δ²) to every
            # term: remove the least-squares quadratic for the dynamic range and add its terms back below
            t = (np.arange(n, dtype=np.float64) - 0.5 * (n - 1)) / n
            basis = np.vstack([np.ones(n), t, t * t - np.mean(t * t)])
            coef = np.linalg.lstsq(basis.T, rec.x.T, rcond=None)[0]
            xd = rec.x - coef.T @ basis
            cache["R_theo"] = (xd, _xcorr(xd, xd, n - 1), coef[2] / float(n) ** 2)
        xd, r, a = cache["R_theo"]
        v, err = _theo1_sumsq_fft(xd, m, r)
        if np.any(a != 0.0):
            h = m // 2
            count = n - m
            dl = np.arange(h)
            w = 1.0 / (h - dl)
            qd = 2.0 * (h * h - dl * dl.astype(np.float64))
            ps = np.zeros((xd.shape[0], n + 1))
            np.cumsum(xd, axis=1, out=ps[:, 1:])

            def wsum(o: NDArray[np.int64] | int) -> NDArray[np.float64]:
                return ps[:, np.asarray(o) + count] - ps[:, np.asarray(o)]

            esum = wsum(np.zeros(h, dtype=np.int64)) + wsum(np.full(h, m)) - wsum(h - dl) - wsum(h + dl)
            cross = 2.0 * a * (esum @ (w * qd))
            square = count * a * a * float(np.sum(w * qd * qd))
            v = v + cross + square
            with np.errstate(divide="ignore", invalid="ignore"):
                err = err + 1.1e-16 * 8.0 * (np.abs(cross) + np.abs(square)) / np.abs(v)
        if np.all(err < _FFT_MAX_ERR):
            return v, np.full(xd.shape[0], (n - m) * (m // 2), dtype=np.int64)
    return _theo1_sumsq(rec, m)


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
    if name in ("adev", "oadev"):
        s, k = _diff_sumsq(rec, m, (1.0, -2.0, 1.0), m if name == "adev" else 1)
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
        s, k = _tot_sumsq(rec, m)
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
    c = rec.x.shape[0]
    out: dict[str, Estimate] = {}
    cache: dict = {}
    classic = None
    if rec.data_type == "freq" and not rec.has_gaps:
        want = [e for e in ("adev", "oadev", "mdev", "totdev") if e in estimators]
        if want:
            from analysis.noise.allan import allan_variances

            ms = grid[grid <= max(_MAX_M[e](rec.n) for e in want)]
            classic = allan_variances(rec.freq_raw.T, rate, ms / rate, max_m=int(ms.max()) if ms.size else 1)
    key = {"adev": "avar", "oadev": "oavar", "mdev": "mvar", "totdev": "totvar"}
    for name in estimators:
        if name in ("theoh", "theobr"):
            continue
        ms = grid[grid <= _MAX_M[name](rec.n)]
        if name == "theo1":
            ms = ms[ms % 2 == 0]
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


_USE_RN = ESTIMATORS
"""Estimators whose B1 fallback splits phase noise by R(n) = MVAR/AVAR. Stable32 does it only for the modified
and total estimators and calls every B1 phase-noise result flicker PM for the others; that misreads white PM
at long τ (coverage test) — the split costs one MVAR per τ and is used for all."""

_ID_POINTS = 1 << 20
"""Noise identification uses at most this many decimated points per τ (the lag-1 ACF is then exact to ~1e-3)."""


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
    phases: dict[int, NDArray[np.float64]] = {}
    prev: dict[tuple[str, int], int] = {}

    def alpha_of(name: str, ch: int, m: int, dmax: int, n_terms: int, carry: bool = False) -> int:
        if ch not in phases:
            phases[ch] = _id_phase(rec, ch)
        x = phases[ch]
        key = (ch, m, dmax)
        if key not in lag1_cache:
            lag1_cache[key] = ci.lag1_alpha(x[: _ID_POINTS * m], m, dmax)
        a = lag1_cache[key]
        if a is None and carry:
            a = prev.get((name, ch))
        if a is None:
            a = ci.b1_alpha(x, m, rec.ts, n_terms, name in _USE_RN)
        if a is None:
            a = prev.get((name, ch), 0)
        a = int(min(2, max(-2, a)))
        prev[(name, ch)] = a
        return a

    n = rec.n
    for name, est in res.estimates.items():
        if name in ("mtie", "tierms"):
            continue
        mcount, c = est.dev.shape
        alpha = np.zeros((mcount, c), dtype=np.int64)
        e = np.full((mcount, c), np.nan)
        dmax = 3 if name in ("hdev", "ohdev", "htotdev") else 2
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
        est.alpha = alpha
        est.edf = e
        if name in ("totdev", "htotdev"):
            t_rec = (n - 1) * rec.ts
            est.bias = ci.bias_factor(name, alpha, est.m, est.tau, t_rec)
        est.lo, est.hi = ci.chi2_interval(est.unbiased(), e, res.confidence)


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
    c = rec.x.shape[0]
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

    Its intervals use the Theo1 EDF, as Stable32 and W. Riley's TheoBR.cpp do. That ignores the scatter of kf,
    which is set by the long-τ AVAR: simulated (N = 1024, 200 records) TheoBR's actual EDF is about 20 (white FM)
    and 11–28 (random-walk FM) at every m, so the 68 % intervals cover 10–58 % (Theo1's own: 62–71 %).
    TheoH uses TheoBR only at τ ≥ 0.2 T, where the Theo1 EDF (8–19) is about twice the actual one."""
    kf = _theobr_factor(rec, cache)
    ms = grid[(grid % 2 == 0) & (grid <= _MAX_M["theobr"](rec.n))]
    c = rec.x.shape[0]
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
    c = rec.x.shape[0]
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
