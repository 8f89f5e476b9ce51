"""FFT building blocks of the closed forms: in-place real FFTs of one buffer, packed-spectrum updates, the
autocorrelation of a series in one buffer of N + maxlag points, and the least-squares quadratic removed on demand
(:class:`Detrended`). See docs/methods/noise.md."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import fft as sfft

from analysis.noise.allan import sum_of_products


def fast_len(n: int) -> int:
    """A fast real FFT length ≥ n."""
    return int(sfft.next_fast_len(max(int(n), 2), real=True))


IP_STEP = 1 << 15
"""Chunk (complex values) of the in-place spectrum passes."""
IP_SMALL = 1 << 18
"""Buffers up to this length are transformed by scipy's real FFT through a temporary (faster when small)."""


def rfft_ip(buf: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Real FFT of ``buf`` (even length nf) in place: returns the complex view of buf holding X_k, k < nf/2, with
    the two real values packed in slot 0 (X_0 + i X_{nf/2}). A complex FFT of the even/odd sample pairs, then
    the real-FFT split pair by pair (k, nf/2 − k) in chunks: no buffer besides buf."""
    z = buf.view(np.complex128)
    h = z.size
    nf = 2 * h
    if nf <= IP_SMALL:  # small: scipy's real FFT (a temporary of nf points), packed
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
    for a in range(1, half + 1, IP_STEP):  # X_k = E − F, X_{h−k} = conj(E + F), F = i W^k O, W = e^{−2πi/nf}
        b = min(half + 1, a + IP_STEP)
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


def irfft_ip(z: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Inverse of :func:`rfft_ip` in place (packed spectrum → the real series, 1/nf included), returned as the
    float view of the same buffer."""
    h = z.size
    nf = 2 * h
    x0, xh = z[0].real, z[0].imag
    if nf <= IP_SMALL:
        f = np.empty(h + 1, dtype=np.complex128)
        f[1:h] = z[1:]
        f[0], f[h] = x0, xh
        out = z.view(np.float64)
        out[:] = sfft.irfft(f, nf, workers=1)
        return out
    half = h // 2
    for a in range(1, half + 1, IP_STEP):  # Z_k = Ev_k + i Od_k, Ev = (X_k + conj X_{h−k})/2, Od = W^{−k}(X_k − …)/2
        b = min(half + 1, a + IP_STEP)
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


def spec_update(z: NDArray[np.complex128], op: str, w: NDArray[np.complex128] | None = None) -> None:
    """In place on a packed spectrum (:func:`rfft_ip`): "pow" |z|², "sq" z², "mulc" z·conj(w), "cmul"
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


def even_len(n: int) -> int:
    """A fast even FFT length ≥ n (whose half is a fast complex length)."""
    return 2 * int(sfft.next_fast_len(max((int(n) + 1) // 2, 1), real=False))


def autocorr(s, maxlag: int, step: int = 1) -> NDArray[np.float64]:
    """R_d = Σ_t s_t s_{t+d}, d = 0, step, 2·step … ≤ maxlag, of a 1-D series (zero outside; an array or a
    :class:`Detrended`, written into the buffer chunk by chunk).

    One buffer of ≈ N + maxlag points holds everything: the series is transformed in place (:func:`rfft_ip`),
    the power spectrum is written over it and a DCT-I of that (real, even) spectrum, also in place, gives R; the
    buffer is then shrunk to the lags kept. Peak memory: the series plus N + maxlag points."""
    n = s.size
    maxlag = min(int(maxlag), n - 1)
    nf = even_len(n + maxlag)
    h = nf // 2
    buf = np.empty(nf)
    fill(buf, s, 0, n)
    z = rfft_ip(buf)
    spec_update(z, "pow")
    ph = z[0].imag
    del z
    for a in range(1, h, IP_STEP):  # compact the real parts: buf[k] = P_k
        b = min(h, a + IP_STEP)
        buf[a:b] = buf[2 * a : 2 * b : 2]
    buf[h] = ph
    r = sfft.dct(buf[: h + 1], type=1, overwrite_x=True, workers=1)
    if not np.shares_memory(r, buf):  # pragma: no cover - DCT-I of a contiguous view runs in place
        buf[: h + 1] = r
    del r
    keep = maxlag // step + 1
    if step > 1:
        for a in range(1, keep, IP_STEP):
            b = min(keep, a + IP_STEP)
            buf[a:b] = buf[step * a : step * b : step]
    buf.resize(keep, refcheck=False)
    buf /= nf
    return buf


def fill(buf: NDArray[np.float64], s, a: int, b: int, ramp: bool = False) -> None:
    """buf[: b − a] = s[a:b] (times its local index 0 … b − a − 1 if ``ramp``), zeros after; s an array or a
    :class:`Detrended`, in chunks."""
    k = b - a
    step = 1 << 16
    for c0 in range(0, k, step):
        c1 = min(k, c0 + step)
        blk = buf[c0:c1]
        blk[:] = s[a + c0 : a + c1] if isinstance(s, np.ndarray) else s.seg(a + c0, a + c1)
        if ramp:
            blk *= np.arange(c0, c1, dtype=np.float64)
    buf[k:] = 0.0


class Detrended:
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


def detrend_quadratic(s: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """A 1-D series minus its least-squares quadratic (stored), and the quadratic's coefficient per sample²."""
    d = Detrended(s)
    return d.seg(0, s.size), d.a
