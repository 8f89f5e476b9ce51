"""The modified-total family's closed form (MTOTDEV, TTOTDEV, HTOTDEV): the sum of
:func:`analysis.noise.direct.reflected_sumsq` of one gap-free channel from the record's autocorrelation and FFT
correlations of the 3m − 1 end samples, O(N) once plus O(m log m) per τ (:func:`mtot_fft`).
See docs/methods/noise.md."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from analysis.noise.allan import sum_of_products
from analysis.noise.fftkit import even_len, fill, irfft_ip, rfft_ip, spec_update


def rho_slice(m: int, t0: int, t1: int) -> NDArray[np.float64]:
    """ρ(t) of :func:`kernel_rho` for t = t0 … t1 − 1 (0 ≤ t0 ≤ t1 ≤ 6m) by its closed form (integers)."""
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


def rho_spectrum(m: int, f0: int, f1: int) -> NDArray[np.float64]:
    """The real FFT of ρ (period 6m) at f = f0 … f1 − 1: ρ is the kernel's circular autocorrelation, so its
    spectrum is |κ̂|² = 16 sin⁶(πf/6) / sin²(πf/6m) (0 at f = 0), sin⁶(πf/6) taken exactly from f mod 6."""
    f = np.arange(f0, f1)
    s6 = np.array([0.0, 1.0 / 64.0, 27.0 / 64.0, 1.0, 27.0 / 64.0, 1.0 / 64.0])[f % 6]
    den = np.sin(f * (np.pi / (6 * m)))
    den *= den
    return np.divide(16.0 * s6, den, out=np.zeros(f.size), where=f > 0)


class ParityCumsum:
    """RC[j] = Σ ρ(u) over u ≤ j − 2 with u ≡ j (mod 2), j = 0 … 6m + 1 (RC[0] = RC[1] = 0), slice by slice from
    checkpoints: ρ is integer-valued, so these are exactly the numbers of one cumulative sum."""

    CH = 1 << 16

    def __init__(self, m: int) -> None:
        self.m = m
        p = 6 * m
        self.full = None
        if p <= self.CH:  # small: the whole array
            r = kernel_rho(m)
            self.full = np.zeros(p + 2)
            self.full[2::2] = np.cumsum(r[0::2])
            self.full[3::2] = np.cumsum(r[1::2])
            return
        self.chk = [(0.0, 0.0)]
        e = o = 0.0
        for t0 in range(0, p, self.CH):
            r = rho_slice(m, t0, min(p, t0 + self.CH))
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
            r = rho_slice(self.m, base, j1 - 2)
            out[2::2] += np.cumsum(r[0::2])
            out[3::2] += np.cumsum(r[1::2])
        return out[j0 - base :]


class Prefix:
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


def beta_chunk(p: Prefix, d0: int, d1: int, L: int, h1: int, D: float) -> NDArray[np.float64]:
    """Σ_k β_k v_{k+d} for d = d0 … d1 − 1, β the half-mean slope kernel (−1/(h1·D) on the first h1 of L = 3m
    points, +1/(h1·D) on the last h1), v zero outside its points: differences of v's prefix sums."""
    res = p.at(d0 + L, d1 + L)
    res -= p.at(d0 + L - h1, d1 + L - h1)
    res -= p.at(d0 + h1, d1 + h1)
    res += p.at(d0, d1)
    res /= h1 * D
    return res


def q_apply(m: int, v) -> NDArray[np.float64]:
    """Q v with Q_kl = 2[ρ(k−l) + ρ(k+l+1)], k, l < L = 3m, v an array or ``v(a, b)`` = v[a:b]: Q = Eᵀ C E with E
    the even extension of period 6m and C the circulant of ρ, so Q v folds one circular convolution of period 6m,
    done in one buffer of 6m points (:func:`rfft_ip`, ρ's spectrum in closed form)."""
    L = 3 * m
    p = 2 * L
    get = (lambda a, b: v[a:b]) if isinstance(v, np.ndarray) else v
    buf = np.empty(p)
    step = 1 << 16
    for a in range(0, L, step):
        b = min(L, a + step)
        buf[a:b] = get(a, b)
        buf[p - b : p - a] = buf[a:b][::-1]
    z = rfft_ip(buf)
    sp = rho_spectrum(m, L, L + 1)[0]
    z[0] = complex(z[0].real * rho_spectrum(m, 0, 1)[0], z[0].imag * sp)
    for a in range(1, L, step):
        b = min(L, a + step)
        z[a:b] *= rho_spectrum(m, a, b)
    del z
    u = irfft_ip(buf.view(np.complex128))
    del u
    for a in range(0, L, step):  # fold: Q v = u[:L] + u[L:][::-1]
        b = min(L, a + step)
        buf[a:b] += buf[p - b : p - a][::-1]
    buf.resize(L, refcheck=False)
    return buf


_STEP = 1 << 16
"""Slice length of the weights and sums of :func:`mtot_fft`."""


def _half_mean_geometry(m: int) -> tuple[int, int, int, float]:
    """(L = 3m, h1, h2, D) of the half-mean slope over a 3m-point subsequence."""
    L = 3 * m
    h1 = L // 2
    h2 = L - h1
    D = (0.5 * (L - 1) + 1) if L % 2 else 0.5 * L
    return L, h1, h2, D


class _Weights:
    """wr(d) = w_d ρ(d), rc_hi(d), rc_lo(d) over a slice of lags (ρ and its parity sums slice by slice)."""

    def __init__(self, m: int) -> None:
        self.m = m
        self.L = 3 * m
        self.rc = ParityCumsum(m)
        self.rho_all = kernel_rho(m)[: self.L] if self.L <= _STEP else None

    def __call__(self, d0: int, d1: int) -> tuple[NDArray, NDArray, NDArray]:
        L = self.L
        wr = 2.0 * (self.rho_all[d0:d1] if self.rho_all is not None else rho_slice(self.m, d0, d1))
        if d0 == 0:
            wr[0] *= 0.5
        return wr, self.rc.get(2 * L + 2 - d1, 2 * L + 2 - d0)[::-1], self.rc.get(1 + d0, 1 + d1)


def _toeplitz_interior(Rv: NDArray[np.float64], weights: _Weights) -> float:
    """The Toeplitz part's interior: Σ_d R_d [2(Rc(2L−1−d) − Rc(d−1)) + w_d ρ(d)(L − d)]."""
    L = weights.L
    T1 = 0.0
    for d0 in range(0, L, _STEP):
        d1 = min(L, d0 + _STEP)
        wr, hi, lo = weights(d0, d1)
        wa = np.subtract(hi, lo)
        wa *= 2.0
        if d0 == 0:
            wa[0] *= 0.5
        wa += wr * np.arange(L - d0, L - d1, -1, dtype=np.float64)
        T1 += 2.0 * sum_of_products(Rv[d0:d1], wa)
    return T1


def _quadratic_terms(s, seg, m: int, a: float) -> tuple[float, float]:
    """The removed quadratic a t²'s exact terms 2 Σ_i rᵀQz_i + M rᵀQr (r = a(k² − βk)) and their error scale."""
    ls = s.size
    L, h1, h2, D = _half_mean_geometry(m)
    M = ls - L + 1
    step = _STEP
    kk = np.arange(L, dtype=np.float64)
    beta_s = ((kk[h2:] ** 2).mean() - (kk[:h1] ** 2).mean()) / D
    del kk

    def r1(i: int, j: int) -> NDArray[np.float64]:
        k = np.arange(i, j, dtype=np.float64)
        return k * k - beta_s * k

    qr1 = q_apply(m, r1)
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
    return cross + square, 8.0 * (abs(cross) + abs(square))


def _beta_full(p: Prefix, rv: NDArray, m: int, r0: float) -> tuple[float, float]:
    """Σ_d c(d) R_|d|, c = β ⋆ v, d = −(L−1) … L−1, and its error scale Σ|c| R_0 (v given by its prefix sums)."""
    L, h1, _, D = _half_mean_geometry(m)
    c0 = float(beta_chunk(p, 0, 1, L, h1, D)[0])
    tot, ab = c0 * float(rv[0]), abs(c0)
    for d0 in range(1, L, _STEP):
        d1 = min(L, d0 + _STEP)
        cp = beta_chunk(p, d0, d1, L, h1, D)
        cn = beta_chunk(p, 1 - d1, 1 - d0, L, h1, D)[::-1]
        ab += float(np.abs(cp).sum() + np.abs(cn).sum())
        cp += cn
        tot += sum_of_products(cp, rv[d0:d1])
    return tot, r0 * ab


def _partial_windows(s, seg, q: NDArray, m: int, nf: int, sums: list[float]) -> None:
    """Subtract the partial windows over the head and the tail from the detrend sums [s_bu, sc_bu, s_bb, sc_bb]
    (in place): Σ_i sb_i sq_i with sq = q ⋆ segment (one FFT of q for both ends)."""
    L, h1, _, D = _half_mean_geometry(m)
    M = s.size - L + 1
    n = L - 1
    bq = np.empty(nf)
    fill(bq, q, 0, L)
    qz = rfft_ip(bq)
    for s0, lo, hi in ((0, -(L - 1), 0), (M, 0, L - 1)):
        bs = np.empty(nf)
        fill(bs, s, s0, s0 + n)
        sz = rfft_ip(bs)
        spec_update(sz, "mulc", qz)
        out = irfft_ip(sz)  # out[i mod nf] = Σ_k q_k seg_{i+k}
        del sz
        pre = Prefix(lambda i, j, s0=s0: seg(s0 + i, s0 + j), n)
        for i0 in range(lo, hi, _STEP):
            i1 = min(hi, i0 + _STEP)
            sb = beta_chunk(pre, i0, i1, L, h1, D)
            sq = out[i0 % nf : i0 % nf + (i1 - i0)]
            sums[0] -= sum_of_products(sb, sq)
            sums[1] += sum_of_products(np.abs(sb), np.abs(sq))
            bb = sum_of_products(sb, sb)
            sums[2] -= bb
            sums[3] += bb
            del sb, sq
        del out, bs, pre
    del qz, bq


def _end_segments(s, m: int, nf: int, weights: _Weights, T1: float) -> float:
    """The head and tail segments' terms: the Toeplitz part's window-count corrections (Σ wa_d A_d with A the
    segment's autocorrelation, Σ wb_d B_d with B_d = Σ_t t h_t h_{t+d}) and the Hankel part's end terms
    (Σ wc_σ C_σ, C the self-convolution), from the segment's spectrum (two buffers), added to T1 in order."""
    L = 3 * m
    M = s.size - L + 1
    n = L - 1
    rc = weights.rc
    for s0, sign in ((0, 1.0), (M, -1.0)):
        b1 = np.empty(nf)
        fill(b1, s, s0, s0 + n)
        hz = rfft_ip(b1)
        b2 = np.empty(nf)
        fill(b2, s, s0, s0 + n, ramp=True)
        tz = rfft_ip(b2)
        spec_update(tz, "cmul", hz)  # conj(TH)·H
        out = irfft_ip(tz)
        del tz
        for d0 in range(0, n, _STEP):
            d1 = min(n, d0 + _STEP)
            T1 += 2.0 * sign * sum_of_products(out[d0:d1], weights(d0, d1)[0])
        np.copyto(b2, b1)
        cz = b2.view(np.complex128)
        spec_update(cz, "sq")
        out = irfft_ip(cz)
        del cz
        for c0 in range(0, 2 * n - 1, _STEP):
            c1 = min(2 * n - 1, c0 + _STEP)
            T1 += 2.0 * sign * sum_of_products(out[c0:c1], rc.get(3 + c0, 3 + c1))
        del out, b2
        spec_update(hz, "pow")
        out = irfft_ip(hz)
        del hz
        for d0 in range(0, n, _STEP):
            d1 = min(n, d0 + _STEP)
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
    return T1


def mtot_fft(s, m: int, R, a: float) -> tuple[float, float]:
    """The sum of :func:`reflected_sumsq` for one gap-free channel in O(N) + O(m log m) given R, and an
    error scale (≈ ε × the largest summand / E).

    s is the series with its least-squares quadratic removed (an array or a :class:`Detrended`, a its
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
    points are alive (:func:`rfft_ip`; R released before them when owned).
    """
    own = isinstance(R, list)
    Rv = R.pop() if own else R
    seg = (lambda i, j: s[i:j]) if isinstance(s, np.ndarray) else s.seg
    L, h1, h2, D = _half_mean_geometry(m)
    n = L - 1  # end-segment length
    rho0 = 6.0 * m  # ρ(0)
    r0 = abs(float(Rv[0]))
    weights = _Weights(m)
    T1 = _toeplitz_interior(Rv, weights)
    E_quad = scale_quad = 0.0
    if a != 0.0:  # the removed quadratic's exact terms: r1 = k² − β_s k, Q r1, and Σ_i z_i
        E_quad, scale_quad = _quadratic_terms(s, seg, m, a)
    # detrend terms: β the half-mean slope, q = Qk; Σ_{i<M} (βᵀX_i)(vᵀX_i) = Σ_d c_βv(d) R_|d| − partial windows
    q = q_apply(m, np.arange(L, dtype=np.float64))
    kqk = sum(
        sum_of_products(np.arange(i, min(L, i + _STEP), dtype=np.float64), q[i : i + _STEP]) for i in range(0, L, _STEP)
    )

    def beta(i: int, j: int) -> NDArray[np.float64]:
        k = np.arange(i, j)
        return np.where(k < h1, -1.0 / (h1 * D), np.where(k >= h2, 1.0 / (h1 * D), 0.0))

    s_bu, sc_bu = _beta_full(Prefix(lambda i, j, q=q: q[i:j], L), Rv, m, r0)
    s_bb, sc_bb = _beta_full(Prefix(beta, L), Rv, m, r0)
    del Rv  # every R term is summed
    nf = even_len(2 * n)  # ≥ 2n − 1 (self-convolutions) and ≥ n + L − 1 (the correlations with q)
    sums = [s_bu, sc_bu, s_bb, sc_bb]
    _partial_windows(s, seg, q, m, nf, sums)
    del q
    s_bu, sc_bu, s_bb, sc_bb = sums
    T1 = _end_segments(s, m, nf, weights, T1)
    E = T1 - 2.0 * s_bu + kqk * s_bb + E_quad
    scale = 4.0 * L * abs(rho0) * r0 + 2.0 * sc_bu + abs(kqk) * sc_bb + scale_quad
    err = 1.1e-16 * scale / abs(E) if E != 0.0 else math.inf
    return E, err



def kernel_rho(m: int) -> NDArray[np.float64]:
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

