"""Dispatch between the closed forms (:mod:`analysis.noise.mtot`, :mod:`analysis.noise.theo1`) and the direct sums
(:mod:`analysis.noise.direct`): cached detrended series and autocorrelations per channel, the channel-by-channel
pre-pass over a τ grid, and block-by-block evaluation where the record-wide rounding estimate is too large.
See docs/methods/noise.md."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from analysis.noise.direct import reflected_sumsq, theo1_sumsq
from analysis.noise.fftkit import Detrended, autocorr, detrend_quadratic
from analysis.noise.mtot import mtot_fft
from analysis.noise.record import Record
from analysis.noise.theo1 import theo1_fft

FFT_MIN_M = 8
"""Below this m the direct O(N·m) evaluation is cheap and exact; above it the O(N log N) form is tried."""
FFT_MAX_ERR = 1e-10
"""Largest estimated relative rounding error of the variance accepted from the FFT form (else the direct sum is
used). The estimate can be ~5× short of the actual error: at 1e-9, MTOTDEV at m = 2048 on the N = 10⁷ benchmark
record was accepted 3e-9 (variance) off the blocked sum; at 1e-10 that τ goes block by block (+0.3 s) and every
value agrees with a 1e-11 bar."""



def series_cache(
    s: NDArray[np.float64], ch: int, cache: dict, key: str, need: int
) -> tuple[NDArray, NDArray, float]:
    """(series minus its least-squares quadratic, its autocorrelation, the quadratic coefficient) of one
    channel, computed once per record and kept in ``cache``.

    The autocorrelation holds the lags up to ``need`` at least, or up to ``cache[("maxlag", key)]`` (the largest
    lag of the estimator's τ grid, set by :func:`prepass`) when that is larger; every lag without that hint or
    when a cached one falls short (TheoBR's ratios ask for growing m); ``R_theo`` (Theo1) keeps the even lags
    only (r[j] = R_2j), the only ones Theo1 reads."""
    ck = (key, ch)
    step = 2 if key == "R_theo" else 1
    if ck not in cache or (cache[ck][1].size - 1) * step < need:
        hint = cache.get(("maxlag", key))
        lag = max(need, hint) if hint is not None and ck not in cache else s.shape[1] - 1  # else: every lag
        cache.pop(ck, None)
        d = Detrended(s[ch])  # formed on demand: R's buffer is filled from it
        r = autocorr(d, lag, step)
        # Theo1 reads the whole series many times: stored (after R's buffer is shrunk); the total family reads
        # its two end segments and a few sums: kept on demand
        cache[ck] = (d.seg(0, d.size) if key == "R_theo" else d, r, d.a)
    return cache[ck]


BLOCK_MIN = 1 << 16
"""Fewest windows per block of :func:`blocked_sum`."""


def blocked_sum(s: NDArray[np.float64], m: int, kind: str) -> float:
    """The closed form evaluated block by block: windows i ∈ [b₀, b₁) use only s[b₀ : b₁ + span], so their sum
    is the closed form of that segment (its own quadratic removed, its own autocorrelation). A short segment's
    autocorrelation is small next to the record's (a random-walk phase: R₀ ∝ length²), which keeps the
    expansion's rounding below :data:`FFT_MAX_ERR` where the record-wide form is not; a block still above it
    is summed directly. O(N log B) per τ for blocks of B ≈ max(2¹⁶, 16·span) windows."""
    if kind == "mtot":
        span, count, fn = 3 * m - 1, s.size - 3 * m + 1, mtot_fft
    else:
        span, count, fn = m, s.size - m, theo1_fft
    block = max(BLOCK_MIN, 16 * span)
    total = 0.0
    for b0 in range(0, count, block):
        b1 = min(count, b0 + block)
        seg = s[b0 : b1 + span]
        sd, a = detrend_quadratic(seg)
        r = autocorr(sd, min(seg.size - 1, span + 1), 1 if kind == "mtot" else 2)
        v, err = fn(sd, m, r, a)
        del sd, r
        if err >= FFT_MAX_ERR:
            if kind == "mtot":
                v = float(reflected_sumsq(seg[None, :], m, None)[0][0])
            else:
                v = float(theo1_sumsq(seg[None, :], m, None)[0][0])
        total += v
    return total


def total_sumsq(
    s: NDArray[np.float64], m: int, ok: NDArray[np.bool_] | None, cache: dict, key: str
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`reflected_sumsq` through :func:`mtot_fft` (channel by channel) when the record has no gaps,
    m ≥ :data:`FFT_MIN_M` and its rounding estimate is below :data:`FFT_MAX_ERR`; otherwise directly.

    For the dynamic range the record's least-squares quadratic is removed first: each subsequence is
    detrended, so the line changes nothing and the quadratic's exact terms are added back."""
    c, n_s = s.shape
    count = n_s - 3 * m + 1
    if ok is None and m >= FFT_MIN_M and count > 0:
        pre = cache.get(("pre", key, m))
        e = np.zeros(c)
        for ch in range(c):
            if pre is not None:
                v, err = pre[ch], 0.0 if np.isfinite(pre[ch]) else math.inf
            else:
                sd, r, a = series_cache(s, ch, cache, key, 3 * m - 1)
                if 3 * m - 1 >= cache.get(("maxlag", key), math.inf):  # the grid's largest m: R's last use
                    del cache[(key, ch)]
                    r = [r]  # owned: released inside once its terms are summed
                v, err = mtot_fft(sd, m, r, a)
                del sd, r
            e[ch] = v if err < FFT_MAX_ERR else blocked_sum(s[ch], m, "mtot")
        return e, np.full(c, count, dtype=np.int64)
    return reflected_sumsq(s, m, ok)


def prepass(rec: Record, name: str, ms: NDArray[np.int64], cache: dict) -> None:
    """Gap-free records: the O(N log N) forms of one estimator for every m of its grid, channel by channel, so
    that only one channel's detrended series and autocorrelation are alive at a time (memory a few × one
    channel instead of × all channels). Stored as ``cache[("pre", key, m)]`` (NaN: rounding estimate too
    large, the direct sum is used)."""
    if rec.has_gaps:
        return
    if name in ("mtotdev", "ttotdev"):
        key, fn, src = "R_phase", mtot_fft, rec.x
        todo = [int(m) for m in ms if m >= FFT_MIN_M and rec.n - 3 * m + 1 > 0]
    elif name == "htotdev":
        if "freq" not in cache:
            cache["freq"] = rec.frequency()
        key, fn, src = "R_freq", mtot_fft, cache["freq"][0]
        todo = [int(m) for m in ms if m >= FFT_MIN_M and src.shape[1] - 3 * m + 1 > 0]
    elif name == "theo1":
        key, fn, src = "R_theo", theo1_fft, rec.x
        todo = [int(m) for m in ms if m >= 64 and m % 2 == 0 and rec.n - m > 0]
    else:
        return
    if todo:  # the largest lag the grid reads: R_d, d < 3m (total family); R_2δ, δ < m/2 (Theo1)
        need = max(todo) - 2 if fn is theo1_fft else 3 * max(todo) - 1
        cache[("maxlag", key)] = max(need, cache.get(("maxlag", key), 0))
    if rec.channels == 1:  # one channel: the τ loop computes each m in turn, with the same cached series
        return
    todo = [m for m in todo if ("pre", key, m) not in cache]
    if not todo:
        return
    vals = {m: np.full(rec.channels, np.nan) for m in todo}
    for ch in range(rec.channels):
        sd, r, a = series_cache(src, ch, cache, key, cache[("maxlag", key)])
        del cache[(key, ch)]
        rr = [r]  # the total family releases R at the last m (see mtot_fft)
        del r
        bad = []
        for j, m in enumerate(todo):
            v, err = fn(sd, m, rr if fn is mtot_fft and j == len(todo) - 1 else rr[0], a)
            if err < FFT_MAX_ERR:
                vals[m][ch] = v
            else:
                bad.append(m)
        del sd, rr
        for m in bad:  # record-wide rounding too large: block by block (see blocked_sum)
            vals[m][ch] = blocked_sum(src[ch], m, "theo1" if fn is theo1_fft else "mtot")
    for m in todo:
        cache[("pre", key, m)] = vals[m]




def theo1_total(rec: Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Theo1 sums: :func:`theo1_fft` channel by channel for gap-free records with m ≥ 64 when its rounding
    estimate is below :data:`FFT_MAX_ERR`, else :func:`theo1_sumsq`."""
    n = rec.n
    if not rec.has_gaps and m >= 64 and m % 2 == 0 and n - m > 0:
        c = rec.channels
        out = np.zeros(c)
        pre = cache.get(("pre", "R_theo", m))
        for ch in range(c):
            if pre is not None:
                v, err = pre[ch], 0.0 if np.isfinite(pre[ch]) else math.inf
            else:
                xd, r, a = series_cache(rec.x, ch, cache, "R_theo", m - 2)
                v, err = theo1_fft(xd, m, r, a)
            out[ch] = v if err < FFT_MAX_ERR else blocked_sum(rec.x[ch], m, "theo1")
        return out, np.full(c, (n - m) * (m // 2), dtype=np.int64)
    return theo1_sumsq(rec.x, m, rec.span_ok(0, n - m, m) if n - m > 0 else None)

