"""Theo1's closed form (:func:`theo1_fft`): window sums, one lagged product, a blocked FFT correlation and two
anti-diagonal triangle sums by divide and conquer, O(N log m + m log² m) per τ. See docs/methods/noise.md."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import fft as sfft

from analysis.noise.allan import sum_of_products
from analysis.noise.fftkit import fast_len

LEAN_MIN = 1 << 16
"""Smallest FFT length of the blocked correlations (:func:`fft_cap`)."""
LEAN_DIV = 8
"""The blocked correlations of a series of N points use FFTs of at most about N / this many points, so each of
their few buffers costs a fraction of the series (see :func:`corr_sum`)."""


def fft_cap(n: int) -> int:
    """Largest FFT length (even) of the blocked correlations of a series of n points."""
    cap = fast_len(max(LEAN_MIN, n // LEAN_DIV))
    return cap + cap % 2


def corr_sum(get_a, na: int, get_b, nb: int, kern, lo: int, hi: int, cap: int) -> float:
    """Σ_{u<na, v<nb} a_u b_v K(v − u) for a kernel K that is zero outside the lags [lo, hi).

    ``get_a(i, j)`` and ``get_b(i, j)`` return a[i:j] and b[i:j] (so a series can be formed block by block),
    ``kern(l0, l1)`` K over the lags l0 … l1 − 1. One FFT cross-correlation when na + nb − 1 ≤ cap; otherwise
    blocks of cap/2 points of a against blocks of b whose lags meet [lo, hi), one FFT of cap points per pair
    (memory O(cap), a few buffers, instead of O(na + nb))."""
    if na <= 0 or nb <= 0 or hi <= lo:
        return 0.0
    if na + nb - 1 <= cap:
        nf, blk = fast_len(na + nb - 1), max(na, nb)
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


TRI_BASE = 256
"""Triangle size below which :func:`tri` sums directly."""
_TRI_IDX: dict[int, tuple[NDArray, NDArray]] = {}


def tri(a: NDArray, b: NDArray, gk, off: int, n: int, cap: int) -> float:
    """Σ over u, v ∈ [0, n) with u + v < n of a_u b_v G(v − u + off), 1-D a and b zero beyond their length and
    ``gk(e0, e1)`` G over e0 … e1 − 1 (zero outside [0, ∞)), in O(n log² n).

    Divide and conquer on the anti-diagonal triangle: the square [0, n/2)² is a cross-correlation
    (:func:`corr_sum`, blocked beyond ``cap``), the two remaining strips are triangles of half the size
    (recursion, on views: a strip's missing half is a's or b's end), and for odd n the centre point.
    """
    a = a[:n]
    b = b[:n]
    if n <= 0 or a.size == 0 or b.size == 0:
        return 0.0
    if n <= TRI_BASE:
        if n not in _TRI_IDX:
            u = np.arange(n)
            _TRI_IDX[n] = ((u[None, :] - u[:, None]) + (n - 1), (u[:, None] + u[None, :]) < n)
        idx, mask = _TRI_IDX[n]
        g = gk(off - (n - 1), off + n)
        wmat = g[idx] * mask
        return float(np.einsum("u,uv,v->", a, wmat[: a.size, : b.size], b))
    k = n // 2
    tot = corr_sum(
        lambda i, j: a[i:j], min(a.size, k), lambda i, j: b[i:j], min(b.size, k),
        lambda l0, l1: gk(l0 + off, l1 + off), -off, 1 << 62, cap,
    )
    r = n - k
    tot += tri(a[:k], b[k:n], gk, off + k, r, cap)
    tot += tri(a[k:n], b[:k], gk, off - k, r, cap)
    if n % 2 and k < a.size and k < b.size:
        tot += float(a[k] * b[k] * gk(off, off + 1)[0])
    return tot


def window_sum_chunks(f: NDArray[np.float64], count: int, top: int, sq: bool):
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


def fold_windows(chunks, h: int, coef) -> tuple[float, float, float]:
    """(Σ_{δ<h} c_δ (W[h − δ] + W[h + δ]), W[0], W[2h]) over the chunks of :func:`window_sum_chunks` (top = 2h),
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


def theo1_fft(x: NDArray[np.float64], m: int, r: NDArray[np.float64], a: float) -> tuple[float, float]:
    """Theo1's double sum of one gap-free channel in O(N log m + m log² m) given the even-lag autocorrelation
    r (r[j] = R_2j) of x, and a rounding-error scale (see :func:`theo1_sumsq`).

    With c = i + m/2 and A_c = x_{c−m/2} + x_{c+m/2}, each term is (A_c − x_{c−δ} − x_{c+δ})²/(m/2 − δ); summed
    over δ it is W A_c² − 2 A_c (k∗x)_c + (k∗x²)_c + 2 Σ_δ w_δ x_{c−δ} x_{c+δ} with k the symmetric kernel of the
    weights w_δ = 1/(m/2 − δ). Σ A_c² and Σ (k∗x²)_c are window sums of x² (in chunks) plus one lagged dot
    product; Σ A_c (k∗x)_c is a blocked (overlap-save) FFT correlation, the kernel itself cut into pieces when
    it is long; the last sum over c is Σ_δ w_δ R_{2δ} less two anti-diagonal triangles of the first and of the
    reversed last m − 1 samples (:func:`tri`). x has its least-squares quadratic removed (a its coefficient per
    sample², whose exact terms 2a(h² − δ²) per term are added back). Memory: the weights (m/2 points) and FFT
    buffers of at most :func:`fft_cap` points, whatever m.
    """
    n = x.size
    h = m // 2
    count = n - m
    cap = fft_cap(n)
    w = 1.0 / (h - np.arange(h))
    wsum = float(w.sum())
    t3, w2_0, w2_m = fold_windows(window_sum_chunks(x, count, m, True), h, lambda d0, d1: w[d0:d1])
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
        nf = min(fast_len(max(4 * kp, 1 << 16) if piece == kl else 2 * kp), fast_len(count + kp - 1))
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

    s4 -= tri(x[: m - 1], x[: m - 1], gk, 0, m - 1, cap)
    tail = x[::-1][: m - 1]
    s4 -= tri(tail, tail, gk, 0, m - 1, cap)
    v = t1 - t2 + t3 + 2.0 * s4
    scale = 8.0 * (t1 + abs(t2) + t3 + 2.0 * wsum * abs(float(r[0])))
    if a != 0.0:
        # Theo1 is blind to a line in the phase, and a quadratic a t² adds exactly 2a(h² − δ²) to every term

        def wq(d0: int, d1: int) -> NDArray[np.float64]:  # w_δ · 2(h² − δ²)
            d = np.arange(d0, d1, dtype=np.float64)
            return w[d0:d1] * (2.0 * (h * h - d * d))

        s1, s1_0, s1_m = fold_windows(window_sum_chunks(x, count, m, False), h, wq)
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

