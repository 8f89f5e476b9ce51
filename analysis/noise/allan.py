"""Allan-family variances of rate / specific-force records, with EDF and χ² confidence intervals.

Estimators (docs/methods/noise.md; IEEE 952 / IEEE 1293 and NIST SP 1065 where the spec is
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
Channel by channel, in cache-sized chunks: the phase x (the detrended record integrated, in data unit ×
samples: T_s enters only the final normalisation) gives the overlapping second differences
d_j = x_{j+2m} − 2x_{j+m} + x_j (two subtractions per sample, the first at lag m), which serve the overlapping
AVAR, the central part of the total variance (whose O(m) reflected edge terms are evaluated separately from
reversed slices) and, as the strided subset j = 0, m, 2m, …, the non-overlapping AVAR. The modified AVAR's
terms s_j (m-sums of d) are, on an octave grid, one difference of G_m(j) = S_m(j+m) − S_m(j), S_m the moving
sums of m phase points: G_1 is the detrended record itself and G_{2m}(j) = G_m(j) + 2G_m(j+m) + G_m(j+2m) is
formed in place, chunk by chunk (two adds per sample per τ); otherwise s comes from a running sum of d over
each chunk. Up to :data:`LEVELS_PER_PASS` consecutive octaves share one pass over the record, each a chunk
behind the previous, so the chunks are reused while in cache. The plain sums Σd, Σs and the non-overlapping Σd
telescope to O(m) end sums; sums of squares are single-threaded BLAS dot products of 4096 elements; the chunk
temporaries are preallocated. Cost O(N) per τ (about seven vector operations per sample); memory two float64
arrays of N+1 (phase and G, reused channel after channel) plus O(chunk), i.e. about twice one channel of the
record (measured in benchmarks/bench_noise.py); with ``phase=…`` the caller's phase array serves as x.

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


LEVELS_PER_PASS = 8
"""Octave levels sharing one pass over the record (:func:`octave_levels`); tuning only."""

_DOT_BLOCK = 4096
"""Elements per BLAS dot product in :func:`sum_of_products` (OpenBLAS spreads a dot product of more than 10 000
elements over threads, which on a busy machine costs far more than it saves; below that it runs on the calling
thread)."""

vecdot = getattr(np, "vecdot", None)  # numpy ≥ 2.0
_add_reduce = np.add.reduce


def sum_of_products(u: NDArray[np.float64], v: NDArray[np.float64] | None = None) -> float:
    """Σ u·v (Σ u² without ``v``) of 1-D, possibly strided, float64 arrays: single-threaded BLAS dot products of
    :data:`_DOT_BLOCK` elements (about twice as fast as ``einsum``)."""
    k = u.shape[0]
    q = k - k % _DOT_BLOCK
    tot = 0.0
    if q:
        bu = u[:q].reshape(-1, _DOT_BLOCK)
        bv = bu if v is None else v[:q].reshape(-1, _DOT_BLOCK)
        tot = float(_add_reduce(vecdot(bu, bv) if vecdot is not None else np.einsum("ij,ij->i", bu, bv)))
    if k > q:
        r = u[q:]
        tot += float(np.dot(r, r if v is None else v[q:]))
    return tot


def _line(col: NDArray, ks: NDArray[np.float64]) -> tuple[float, float]:
    """Mean and least-squares slope (data unit per sample) of one channel, in chunks of ``ks.size`` samples
    (``ks`` = 0, 1, 2, …); non-finite if the channel holds NaN or ±inf (they propagate into the sums)."""
    n = col.shape[0]
    kbar = (n - 1) / 2.0
    s0 = 0.0
    s1 = 0.0  # Σ (k − k̄) a_k
    for s in range(0, n, ks.size):
        e = min(n, s + ks.size)
        blk = np.asarray(col[s:e], dtype=np.float64)
        t = float(blk.sum())
        s0 += t
        s1 += sum_of_products(blk, ks[: e - s]) + (s - kbar) * t
    skk = n * (n * n - 1.0) / 12.0
    return s0 / n, (s1 / skk if n > 1 else 0.0)


def prefix_sum(v: NDArray[np.float64], out: NDArray[np.float64], scratch: NDArray[np.float64], depth: int = 4) -> None:
    """out_i = v_0 + … + v_i (1-D, ``out`` may be strided; ``scratch`` ≥ len(v) elements, not overlapping either).

    numpy's cumulative sum adds one element after the other (≈ 2.7 ns per element); here the pair sums
    p_i = v_{2i} + v_{2i+1} are summed recursively (``depth`` levels, then numpy's cumulative sum on 1/16 of the
    elements) and the prefix sums interleaved back, out_{2i+1} = P_i and out_{2i} = P_i − v_{2i+1}: ≈ 1 ns per
    element, and the rounding of a pairwise tree instead of a chain."""
    k = v.shape[0]
    if depth == 0 or k < 256:
        np.cumsum(v, out=out)
        return
    if k % 2:
        prefix_sum(v[:-1], out[:-1], scratch, depth)
        out[-1] = out[-2] + v[-1]
        return
    h = k // 2
    p = scratch[:h]
    np.add(v[0::2], v[1::2], out=p)
    prefix_sum(p, out[1::2], scratch[h:], depth - 1)
    np.subtract(out[1::2], v[1::2], out=out[0::2])


def _integrate(
    col: NDArray,
    mean: float,
    r_s: float,
    ks: NDArray[np.float64],
    x: NDArray[np.float64],
    e_out: NDArray[np.float64],
    scratch: NDArray[np.float64],
) -> None:
    """Phase of one channel minus its line, in data unit × samples: x_0 = 0, x_j = Σ_{k<j} e_k with
    e_k = a_k − mean − r_s (k − k̄), written into ``x`` (N+1,); e itself is left in ``e_out`` — (N+1,): all of
    it, the moving-difference array G_1 of the octave passes; or a chunk-sized scratch buffer. ``scratch``: at
    least a chunk, for :func:`prefix_sum`."""
    n = col.shape[0]
    kbar = (n - 1) / 2.0
    big = ks.size
    ramp = r_s * ks
    whole = e_out.shape[0] > n
    x[0] = 0.0
    carry = 0.0
    for s in range(0, n, big):
        e = min(n, s + big)
        blk = e_out[s:e] if whole else e_out[: e - s]
        np.subtract(col[s:e], ramp[: e - s], out=blk)
        blk -= mean + r_s * (s - kbar)
        first = blk[0]
        blk[0] = first + carry  # the running sum carried into the chunk's cumulative sum
        prefix_sum(blk, x[s + 1 : e + 1], scratch)
        blk[0] = first
        carry = float(x[e])
    if whole:
        e_out[n:] = 0.0


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


def edge_sum_general(x: NDArray[np.float64], m: int, lo: int, hi: int, half_a: float, chunk: int) -> float:
    """Σ over centres lo ≤ i ≤ hi of the squared reflected second differences x*_{i−m} − 2x_i + x*_{i+m},
    plus the removed ramp's exact contribution half_a·(2m² − 2·max(m−i, 0)² − 2·max(i+m−N, 0)²); any m ≤ N
    (a centre may reach past both ends). ``x`` is one channel's phase, (N+1,)."""
    n = x.shape[0] - 1
    x2 = x[None, :]
    out = 0.0
    for a in range(lo, hi + 1, chunk):
        b = min(hi, a + chunk - 1)
        d = (_reflected_range(x2, a - m, b - m) + _reflected_range(x2, a + m, b + m))[0]
        d -= 2.0 * x[a : b + 1]
        if half_a != 0.0:
            i = np.arange(a, b + 1, dtype=np.float64)
            d += half_a * (2.0 * m * m - 2.0 * np.maximum(m - i, 0.0) ** 2 - 2.0 * np.maximum(i + m - n, 0.0) ** 2)
        out += sum_of_products(d)
    return out


def edge_sums(x: NDArray[np.float64], m: int, half_a: float, chunk: int, bufs: _Buffers) -> float:
    """Σ of the squared reflected second differences (with the removed ramp's contribution) over the total
    variance's edge centres, 1 ≤ i ≤ m − 1 and N − m + 1 ≤ i ≤ N − 1, of one channel's phase x (N+1,), x_0 = 0.

    For 2m ≤ N each edge centre reaches past one end only: with u = i (left) or N − i (right), 1 ≤ u ≤ m − 1,
    the terms are x_{u+m} − 2x_u − x_{m−u} and 2x_N − x_{N+u−m} − 2x_{N−u} + x_{N−u−m}, and the ramp adds
    half_a·2u(2m − u) to both (reversed slices, no index arrays). Otherwise :func:`edge_sum_general`."""
    n = x.shape[0] - 1
    if n < 3:
        return 0.0
    if 2 * m > n:
        left_end = min(m - 1, n - 1)
        out = edge_sum_general(x, m, 1, left_end, half_a, chunk)
        return out + edge_sum_general(x, m, max(n - m + 1, left_end + 1), n - 1, half_a, chunk)
    out = 0.0
    two_xn = 2.0 * float(x[n])
    ks = bufs.ks
    for u0 in range(1, m, chunk):
        u1 = min(m, u0 + chunk)
        k = u1 - u0
        d = bufs.b2[:k]
        t = bufs.b3[:k]
        if half_a != 0.0:  # q = half_a · 2u(2m − u)
            q = bufs.b1[:k]
            np.add(ks[:k], u0, out=t)  # u
            np.subtract(2.0 * m, t, out=q)
            q *= t
            q *= 2.0 * half_a
        np.subtract(x[u0 + m : u1 + m], x[m - u0 : m - u1 : -1], out=d)  # left: x_{u+m} − x_{m−u}
        d -= x[u0:u1]
        d -= x[u0:u1]
        if half_a != 0.0:
            d += q
        out += sum_of_products(d)
        np.subtract(x[n - m - u0 : n - m - u1 : -1], x[n - m + u0 : n - m + u1], out=d)  # right
        d -= x[n - u0 : n - u1 : -1]
        d -= x[n - u0 : n - u1 : -1]
        d += two_xn
        if half_a != 0.0:
            d += q
        out += sum_of_products(d)
    return out


def _range_sum(x: NDArray[np.float64], a: int, b: int) -> float:
    """Σ_{a ≤ j < b} x_j (zero for an empty range)."""
    return float(x[a:b].sum()) if b > a else 0.0


def lag_sum(x: NDArray[np.float64], m: int, count: int, off: int = 0) -> float:
    """Σ_{i<count} (x_{i+off+m} − x_{i+off}) by telescoping: O(min(count, m)) elements read."""
    if count >= m:
        return _range_sum(x, off + count, off + count + m) - _range_sum(x, off, off + m)
    return _range_sum(x, off + m, off + m + count) - _range_sum(x, off, off + count)


def _lag2_sum(x: NDArray[np.float64], m: int, count: int) -> float:
    """Σ_{i<count} (x_{i+2m} − 2x_{i+m} + x_i) by telescoping."""
    return lag_sum(x, m, count, m) - lag_sum(x, m, count, 0)


class _Buffers:
    """Chunk scratch arrays shared by the passes of one call (no allocation per chunk or per τ)."""

    def __init__(self, chunk: int, width1: int) -> None:
        self.ks = np.arange(chunk, dtype=np.float64)  # 0, 1, …: sample offsets inside a chunk
        self.b1 = np.empty(max(width1, chunk))
        self.b2 = np.empty(chunk)
        self.b3 = np.empty(chunk)
        self._b4: NDArray[np.float64] | None = None

    @property
    def b4(self) -> NDArray[np.float64]:
        """A fourth chunk-sized buffer, allocated on first use (only the passes with m ≥ chunk need it)."""
        if self._b4 is None:
            self._b4 = np.empty(self.b2.size)
        return self._b4


def _second_diff(x: NDArray[np.float64], m: int, s: int, k: int, bufs: _Buffers) -> NDArray[np.float64]:
    """d_j = x_{j+2m} − 2x_{j+m} + x_j for j = s … s+k−1 (k ≤ chunk), in ``bufs.b2``."""
    d = bufs.b2[:k]
    if k > m:  # first differences at lag m (k + m of them, in cache), then their difference
        d1 = bufs.b1[: k + m]
        np.subtract(x[s + m : s + k + 2 * m], x[s : s + k + m], out=d1)
        np.subtract(d1[m:], d1[:k], out=d)
    else:
        t = bufs.b3[:k]
        np.subtract(x[s + 2 * m : s + k + 2 * m], x[s + m : s + k + m], out=d)
        np.subtract(x[s + m : s + k + m], x[s : s + k], out=t)
        d -= t
    return d


def _double_g(g: NDArray[np.float64], m: int, s: int, k: int, bufs: _Buffers) -> None:
    """In place for j = s … s+k−1: G_{2m}(j) = G_m(j) + 2G_m(j+m) + G_m(j+2m), reading G_m up to j + 2m only
    (columns ≥ s + k are still G_m afterwards)."""
    if k > m:
        h = bufs.b1[: k + m]
        np.add(g[s : s + k + m], g[s + m : s + k + 2 * m], out=h)
        np.add(h[:k], h[m : m + k], out=g[s : s + k])
    else:  # 2m ≥ k: the shifted slices do not overlap the written one
        w = g[s : s + k]
        w += g[s + 2 * m : s + k + 2 * m]
        w += g[s + m : s + k + m]
        w += g[s + m : s + k + m]


def octave_levels(
    x: NDArray[np.float64], g: NDArray[np.float64], levels: list[tuple[int, int, bool]], chunk: int, bufs: _Buffers
) -> list[tuple[float, float, float, float]]:
    """One pass over the record for consecutive averaging factors m, 2m, 4m, … of the octave grid, one channel.

    Per level (m, k_avar, double): Σd² over the N + 1 − 2m overlapping second differences d of the phase x,
    Σd² over the non-overlapping subset j = 0, m, …, (k_avar − 1)m, and Σs² and Σs over the N + 2 − 3m
    modified-AVAR terms s_j = G_m(j+m) − G_m(j) (m > 1; at m = 1 the caller takes s = d).

    G_m(j) = S_m(j+m) − S_m(j), with S_m the moving sums of m phase points (G_1 is the detrended record itself):
    s is then one difference, and ``double`` turns G_m into G_{2m} = G_m(j) + 2G_m(j+m) + G_m(j+2m) in place,
    chunk by chunk, for the next level (the moving sums themselves are never formed). Level l works one chunk
    behind level l − 1, whose G it needs up to 2m columns ahead (every level after the first has 2m ≤ chunk):
    the levels of one pass share the chunks while they are still in cache instead of each streaming the record.
    Σs telescopes to Σ G_m over the last m columns (never overwritten: later levels double only lower columns)
    minus the first m (read before this level doubles them).
    """
    n = x.shape[0] - 1
    spans = [(n + 1 - 2 * m, n + 2 - 3 * m if m > 1 else 0, n + 2 - 4 * m if double else 0) for m, _, double in levels]
    acc = [[0.0, 0.0, 0.0, 0.0] for _ in levels]  # Σd², Σd² (non-overlapping), Σs², Σs
    nchunk = -(-max(spans[0][0], 0) // chunk)
    for it in range(nchunk + len(levels) - 1):
        for lv, (m, k_avar, _) in enumerate(levels):
            s = (it - lv) * chunk
            n_o, n_m, n_g = spans[lv]
            if s < 0 or s >= n_o:  # n_o > n_m, n_g
                continue
            sums = acc[lv]
            e = min(n_o, s + chunk)
            d = _second_diff(x, m, s, e - s, bufs)
            sums[0] += sum_of_products(d)
            if m > 1:
                lo = (-s) % m
                hi = min(e - s, k_avar * m - s)
                if hi > lo:
                    sums[1] += sum_of_products(d[lo:hi:m])
            if s < n_m:
                kk = min(e, n_m) - s
                if s == 0:  # the head of Σs's telescoped form, before G_m is doubled
                    sums[3] = -_range_sum(g, 0, m) if n_m >= m else _range_sum(g, m, m + n_m) - _range_sum(g, 0, n_m)
                inner = bufs.b3[:kk]
                np.subtract(g[s + m : s + m + kk], g[s : s + kk], out=inner)
                sums[2] += sum_of_products(inner)
            if s < n_g:
                _double_g(g, m, s, min(e, n_g) - s, bufs)
    for (m, _, _), (_, n_m, _), sums in zip(levels, spans, acc, strict=True):
        if n_m >= m > 1:
            sums[3] += _range_sum(g, n_m, n_m + m)
    return [(a[0], a[1], a[2], a[3]) for a in acc]


def octave_far(
    x: NDArray[np.float64], g: NDArray[np.float64], m: int, k_avar: int, double: bool, chunk: int, bufs: _Buffers
) -> tuple[float, float, float, float]:
    """:func:`octave_levels` for one level with m ≥ chunk, walking the record column by column: for each offset
    block [c, c + w) of the period m, the blocks j = c + t·m + [0, w), t = 0, 1, …, in turn. Consecutive blocks
    then share their lag-m first differences D1(j) = x_{j+m} − x_j and pair sums h(j) = G_m(j) + G_m(j+m):
    d = D1(j+m) − D1(j) and G_{2m}(j) = h(j) + h(j+m) cost one new operation each (three with independent
    chunks), and each step reads one new block of x and of G. Blocks of one column never overlap those of
    another, and G_m(j) is overwritten only after its last use (by this block's s and h)."""
    n = x.shape[0] - 1
    n_o = n + 1 - 2 * m
    n_m = n + 2 - 3 * m
    n_g = n + 2 - 4 * m if double else 0
    s2 = a2 = t2 = 0.0
    t1 = lag_sum(g, m, n_m) if n_m > 0 else 0.0  # Σs telescoped, before G is doubled
    d1a, d1b = bufs.b1[:chunk], bufs.b1[chunk : 2 * chunk]
    ha, hb = bufs.b2, bufs.b3
    d = bufs.b4
    for c in range(0, min(m, max(n_o, 0)), chunk):
        w = min(chunk, m - c, n_o - c)
        np.subtract(x[c + m : c + m + w], x[c : c + w], out=d1a[:w])
        kg = min(w, n_g - c)
        if kg > 0:
            np.add(g[c : c + kg], g[c + m : c + m + kg], out=ha[:kg])
        j0 = c
        while j0 < n_o:
            kd = min(w, n_o - j0)
            nxt = d1b[:kd]
            np.subtract(x[j0 + 2 * m : j0 + 2 * m + kd], x[j0 + m : j0 + m + kd], out=nxt)
            dd = d[:kd]
            np.subtract(nxt, d1a[:kd], out=dd)
            s2 += sum_of_products(dd)
            if c == 0 and j0 < k_avar * m:  # the non-overlapping terms j = 0, m, 2m, …
                a2 += float(dd[0]) ** 2
            if j0 < n_m:
                ki = min(w, n_m - j0)
                inner = d[:ki]
                np.subtract(g[j0 + m : j0 + m + ki], g[j0 : j0 + ki], out=inner)
                t2 += sum_of_products(inner)
            kg = min(w, n_g - j0)
            if kg > 0:
                hn = hb[:kg]
                np.add(g[j0 + m : j0 + m + kg], g[j0 + 2 * m : j0 + 2 * m + kg], out=hn)
                np.add(ha[:kg], hn, out=g[j0 : j0 + kg])
                ha, hb = hb, ha
            d1a, d1b = d1b, d1a
            j0 += m
    return s2, a2, t2, t1


def _general_level(x: NDArray[np.float64], m: int, k_avar: int, chunk: int) -> tuple[float, float, float, float]:
    """Any m, one channel: Σd², the non-overlapping subset's Σd², and Σs, Σs² of the modified-AVAR terms s_j
    (m-sums of d, from a running sum of d over each chunk extended by m − 1)."""
    n = x.shape[0] - 1
    n_o = n + 1 - 2 * m
    n_m = n + 2 - 3 * m
    s2 = a2 = t1 = t2 = 0.0
    if n_o <= 0:
        return s2, a2, t1, t2
    step = max(chunk, 2 * m)
    width = min(n_o, step) + m - 1
    bufs = _Buffers(width, 2 * width)
    for s in range(0, n_o, step):
        e = min(n_o, s + step)
        ee = min(n_o, e + m - 1) if n_m > 0 else e
        d = _second_diff(x, m, s, ee - s, bufs)
        dc = d[: e - s]
        s2 += sum_of_products(dc)
        lo = (-s) % m
        hi = min(e - s, k_avar * m - s)
        if hi > lo:
            a2 += sum_of_products(dc[lo:hi:m])
        if n_m > 0 and s < n_m:
            kk = min(e, n_m) - s
            cs = np.cumsum(d)
            inner = cs[m - 1 : m - 1 + kk].copy()
            inner[1:] -= cs[: kk - 1]
            t1 += float(inner.sum())
            t2 += sum_of_products(inner)
    return s2, a2, t1, t2


def allan_variances(
    data: ArrayLike,
    rate: float,
    taus: str | ArrayLike = "octave",
    *,
    points_per_decade: int = 10,
    max_m: int | None = None,
    confidence: float | None = 0.683,
    chunk: int = _CHUNK,
    phase: NDArray[np.float64] | None = None,
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
    confidence : float or None
        Two-sided probability of the χ² intervals (default 0.683, "1σ"); None: variances only (no noise type,
        EDF or intervals).
    chunk : int
        Samples per chunk of the passes (tuning and tests only).
    phase : ndarray (C, N+1), optional
        Receives each channel's phase x_j = T_s Σ_{k<j} (Ω_k − Ω̄), x_0 = 0 (the record integrated with only its
        mean removed, in u·s); the passes then run in it instead of in a phase array of their own, and the
        removed ramp's phase is added back at the end (no second integration for a caller that needs it).

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
    chunk = max(16, int(chunk))
    bufs = _Buffers(chunk, 2 * chunk)
    lines = [_line(a[:, ch], bufs.ks) for ch in range(c)]
    if not all(math.isfinite(v) for ln in lines for v in ln) and not np.all(np.isfinite(a)):
        raise ValueError("record contains NaN or inf; remove or interpolate them before the analysis")
    if confidence is not None and not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    ts = 1.0 / rate
    ms = tau_grid(n, rate, taus, points_per_decade, max_m)
    if ms.size == 0:
        raise ValueError(f"no averaging time of the requested grid fits a record of {n} samples at {rate} Hz")
    nm = ms.size
    var = {k: np.full((nm, c), np.nan) for k in ESTIMATORS}
    nterm = {k: np.zeros(nm, dtype=np.int64) for k in ESTIMATORS}
    octave = bool(np.all(ms & (ms - 1) == 0))  # all powers of two: G doubled in place from one τ to the next
    if phase is not None and (phase.shape != (c, n + 1) or phase.dtype != np.float64 or not phase.flags.c_contiguous):
        raise ValueError(f"phase must be a C-contiguous float64 array of shape {(c, n + 1)}")
    # phase of one channel at a time (and G): two record-sized arrays in all
    x = np.empty(n + 1) if phase is None else None
    g = np.empty(n + 1) if octave else bufs.b2
    for ch, (mean, r_s) in enumerate(lines):
        xc = x if phase is None else phase[ch]
        _integrate(a[:, ch], mean, r_s, bufs.ks, xc, g, bufs.b1)
        _channel(xc, g if octave else None, r_s, ms, chunk, bufs, var, nterm, ch)
        if phase is not None:
            _add_ramp_phase(xc, r_s, ts, bufs)
    del x, g
    res = AllanResult(ms * ts, ms, float(rate), n, var, nterm, confidence=confidence or 0.683)
    if confidence is not None:
        _attach_confidence(res)
    return res


def _add_ramp_phase(x: NDArray[np.float64], r_s: float, ts: float, bufs: _Buffers) -> None:
    """In place: detrended phase (data unit × samples) → T_s·(x_j + r_s Σ_{k<j} (k − k̄)), the phase with only
    the mean removed; Σ_{k<j} (k − k̄) = j ((j − 1)/2 − k̄), k̄ = (N − 1)/2."""
    n1 = x.shape[0]
    c0 = 1.0 + (n1 - 2)  # 1 + 2k̄
    step = bufs.ks.size
    for s in range(0, n1, step):
        e = min(n1, s + step)
        jj = bufs.b2[: e - s]
        np.add(bufs.ks[: e - s], s, out=jj)
        t = bufs.b3[: e - s]
        np.subtract(jj, c0, out=t)
        t *= jj
        t *= 0.5 * r_s
        seg = x[s:e]
        seg += t
        seg *= ts


def _channel(
    x: NDArray[np.float64],
    g: NDArray[np.float64] | None,
    r_s: float,
    ms: NDArray[np.int64],
    chunk: int,
    bufs: _Buffers,
    var: dict[str, NDArray[np.float64]],
    nterm: dict[str, NDArray[np.int64]],
    ch: int,
) -> None:
    """Fill column ``ch`` of ``var`` / ``nterm`` from one channel's detrended phase x (data unit × samples) and,
    on an octave grid, G_1 in ``g`` (overwritten: doubled up the grid).

    The removed line's slope r_s (per sample) is added back exactly: the phase of the ramp is the quadratic
    (r_s/2) j² + linear, which adds cr = r_s m² to every central second difference and m·cr to every
    modified-AVAR term, and a known quadratic to the reflected edge terms of the total variance. Phase units
    are data unit × samples, so a variance is Σ (term)² / (2 m² ⋯) with no T_s.
    """
    n = x.shape[0] - 1
    half_a = 0.5 * r_s
    ml = [int(m) for m in ms]
    sums: list[tuple[float, float, float, float]] = []  # Σd², Σd² (non-overlapping), Σs², Σs per τ
    if g is not None:
        m_cur = 1  # g holds G_{m_cur}
        while len(sums) < len(ml):
            j = len(sums)
            while m_cur < ml[j]:  # a power of two missing from the grid: doubling only
                top = n + 2 - 4 * m_cur
                for s in range(0, top, chunk):
                    _double_g(g, m_cur, s, min(top, s + chunk) - s, bufs)
                m_cur *= 2
            if ml[j] >= chunk:
                sums.append(octave_far(x, g, ml[j], n // ml[j] - 1, j + 1 < len(ml), chunk, bufs))
                m_cur = 2 * ml[j]
                continue
            group = [j]  # next levels of the same pass: consecutive octaves with 2m ≤ chunk
            while (
                len(group) < LEVELS_PER_PASS
                and group[-1] + 1 < len(ml)
                and ml[group[-1] + 1] == 2 * ml[group[-1]]
                and 2 * ml[group[-1] + 1] <= chunk
            ):
                group.append(group[-1] + 1)
            levels = [(ml[i], n // ml[i] - 1, i + 1 < len(ml)) for i in group]
            sums += octave_levels(x, g, levels, chunk, bufs)
            m_cur = 2 * ml[group[-1]]
    else:
        for m in ml:
            s2, a2, t1, t2 = _general_level(x, m, n // m - 1, chunk)
            sums.append((s2, a2, t2, t1))
    for j, m in enumerate(ml):
        s2, a2, t2, t1 = sums[j]
        cr = r_s * m * m
        n_o = n + 1 - 2 * m
        n_m = n + 2 - 3 * m
        k_avar = n // m - 1
        if n_o > 0:
            s1 = _lag2_sum(x, m, n_o)
            central = s2 + 2.0 * cr * s1 + n_o * cr * cr
            var["oavar"][j, ch] = central / (2.0 * m * m * n_o)
            nterm["oavar"][j] = n_o
            if m == 1:  # the non-overlapping and modified terms are the overlapping ones
                var["avar"][j, ch] = var["oavar"][j, ch]
                nterm["avar"][j] = n_o
                t1, t2 = s1, s2
        else:
            central = 0.0
        if k_avar >= 1 and m > 1:  # Σ of the strided subset telescopes: (x_{(k+1)m} − x_{km}) − (x_m − x_0)
            a1 = float((x[(k_avar + 1) * m] - x[k_avar * m]) - (x[m] - x[0]))
            var["avar"][j, ch] = (a2 + 2.0 * cr * a1 + k_avar * cr * cr) / (2.0 * m * m * k_avar)
            nterm["avar"][j] = k_avar
        if n_m > 0:
            tot = t2 + 2.0 * m * cr * t1 + n_m * (m * cr) ** 2
            var["mvar"][j, ch] = tot / (2.0 * m**4 * n_m)
            nterm["mvar"][j] = n_m
        if m <= n and n >= 3:
            edge = edge_sums(x, m, half_a, chunk, bufs)
            var["totvar"][j, ch] = (central + edge) / (2.0 * m * m * (n - 1))
            nterm["totvar"][j] = n - 1


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
