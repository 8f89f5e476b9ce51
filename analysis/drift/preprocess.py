"""Pre-processing of a static drift record: outlier replacement and polynomial detrending.

Specification: docs/methods/drift.md ("Pre-processing"). The input is one channel of a static
record (a gyro in rad/s or an accelerometer in m/s², any frame: the functions act on a scalar series), sampled
uniformly. Nothing here depends on the unit of the series; outputs carry the input's unit.

Errors (NaNs, constant or too-short series) raise :class:`DriftInputError` with a message naming the problem
and the fix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.units import magnitude_problem
from core.errors import UserError

MAD_TO_SIGMA: float = 1.4826022185056018
"""Scale factor making the median absolute deviation a consistent estimator of σ for Gaussian data."""


class DriftInputError(UserError, ValueError):
    """A series cannot be analysed (NaNs, constant, too short); the message names the fix."""


def check_series(x: ArrayLike, name: str = "series", min_samples: int = 16) -> NDArray[np.float64]:
    """Return ``x`` as a finite, non-constant 1-D float64 array, or raise :class:`DriftInputError`.

    Parameters
    ----------
    x : array_like
        Scalar time series (any SI unit).
    name : str
        Name used in error messages (e.g. the channel name).
    min_samples : int
        Minimum accepted length.
    """
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 1:
        raise DriftInputError(f"{name}: expected a 1-D series, got shape {a.shape}")
    if a.size < min_samples:
        raise DriftInputError(f"{name}: only {a.size} samples; at least {min_samples} are needed (record longer)")
    bad = ~np.isfinite(a)
    if bad.any():
        raise DriftInputError(
            f"{name}: {int(bad.sum())} NaN/inf value(s), first at sample {int(np.argmax(bad))}; "
            "remove or interpolate them before drift analysis"
        )
    too_large = magnitude_problem(a, "variance and likelihood")
    if too_large:
        raise DriftInputError(f"{name}: {too_large}")
    scale = max(float(np.max(np.abs(a))), np.finfo(float).tiny)
    if float(np.ptp(a)) <= 1e-13 * scale:
        raise DriftInputError(
            f"{name}: the series is constant ({a[0]:.6g}); drift analysis needs a varying signal "
            "(check the channel selection or the sensor's quantisation)"
        )
    return a


@dataclass
class OutlierResult:
    """Result of :func:`replace_outliers`.

    Attributes
    ----------
    cleaned : ndarray
        Series with every flagged sample replaced by the previous retained (or replaced) sample.
    replaced : int
        Number of samples replaced.
    mask : ndarray of bool
        True where a sample was replaced.
    centre, scale : float
        Final location and scale (σ, or 1.4826·MAD) used for the k·scale threshold, input units.
    method : str
        ``"sigma"`` (Pauta / 3σ rule) or ``"mad"`` (robust).
    iterations : int
        Passes made until no new outlier was flagged.
    """

    cleaned: NDArray[np.float64]
    replaced: int
    mask: NDArray[np.bool_]
    centre: float
    scale: float
    method: str
    iterations: int


def _forward_fill(x: NDArray[np.float64], mask: NDArray[np.bool_], first_value: float) -> NDArray[np.float64]:
    """Replace masked samples by the last unmasked sample before them (vectorised)."""
    idx = np.where(~mask, np.arange(x.size), -1)
    np.maximum.accumulate(idx, out=idx)
    out = np.where(idx >= 0, x[np.maximum(idx, 0)], first_value)
    return out


def replace_outliers(x: ArrayLike, k: float = 3.0, method: str = "sigma", max_iter: int = 10) -> OutlierResult:
    """Flag samples beyond ``k`` times the scale from the centre and replace them with the previous sample.

    With ``method="sigma"`` this is the Pauta (3σ) rule with mean and standard deviation; since outliers
    inflate σ, the rule is iterated until no new sample is flagged (at most ``max_iter`` passes), always on
    the original values of the retained samples. ``method="mad"`` uses the median and 1.4826·MAD, which
    outliers barely move. A flagged first sample is replaced by the centre.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    k : float
        Threshold in scale units (3 by default).
    method : {"sigma", "mad"}
        Scale estimator.
    max_iter : int
        Maximum number of passes.

    Returns
    -------
    OutlierResult
    """
    a = check_series(x, min_samples=3)
    if method not in ("sigma", "mad"):
        raise DriftInputError(f"outlier method must be 'sigma' or 'mad', got {method!r}")
    if not (k > 0 and math.isfinite(k)):
        raise DriftInputError(f"outlier threshold k must be a positive number, got {k}")
    mask = np.zeros(a.size, dtype=bool)
    centre = scale = 0.0
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - number of passes is reported
        kept = a[~mask]
        if method == "sigma":
            centre, scale = float(kept.mean()), float(kept.std(ddof=1))
        else:
            centre = float(np.median(kept))
            scale = MAD_TO_SIGMA * float(np.median(np.abs(kept - centre)))
        if scale <= 0.0:
            break
        new = np.abs(a - centre) > k * scale
        if not (new & ~mask).any():
            break
        mask |= new
    cleaned = _forward_fill(a, mask, centre) if mask.any() else a.copy()
    return OutlierResult(cleaned, int(mask.sum()), mask, centre, scale, method, it)


@dataclass
class DetrendResult:
    """Result of :func:`detrend`.

    Attributes
    ----------
    residual : ndarray
        Series minus mean and polynomial trend (input units).
    trend : ndarray
        The fitted mean + polynomial (input units).
    order : int
        Polynomial order used (0 = mean only).
    coefficients : ndarray
        Power-series coefficients in time (s), lowest order first: trend(t) = Σ c_i t^i with t from 0 s.
    criteria : dict[int, float]
        Information criterion value per tried order (empty when the order was given).
    """

    residual: NDArray[np.float64]
    trend: NDArray[np.float64]
    order: int
    coefficients: NDArray[np.float64]
    criteria: dict[int, float]


def detrend(
    x: ArrayLike, rate: float = 1.0, order: int | None = None, max_order: int = 3, criterion: str = "bic"
) -> DetrendResult:
    """Remove the mean and a least-squares polynomial trend.

    The fit is made in Legendre polynomials of time scaled to [−1, 1] (well conditioned) and the
    coefficients are reported as an ordinary power series in seconds. When ``order`` is None it is chosen
    among 0..``max_order`` by ``criterion``: AIC = n ln σ̂² + 2(k+1), BIC = n ln σ̂² + (k+1) ln n with k the
    order. These criteria assume white residuals; on strongly coloured drift they favour higher orders,
    so a fixed order is preferable when the physics is known.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    rate : float
        Sample rate, Hz (only used to express the coefficients in seconds).
    order : int or None
        Polynomial order (0 = remove the mean only), or None to choose by ``criterion``.
    max_order : int
        Highest order tried when choosing.
    criterion : {"bic", "aic"}
        Information criterion for the order choice.
    """
    a = check_series(x)
    n = a.size
    if order is not None and (order < 0 or order >= n // 2):
        raise DriftInputError(f"detrend order {order} is invalid for {n} samples; use 0..{max(n // 2 - 1, 0)}")
    if criterion not in ("aic", "bic"):
        raise DriftInputError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    u = np.linspace(-1.0, 1.0, n)
    orders = [order] if order is not None else list(range(0, min(max_order, n // 2 - 1) + 1))
    vander = np.polynomial.legendre.legvander(u, max(orders))
    crits: dict[int, float] = {}
    fits: dict[int, NDArray[np.float64]] = {}
    for k in orders:
        coef, *_ = np.linalg.lstsq(vander[:, : k + 1], a, rcond=None)
        trend = vander[:, : k + 1] @ coef
        s2 = float(np.mean((a - trend) ** 2))
        fits[k] = coef
        if order is None:
            pen = 2.0 * (k + 1) if criterion == "aic" else (k + 1) * math.log(n)
            crits[k] = n * math.log(max(s2, np.finfo(float).tiny)) + pen
    best = order if order is not None else min(crits, key=crits.__getitem__)
    coef = fits[best]
    trend = vander[:, : best + 1] @ coef
    # Legendre in u → power series in u → power series in t (u = 2 t / T − 1, T = (n−1)/rate).
    pu = np.polynomial.legendre.leg2poly(coef)
    span = (n - 1) / rate if n > 1 else 1.0
    pt = np.polynomial.polynomial.Polynomial(pu)(np.polynomial.polynomial.Polynomial([-1.0, 2.0 / span]))
    coeffs_t = np.zeros(best + 1)
    coeffs_t[: len(pt.coef)] = pt.coef
    return DetrendResult(a - trend, trend, int(best), coeffs_t, crits)


@dataclass
class ToneFit:
    """A sinusoid removed by :func:`remove_tones`: frequency (Hz), amplitude (input units), phase (rad, cosine)."""

    frequency_hz: float
    amplitude: float
    phase: float


def remove_tones(
    x: ArrayLike, rate: float, frequencies: list[float], resolution_hz: float
) -> tuple[NDArray[np.float64], list[ToneFit]]:
    """Subtract least-squares sinusoids A cos(2π f t + φ) at the given tone frequencies.

    Each frequency is refined within ± ``resolution_hz`` (the Welch bin width) by maximising the
    least-squares explained power, then all tones are fitted jointly. Intended to keep strong periodic errors
    (analysed by ``tablebench periodic``) out of the ARMA drift model.

    Returns
    -------
    residual : ndarray
        Series minus the fitted tones.
    tones : list of ToneFit
    """
    from scipy import optimize

    a = np.asarray(x, dtype=np.float64)
    t = np.arange(a.size) / rate
    d = a - a.mean()

    def power(f: float) -> float:
        # explained power of the 2-column LS fit, by einsum dots (no threaded BLAS in this inner loop)
        c, s = np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)
        cc, ss, cs = np.einsum("i,i->", c, c), np.einsum("i,i->", s, s), np.einsum("i,i->", c, s)
        cd, sd = np.einsum("i,i->", c, d), np.einsum("i,i->", s, d)
        det = cc * ss - cs * cs
        if det <= 0:
            return 0.0
        return -float((ss * cd * cd - 2 * cs * cd * sd + cc * sd * sd) / det)

    refined = []
    for f0 in frequencies:
        lo, hi = max(f0 - resolution_hz, 1e-9), min(f0 + resolution_hz, 0.5 * rate - 1e-9)
        res = optimize.minimize_scalar(power, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6 * rate})
        refined.append(float(res.x))
    if not refined:
        return a.copy(), []
    cols = []
    for f in refined:
        cols += [np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)]
    m = np.stack(cols, axis=1)
    coef, *_ = np.linalg.lstsq(m, d, rcond=None)
    fits = [
        ToneFit(f, float(math.hypot(coef[2 * i], coef[2 * i + 1])), float(math.atan2(-coef[2 * i + 1], coef[2 * i])))
        for i, f in enumerate(refined)
    ]
    return a - m @ coef, fits
