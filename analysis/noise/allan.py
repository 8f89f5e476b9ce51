"""Allan-family variances of rate / specific-force records, with EDF and χ² confidence intervals.

Estimators (``/work/shared/spec/noise-variance.md``; IEEE 952 / IEEE 1293 and NIST SP 1065 where the spec is
silent), for a record Ω_1..Ω_N sampled every T_s (any SI rate unit: rad/s for gyros, m/s² for accelerometers),
τ = m T_s, and the phase (integrated record, rad or m/s) x_0 = 0, x_j = x_{j-1} + Ω_j T_s:

- ``avar``  non-overlapping Allan variance, K = ⌊N/m⌋ blocks, K−1 block-mean differences;
- ``oavar`` overlapping Allan variance (stride 1), N+1−2m second differences of x;
- ``totvar`` total variance (Howe): the phase extended by inverted reflection at both ends, second differences
  centred on the N−1 interior points;
- ``mvar``  modified Allan variance (SP 1065 eq. 14), N+2−3m terms.

They equal allantools ``adev``/``oadev``/``totdev``/``mdev`` with ``data_type='freq'`` (squared).

Implementation
--------------
One pass per τ over the phase, in cache-sized chunks, vectorised over the channels: the second differences
d_i = x_{i+2m} − 2x_{i+m} + x_i serve the overlapping AVAR, the central part of the total variance (whose
remaining O(m) reflected edge terms are evaluated separately from slices) and the modified AVAR — on an
octave grid from moving sums of the phase, doubled in place from one τ to the next (one add per sample per
τ), otherwise from a running sum of d over each chunk; the non-overlapping AVAR is the strided subset. The
chunk temporaries are two preallocated buffers (no allocation per chunk) and the plain sums Σd, Σs telescope to
O(m) end sums, so a pass is two differences and one product-sum per estimator. Cost O(N) per τ; memory two
float64 arrays of N+1 per channel (phase and moving sums) plus O(chunk) temporaries, i.e. about twice the
record (measured in benchmarks/bench_noise.py).

Precision: before integration the least-squares line (mean and rate ramp) is removed from each channel and
its contribution is added back analytically (a ramp r adds exactly r τ² to every central second difference,
and a known quadratic, 2m² − 2(m−i)₊² − 2(i+m−N)₊², to the reflected edge terms). The phase therefore
stays a zero-mean random walk and rounding stays at the ε·√N level (≈1e-12 relative for 10⁸ samples), even
for records dominated by a ramp, where a plain cumulative sum loses ε·(T/τ)².

Since issue 16 the whole stability family, its noise identification (lag-1 ACF / B1 / R(n)), Greenhall EDF and
χ² intervals live in :mod:`analysis.noise.stability` and :mod:`analysis.noise.confidence` (used by
``analyse_noise`` and ``tablebench noise``); this module remains the fast gap-free path for the four classic
estimators on frequency data (``stability`` calls it) and the spec's reproduction of the "improved" form. Its
own intervals below are the older approximation, kept for :func:`improved_total_variance`.

Confidence: equivalent degrees of freedom (EDF) per τ from the noise type identified by the local slope of the
AVAR curve (white/flicker PM, white/flicker/random-walk FM), using the SP 1065 approximations for the
overlapping AVAR (non-overlapping: the same with m = 1 on the decimated record, which reproduces the
white-noise scatter √(3/(4(K−1))) of the deviation), Howe's b·T/τ − c for the total variance, and for the
modified AVAR the overlapping formulas on the shortened span (an approximation). χ² intervals follow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

ESTIMATORS: tuple[str, ...] = ("avar", "oavar", "totvar", "mvar")
"""Names of the variance estimators computed by :func:`allan_variances`."""

_CHUNK = 1 << 16
"""Columns per chunk of the per-τ passes (per channel 512 kB of float64 per temporary: near the L2 cache)."""


@dataclass
class AllanResult:
    """Allan-family variances of C channels on M averaging times.

    Attributes
    ----------
    tau : ndarray (M,)
        Averaging times τ = m T_s, s.
    m : ndarray (M,) of int
        Averaging factors.
    rate : float
        Sample rate, Hz.
    n_samples : int
        Record length N.
    var : dict[str, ndarray (M, C)]
        Variance per estimator (``avar``, ``oavar``, ``totvar``, ``mvar``), in (data unit)², NaN where the
        estimator is undefined (too few terms).
    n_terms : dict[str, ndarray (M,)]
        Number of squared differences averaged per τ.
    edf : dict[str, ndarray (M, C)]
        Equivalent degrees of freedom per estimator.
    alpha : ndarray (M, C) of int
        Identified power-law noise type (S_y ∝ f^α: 2 white PM, 1 flicker PM, 0 white FM, −1 flicker FM,
        −2 random-walk FM) used for the EDF.
    confidence : float
        Two-sided probability of the intervals in ``lo``/``hi``.
    lo, hi : dict[str, ndarray (M, C)]
        χ² confidence bounds of the *deviation* per estimator, in the data unit.
    """

    tau: NDArray[np.float64]
    m: NDArray[np.int64]
    rate: float
    n_samples: int
    var: dict[str, NDArray[np.float64]]
    n_terms: dict[str, NDArray[np.int64]]
    edf: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    alpha: NDArray[np.int64] | None = None
    confidence: float = 0.683
    lo: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    hi: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    def dev(self, name: str) -> NDArray[np.float64]:
        """Deviation (square root of the variance ``name``), shape (M, C), data unit."""
        return np.sqrt(self.var[name])


def _as_channels(data: ArrayLike) -> NDArray[np.float64]:
    """Data as an (N, C) float array view (1-D input becomes one channel)."""
    a = np.asarray(data)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise ValueError(f"expected a 1-D record or a 2-D array (samples × channels), got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise ValueError(f"expected real numeric data, got dtype {a.dtype}")
    return a


def tau_grid(
    n_samples: int,
    rate: float,
    taus: str | ArrayLike = "octave",
    points_per_decade: int = 10,
    max_m: int | None = None,
) -> NDArray[np.int64]:
    """Averaging factors m (τ = m / rate) for a record of ``n_samples``.

    Parameters
    ----------
    n_samples : int
        Record length N.
    rate : float
        Sample rate, Hz.
    taus : {"octave", "log", "all"} or array_like
        ``octave``: m = 1, 2, 4, …; ``log``: ``points_per_decade`` log-spaced values (rounded, unique);
        ``all``: every m (O(N²) in total — small records only); an array: τ in seconds, rounded to the
        nearest m like allantools.
    points_per_decade : int
        Density of the ``log`` grid.
    max_m : int, optional
        Largest m kept; default ⌊N/3⌋, where every estimator (also the modified AVAR) is defined.

    Returns
    -------
    ndarray of int64
        Sorted unique averaging factors in [1, max_m].
    """
    n = int(n_samples)
    top = max(1, n // 3) if max_m is None else int(max_m)
    top = min(top, n)
    if isinstance(taus, str):
        kind = taus.lower()
        if kind == "octave":
            m = 2 ** np.arange(int(math.floor(math.log2(top))) + 1, dtype=np.int64)
        elif kind == "log":
            k = int(math.floor(points_per_decade * math.log10(top))) if top > 1 else 0
            m = np.unique(np.rint(10.0 ** (np.arange(k + 1) / points_per_decade)).astype(np.int64))
        elif kind == "all":
            m = np.arange(1, top + 1, dtype=np.int64)
        else:
            raise ValueError(f"unknown τ grid {taus!r}; use 'octave', 'log', 'all' or an array of τ in seconds")
    else:
        t = np.atleast_1d(np.asarray(taus, dtype=np.float64))
        if not np.all(np.isfinite(t)) or np.any(t <= 0):
            raise ValueError("τ values must be positive finite seconds")
        m = np.unique(np.rint(t * rate).astype(np.int64))
    m = m[(m >= 1) & (m <= top)]
    return m


def _detrend_and_integrate(a: NDArray, ts: float, chunk: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Phase of the detrended record and the removed ramp per sample.

    Returns
    -------
    x : ndarray (C, N+1)
        x_0 = 0, x_j = T_s Σ_{k≤j} e_k with e the record minus its least-squares line.
    r_s : ndarray (C,)
        Slope of the removed line, data unit per sample.
    """
    n, c = a.shape
    kbar = (n - 1) / 2.0
    s0 = np.zeros(c)
    s1 = np.zeros(c)
    big = max(chunk, 1 << 16)
    for s in range(0, n, big):
        e = min(n, s + big)
        blk = np.asarray(a[s:e], dtype=np.float64)
        s0 += blk.sum(axis=0)
        # einsum, not matmul: BLAS threads on a busy machine cost more than this O(N) reduction
        s1 += np.einsum("i,ij->j", np.arange(s, e, dtype=np.float64) - kbar, blk)
    mean = s0 / n
    skk = n * (n * n - 1.0) / 12.0
    r_s = s1 / skk if n > 1 else np.zeros(c)
    x = np.empty((c, n + 1))
    x[:, 0] = 0.0
    carry = np.zeros(c)
    for s in range(0, n, big):
        e = min(n, s + big)
        blk = np.ascontiguousarray(np.asarray(a[s:e], dtype=np.float64).T) - mean[:, None]
        blk -= r_s[:, None] * (np.arange(s, e, dtype=np.float64) - kbar)
        np.cumsum(blk, axis=1, out=x[:, s + 1 : e + 1])
        x[:, s + 1 : e + 1] += carry[:, None]
        carry = x[:, e].copy()
    x *= ts
    return x, r_s


def _reflected_range(x: NDArray[np.float64], a: int, b: int) -> NDArray[np.float64]:
    """x*_idx for the contiguous indices a ≤ idx ≤ b of the phase extended by inverted reflection.

    x has N+1 columns (x_0 … x_N); x*_{−j} = 2x_0 − x_j and x*_{N+j} = 2x_N − x_{N−j}, for a ≥ −N, b ≤ 2N − 1.
    Built from at most three (reversed) slices: no index arrays.
    """
    n = x.shape[1] - 1
    parts = []
    if a < 0:
        b1 = min(b, -1)
        parts.append(2.0 * x[:, :1] - x[:, -a : -b1 - 1 : -1])  # stop −b1−1 ≥ 0
    lo, hi = max(a, 0), min(b, n)
    if lo <= hi:
        parts.append(x[:, lo : hi + 1])
    if b > n:
        a3 = max(a, n + 1)
        parts.append(2.0 * x[:, n : n + 1] - x[:, 2 * n - a3 : 2 * n - b - 1 : -1])  # stop ≥ 0
    return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)


def _edge_sum(x: NDArray[np.float64], m: int, lo: int, hi: int, half_a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ over centres lo ≤ i ≤ hi of the squared reflected second differences x*_{i−m} − 2x_i + x*_{i+m},
    plus the removed ramp's exact contribution half_a·(2m² − 2·max(m−i, 0)² − 2·max(i+m−N, 0)²)."""
    n = x.shape[1] - 1
    out = np.zeros(x.shape[0])
    for a in range(lo, hi + 1, _CHUNK):
        b = min(hi, a + _CHUNK - 1)
        d = _reflected_range(x, a - m, b - m) + _reflected_range(x, a + m, b + m)
        d -= 2.0 * x[:, a : b + 1]
        if np.any(half_a != 0.0):
            i = np.arange(a, b + 1, dtype=np.float64)
            dq = 2.0 * m * m - 2.0 * np.maximum(m - i, 0.0) ** 2 - 2.0 * np.maximum(i + m - n, 0.0) ** 2
            d += half_a[:, None] * dq[None, :]
        out += np.einsum("ij,ij->i", d, d)
    return out


def _range_sum(x: NDArray[np.float64], a: int, b: int) -> NDArray[np.float64]:
    """Σ_{a ≤ j < b} x_j per channel (zero for an empty range)."""
    return x[:, a:b].sum(axis=1) if b > a else np.zeros(x.shape[0])


def _lag2_sum(x: NDArray[np.float64], m: int, count: int) -> NDArray[np.float64]:
    """Σ_{i<count} (x_{i+2m} − 2x_{i+m} + x_i) per channel by telescoping: O(min(count, m)) columns read."""

    def lag_sum(off: int) -> NDArray[np.float64]:  # Σ_{i<count} (x_{i+off+m} − x_{i+off})
        if count >= m:
            return _range_sum(x, off + count, off + count + m) - _range_sum(x, off, off + m)
        return _range_sum(x, off + m, off + m + count) - _range_sum(x, off, off + count)

    return lag_sum(m) - lag_sum(0)


def _sums_one_m(
    x: NDArray[np.float64], m: int, chunk: int, msum: NDArray[np.float64] | None = None, double: bool = False
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], int, int]:
    """Σd and Σd² of the overlapping second differences d_i = x_{i+2m} − 2x_{i+m} + x_i, and Σs and Σs² of
    their m-sums s_j = d_j + … + d_{j+m−1} (modified AVAR).

    ``msum`` (optional): the moving sums S_j = x_j + … + x_{j+m−1}, then s_j = S_{j+2m} − 2S_{j+m} + S_j;
    otherwise s_j is formed from a running sum of d over the chunk extended by m − 1. The plain sums Σd and
    (with ``msum``) Σs telescope to O(m) end sums; the squares are accumulated chunk by chunk in preallocated
    buffers (no allocation per chunk).

    ``double`` (with ``msum``): leave ``msum`` as the moving sums over 2m (:func:`_double_moving_sum`), each
    chunk doubled right after its last use while it is still in cache (one pass over the record saved per τ).
    """
    c, n1 = x.shape
    n = n1 - 1
    n_o = n + 1 - 2 * m
    n_m = n + 2 - 3 * m
    s2 = np.zeros(c)
    t1 = np.zeros(c)
    t2 = np.zeros(c)
    if n_o <= 0:
        if double and msum is not None:
            _double_moving_sum(msum, m, chunk)
        return np.zeros(c), s2, t1, t2, max(n_o, 0), max(n_m, 0)
    s1 = _lag2_sum(x, m, n_o)
    if n_m > 0 and msum is not None:
        t1 = _lag2_sum(msum, m, n_m)  # before msum is doubled in place below
    top = msum.shape[1] - m if msum is not None else 0
    done = 0  # msum columns [0, done) already doubled
    step = max(chunk, 2 * m) if msum is None else chunk
    width = min(n_o, step) + (m - 1 if msum is None else 0)
    buf1 = np.empty((c, 2 * width if width > m else 0))
    buf2 = np.empty((c, width))
    for s in range(0, n_o, step):
        e = min(n_o, s + step)
        ee = min(n_o, e + m - 1) if (n_m > 0 and msum is None) else e
        k = ee - s
        d = buf2[:, :k]
        if k <= m:
            np.add(x[:, s + 2 * m : ee + 2 * m], x[:, s:ee], out=d)
            d -= x[:, s + m : ee + m]
            d -= x[:, s + m : ee + m]
        else:  # first differences at lag m, then their difference: two passes instead of three
            d1 = buf1[:, : k + m]
            np.subtract(x[:, s + m : ee + 2 * m], x[:, s : ee + m], out=d1)
            np.subtract(d1[:, m:], d1[:, :k], out=d)
        dc = d[:, : e - s]
        s2 += np.einsum("ij,ij->i", dc, dc)
        if n_m > 0 and s < n_m:
            kk = min(e, n_m) - s
            if msum is not None:
                inner = buf2[:, :kk]
                if m == 1 and k > m and kk <= k:  # S_1 is x itself: inner = d and g1 = d1, bit for bit
                    g1 = d1
                elif kk <= m:
                    np.add(msum[:, s + 2 * m : s + 2 * m + kk], msum[:, s : s + kk], out=inner)
                    inner -= msum[:, s + m : s + m + kk]
                    inner -= msum[:, s + m : s + m + kk]
                else:
                    g1 = buf1[:, : kk + m]
                    np.subtract(msum[:, s + m : s + 2 * m + kk], msum[:, s : s + m + kk], out=g1)
                    np.subtract(g1[:, m:], g1[:, :kk], out=inner)
                if double:  # columns < s + kk are not read again at this m (later chunks start at s + kk)
                    hi = min(top, s + kk)
                    if hi > done:
                        if kk > m and done == s:  # S_2m(j) = 2 S_m(j) + (S_m(j+m) − S_m(j)): g1 is in cache
                            blk = msum[:, s:hi]
                            blk *= 2.0
                            blk += g1[:, : hi - s]
                        else:
                            msum[:, done:hi] += msum[:, done + m : hi + m]
                        done = hi
            else:
                cs = np.cumsum(d, axis=1)
                inner = cs[:, m - 1 : m - 1 + kk].copy()
                inner[:, 1:] -= cs[:, : kk - 1]
                t1 += inner.sum(axis=1)
            t2 += np.einsum("ij,ij->i", inner, inner)
    if double and msum is not None:
        _double_moving_sum(msum, m, chunk, start=done)  # the columns not doubled in the loop
    return s1, s2, t1, t2, n_o, max(n_m, 0)


def _double_moving_sum(msum: NDArray[np.float64], m: int, chunk: int, start: int = 0) -> None:
    """In place: moving sums over m → over 2m (S_{2m}(j) = S_m(j) + S_m(j+m)), ascending chunks, from column
    ``start`` on (the columns before it already doubled)."""
    top = msum.shape[1] - m
    for s in range(start, top, chunk):
        e = min(top, s + chunk)
        msum[:, s:e] += msum[:, s + m : e + m]
    msum[:, top:] = np.nan  # windows that run past the record are undefined


def allan_variances(
    data: ArrayLike,
    rate: float,
    taus: str | ArrayLike = "octave",
    *,
    points_per_decade: int = 10,
    max_m: int | None = None,
    confidence: float = 0.683,
    chunk: int = _CHUNK,
) -> AllanResult:
    """Non-overlapping, overlapping, total and modified Allan variances with EDF and confidence intervals.

    Parameters
    ----------
    data : array_like (N,) or (N, C)
        Rate or specific-force record, one column per channel (any frame: each channel is analysed on its
        own), SI unit u (rad/s, m/s²); must be finite.
    rate : float
        Sample rate 1/T_s, Hz.
    taus : {"octave", "log", "all"} or array_like
        τ grid, see :func:`tau_grid`.
    points_per_decade : int
        Density of the ``log`` grid.
    max_m : int, optional
        Largest averaging factor (default ⌊N/3⌋).
    confidence : float
        Two-sided probability of the χ² intervals (default 0.683, "1σ").
    chunk : int
        Columns per chunk (tuning only).

    Returns
    -------
    AllanResult
        Variances in u², deviations via ``result.dev(name)``.
    """
    a = _as_channels(data)
    n, c = a.shape
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"sample rate must be a positive number of Hz, got {rate}")
    if n < 4:
        raise ValueError(f"record too short for Allan variance: {n} samples (need at least 4)")
    if not np.all(np.isfinite(a)):
        raise ValueError("record contains NaN or inf; remove or interpolate them before the analysis")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    ts = 1.0 / rate
    ms = tau_grid(n, rate, taus, points_per_decade, max_m)
    if ms.size == 0:
        raise ValueError(f"no averaging time of the requested grid fits a record of {n} samples at {rate} Hz")
    x, r_s = _detrend_and_integrate(a, ts, chunk)
    half_a = 0.5 * ts * r_s  # x_ramp(j) = half_a (j² + j) + linear: a quadratic in the phase
    nm = ms.size
    var = {k: np.full((nm, c), np.nan) for k in ESTIMATORS}
    nterm = {k: np.zeros(nm, dtype=np.int64) for k in ESTIMATORS}
    octave = bool(np.all(ms & (ms - 1) == 0))  # all powers of two: modified AVAR by moving-sum doubling
    msum = x.copy() if octave and int(ms.max()) * 3 <= n + 2 else None
    m_cur = 1
    for j, m in enumerate(ms):
        m = int(m)
        tau = m * ts
        cr = 2.0 * half_a * m * m  # exact central second difference of the removed ramp (phase units)
        # non-overlapping: strided subset
        k = n // m - 1
        if k >= 1 and m > 1:  # at m = 1 the non-overlapping terms are the overlapping ones (copied below)
            a1 = np.zeros(c)
            a2 = np.zeros(c)
            for k0 in range(0, k, chunk):
                xd = x[:, k0 * m : (min(k, k0 + chunk) + 1) * m + 1 : m]
                d = xd[:, 2:] + xd[:, :-2]
                d -= 2.0 * xd[:, 1:-1]
                a1 += d.sum(axis=1)
                a2 += np.einsum("ij,ij->i", d, d)
            tot = a2 + 2.0 * cr * a1 + k * cr * cr
            var["avar"][j] = tot / (2.0 * tau * tau * k)
            nterm["avar"][j] = k
        fuse = False
        if msum is not None:
            while m_cur < m:
                _double_moving_sum(msum, m_cur, chunk)
                m_cur *= 2
            fuse = j + 1 < nm and int(ms[j + 1]) == 2 * m  # the next τ needs the sums over 2m
        s1, s2, t1, t2, n_o, n_m = _sums_one_m(x, m, chunk, msum, double=fuse)
        if fuse:
            m_cur = 2 * m
        if n_o > 0:
            central = s2 + 2.0 * cr * s1 + n_o * cr * cr
            var["oavar"][j] = central / (2.0 * tau * tau * n_o)
            nterm["oavar"][j] = n_o
            if m == 1:
                var["avar"][j], nterm["avar"][j] = var["oavar"][j], n_o
        else:
            central = np.zeros(c)
        if n_m > 0:
            tot = t2 + 2.0 * m * cr * t1 + n_m * (m * cr) ** 2
            var["mvar"][j] = tot / (2.0 * m * m * tau * tau * n_m)
            nterm["mvar"][j] = n_m
        if m <= n and n >= 3:
            left_end = min(m - 1, n - 1)
            edge = _edge_sum(x, m, 1, left_end, half_a)
            edge += _edge_sum(x, m, max(n - m + 1, left_end + 1), n - 1, half_a)
            var["totvar"][j] = (central + edge) / (2.0 * tau * tau * (n - 1))
            nterm["totvar"][j] = n - 1
    del msum
    res = AllanResult(ms * ts, ms, float(rate), n, var, nterm, confidence=confidence)
    _attach_confidence(res)
    return res


# ----------------------------------------------------------------------------------------------- EDF / χ²


def _window_slope(y: NDArray[np.float64], x: NDArray[np.float64], half: int = 2) -> NDArray[np.float64]:
    """Least-squares slope dy/dx over a window of ±``half`` grid points (truncated at the ends), per column."""
    m = x.size
    out = np.full(y.shape, np.nan)
    for i in range(m):
        lo, hi = max(0, i - half), min(m, i + half + 1)
        xs = x[lo:hi]
        ys = y[lo:hi]
        xc = xs - xs.mean()
        den = float(xc @ xc)
        if den > 0:
            ok = np.all(np.isfinite(ys), axis=0)
            yf = np.where(ok, ys, 0.0)
            yc = np.where(ok, yf - yf.mean(axis=0), 0.0)
            out[i] = np.where(ok, xc @ yc / den, np.nan)
    return out


def identify_alpha(res: AllanResult) -> NDArray[np.int64]:
    """Power-law noise type per τ and channel from the local log-log slopes of the AVAR and MVAR curves.

    The slope μ of σ²(τ) ∝ τ^μ (least squares over ±2 grid points) gives α = −μ − 1 for random-walk, flicker
    and white FM (μ = 1, 0, −1); for μ ≈ −2 the modified AVAR slope separates white PM (−3) from flicker PM
    (−2). Slopes steeper than +1 (rate ramp) are treated as random-walk FM. For a sum of power laws the
    dominant α cannot increase with τ, so α is made non-increasing along τ (this also stops the noisy
    long-τ end from being read as phase noise).
    """
    lt = np.log(res.tau)
    m_count = res.tau.size
    c = res.var["oavar"].shape[1]
    if m_count < 2:
        return np.zeros((m_count, c), dtype=np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        lv = np.log(np.where(res.var["oavar"] > 0, res.var["oavar"], np.nan))
        lm = np.log(np.where(res.var["mvar"] > 0, res.var["mvar"], np.nan))
    mu = _window_slope(lv, lt)
    mu_mod = _window_slope(lm, lt)
    alpha = np.rint(-mu - 1.0)
    alpha = np.where(np.isfinite(alpha), alpha, 0.0)
    pm = alpha >= 1
    alpha = np.where(pm, np.where(np.nan_to_num(mu_mod, nan=-3.0) < -2.5, 2, 1), alpha)
    alpha = np.clip(alpha, -2, 2)
    alpha = np.minimum.accumulate(alpha, axis=0)
    return alpha.astype(np.int64)


def edf_oavar(n_phase: ArrayLike, m: ArrayLike, alpha: ArrayLike) -> NDArray[np.float64]:
    """EDF of the overlapping AVAR (NIST SP 1065 Table 5 approximations, after Howe, Allan and Barnes).

    Parameters
    ----------
    n_phase : array_like
        Number of phase points (record samples + 1).
    m : array_like
        Averaging factor.
    alpha : array_like of int
        Noise type (2, 1, 0, −1, −2).
    """
    nn, mm, al = np.broadcast_arrays(
        np.asarray(n_phase, dtype=np.float64), np.asarray(m, dtype=np.float64), np.asarray(alpha)
    )
    out = np.empty(nn.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        wpm = (nn + 1) * (nn - 2 * mm) / (2 * (nn - mm))
        lg = np.log(np.maximum((nn - 1) / (2 * mm), 1.0 + 1e-12)) * np.log(np.maximum((2 * mm + 1) * (nn - 1) / 4, 1.0))
        fpm = np.exp(np.sqrt(np.maximum(lg, 0.0)))
        wfm = (3 * (nn - 1) / (2 * mm) - 2 * (nn - 2) / nn) * 4 * mm**2 / (4 * mm**2 + 5)
        ffm = np.where(mm == 1, 2 * (nn - 2) ** 2 / (2.3 * nn - 4.9), 5 * nn**2 / (4 * mm * (nn + 3 * mm)))
        rwfm = (nn - 2) / mm * ((nn - 1) ** 2 - 3 * mm * (nn - 1) + 4 * mm**2) / (nn - 3) ** 2
    out = np.select([al >= 2, al == 1, al == 0, al == -1], [wpm, fpm, wfm, ffm], rwfm)
    return np.maximum(np.nan_to_num(out, nan=1.0, posinf=1.0), 1.0)


_TOT_BC: dict[int, tuple[float, float]] = {0: (1.5, 0.0), -1: (1.168, 0.222), -2: (0.927, 0.358)}


def _attach_confidence(res: AllanResult) -> None:
    """Fill ``alpha``, ``edf``, ``lo`` and ``hi`` of ``res`` in place."""
    alpha = identify_alpha(res)
    res.alpha = alpha
    n = res.n_samples
    m = res.m[:, None].astype(np.float64)
    k_blocks = (n // res.m)[:, None].astype(np.float64)
    edf = {
        "avar": edf_oavar(k_blocks + 1, 1.0, alpha),
        "oavar": edf_oavar(n + 1, m, alpha),
        "mvar": edf_oavar(np.maximum(n + 1 - m, 4.0), m, alpha),
    }
    tot = edf["oavar"].copy()
    for a_, (b, c_) in _TOT_BC.items():
        tot = np.where(alpha == a_, np.maximum(b * n / m - c_, 1.0), tot)
    edf["totvar"] = tot
    p_lo = 0.5 * (1.0 - res.confidence)
    for name in ESTIMATORS:
        e = np.minimum(edf[name], np.maximum(res.n_terms[name][:, None].astype(np.float64), 1.0))
        res.edf[name] = e
        dev = np.sqrt(res.var[name])
        res.lo[name] = dev * np.sqrt(e / stats.chi2.ppf(1.0 - p_lo, e))
        res.hi[name] = dev * np.sqrt(e / stats.chi2.ppf(p_lo, e))


# ------------------------------------------------------------------------- the published "improved" form


def improved_total_variance(data: ArrayLike, rate: float, taus: str | ArrayLike = "octave") -> AllanResult:
    """The published "improved total variance" (Shi et al. 2012, eqs. 10–11), reproduced for comparison only.

    D_k = (1/m²)[Σ_{i=1}^{m}(Ω*_{km+i} − Ω*_{(k−1)m+i})]² over the non-overlapping m-blocks of the
    reflected record Ω*, and σ²_Atol = Σ_k D_k / (2(2N/m − 2)). The paper's normaliser 2N/m implies a
    reflected record of length 2N; we take it as the record with ⌊N/2⌋ samples mirrored at the start and
    ⌈N/2⌉ at the end (the paper does not state the extension unambiguously).

    This is **not** a better estimator: the mirrored blocks are copies of blocks of the record, so the sum
    repeats terms of the ordinary non-overlapping AVAR instead of adding independent ones — it gains no
    degrees of freedom over AVAR (EDF reported as AVAR's). The bias the paper attributes to the total variance
    comes from differencing raw samples instead of m-averages; the total variance computed properly
    (:func:`allan_variances`, ``totvar``) is unbiased for white noise and keeps more EDF at long τ.

    Returns
    -------
    AllanResult
        With the single estimator ``"itotvar"`` in ``var`` (u²); ``edf``/``lo``/``hi`` as AVAR's.
    """
    a = _as_channels(data)
    n, c = a.shape
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"sample rate must be a positive number of Hz, got {rate}")
    if n < 4:
        raise ValueError(f"record too short: {n} samples (need at least 4)")
    ms = tau_grid(n, rate, taus)
    h0 = n // 2
    h1 = n - h0
    ext = np.concatenate([a[:h0][::-1], a, a[n - h1 :][::-1]], axis=0).astype(np.float64)
    ext -= ext.mean(axis=0)
    cs = np.concatenate([np.zeros((1, c)), np.cumsum(ext, axis=0)], axis=0)
    out = np.full((ms.size, c), np.nan)
    for j, m in enumerate(ms):
        m = int(m)
        sums = cs[::m][: ext.shape[0] // m + 1]
        means = np.diff(sums, axis=0) / m
        dk = np.diff(means, axis=0) ** 2
        denom = 2.0 * (2.0 * n / m - 2.0)
        if dk.shape[0] >= 1 and denom > 0:
            out[j] = dk.sum(axis=0) / denom
    ref = allan_variances(a, rate, ms / rate)
    res = AllanResult(ms / rate, ms, float(rate), n, {"itotvar": out}, {"itotvar": ref.n_terms["avar"]})
    res.alpha = ref.alpha
    res.confidence = ref.confidence
    res.edf["itotvar"] = ref.edf["avar"]
    dev = np.sqrt(out)
    ratio_lo = ref.lo["avar"] / np.sqrt(ref.var["avar"])
    ratio_hi = ref.hi["avar"] / np.sqrt(ref.var["avar"])
    res.lo["itotvar"] = dev * ratio_lo
    res.hi["itotvar"] = dev * ratio_hi
    return res
