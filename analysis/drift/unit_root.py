"""Unit-root and stationarity tests of a drift record: augmented Dickey–Fuller (ADF) and KPSS.

The two tests look from opposite sides. ADF (Dickey & Fuller 1979; Said & Dickey 1984) has the *unit root* as its
null: Δx_t = a + (ρ − 1) x_{t−1} + Σ_{j≤p} γ_j Δx_{t−j} + e_t, the statistic is the t-ratio of (ρ − 1), and the
lag order p is the one of 0 … p_max (p_max = ⌈12 (n/100)^¼⌉, Schwert 1989) with the smallest AIC (or BIC), all
candidates fitted on the same samples, then the chosen one refitted on every sample it allows. Its p-value is
MacKinnon's (1994) response-surface approximation, its critical values MacKinnon's (2010) finite-sample ones.
KPSS (Kwiatkowski, Phillips, Schmidt & Shin 1992) has *stationarity* (about a level, or a line) as its null:
η = Σ S_t² / (n² σ̂²) with S_t the partial sums of the residuals and σ̂² their Newey–West long-run variance with
the Bartlett kernel over the lags chosen by Hobijn, Franses & Ooms (1998); its p-value is interpolated in the
KPSS table (0.10 … 0.01, so it is clipped to that range). Both reproduce statsmodels' ``adfuller`` and ``kpss``
(the test reference). A drift record that ADF finds stationary and KPSS does not reject is stationary by both
readings; ADF failing to reject and KPSS rejecting points to a random walk (rate random walk) in the record.

The regressions are solved by one QR factorisation of the augmented design [X | y] (formed in row blocks, so a
long record needs no design matrix in memory): the nested lag models of the order search share it, each one's
residual sum of squares being the full model's plus the squares of the dropped components of Qᵀy.
See docs/methods/drift.md.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats

from analysis.drift.hypothesis_tests import TestResult
from analysis.drift.preprocess import DriftInputError

# MacKinnon (1994), Table 3 (N = 1 series): p = Φ(Σ c_k τ^k), "small p" below τ*, "large p" above; beyond
# [τ_min, τ_max] the p-value is 0 or 1. Keys: regression "n" (none), "c" (constant), "ct" (constant + trend).
_TAU_MAX = {"n": math.inf, "c": 2.74, "ct": 0.7}
_TAU_MIN = {"n": -19.04, "c": -18.83, "ct": -16.18}
_TAU_STAR = {"n": -1.04, "c": -1.61, "ct": -2.89}
_SMALL_P = {
    "n": (0.6344, 1.2378, 3.2496e-2),
    "c": (2.1659, 1.4412, 3.8269e-2),
    "ct": (3.2512, 1.6047, 4.9588e-2),
}
_LARGE_P = {
    "n": (0.4797, 0.93557, -0.06999, 0.033066),
    "c": (1.7339, 0.93202, -0.12745, -0.010368),
    "ct": (2.5261, 0.61654, -0.37956, -0.060285),
}
# MacKinnon (2010), Table 2 (N = 1): critical value at 1 %, 5 %, 10 % = β∞ + β₁/n + β₂/n² + β₃/n³.
_CRIT_2010 = {
    "n": ((-2.56574, -2.2358, -3.627, 0.0), (-1.94100, -0.2686, -3.365, 31.223), (-1.61682, 0.2656, -2.714, 25.364)),
    "c": (
        (-3.43035, -6.5393, -16.786, -79.433),
        (-2.86154, -2.8903, -4.234, -40.040),
        (-2.56677, -1.5384, -2.809, 0.0),
    ),
    "ct": (
        (-3.95877, -9.0531, -28.428, -134.155),
        (-3.41049, -4.3904, -9.036, -45.374),
        (-3.12705, -2.5856, -3.925, -22.380),
    ),
}
# KPSS (1992), Table 1: upper-tail critical values at 10 %, 5 %, 2.5 %, 1 % (level / trend stationarity).
_KPSS_CRIT = {"c": (0.347, 0.463, 0.574, 0.739), "ct": (0.119, 0.146, 0.176, 0.216)}
_KPSS_P = (0.10, 0.05, 0.025, 0.01)
_ROWS = 1 << 14
"""Rows per block of the QR factorisation."""


def mackinnon_p(stat: float, regression: str = "c") -> float:
    """MacKinnon's (1994) approximate p-value of an ADF t-statistic (one series)."""
    if stat > _TAU_MAX[regression]:
        return 1.0
    if stat < _TAU_MIN[regression]:
        return 0.0
    c = _SMALL_P[regression] if stat <= _TAU_STAR[regression] else _LARGE_P[regression]
    return float(stats.norm.cdf(sum(ck * stat**k for k, ck in enumerate(c))))


def mackinnon_critical(nobs: int, regression: str = "c") -> dict[str, float]:
    """MacKinnon's (2010) finite-sample ADF critical values at 1 %, 5 %, 10 % for ``nobs`` regression samples."""
    return {
        lvl: sum(b / nobs**k for k, b in enumerate(row))
        for lvl, row in zip(("1%", "5%", "10%"), _CRIT_2010[regression], strict=True)
    }


def _augmented_r(columns, nrows: int) -> NDArray[np.float64]:
    """R of the QR factorisation of the n × k matrix whose row block [a, b) is ``columns(a, b)`` (last column
    the response), accumulated block by block."""
    r = None
    for a in range(0, nrows, _ROWS):
        blk = columns(a, min(nrows, a + _ROWS))
        r = np.linalg.qr(blk if r is None else np.vstack([r, blk]), mode="r")
    return r


def _design(x: NDArray[np.float64], dx: NDArray[np.float64], lags: int, first: int, trend: int, level_last: bool):
    """Row-block builder of [trend cols, x_{t−1}, Δx_{t−1} … Δx_{t−lags}, Δx_t] (x_{t−1} after the lags when
    ``level_last``) for the regression rows i = first … len(dx) − 1 (Δx_i = x_{i+1} − x_i)."""
    n = dx.size - first

    def columns(a: int, b: int) -> NDArray[np.float64]:
        i = np.arange(first + a, first + b)
        cols = []
        if trend >= 1:
            cols.append(np.ones(i.size))
        if trend >= 2:
            cols.append((i - first + 1.0) / n)
        lagcols = [dx[i - j] for j in range(1, lags + 1)]
        cols += [*lagcols, x[i]] if level_last else [x[i], *lagcols]
        cols.append(dx[i])
        return np.column_stack(cols)

    return columns, n


def adf_test(
    x: ArrayLike,
    regression: str = "c",
    autolag: str | None = "aic",
    maxlag: int | None = None,
    alpha: float = 0.05,
) -> TestResult:
    """Augmented Dickey–Fuller test (null: a unit root), as statsmodels' ``adfuller``.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    regression : {"c", "ct", "n"}
        Deterministic terms: constant, constant + linear trend, none.
    autolag : {"aic", "bic"} or None
        Lag order by the information criterion over 0 … ``maxlag``, or ``maxlag`` itself when None.
    maxlag : int, optional
        Largest lag order (default ⌈12 (n/100)^¼⌉, at most n/2 − terms − 1).
    alpha : float
        Significance level of the verdict.

    Returns
    -------
    TestResult
        ``statistic`` the t-ratio, ``p_value`` MacKinnon's, ``threshold`` the critical value at 1, 5 or 10 %
        (the nearest to ``alpha``), verdict "pass" when the unit root is rejected (p < alpha: stationary), with
        ``extra`` = {used_lag, nobs, critical_values, ic_best, regression}.
    """
    if regression not in _TAU_MAX:
        raise DriftInputError(f"ADF regression must be 'c', 'ct' or 'n', got {regression!r}")
    if autolag not in ("aic", "bic", None):
        raise DriftInputError(f"ADF autolag must be 'aic', 'bic' or None, got {autolag!r}")
    a = np.asarray(x, dtype=np.float64).ravel()
    n = a.size
    if n < 8 or not np.all(np.isfinite(a)) or a.max() == a.min():
        raise DriftInputError("ADF needs at least 8 finite, not all equal values")
    trend = {"n": 0, "c": 1, "ct": 2}[regression]
    if maxlag is None:
        maxlag = min(n // 2 - trend - 1, int(math.ceil(12.0 * (n / 100.0) ** 0.25)))
    if maxlag < 0 or maxlag > n // 2 - trend - 1:
        raise DriftInputError(f"ADF: maxlag {maxlag} does not fit a series of {n} values")
    dx = np.diff(a)
    ic_best = math.nan
    lag = maxlag
    if autolag is not None:
        columns, m = _design(a, dx, maxlag, maxlag, trend, level_last=False)
        r = _augmented_r(columns, m)
        z = r[:-1, -1]
        ssr_full = float(r[-1, -1]) ** 2
        best = None
        for lg in range(maxlag + 1):
            k = trend + 1 + lg
            ssr = ssr_full + float(np.sum(z[k:] ** 2))
            ll2 = m * (math.log(2.0 * math.pi) + math.log(ssr / m) + 1.0)  # −2 ln L
            ic = ll2 + (2.0 * k if autolag == "aic" else k * math.log(m))
            if best is None or (ic, lg) < best:
                best = (ic, lg)
        ic_best, lag = best
    columns, m = _design(a, dx, lag, lag, trend, level_last=True)
    r = _augmented_r(columns, m)
    k = trend + lag + 1
    s2 = float(r[-1, -1]) ** 2 / (m - k)
    stat = float(r[k - 1, -1] * math.copysign(1.0, r[k - 1, k - 1]) / math.sqrt(s2))
    p = mackinnon_p(stat, regression)
    crit = mackinnon_critical(m, regression)
    level = min(crit, key=lambda s: abs(float(s.rstrip("%")) / 100.0 - alpha))
    return TestResult(
        "adf",
        stat,
        crit[level],
        "pass" if p < alpha else "reject",
        alpha,
        p,
        "null: a unit root (random walk); 'pass' = the unit root is rejected, the record is stationary "
        f"(MacKinnon p-value; threshold: the {level} critical value)",
        {"used_lag": int(lag), "nobs": int(m), "critical_values": crit, "ic_best": ic_best, "regression": regression},
    )


def _long_run_variance(e: NDArray[np.float64], lags: int) -> float:
    """Newey–West (Bartlett kernel) long-run variance of residuals e over ``lags`` lags."""
    n = e.size
    s = float(np.dot(e, e))
    for i in range(1, lags + 1):
        s += 2.0 * float(np.dot(e[i:], e[: n - i])) * (1.0 - i / (lags + 1.0))
    return s / n


def _kpss_lags(e: NDArray[np.float64]) -> int:
    """Hobijn, Franses & Ooms (1998) automatic bandwidth for the Bartlett kernel."""
    n = e.size
    cov_lags = int(n ** (2.0 / 9.0))
    s0 = float(np.dot(e, e)) / n
    s1 = 0.0
    for i in range(1, cov_lags + 1):
        g = float(np.dot(e[i:], e[: n - i])) / (n / 2.0)
        s0 += g
        s1 += i * g
    gamma = 1.1447 * ((s1 / s0) ** 2) ** (1.0 / 3.0)
    return int(gamma * n ** (1.0 / 3.0))


def kpss_test(x: ArrayLike, regression: str = "c", nlags: int | str = "auto", alpha: float = 0.05) -> TestResult:
    """KPSS test (null: stationary about a level, or about a line with ``regression="ct"``), as statsmodels' ``kpss``.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    regression : {"c", "ct"}
        Level or trend stationarity.
    nlags : int or {"auto", "legacy"}
        Bartlett-kernel lags: Hobijn et al. (1998) ("auto"), ⌈12 (n/100)^¼⌉ ("legacy") or a number.
    alpha : float
        Significance level of the verdict.

    Returns
    -------
    TestResult
        ``statistic`` η, ``p_value`` interpolated in the KPSS table (clipped to 0.01 … 0.10: the note says when),
        ``threshold`` the table's critical value nearest ``alpha``; verdict "reject" when p < alpha.
    """
    if regression not in _KPSS_CRIT:
        raise DriftInputError(f"KPSS regression must be 'c' or 'ct', got {regression!r}")
    a = np.asarray(x, dtype=np.float64).ravel()
    n = a.size
    if n < 8 or not np.all(np.isfinite(a)):
        raise DriftInputError("KPSS needs at least 8 finite values")
    if regression == "ct":
        t = np.arange(1, n + 1, dtype=np.float64)
        design = np.column_stack([np.ones(n), t])
        coef, *_ = np.linalg.lstsq(design, a, rcond=None)
        e = a - design @ coef
    else:
        e = a - a.mean()
    if nlags == "auto":
        lags = min(_kpss_lags(e), n - 1)
    elif nlags == "legacy":
        lags = min(int(math.ceil(12.0 * (n / 100.0) ** 0.25)), n - 1)
    else:
        lags = int(nlags)
        if not 0 <= lags < n:
            raise DriftInputError(f"KPSS: {lags} lags do not fit a series of {n} values")
    eta = float(np.sum(np.cumsum(e) ** 2)) / n**2
    stat = eta / _long_run_variance(e, lags)
    crit = _KPSS_CRIT[regression]
    p = float(np.interp(stat, crit, _KPSS_P))
    note = "null: stationary about a " + ("level" if regression == "c" else "linear trend")
    if p in (_KPSS_P[0], _KPSS_P[-1]):
        note += f"; the statistic is outside the table: the p-value is {'above' if p == _KPSS_P[0] else 'below'} {p}"
    j = int(np.argmin([abs(q - alpha) for q in _KPSS_P]))
    return TestResult(
        "kpss",
        stat,
        crit[j],
        "reject" if p < alpha else "pass",
        alpha,
        p,
        note,
        {"lags": lags, "critical_values": dict(zip(("10%", "5%", "2.5%", "1%"), crit, strict=True)),
         "regression": regression},
    )  # fmt: skip
