"""Statistical tests and correlation functions for drift records.

Specification: docs/methods/drift.md. All functions take a scalar series (any unit, usually the
detrended residual of one gyro or accelerometer channel) and return a :class:`TestResult` with the
statistic, the threshold it is compared against, and the verdict, or arrays for ACF/PACF.

- Daniel test: Spearman rank correlation q of the series with time, T = q√(n−2)/√(1−q²) ~ t(n−2).
- Reverse-arrangement test on M sub-series means (or mean squares, to catch variance drift):
  A = #{i<j: z_i > z_j}, E[A] = M(M−1)/4, Var[A] = M(2M+5)(M−1)/72, U = (A − E[A])/√Var[A], |U| < z_{1−α/2}.
- Jarque–Bera: JB = n/6 [S² + (K−3)²/4] ~ χ²(2). Caveat: for n ~ 10⁵ the test rejects on a kurtosis excess
  far too small to matter for navigation (e.g. quantisation or a slight mixture); read its verdict as
  "detectably non-Gaussian", not "badly non-Gaussian".
- Ljung–Box: Q = n(n+2) Σ_{k=1..L} r_k²/(n−k) ~ χ²(L − p − q).
- Welch periodicity check: Welch PSD, each bin compared with a running-median background; a bin is a tone
  when its ratio exceeds the χ²(ν)/ν quantile at α/(number of bins) (Bonferroni), ν the equivalent degrees of
  freedom of the Welch average. Tones are handed to the periodic-error analysis (``tablebench periodic``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal, stats

from analysis.drift.preprocess import DriftInputError, check_series

JB_CAVEAT = (
    "for long records (n ~ 1e5) Jarque-Bera rejects on a tiny kurtosis or skewness excess; a rejection means "
    "detectably, not necessarily materially, non-Gaussian"
)


@dataclass
class TestResult:
    """Outcome of one test.

    Attributes
    ----------
    name : str
        Test name.
    statistic : float
        Value of the test statistic.
    threshold : float
        Critical value; the null hypothesis is rejected when ``|statistic| > threshold`` (two-sided tests) or
        ``statistic > threshold`` (one-sided: JB, Ljung–Box).
    verdict : str
        ``"pass"`` (null not rejected: stationary / Gaussian / white) or ``"reject"``.
    alpha : float
        Significance level.
    p_value : float
        p-value of the statistic under the null.
    note : str
        Details or caveats.
    extra : dict
        Additional figures (e.g. tone list for the periodicity check).
    """

    __test__ = False  # not a pytest class

    name: str
    statistic: float
    threshold: float
    verdict: str
    alpha: float
    p_value: float
    note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def rejected(self) -> bool:
        """True when the null hypothesis is rejected."""
        return self.verdict == "reject"

    def to_dict(self) -> dict:
        """JSON-ready dictionary (statistic, threshold, verdict first)."""
        d = asdict(self)
        d.pop("name")
        return d


def segment_stats(x: ArrayLike, segments: int, what: str = "mean") -> NDArray[np.float64]:
    """Means (``what="mean"``) or mean squares (``"mean_square"``) of ``segments`` equal consecutive sub-series.

    Trailing samples that do not fill a segment are dropped.
    """
    a = np.asarray(x, dtype=np.float64)
    if segments < 4 or a.size < 2 * segments:
        raise DriftInputError(f"need at least 4 segments of 2 samples; got {segments} segments for {a.size} samples")
    m = a.size // segments
    blocks = a[: m * segments].reshape(segments, m)
    if what == "mean":
        return blocks.mean(axis=1)
    if what == "mean_square":
        return (blocks**2).mean(axis=1)
    raise ValueError(f"what must be 'mean' or 'mean_square', got {what!r}")


def daniel_test(x: ArrayLike, alpha: float = 0.05) -> TestResult:
    """Daniel trend test: Spearman rank correlation of ``x`` with time, two-sided t-test on n − 2 dof.

    Apply it to the series itself (white residuals) or to sub-series means (:func:`segment_stats`) for a
    coloured series, whose autocorrelation otherwise inflates the rejection rate.
    """
    a = np.asarray(x, dtype=np.float64)
    n = a.size
    if n < 4:
        raise DriftInputError(f"Daniel test needs at least 4 values, got {n}")
    r = stats.rankdata(a)
    t = np.arange(1.0, n + 1)
    rc = r - r.mean()
    tc = t - t.mean()
    den = math.sqrt(float(rc @ rc) * float(tc @ tc))
    q = float(rc @ tc) / den if den > 0 else 0.0
    q = max(min(q, 1.0 - 1e-15), -1.0 + 1e-15)
    stat = q * math.sqrt(n - 2) / math.sqrt(1.0 - q * q)
    thr = float(stats.t.ppf(1.0 - alpha / 2.0, n - 2))
    p = float(2.0 * stats.t.sf(abs(stat), n - 2))
    return TestResult(
        "daniel",
        stat,
        thr,
        "reject" if abs(stat) > thr else "pass",
        alpha,
        p,
        f"Spearman q = {q:.4g} over {n} values",
        {"spearman_q": q, "n": n},
    )


def reverse_arrangement_test(z: ArrayLike, alpha: float = 0.05) -> TestResult:
    """Reverse-arrangement test on a short sequence ``z`` (usually M sub-series means or mean squares).

    A = #{i<j: z_i > z_j}; U = (A − M(M−1)/4)/√(M(2M+5)(M−1)/72); two-sided normal threshold.
    """
    a = np.asarray(z, dtype=np.float64)
    m = a.size
    if m < 4:
        raise DriftInputError(f"reverse-arrangement test needs at least 4 values, got {m}")
    if m <= 4000:
        count = int(np.count_nonzero(np.triu(a[:, None] > a[None, :], k=1)))
    else:  # O(M log M) by ranks: inversions count via a merge of sorted order
        count = _inversions(a)
    mean = m * (m - 1) / 4.0
    var = m * (2 * m + 5) * (m - 1) / 72.0
    u = (count - mean) / math.sqrt(var)
    thr = float(stats.norm.ppf(1.0 - alpha / 2.0))
    p = float(2.0 * stats.norm.sf(abs(u)))
    return TestResult(
        "reverse_arrangement",
        u,
        thr,
        "reject" if abs(u) > thr else "pass",
        alpha,
        p,
        f"A = {count} reverse arrangements among M = {m} values (E[A] = {mean:g})",
        {"A": count, "M": m},
    )


def _inversions(a: NDArray[np.float64]) -> int:
    """Number of pairs i<j with a_i > a_j (Fenwick tree over ranks)."""
    ranks = stats.rankdata(a, method="dense").astype(np.int64)
    size = int(ranks.max())
    tree = [0] * (size + 1)
    total = 0
    seen = 0
    for r in ranks.tolist():
        # count of seen values <= r
        i, s = r, 0
        while i > 0:
            s += tree[i]
            i -= i & -i
        total += seen - s
        i = r
        while i <= size:
            tree[i] += 1
            i += i & -i
        seen += 1
    return total


def jarque_bera_test(x: ArrayLike, alpha: float = 0.05) -> TestResult:
    """Jarque–Bera normality test, JB = n/6 [S² + (K−3)²/4] against χ²(2) (5.99 at 5 %). See :data:`JB_CAVEAT`."""
    a = np.asarray(x, dtype=np.float64)
    n = a.size
    if n < 8:
        raise DriftInputError(f"Jarque-Bera needs at least 8 values, got {n}")
    d = a - a.mean()
    m2 = float(np.mean(d * d))
    if m2 <= 0:
        raise DriftInputError("Jarque-Bera: the series is constant")
    s = float(np.mean(d**3)) / m2**1.5
    k = float(np.mean(d**4)) / m2**2
    jb = n / 6.0 * (s * s + (k - 3.0) ** 2 / 4.0)
    thr = float(stats.chi2.ppf(1.0 - alpha, 2))
    return TestResult(
        "jarque_bera",
        jb,
        thr,
        "reject" if jb > thr else "pass",
        alpha,
        float(stats.chi2.sf(jb, 2)),
        JB_CAVEAT,
        {"skewness": s, "kurtosis": k},
    )


ACF_DIRECT_LAGS = 8
"""Up to this many lags :func:`acf` sums the lag products directly (a few passes over the record cost less than
a zero-padded FFT of twice its length: the ARMA fit's moment start asks for p + q + 1 lags)."""


def acf(x: ArrayLike, nlags: int) -> NDArray[np.float64]:
    """Sample autocorrelation r_0..r_nlags (biased estimator, denominator n, mean removed), via FFT (direct lag
    sums for at most :data:`ACF_DIRECT_LAGS` lags)."""
    a = np.asarray(x, dtype=np.float64)
    n = a.size
    nlags = int(min(nlags, n - 1))
    d = a - a.mean()
    if nlags <= ACF_DIRECT_LAGS:
        c = np.array([np.einsum("i,i->", d[: n - k], d[k:]) for k in range(nlags + 1)]) / n
    else:
        nfft = 1 << int(math.ceil(math.log2(2 * n - 1)))
        f = np.fft.rfft(d, nfft)
        c = np.fft.irfft(f * np.conj(f), nfft)[: nlags + 1] / n
    if c[0] <= 0:
        raise DriftInputError("autocorrelation of a constant series is undefined")
    return c / c[0]


def autocovariance(x: ArrayLike, nlags: int) -> NDArray[np.float64]:
    """Sample autocovariance γ̂_0..γ̂_nlags (denominator n, mean removed), input unit squared."""
    a = np.asarray(x, dtype=np.float64)
    return acf(a, nlags) * float(np.var(a))


def pacf_from_acf(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Partial autocorrelations φ_kk, k = 0..len(r)−1 (φ_00 = 1), by the Durbin–Levinson recursion."""
    nl = len(r) - 1
    out = np.zeros(nl + 1)
    out[0] = 1.0
    phi = np.zeros(nl + 1)
    v = 1.0
    for k in range(1, nl + 1):
        num = r[k] - float(phi[1:k] @ r[k - 1 : 0 : -1]) if k > 1 else r[1]
        a = num / v if v > 0 else 0.0
        new = phi.copy()
        new[k] = a
        if k > 1:
            new[1:k] = phi[1:k] - a * phi[k - 1 : 0 : -1]
        phi = new
        v *= 1.0 - a * a
        out[k] = a
    return out


def pacf(x: ArrayLike, nlags: int) -> NDArray[np.float64]:
    """Sample partial autocorrelation 1, φ_11, …, φ_LL (Durbin–Levinson on the biased ACF, i.e. Yule–Walker)."""
    return pacf_from_acf(acf(x, nlags))


def correlation_bands(n: int, r: NDArray[np.float64] | None = None, alpha: float = 0.05) -> NDArray[np.float64]:
    """Half-widths of the (1−α) confidence band per lag.

    Without ``r``: ±z/√n (white-noise band, used for the PACF), an array of one value. With the ACF ``r``
    (lags 0..L): Bartlett's band z √((1 + 2 Σ_{j<k} r_j²)/n) for lag k (MA(k−1) null), lag 0 set to 0.
    """
    z = float(stats.norm.ppf(1.0 - alpha / 2.0))
    if r is None:
        return np.full(1, z / math.sqrt(n))
    cs = np.concatenate([[0.0], np.cumsum(r[1:] ** 2)])  # cs[k] = Σ_{j=1..k} r_j²
    band = np.zeros(r.size)
    band[1:] = z * np.sqrt((1.0 + 2.0 * cs[:-1]) / n)
    return band


def ljung_box_test(resid: ArrayLike, lags: int | None = None, dof_used: int = 0, alpha: float = 0.05) -> TestResult:
    """Ljung–Box whiteness test of residuals, Q = n(n+2) Σ r_k²/(n−k), k = 1..L, against χ²(L − dof_used).

    ``dof_used`` is p + q for ARMA residuals. L defaults to min(20, n/5) but at least dof_used + 5.
    """
    a = check_series(resid, "residuals", min_samples=10)
    n = a.size
    if lags is None:
        lags = max(min(20, n // 5), dof_used + 5)
    if lags <= dof_used or lags >= n:
        raise DriftInputError(f"Ljung-Box: lags ({lags}) must exceed p+q ({dof_used}) and be below n ({n})")
    r = acf(a, lags)
    k = np.arange(1, lags + 1)
    q = float(n * (n + 2) * np.sum(r[1:] ** 2 / (n - k)))
    dof = lags - dof_used
    thr = float(stats.chi2.ppf(1.0 - alpha, dof))
    return TestResult(
        "ljung_box",
        q,
        thr,
        "reject" if q > thr else "pass",
        alpha,
        float(stats.chi2.sf(q, dof)),
        f"L = {lags} lags, {dof} degrees of freedom",
        {"lags": lags, "dof": dof},
    )


def _symmetric_running_median(p: NDArray[np.float64], half: int, min_half: int) -> NDArray[np.float64]:
    """Median of p[i−h .. i+h] excluding bin 0 (DC), h = min(half, i − 1, n − 2 − i); 0 where h < min_half.

    The window stays symmetric near the ends, so a smooth monotone spectrum (steep coloured drift near DC)
    gives a ratio near one instead of a spurious peak; bins too close to the ends are not tested.
    """
    n = p.size
    out = np.zeros(n)
    if n >= 2 * half + 3:
        win = np.lib.stride_tricks.sliding_window_view(p[1:], 2 * half + 1)
        out[1 + half : 1 + half + win.shape[0]] = np.median(win, axis=1)
    for i in range(1, n - 1):
        h = min(half, i - 1, n - 2 - i)
        if h < half and h >= min_half:
            out[i] = float(np.median(p[i - h : i + h + 1]))
        elif h < min_half:
            out[i] = 0.0
    return out


def welch_tones(
    x: ArrayLike, rate: float, alpha: float = 0.01, nperseg: int | None = None, background_bins: int = 31
) -> TestResult:
    """Welch periodicity check: list the tones standing significantly above the local PSD background.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    rate : float
        Sample rate, Hz.
    alpha : float
        Family-wise significance (Bonferroni over the bins).
    nperseg : int, optional
        Welch segment length; default n/16 rounded to a power of two, at least 64.
    background_bins : int
        Width of the running median giving the background; it is kept symmetric, so the 3 bins at each end
        of the spectrum (and DC) are not tested.

    Returns
    -------
    TestResult
        ``statistic`` is the largest PSD/background ratio, ``threshold`` the critical ratio; ``extra`` holds
        ``tones`` (list of dicts: frequency_hz, ratio, amplitude = √(2·PSD·Δf) estimate in input units),
        ``frequencies`` (the frequencies only, Hz) for ``tablebench periodic``.
    """
    a = np.asarray(x, dtype=np.float64)
    n = a.size
    if nperseg is None:
        nperseg = max(64, 1 << int(math.floor(math.log2(max(n // 16, 2)))))
    nperseg = int(min(nperseg, n))
    f, pxx = signal.welch(a - a.mean(), fs=rate, window="hann", nperseg=nperseg, noverlap=nperseg // 2)
    nseg = max(1, (n - nperseg) // (nperseg // 2) + 1)
    # Equivalent degrees of freedom of a 50 %-overlapped Hann Welch average (Welch 1967; ρ(50 %) ≈ 0.167).
    nu = 2.0 * nseg / (1.0 + 2.0 * 0.167**2 * (nseg - 1) / nseg)
    bg = _symmetric_running_median(pxx, background_bins // 2, min_half=3)
    bg = bg / (stats.chi2.ppf(0.5, nu) / nu)  # median of χ²_ν/ν → mean
    inner = slice(1, pxx.size - 1)  # skip DC and Nyquist
    ratio = np.zeros_like(pxx)
    ok = bg > 0
    ratio[ok] = pxx[ok] / bg[ok]
    nbins = max(int(np.count_nonzero(ok)), 1)
    thr = float(stats.chi2.ppf(1.0 - alpha / nbins, nu) / nu)
    r_in = ratio[inner]
    peaks = [
        i + 1
        for i in range(r_in.size)
        if r_in[i] > thr and (i == 0 or r_in[i] >= r_in[i - 1]) and (i == r_in.size - 1 or r_in[i] >= r_in[i + 1])
    ]
    df = f[1] - f[0] if f.size > 1 else rate
    # Hann-window equivalent noise bandwidth 1.5 bins: tone power ≈ Σ PSD over the peak × Δf.
    tones = []
    for i in peaks:
        lo, hi = max(i - 2, 0), min(i + 3, pxx.size)
        power = float(np.sum(pxx[lo:hi] - bg[lo:hi]) * df)
        tones.append(
            {"frequency_hz": float(f[i]), "ratio": float(ratio[i]), "amplitude": math.sqrt(max(2.0 * power, 0.0))}
        )
    stat = float(r_in.max()) if r_in.size else 0.0
    p = float(min(1.0, nbins * stats.chi2.sf(stat * nu, nu)))
    note = (
        f"{len(tones)} tone(s) above the background; hand to 'tablebench periodic'" if tones else "no significant tone"
    )
    return TestResult(
        "welch_periodicity",
        stat,
        thr,
        "reject" if tones else "pass",
        alpha,
        p,
        note,
        {"tones": tones, "frequencies": [t["frequency_hz"] for t in tones], "nperseg": nperseg, "dof": nu},
    )
