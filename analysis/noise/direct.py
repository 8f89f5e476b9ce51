"""Direct sums of the stability estimators (point and span differences, the total variance, the modified-total
reflected sums, Theo1's double sum and MTIE), with gaps skipped: exact, O(N) or O(N·m) per τ, in chunks.
See docs/methods/noise.md."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from analysis.noise.record import CHUNK, Record


def diff_sumsq(
    rec: Record, m: int, coeffs: tuple[float, ...], stride: int
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
    step = max(CHUNK - CHUNK % stride, stride)
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


def mod_sumsq(rec: Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
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


def mirror(j: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    """The sample a reflected index −(n−1) ≤ j ≤ 2(n−1) mirrors: −j before the start, 2(n−1) − j after the end."""
    return np.where(j < 0, -j, np.where(j > n - 1, 2 * (n - 1) - j, j))


def reflected(x: NDArray[np.float64], j: NDArray[np.int64]) -> NDArray[np.float64]:
    """x*_j of the phase x (C, n) extended by inverted reflection at both ends (the total variances'
    extension): x*_{−j} = 2x_0 − x_j, x*_{n−1+j} = 2x_{n−1} − x_{n−1−j}."""
    n = x.shape[1]
    v = x[:, mirror(j, n)]
    v = np.where(j < 0, 2.0 * x[:, :1] - v, v)
    return np.where(j > n - 1, 2.0 * x[:, n - 1 : n] - v, v)


def oadev_sumsq(rec: Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Σ (x_{i+2m} − 2x_{i+m} + x_i)² over i = 0 … N−2m−1 (gap terms skipped), once per m (OADEV, TOTDEV)."""
    if ("osum", m) not in cache:
        cache[("osum", m)] = diff_sumsq(rec, m, (1.0, -2.0, 1.0), 1)
    return cache[("osum", m)]


def tot_sumsq_central(rec: Record, m: int, cache: dict) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`tot_sumsq` of a gap-free record: its centres m … N−1−m reach no reflected point, so their terms
    are exactly OADEV's (shared through ``cache``); only the ≤ 2(m−1) centres near the ends are formed here."""
    x = rec.x
    n = rec.n
    c = x.shape[0]
    if m > n - 2:
        return np.zeros(c), np.zeros(c, dtype=np.int64)
    s = oadev_sumsq(rec, m, cache)[0].copy() if n - 2 * m > 0 else np.zeros(c)
    ends = np.concatenate([np.arange(1, min(m, n - 1)), np.arange(max(n - m, m), n - 1)])
    if ends.size:
        v = reflected(x, ends - m) - 2.0 * x[:, ends] + reflected(x, ends + m)
        s += np.einsum("ij,ij->i", v, v)
    return s, np.full(c, n - 2, dtype=np.int64)


def tot_sumsq(rec: Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
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
    v = reflected(x, lo) - 2.0 * x[:, 1 : n - 1] + reflected(x, hi)
    if not rec.has_gaps:
        return np.einsum("ij,ij->i", v, v), np.full(c, n - 2, dtype=np.int64)
    if rec.data_type == "phase":
        p = rec.point_ok
        ok = p[:, 1 : n - 1].copy()
        for j in (lo, hi):
            ok &= p[:, mirror(j, n)]
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


def reflected_reps(m: int) -> list[tuple[float, float, tuple[tuple[int, float], ...], float, float]]:
    """Per evaluated term j of :func:`reflected_sumsq`: (weight, g_tot, ((p, κ_p), …), Σκ_p, Σκ_p q(p))."""
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


def reflected_sumsq(
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
    reps = reflected_reps(m)
    total = np.zeros(c)
    step = max(CHUNK // 8 // max(1, c), 1024)  # short chunks: partial sums stay small (rounding ∝ chunk^1.5)
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



def theo1_sumsq(
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
    step = max(CHUNK // max(1, c), 1024)
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



def mtie(rec: Record, m: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
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

