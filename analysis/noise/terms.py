"""Noise terms of an Allan-variance curve: weighted non-negative least squares and the slope-line reading.

IEEE 952 (gyros) / IEEE 1293 (accelerometers) model (docs/methods/noise.md)::

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln2/π) B² + K² τ/3 + R² τ²/2  =  Σ_{n=−2}^{2} C_n τ^n

All values SI for a record in the data unit u (rad/s for gyros, m/s² for accelerometers):

====  ==========================  =========  ============  ==============================
term  meaning                     SI unit    gyro display  accelerometer display
====  ==========================  =========  ============  ==============================
Q     quantisation                u·s        arcsec        mm/s
N     white noise (ARW / VRW)     u·√s       °/√h          µg/√Hz
B     bias instability (flicker)  u          °/h           µg
K     rate / accel. random walk   u/√s       °/h/√h        µg/√s
R     rate / accel. ramp          u/s        °/h²          µg/s
====  ==========================  =========  ============  ==============================

Uniform quantisation with step LSB (of the integrated quantity) gives Q = LSB/√12.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import nnls

from analysis import units
from analysis.noise.slope import COVERAGE, slope_readings
from analysis.units import magnitude_problem

TERMS: tuple[str, ...] = ("Q", "N", "B", "K", "R")
"""Noise terms in the order of the powers τ^−2 … τ^2."""
POWERS: tuple[int, ...] = (-2, -1, 0, 1, 2)
"""Power of τ of each term's Allan-variance contribution."""
GAINS: tuple[float, ...] = (3.0, 1.0, 2.0 * math.log(2.0) / math.pi, 1.0 / 3.0, 0.5)
"""C_n = GAINS[n] · term² for the Allan variance (IEEE 952)."""
HADAMARD_GAINS: tuple[float, ...] = (
    3.0 * 10.0 / 9.0,
    1.0,
    (8.0 * math.log(2.0) - 3.0 * math.log(3.0)) / (2.0 * math.pi),
    1.0 / 6.0,
    0.0,
)
"""C_n = HADAMARD_GAINS[n] · term² for the Hadamard variance: its response ∫ S_y(f) (8/3) sin⁶(πfτ)/(πfτ)² df
against the Allan variance's 2 sin⁴(πfτ)/(πfτ)² is 10/9 for white PM (same cutoff), 1 for white FM,
(8 ln 2 − 3 ln 3)/(4 ln 2) = 0.811 for flicker FM, 1/2 for random-walk FM and 0 for a rate ramp (the Hadamard
variance does not see linear frequency drift, so R cannot be fitted from it)."""

FIT_GAINS: dict[str, tuple[float, ...]] = {
    "adev": GAINS,
    "oadev": GAINS,
    "totdev": GAINS,
    "theoh": GAINS,
    "hdev": HADAMARD_GAINS,
    "ohdev": HADAMARD_GAINS,
    "htotdev": HADAMARD_GAINS,
}
"""Estimators the noise-term fit accepts, with the gains of their expectation for each IEEE 952 term.

Allan model: ADEV, OADEV, TOTDEV (its value divided by the total-variance bias of the identified noise, as
Stable32 prints it), TheoH (the Allan variance below 20 % of the record, TheoBR beyond). Hadamard model: HDEV,
OHDEV, HTOTDEV (bias-corrected); no rate-ramp term. Refused: MDEV/TDEV/MTOTDEV/TTOTDEV (the modified variances'
gains depend on m and their white-PM term goes as τ⁻³, not τ⁻²), Theo1 (biased against the Allan variance
except for white FM), TheoBR over all τ (one bias factor for the whole run, taken from the long-τ Allan
variance: with white noise at short τ and random walk at long τ it inflates the short-τ part by the random walk's
bias, 1.7× in N on a test record; TheoH uses it only at long τ), MTIE and TIE rms (not variances of the
power-law model)."""
B_FLOOR: float = math.sqrt(2.0 * math.log(2.0) / math.pi)
"""Flicker floor of the Allan deviation per unit bias instability, ≈ 0.6643."""

_DISPLAY_KIND: dict[str, dict[str, str]] = {
    "rad/s": {"Q": "angle_quantisation", "N": "arw", "B": "gyro_bias", "K": "rrw", "R": "rate_ramp"},
    "m/s^2": {
        "Q": "velocity_quantisation",
        "N": "vrw",
        "B": "acceleration",
        "K": "accel_random_walk",
        "R": "accel_ramp",
    },
}
_SI_UNIT: dict[str, dict[str, str]] = {
    "rad/s": {"Q": "rad", "N": "rad/s^0.5", "B": "rad/s", "K": "rad/s^1.5", "R": "rad/s^2"},
    "m/s^2": {"Q": "m/s", "N": "m/s^1.5", "B": "m/s^2", "K": "m/s^2.5", "R": "m/s^3"},
}


def term_unit(term: str, data_unit: str) -> str:
    """SI unit label of ``term`` for a record in ``data_unit`` ("rad/s", "m/s^2", or anything else)."""
    if data_unit in _SI_UNIT:
        return _SI_UNIT[data_unit][term]
    u = f"({data_unit})" if data_unit not in ("SI", "") else "u"
    return {"Q": f"{u}*s", "N": f"{u}*s^0.5", "B": u, "K": f"{u}/s^0.5", "R": f"{u}/s"}[term]


def to_display(term: str, value_si: float, data_unit: str) -> tuple[float, str]:
    """A term value in its conventional display unit (°/√h, °/h, µg/√Hz, µg …); SI unchanged otherwise."""
    kinds = _DISPLAY_KIND.get(data_unit)
    if kinds is None:
        return value_si, term_unit(term, data_unit)
    kind = kinds[term]
    return units.to_display(kind, value_si), units.display_unit(kind)


def noise_model(tau: ArrayLike, coefficients: ArrayLike) -> NDArray[np.float64]:
    """σ²(τ) = Σ C_n τ^n for coefficients (C_−2 … C_2), u²."""
    t = np.asarray(tau, dtype=np.float64)
    c = np.asarray(coefficients, dtype=np.float64)
    return sum(c[i] * t ** POWERS[i] for i in range(5))


def term_contributions(tau: ArrayLike, coefficients: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Allan deviation of each term alone, u, keyed by term name."""
    t = np.asarray(tau, dtype=np.float64)
    return {TERMS[i]: np.sqrt(max(float(coefficients[i]), 0.0) * t ** POWERS[i]) for i in range(5)}


def coefficients_to_terms(
    c: ArrayLike, cov: ArrayLike, gains: tuple[float, ...] = GAINS
) -> dict[str, tuple[float, float]]:
    """Terms (value, 1σ) from C_n and their covariance.

    Term = √(C/g); σ_term = σ_C/(2√(gC)). When C = 0 (at the non-negativity bound) the value is 0 and the
    reported σ is √(σ_C/g): the term size that a 1σ coefficient would mean (an upper-bound scale).
    """
    c = np.asarray(c, dtype=np.float64)
    sig = np.sqrt(np.clip(np.diag(np.asarray(cov, dtype=np.float64)), 0.0, None))
    out: dict[str, tuple[float, float]] = {}
    for i, name in enumerate(TERMS):
        g = gains[i]
        if g == 0.0:
            out[name] = (float("nan"), float("nan"))
            continue
        val = math.sqrt(max(c[i], 0.0) / g)
        s = sig[i] / (2.0 * math.sqrt(g * c[i])) if c[i] > 0 else math.sqrt(sig[i] / g)
        out[name] = (val, float(s))
    return out


@dataclass
class NoiseFit:
    """Result of :func:`fit_noise_terms` for one channel.

    Attributes
    ----------
    coefficients : ndarray (5,)
        C_−2 … C_2 (u²·s^−n), non-negative.
    covariance : ndarray (5, 5)
        Their covariance (diagonal-error sandwich; the correlation of Allan variances between τ is neglected).
    terms : dict[str, tuple[float, float]]
        Q, N, B, K, R: (value, 1σ), SI. σ is the larger of the covariance value and the single-best-point
        bound (see :func:`fit_noise_terms`), because the sandwich alone is optimistic.
    tau_used : ndarray
        τ of the points that entered the fit, s.
    chi2_red : float
        Reduced χ² of the weighted residuals (≈ 1 when the model and the EDF are right).
    """

    coefficients: NDArray[np.float64]
    covariance: NDArray[np.float64]
    terms: dict[str, tuple[float, float]]
    tau_used: NDArray[np.float64]
    chi2_red: float


def fit_noise_terms(
    tau: ArrayLike,
    var: ArrayLike,
    record_time: float,
    edf: ArrayLike | None = None,
    terms: tuple[str, ...] = TERMS,
    iterations: int = 4,
    gains: tuple[float, ...] = GAINS,
) -> NoiseFit:
    """Fit σ²(τ) = Σ C_n τ^n by weighted non-negative least squares.

    Weights 1/(σ_j² √(τ_j/T)) as in the spec (the relative scatter of an Allan variance grows as √(τ/T));
    unweighted least squares returns negative C_n. σ_j² is the measured variance in the first pass and the
    fitted model in the following ``iterations`` − 1 passes (iteratively reweighted: weighting by the
    measured value favours points that scattered low and biases the fit down).

    Parameters
    ----------
    tau : array_like (M,)
        Averaging times, s.
    var : array_like (M,)
        Allan variances (overlapping AVAR recommended), u².
    record_time : float
        Record length T = N T_s, s.
    edf : array_like (M,), optional
        Equivalent degrees of freedom per point, for the coefficient covariance (Var σ²_j = 2σ⁴_j/EDF_j);
        default the white-noise value 1.5 T/τ.
    terms : tuple of str
        Terms to include (others fixed at 0).
    iterations : int
        Reweighting passes.
    gains : tuple of float
        C_n = gains[n]·term² of the fitted variance (:data:`GAINS` Allan, :data:`HADAMARD_GAINS`); a term with
        gain 0 is left out of the fit and reported NaN.

    Returns
    -------
    NoiseFit
    """
    t = np.asarray(tau, dtype=np.float64)
    v = np.asarray(var, dtype=np.float64)
    ok = np.isfinite(v) & (v > 0) & np.isfinite(t) & (t > 0)
    e = np.asarray(edf, dtype=np.float64)[ok] if edf is not None else 1.5 * record_time / t[ok]
    t, v = t[ok], v[ok]
    if t.size < 2:
        raise ValueError("fewer than two usable Allan-variance points; record too short for a noise-term fit")
    cols = [i for i, name in enumerate(TERMS) if name in terms and gains[i] > 0.0]
    a_full = np.stack([t**p for p in POWERS], axis=1)
    a = a_full[:, cols]
    ref = v.copy()
    coef = np.zeros(5)
    for _ in range(max(1, iterations)):
        w = 1.0 / (ref * np.sqrt(t / record_time))
        aw = a * w[:, None]
        scale = np.linalg.norm(aw, axis=0)
        scale[scale == 0] = 1.0
        y, _ = nnls(aw / scale, v * w, maxiter=50 * len(cols) + 100)
        coef = np.zeros(5)
        coef[cols] = y / scale
        model = a_full @ coef
        if not np.all(model > 0):
            break
        ref = model
    # covariance: sandwich with Var(σ²_j) = 2 σ⁴_j / EDF_j, model σ² where available
    sig2 = np.where(a_full @ coef > 0, a_full @ coef, v) ** 2 * 2.0 / np.maximum(e, 1.0)
    w = 1.0 / (ref * np.sqrt(t / record_time))
    resid = (v - a_full @ coef) / np.sqrt(sig2)
    dof = max(t.size - int(np.count_nonzero(coef)), 1)
    chi2_red = float(resid @ resid / dof)
    cov = np.zeros((5, 5))
    aw = a * w[:, None]
    scale = np.linalg.norm(aw, axis=0)
    scale[scale == 0] = 1.0
    aws = aw / scale
    bread = np.linalg.pinv(aws.T @ aws, rcond=1e-13)
    meat = (aws * (w**2 * sig2)[:, None]).T @ aws
    cov_s = bread @ meat @ bread / np.outer(scale, scale)
    cov[np.ix_(cols, cols)] = cov_s
    terms_out = coefficients_to_terms(coef, cov, gains)
    # Allan variances at neighbouring τ are correlated, which the sandwich ignores: a term is not known better
    # than from the single most informative point, where its share f_j of σ²_j and the EDF give
    # δterm/term = 1/(f_j √(2 EDF_j)). The larger of the two is reported.
    model = a_full @ coef
    for i, name in enumerate(TERMS):
        if coef[i] > 0 and np.all(model > 0):
            share = coef[i] * t ** POWERS[i] / model
            rel = float(np.min(1.0 / (share * np.sqrt(2.0 * np.maximum(e, 1.0)))))
            val, sig = terms_out[name]
            terms_out[name] = (val, max(sig, val * rel))
    return NoiseFit(coef, cov, terms_out, t, chi2_red)


FIT_ESTIMATORS: tuple[str, ...] = tuple(FIT_GAINS)
"""Estimators accepted by the noise-term fit (see :data:`FIT_GAINS`)."""


def _rows(arrays: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """The equal-length 1-D float64 arrays as one C-contiguous (C, N) array: a view when they already are the
    consecutive rows of one (as the recording loader delivers them), else one copy."""
    n = arrays[0].size
    step = n * 8
    ptr = [a.__array_interface__["data"][0] for a in arrays]
    if all(a.dtype == np.float64 and a.flags.c_contiguous for a in arrays) and all(
        p == ptr[0] + i * step for i, p in enumerate(ptr)
    ):
        return np.lib.stride_tricks.as_strided(arrays[0], shape=(len(arrays), n), strides=(step, 8), writeable=False)
    out = np.empty((len(arrays), n))
    for i, a in enumerate(arrays):
        out[i] = a
    return out


def analyse_noise(
    channels: dict[str, ArrayLike],
    rate: float,
    units: dict[str, str] | str | None = None,
    taus: str | ArrayLike = "octave",
    confidence: float = 0.683,
    terms: tuple[str, ...] = TERMS,
    published_itotvar: bool = False,
    estimators: tuple[str, ...] = ("adev", "oadev", "mdev", "totdev"),
    data_type: str = "freq",
    fit_estimator: str = "oadev",
    noise_type: int | list[tuple[float, float, int]] | None = None,
    remove_drift: str | None = None,
    edf_rules: str = "tablebench",
) -> dict:
    """Stability deviations with intervals and fitted noise terms of named channels (the ``noise.json`` data).

    Parameters
    ----------
    channels : dict[str, array_like (N,)]
        Channel name → record (equal lengths), SI: rate (rad/s) or specific force (m/s²) for
        ``data_type="freq"``, angle (rad) or velocity (m/s) for ``"phase"``; body frame, each axis on its own;
        NaN samples are gaps.
    rate : float
        Sample rate, Hz.
    units : dict[str, str] or str, optional
        SI unit label of the *rate* quantity per channel ("rad/s", "m/s^2"; anything else is generic);
        default "SI".
    taus : {"octave", "decade", "all", "log"} or array_like
        τ grid (:func:`analysis.noise.stability.m_grid`).
    confidence : float
        Two-sided probability of the intervals.
    terms : tuple of str
        Terms included in the fit.
    published_itotvar : bool
        Also report ``itotdev_published`` (frequency input without gaps only): the published "improved total
        variance" reproduced (:func:`analysis.noise.allan.improved_total_variance`; no better than ADEV).
    estimators : tuple of str
        Estimators to compute (:data:`analysis.noise.stability.ESTIMATORS`); the fit estimator is added.
    data_type : {"freq", "phase"}
        What the records hold.
    fit_estimator : str
        Estimator for the NNLS and slope-line term reading, one of :data:`FIT_ESTIMATORS`.
    noise_type, edf_rules : int or list of (τ_lo, τ_hi, α), optional; {"tablebench", "stable32"}
        Noise type set by hand for the intervals and the fit, and the EDF rules of the intervals
        (:func:`analysis.noise.stability.stability`).
    remove_drift : {"linear", "quadratic"}, optional
        Frequency drift removed from each channel first (:func:`analysis.noise.drift_removal.remove_drift`);
        the removed polynomial is reported per channel under ``"drift_removed"``.

    Returns
    -------
    dict
        ``{"rate_hz", "n_samples", "data_type", "confidence", "estimators", "channels": {NAME: {"unit",
        "gaps": {"samples", "runs"}, "deviations": {EST: {"tau", "m", "value", "n_terms", "edf", "lo",
        "hi", "alpha"[, "value_unbiased"]}}, "tau", "adev", "oadev", …, "terms", "terms_display",
        "slope_terms", "fit"}}}``: deviations in the rate unit (TDEV, TTOTDEV, MTIE, TIE rms in the phase
        unit), terms SI and in display units, each term with its standard uncertainty (1σ); undefined values
        NaN (written as null).
    """
    from analysis.noise.stability import stability

    if fit_estimator not in FIT_ESTIMATORS:
        raise ValueError(
            f"the noise-term fit needs an estimator with a fixed gain per noise term "
            f"({', '.join(FIT_ESTIMATORS)}), got {fit_estimator!r}"
        )
    names, arrays, unit_of = _checked_channels(channels, units)
    removed = {}
    if remove_drift is not None:
        from analysis.noise.drift_removal import remove_drift as _remove

        for i, k in enumerate(names):
            arrays[i], removed[k] = _remove(arrays[i], rate, remove_drift, data_type)
    n = arrays[0].size
    data = _rows(arrays).T  # (N, C) view of a (C, N) array: stability reads its rows without a copy
    del arrays
    ests = tuple(dict.fromkeys((*estimators, fit_estimator)))
    res = stability(data, rate, ests, taus, data_type, confidence=confidence, noise_type=noise_type,
                    edf_rules=edf_rules)  # fmt: skip
    itot = None
    if published_itotvar:
        if data_type != "freq" or np.isnan(data).any():
            raise ValueError("--published-itotvar needs a gap-free frequency (rate) record")
        from analysis.noise.allan import improved_total_variance

        itot = improved_total_variance(data, rate, res.estimates[fit_estimator].tau)
    del data
    record_time = (res.n_points - 1) / rate
    fe = res.estimates[fit_estimator]
    out_channels: dict[str, dict] = {}
    for j, name in enumerate(names):
        try:
            fitted = _channel_terms(fe, j, unit_of[name], res.n_points, record_time, terms, fit_estimator)
        except ValueError as exc:
            raise ValueError(f"channel {name!r}: {exc} (is the channel constant?)") from None
        ch = _channel_deviations(res, j, unit_of[name])
        ch.update(_flat_keys(res, fe, j))
        if itot is not None:
            ch["itotdev_published"] = np.sqrt(itot.var["itotvar"][:, j])
        ch.update(fitted)
        if remove_drift is not None:
            ch["drift_removed"] = {
                "model": remove_drift,
                "data_type": data_type,
                "coefficients": removed[name],
                "powers_of_t_s": list(range(removed[name].size)),
            }
        out_channels[name] = ch
    return {
        "rate_hz": float(rate),
        "n_samples": int(n),
        "data_type": data_type,
        "confidence": confidence,
        "estimators": list(res.estimates),
        "noise_type": "identified" if noise_type is None else noise_type,
        "edf_rules": edf_rules,
        "remove_drift": remove_drift,
        "channels": out_channels,
    }


def _checked_channels(
    channels: dict[str, ArrayLike], units: dict[str, str] | str | None
) -> tuple[list[str], list[NDArray[np.float64]], dict[str, str]]:
    """Names, 1-D float64 records (equal lengths, magnitudes a variance can hold) and unit label per channel."""
    if not channels:
        raise ValueError("no channels to analyse")
    names = list(channels)
    arrays = [np.asarray(channels[k], dtype=np.float64).ravel() for k in names]
    n = arrays[0].size
    bad = [k for k, a in zip(names, arrays, strict=True) if a.size != n]
    if bad:
        raise ValueError(f"channels {', '.join(bad)} differ in length from {names[0]} ({n} samples)")
    for k, a in zip(names, arrays, strict=True):
        too_large = magnitude_problem(a, "variance")
        if too_large:
            raise ValueError(f"channel {k!r}: {too_large}")
    if isinstance(units, str) or units is None:
        unit_of = {k: units or "SI" for k in names}
    else:
        unit_of = {k: units.get(k, "SI") for k in names}
    return names, arrays, unit_of


def _channel_deviations(res, j: int, unit: str) -> dict:
    """Channel j's unit, gaps and deviations of every estimator (with intervals where computed)."""
    ch: dict = {
        "unit": unit,
        "gaps": {"samples": int(res.gap_samples[j]), "runs": int(res.gap_runs[j])},
        "deviations": {},
    }
    for est_name, est in res.estimates.items():
        d = {
            "tau": est.tau,
            "m": est.m,
            "value": est.dev[:, j],
            "n_terms": est.n_terms[:, j],
        }
        if est.edf is not None:
            d.update(edf=est.edf[:, j], lo=est.lo[:, j], hi=est.hi[:, j], alpha=est.alpha[:, j])
        if est.bias is not None:
            d["value_unbiased"] = est.unbiased()[:, j]
        ch["deviations"][est_name] = d
    return ch


def _flat_keys(res, fe, j: int) -> dict:
    """The classic flat keys (τ grid of the fit estimator ``fe``) for existing readers."""
    flat_keys: dict = {"tau": fe.tau}
    for est_name in ("adev", "oadev", "mdev", "totdev"):
        if est_name in res.estimates:
            e = res.estimates[est_name]
            flat = np.full(fe.m.size, np.nan)
            hit = np.isin(fe.m, e.m)
            flat[hit] = e.dev[np.searchsorted(e.m, fe.m[hit]), j]
            flat_keys[est_name] = flat
    return flat_keys


def _channel_terms(
    fe, j: int, unit: str, n_points: int, record_time: float, terms: tuple[str, ...], fit_estimator: str
) -> dict:
    """Channel j's fitted noise terms (SI and display), slope-line readings and fit facts from estimate ``fe``."""
    gains = FIT_GAINS[fit_estimator]
    fit_dev = fe.unbiased()[:, j]
    fit = fit_noise_terms(
        fe.tau, fit_dev**2, record_time, fe.edf[:, j] if fe.edf is not None else None, terms, gains=gains
    )
    out: dict = {}
    out["terms"] = {
        t: {"value": v, "sigma": s, "uncertainty": "standard (1σ)", "unit": term_unit(t, unit)}
        for t, (v, s) in fit.terms.items()
    }
    disp = {}
    for t, (v, s) in fit.terms.items():
        dv, du = to_display(t, v, unit)
        ds, _ = to_display(t, s, unit)
        disp[t] = {"value": dv, "sigma": ds, "uncertainty": "standard (1σ)", "unit": du}
    out["terms_display"] = disp
    slope = slope_readings(fe.tau, fe.dev[:, j], fe.m, n_points, fit_estimator, gains, fit.terms)
    out["slope_terms"] = {
        t: {**d, "unit": term_unit(t, unit), "upper_bound": True, "coverage": COVERAGE} for t, d in slope.items()
    }
    out["fit"] = {
        "estimator": fit_estimator,
        "model": "hadamard" if gains is HADAMARD_GAINS else "allan",
        "coefficients": fit.coefficients,
        "powers": list(POWERS),
        "chi2_red": fit.chi2_red,
        "tau_used": fit.tau_used,
    }
    return out
