"""The slope-line reading of the noise terms (IEEE Std 952-1997, Annex C), made robust to noise identification.

The classic reading moves a straight line of each term's slope (−1, −½, 0, +½, +1 in log-log for Q, N, B, K, R)
until it touches the Allan-deviation curve from below and reads the term off it: Q = σ τ/√3, N = σ √τ,
B = σ / 0.6643, K = σ √(3/τ), R = σ √2/τ (for a deviation with other gains, term = σ τ^(−n/2)/√gain). Every term's
own line lies under the noise-free curve, so each reading is an *upper bound* of its term; on a measured curve
the touching point is the one that scattered lowest, so a reading can fall below the term when noisy points are
read.

This module reads only where the deviation is known well *whatever the noise type*: a point is eligible when the
smallest equivalent degrees of freedom over the plausible power-law types (α = 2 … −2, white PM to random-walk
FM; :func:`analysis.noise.confidence.edf`) is at least :data:`MIN_EDF` — so a misidentified noise type cannot
make a point with two averages look precise. The reading's interval is the χ² interval of that point with that
smallest EDF, each tail at (1 − coverage)/K for K eligible points (Bonferroni over the points the minimum was
taken from): its upper end is then above the true term in at least ``coverage`` of records, for any noise type.
A reading whose upper end falls below the term fitted by weighted NNLS is flagged (``below_fit``): the fit is then
too high for the curve somewhere, or the model is missing a term. See docs/methods/noise.md.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from analysis.noise import confidence as ci

PLAUSIBLE_ALPHA: tuple[int, ...] = (2, 1, 0, -1, -2)
"""Power-law noise types a reading must be robust to (S_y ∝ f^α: white PM … random-walk FM)."""
MIN_EDF: float = 200.0
"""Smallest EDF (over :data:`PLAUSIBLE_ALPHA`) of a point that is read: a 68 % χ² half-width of ≈ 5 %."""
COVERAGE: float = 0.95
"""Probability that a reading's upper bound is at or above the true term, any noise type."""
SLOPES: dict[str, float] = {"Q": -1.0, "N": -0.5, "B": 0.0, "K": 0.5, "R": 1.0}
"""Log-log slope of the Allan *deviation* of each term."""
_POWERS = {"Q": -2, "N": -1, "B": 0, "K": 1, "R": 2}
_EDF_KIND = {"adev": "adev", "oadev": "oadev", "totdev": "totdev", "theoh": "oadev", "hdev": "hdev",
             "ohdev": "ohdev", "htotdev": "htotdev"}  # fmt: skip
"""EDF model per fit estimator (TheoH: the overlapping ADEV's, smaller than TheoBR's at long τ)."""


def worst_edf(estimator: str, m: ArrayLike, n_points: int) -> np.ndarray:
    """Smallest EDF over :data:`PLAUSIBLE_ALPHA` of ``estimator`` at each averaging factor m (NaN: none)."""
    kind = _EDF_KIND[estimator]
    out = []
    for mm in np.atleast_1d(np.asarray(m, dtype=np.int64)):
        vals = [ci.edf(kind, a, int(mm), int(n_points)) for a in PLAUSIBLE_ALPHA]
        vals = [v for v in vals if math.isfinite(v) and v > 0]
        out.append(min(vals) if vals else math.nan)
    return np.asarray(out, dtype=np.float64)


def conservative_dev(estimator: str, dev: ArrayLike, m: ArrayLike, tau: ArrayLike, record_time: float) -> np.ndarray:
    """The deviation read: TOTDEV/HTOTDEV divided by the square root of their largest plausible bias (random-walk
    FM), every other estimator as it is — a reading stays an upper bound whatever the noise type."""
    d = np.asarray(dev, dtype=np.float64)
    if estimator not in ("totdev", "htotdev"):
        return d
    alpha = np.full((d.size, 1), -2, dtype=np.int64)
    b = ci.bias_factor(estimator, alpha, np.asarray(m), np.asarray(tau, dtype=np.float64), record_time)[:, 0]
    return d / np.sqrt(np.where(np.isfinite(b) & (b > 0), b, 1.0))


def slope_readings(
    tau: ArrayLike,
    dev: ArrayLike,
    m: ArrayLike,
    n_points: int,
    estimator: str,
    gains: tuple[float, ...],
    fitted: dict[str, tuple[float, float]] | None = None,
    coverage: float = COVERAGE,
    min_edf: float = MIN_EDF,
) -> dict[str, dict[str, float | bool | int]]:
    """Slope-line readings of the noise terms from a deviation curve (see the module docstring).

    Parameters
    ----------
    tau, dev, m : array_like (M,)
        Averaging times (s), deviations (u; TOTDEV/HTOTDEV raw, the conservative bias is applied here) and
        averaging factors of ``estimator``.
    n_points : int
        Phase points of the record (N_f + 1 for frequency data).
    estimator : str
        The fit estimator (:data:`analysis.noise.terms.FIT_ESTIMATORS`).
    gains : tuple of float
        Gains C_n = gain·term² of the deviation's variance for Q … R; terms with gain 0 are not read.
    fitted : dict, optional
        Term → (value, σ) of the NNLS fit, for the ``below_fit`` flag.
    coverage : float
        Probability that the stated upper bound is at or above the true term.
    min_edf : float
        Smallest worst-case EDF of a point that is read.

    Returns
    -------
    dict
        term → {"value", "lo", "hi", "sigma" (SI), "tau" (s), "edf" (worst case at the point), "points" (K),
        "observed" (the curve's local slope within ±0.2 of the term's), "below_fit" (hi below the fitted term)};
        empty when no point is known well enough.
    """
    t = np.asarray(tau, dtype=np.float64)
    mm = np.asarray(m, dtype=np.int64)
    record_time = (int(n_points) - 1) * float(t[0] / mm[0]) if t.size else 0.0
    d = conservative_dev(estimator, dev, mm, t, record_time)
    ok = np.isfinite(d) & (d > 0) & np.isfinite(t) & (t > 0)
    t, d, mm = t[ok], d[ok], mm[ok]
    local = np.gradient(np.log(d), np.log(t)) if t.size >= 2 else np.zeros(t.shape)
    e = worst_edf(estimator, mm, n_points) if t.size else np.zeros(0)
    good = np.isfinite(e) & (e >= min_edf)
    out: dict[str, dict[str, float | bool | int]] = {}
    k = int(np.count_nonzero(good))
    if k == 0:
        return out
    t, d, e, local = t[good], d[good], e[good], local[good]
    tail = (1.0 - coverage) / k
    names = ("Q", "N", "B", "K", "R")
    for i, name in enumerate(names):
        g = gains[i]
        if g <= 0.0:
            continue
        vals = d * t ** (-_POWERS[name] / 2.0) / math.sqrt(g)
        j = int(np.argmin(vals))
        v, ej = float(vals[j]), float(e[j])
        lo = v * math.sqrt(ej / stats.chi2.ppf(1.0 - tail, ej))
        hi = v * math.sqrt(ej / stats.chi2.ppf(tail, ej))
        fit_v = fitted.get(name, (math.nan, math.nan))[0] if fitted else math.nan
        out[name] = {
            "value": v,
            "lo": lo,
            "hi": hi,
            "sigma": v / math.sqrt(2.0 * ej),
            "tau": float(t[j]),
            "edf": ej,
            "points": k,
            "observed": bool(abs(local[j] - SLOPES[name]) <= 0.2),
            "below_fit": bool(math.isfinite(fit_v) and hi < fit_v),
        }
    return out
