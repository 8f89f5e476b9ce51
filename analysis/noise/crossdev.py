"""The parabolic deviation (PDEV), the Groslambert codeviation (GCODEV) and the three-cornered hat.

PDEV (Vernotte, Lenczner, Bourgeois & Rubiola, "The parabolic variance (PVAR)", IEEE UFFC 63, 2016): the
frequency estimated by a least-squares line fit over each τ (Ω counter) instead of a mean (Π counter); with
d_j = x_j − x_{j+m}, PVAR(τ) = 72 Σ_{i<M} [Σ_{k<m} ((m − 1)/2 − k) d_{i+k}]² / (M m⁴ τ²), M = N − 2m phase points
(the overlapping Allan variance at m = 1). It separates white and flicker PM better than MVAR with more degrees of
freedom.

GCODEV (F. Vernotte, C. Plantard, E. Lantz et al.; "Groslambert covariance"): the overlapping Allan variance with
one squared second difference replaced by the product of the two records' second differences,
GCOV(τ) = Σ Δ²x₁ Δ²x₂ / (2 n τ²). Noise common to two records (the table's, a shared reference) survives it;
noise of one record alone averages out — signed, it can be negative where only uncorrelated noise remains.

Three-cornered hat: three units A, B, C observing the same input. The pair differences cancel the input; with
independent unit noises, AVAR(A − B) = σ²_A + σ²_B, so σ²_A = ½[AVAR(A−B) + AVAR(C−A) − AVAR(B−C)] (classic,
as allantools' ``three_cornered_hat_phase``), or directly σ²_A = GCOV(A − B, A − C) (the codeviation form,
which never needs the difference of two large numbers). Each equals allantools where it has them
(tests/analysis/noise/test_crossdev.py). See docs/methods/noise.md.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from analysis.noise.record import Record, m_grid


def _phase(data: ArrayLike, rate: float, data_type: str) -> NDArray[np.float64]:
    rec = Record(data, rate, data_type)
    if rec.has_gaps:
        raise ValueError("PDEV/GCODEV/three-cornered hat need gap-free records")
    if rec.channels != 1:
        raise ValueError("one channel per record")
    return rec.x[0]


def _second_differences(x: NDArray[np.float64], m: int) -> NDArray[np.float64]:
    return x[2 * m :] - 2.0 * x[m:-m] + x[: -2 * m]


def pdev(
    data: ArrayLike, rate: float, taus: str | ArrayLike = "octave", data_type: str = "freq"
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Parabolic deviation of one record: (τ s, PDEV in the data's rate unit, terms M per τ)."""
    x = _phase(data, rate, data_type)
    n = x.size
    ms = m_grid(n, taus, rate)
    ms = ms[n - 2 * ms >= 2]  # at least two terms (as allantools keeps)
    tau0 = 1.0 / rate
    out = np.empty(ms.size)
    count = np.empty(ms.size, dtype=np.int64)
    for j, m in enumerate(ms):
        m = int(m)
        if m == 1:
            v = _second_differences(x, 1)
            count[j] = v.size
            out[j] = math.sqrt(float(np.dot(v, v)) / (2.0 * v.size)) / tau0
            continue
        big_m = n - 2 * m
        d = x[: n - m] - x[m:]  # d_j = x_j − x_{j+m}, j < N − m
        w = (m - 1) / 2.0 - np.arange(m, dtype=np.float64)
        s = signal.oaconvolve(d[: big_m + m - 1], w[::-1], mode="valid") if m > 64 else np.convolve(
            d[: big_m + m - 1], w[::-1], mode="valid"
        )
        count[j] = big_m
        out[j] = math.sqrt(72.0 * float(np.dot(s, s)) / (big_m * m**4 * (m * tau0) ** 2))
    return ms * tau0, out, count


def gcodev(
    data_1: ArrayLike, data_2: ArrayLike, rate: float, taus: str | ArrayLike = "octave", data_type: str = "freq"
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Groslambert codeviation of two simultaneous records: (τ s, signed codeviation sign(GCOV)·√|GCOV|, terms).

    allantools' ``gcodev`` returns √|GCOV| (the sign dropped); ``abs`` of this value equals it."""
    x1 = _phase(data_1, rate, data_type)
    x2 = _phase(data_2, rate, data_type)
    if x1.size != x2.size:
        raise ValueError(f"the two records differ in length ({x1.size - 1} and {x2.size - 1} samples)")
    n = x1.size
    ms = m_grid(n, taus, rate)
    ms = ms[n - 2 * ms >= 2]
    tau0 = 1.0 / rate
    out = np.empty(ms.size)
    count = np.empty(ms.size, dtype=np.int64)
    for j, m in enumerate(ms):
        v1, v2 = _second_differences(x1, int(m)), _second_differences(x2, int(m))
        cov = float(np.dot(v1, v2)) / (2.0 * v1.size * (m * tau0) ** 2)
        out[j] = math.copysign(math.sqrt(abs(cov)), cov)
        count[j] = v1.size
    return ms * tau0, out, count


def three_cornered_hat(
    a: ArrayLike, b: ArrayLike, c: ArrayLike, rate: float, taus: str | ArrayLike = "octave", data_type: str = "freq"
) -> dict[str, object]:
    """Each of three simultaneous records' own deviation, the common input removed.

    Returns
    -------
    dict
        {"tau": s, "classic": {"a", "b", "c"}: √max(0, ½[σ²_ab + σ²_ca − σ²_bc]) from the overlapping Allan
        variances of the pair differences, "gcodev": {"a", "b", "c"}: signed √GCOV(A−B, A−C) etc.,
        "n_terms"}; deviations in the data's rate unit.
    """
    ra, rb, rc = (np.asarray(v, dtype=np.float64).ravel() for v in (a, b, c))
    if not ra.size == rb.size == rc.size:
        raise ValueError("the three records differ in length")
    pairs = {"ab": ra - rb, "bc": rb - rc, "ca": rc - ra}
    from analysis.noise.stability import stability  # lazy: the driver imports this package's kernels

    var = {}
    tau = None
    for k, d in pairs.items():
        est = stability(d, rate, ("oadev",), taus, data_type, confidence=None).estimates["oadev"]
        var[k], tau = est.dev[:, 0] ** 2, est.tau
    classic = {
        "a": np.sqrt(np.clip(0.5 * (var["ab"] + var["ca"] - var["bc"]), 0.0, None)),
        "b": np.sqrt(np.clip(0.5 * (var["ab"] + var["bc"] - var["ca"]), 0.0, None)),
        "c": np.sqrt(np.clip(0.5 * (var["bc"] + var["ca"] - var["ab"]), 0.0, None)),
    }
    t_g, g_a, n = gcodev(ra - rb, ra - rc, rate, taus, data_type)
    _, g_b, _ = gcodev(rb - rc, rb - ra, rate, taus, data_type)
    _, g_c, _ = gcodev(rc - ra, rc - rb, rate, taus, data_type)
    keep = np.isin(tau, t_g)
    return {
        "tau": tau[keep],
        "classic": {k: v[keep] for k, v in classic.items()},
        "gcodev": {"a": g_a, "b": g_b, "c": g_c},
        "n_terms": n,
    }
