"""Drift analysis of static records: the whole chain of docs/methods/drift.md per channel.

For every channel (a scalar series in SI: rad/s for gyros, m/s² for accelerometers, body frame, any axis):

1. outlier replacement (3σ / MAD, previous-sample substitution), count reported;
2. mean + least-squares polynomial trend removal (order given or by BIC);
3. stationarity: Daniel and reverse-arrangement tests on M sub-series means and mean squares, ADF (null: a
   unit root) and KPSS (null: stationary) as statsmodels computes them;
4. periodicity: Welch peak significance, strong tones listed for ``tablebench periodic`` and (by default)
   subtracted by least squares before the ARMA modelling;
5. normality: Jarque–Bera (with the large-n caveat);
6. ACF / PACF with bands, ARMA order by BIC (AIC reported beside it; p, q ≤ 3, p ≥ q only on request) over
   exact maximum-likelihood fits with the mean estimated jointly (or fixed at zero; CSS on request), moment
   estimates, standard errors, convergence of every fit and parameter-redundancy flags, Ljung–Box on the
   residuals;
7. online RLS / extended LS over the record (compared with the batch fit);
8. compensation: state-space ARMA, steady-state Kalman filter over the record, sliding-window LM smoother
   over the first ``smoother_samples`` samples; standard deviations before and after.

:func:`analyse_drift` returns a JSON-ready dict ``{"channels": {NAME: {"model": …, "tests": …, …}}, …}``;
:func:`analyse_channel` returns the same per channel plus the arrays used for the plots. What could not be
settled is listed per channel under ``"unsettled"`` (candidate fits that did not converge, with their status and
gradient norm; a chosen model with a near-cancelling AR/MA root pair).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.drift.arma import REDUNDANCY_DISTANCE, OrderSelection, css_residuals, moment_estimates, select_order
from analysis.drift.hypothesis_tests import (
    acf,
    correlation_bands,
    daniel_test,
    jarque_bera_test,
    ljung_box_test,
    pacf_from_acf,
    reverse_arrangement_test,
    segment_stats,
    welch_tones,
)
from analysis.drift.preprocess import DriftInputError, check_series, detrend, remove_tones, replace_outliers
from analysis.drift.rls import OnlineArma
from analysis.drift.smoother import arma_state_space, sliding_window_smoother, steady_state_filter
from analysis.drift.unit_root import adf_test, kpss_test

MIN_SAMPLES = 200
"""Shortest record accepted for a drift analysis (the order selection needs ≥ 10 samples per parameter)."""


@dataclass
class DriftOptions:
    """Settings of the drift analysis (defaults follow the spec).

    Attributes
    ----------
    outlier_method : "sigma" (3σ Pauta rule) or "mad".
    outlier_k : threshold in scale units.
    detrend_order : polynomial order, or None to choose among 0..3 by BIC.
    segments : number M of sub-series for the stationarity tests.
    alpha : significance level of the tests.
    tone_alpha : family-wise significance of the Welch tone search.
    remove_tones : subtract least-squares sinusoids at the detected tones before the ARMA modelling (the
        tones themselves belong to ``tablebench periodic``).
    max_p, max_q : largest ARMA orders tried.
    p_ge_q : only orders with p ≥ q (the published method's rule; off by default so a pure MA(q) is reachable).
    include_mean : estimate the ARMA mean jointly by maximum likelihood (default; the detrended residual of a
        correlated record keeps an offset the least-squares mean removal mis-estimates), or fix it at zero.
    criterion : "bic" (the spec's choice) or "aic".
    fit_method : "ml" (exact maximum likelihood, default) or "css" (conditional least squares, faster on long
        records; the two agree within a fraction of a standard error there, but the order choice can differ).
    nlags : lags of the ACF/PACF and Ljung–Box (None: min(40, n/10) for the plots, 20 for Ljung–Box).
    online : run the online RLS/ELS over the record.
    forgetting : forgetting factor λ of the online estimator.
    measurement_var : R of the compensation model (unit²); None: the ARMA innovation variance σ².
    smoother_samples : samples smoothed by the sliding-window LM smoother (from the start of the record).
    window, stride : smoother window and stride, samples.
    """

    outlier_method: str = "sigma"
    outlier_k: float = 3.0
    detrend_order: int | None = None
    segments: int = 50
    alpha: float = 0.05
    tone_alpha: float = 0.01
    remove_tones: bool = True
    max_p: int = 3
    max_q: int = 3
    p_ge_q: bool = False
    include_mean: bool = True
    criterion: str = "bic"
    fit_method: str = "ml"
    nlags: int | None = None
    online: bool = True
    forgetting: float = 1.0
    measurement_var: float | None = None
    smoother_samples: int = 5000
    window: int = 400
    stride: int = 200


@dataclass
class ChannelDrift:
    """Result for one channel: the JSON-ready ``summary`` plus arrays for the plots (input units)."""

    summary: dict
    raw: NDArray[np.float64]
    residual: NDArray[np.float64]
    innovations: NDArray[np.float64]
    compensated: NDArray[np.float64]
    smoothed_drift: NDArray[np.float64]
    acf: NDArray[np.float64]
    pacf: NDArray[np.float64]
    acf_band: NDArray[np.float64]
    pacf_band: float
    extra: dict = field(default_factory=dict)


def unsettled(sel: OrderSelection) -> list[dict]:
    """What the ARMA modelling could not settle: each candidate fit that did not converge (status, gradient norm,
    log-likelihood still to gain), and the chosen model's near-cancelling AR/MA root pairs (parameter
    redundancy). Empty when everything converged and the chosen model has no such pair."""
    out = [
        {
            "item": f"ARMA({m.p},{m.q}) fit",
            "issue": m.status,
            "gradient_norm": m.gradient_norm,
            "likelihood_gap": m.likelihood_gap,
            "chosen": m is sel.best,
            "note": m.note,
        }
        for m in sel.unconverged
    ]
    if sel.best.redundant_pairs:
        d = min(pair["distance"] for pair in sel.best.redundant_pairs)
        out.append(
            {
                "item": f"ARMA({sel.best.p},{sel.best.q}) model",
                "issue": "parameter redundancy",
                "chosen": True,
                "note": f"an AR and an MA root nearly cancel (distance {d:.3g} < {REDUNDANCY_DISTANCE}); compare with "
                f"ARMA({sel.best.p - 1},{sel.best.q - 1}) in the order-selection table",
            }
        )
    return out


def _record_tests(
    a: NDArray[np.float64], y: NDArray[np.float64], trend: NDArray[np.float64], replaced: int, o: DriftOptions
) -> dict:
    """Stationarity (Daniel, reverse arrangement on sub-series means and mean squares) and normality (Jarque–Bera)
    of the detrended record ``y`` (``a`` the raw record, ``trend`` the removed trend)."""
    tests = {}
    means = segment_stats(y, o.segments, "mean")
    msq = segment_stats(y, o.segments, "mean_square")
    for label, z in (("mean", means), ("mean_square", msq)):
        t = daniel_test(z, o.alpha)
        t.name = f"daniel_{label}"
        tests[t.name] = t
        t = reverse_arrangement_test(z, o.alpha)
        t.name = f"reverse_arrangement_{label}"
        tests[t.name] = t
    # unit root (ADF: null a random walk) and stationarity (KPSS: null stationary), statsmodels' defaults
    tests["adf"] = adf_test(y, "c", "aic", alpha=o.alpha)
    tests["kpss"] = kpss_test(y, "c", "auto", alpha=o.alpha)
    jb = jarque_bera_test(y, o.alpha)
    if replaced and o.outlier_k <= 4:
        jb.note += (
            f"; the {o.outlier_k:g}-sigma replacement of {replaced} samples truncates the tails (Gaussian data "
            "lose ~0.16 of kurtosis at 3 sigma), which alone makes JB reject for n above a few thousand"
        )
    jb.extra["before_outlier_replacement"] = jarque_bera_test(a - trend, o.alpha).statistic
    tests["jarque_bera"] = jb
    return tests


def _online_pass(model, centred: NDArray[np.float64], o: DriftOptions, say: Callable[[str], None]) -> dict:
    """The online RLS / extended-LS pass over the record after a batch start on its first samples."""
    n = centred.size
    online: dict = {"run": False}
    if o.online and model.p + model.q > 0:
        say("online RLS/ELS pass")
        n0 = min(max(1000, n // 20), n // 2)
        try:
            est = OnlineArma(model.p, model.q, o.forgetting).initialise(centred[:n0])
            t0 = time.perf_counter()
            est.feed(centred[n0:])
            dt = time.perf_counter() - t0
            st = est.state()
            online = {
                "run": True,
                "method": "rls" if model.q == 0 else "extended_ls",
                "forgetting": o.forgetting,
                "initial_samples": n0,
                "phi": st.phi.tolist(),
                "theta": st.theta.tolist(),
                "samples_per_s": (n - n0) / dt if dt > 0 else math.inf,
            }
        except DriftInputError as exc:
            online = {"run": False, "note": str(exc)}
    return online


def _compensation(
    model, centred: NDArray[np.float64], o: DriftOptions, say: Callable[[str], None]
) -> tuple[dict, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """State-space ARMA compensation: the steady-state filter over the record and the sliding-window smoother over
    its first samples; (summary, innovations, compensated span, smoothed drift)."""
    n = centred.size
    s2 = model.sigma2
    rvar = float(o.measurement_var) if o.measurement_var is not None else s2
    comp: dict = {"measurement_var": rvar, "std_before": float(np.std(centred))}
    innov = np.zeros(0)
    compensated = np.zeros(0)
    smoothed = np.zeros(0)
    if model.p > 0:
        ss = arma_state_space(model.phi, model.theta, s2, rvar)
        yc = centred
        _, pred = steady_state_filter(ss, yc)
        innov = yc - pred
        comp["std_after_filter"] = float(np.std(innov))
        ns = int(min(o.smoother_samples, n))
        if ns >= 2:
            say(f"sliding-window smoother over {ns} samples")
            sm = sliding_window_smoother(ss, yc[:ns], o.window, min(o.stride, o.window))
            smoothed = sm.drift
            compensated = yc[:ns] - sm.drift
            comp.update(
                {
                    "smoother_samples": ns,
                    "std_before_smoothed_span": float(np.std(yc[:ns])),
                    "std_after_smoother": float(np.std(compensated)),
                    "windows": sm.windows,
                    "max_lm_iterations": sm.max_iterations,
                }
            )
    else:
        comp["note"] = "white residual (p = 0): nothing predictable to compensate"
    return comp, innov, compensated, smoothed


def _summary(n, rate, out, det, sel, moments, tests, tones, removed, r, pr, band_acf, band_pacf, online, comp, o):
    """The JSON-ready summary of one channel's drift chain."""
    model = sel.best
    model_d = model.to_dict()
    model_d["moment"] = {
        "phi": moments.phi.tolist(),
        "theta": moments.theta.tolist(),
        "sigma2": moments.sigma2,
        "note": moments.note,
    }
    summary = {
        "samples": n,
        "rate_hz": rate,
        "outliers": {
            "method": out.method,
            "k": o.outlier_k,
            "replaced": out.replaced,
            "centre": out.centre,
            "scale": out.scale,
        },
        "detrend": {"order": det.order, "coefficients": det.coefficients.tolist(), "criteria": det.criteria},
        "model": model_d,
        "order_selection": {
            "criterion": o.criterion,
            "by_aic": list(sel.by_aic),
            "by_bic": list(sel.by_bic),
            "p_ge_q": o.p_ge_q,
            "table": sel.table,
        },
        "unsettled": unsettled(sel),
        "tests": {k: v.to_dict() for k, v in tests.items()},
        "tones_hz": tones.extra["frequencies"],
        "tones_removed": [
            {"frequency_hz": t.frequency_hz, "amplitude": t.amplitude, "phase": t.phase} for t in removed
        ],
        "periodic_handoff": "run 'tablebench periodic' on these tones" if tones.extra["frequencies"] else "",
        "acf": {"values": r.tolist(), "band": band_acf.tolist()},
        "pacf": {"values": pr.tolist(), "band": band_pacf},
        "online": online,
        "compensation": comp,
    }
    return summary


def analyse_channel(
    x: ArrayLike,
    rate: float,
    name: str = "series",
    options: DriftOptions | None = None,
    progress: Callable[[str], None] | None = None,
) -> ChannelDrift:
    """Run the drift chain on one channel (see the module docstring).

    Parameters
    ----------
    x : array_like
        Static record of one channel, SI units (rad/s or m/s²).
    rate : float
        Sample rate, Hz.
    name : str
        Channel name for messages.
    options : DriftOptions, optional
    progress : callable, optional
        Called with a short message as each stage starts (tests, each ARMA candidate, online pass, smoother).
    """
    o = options or DriftOptions()

    def say(msg: str) -> None:
        if progress is not None:
            progress(f"{name}: {msg}")

    if not (math.isfinite(rate) and rate > 0):
        raise DriftInputError(f"{name}: sample rate must be a positive number of Hz, got {rate}")
    a = check_series(x, name, min_samples=MIN_SAMPLES)
    n = a.size
    if n < 2 * o.segments:
        raise DriftInputError(f"{name}: {n} samples are too few for {o.segments} sub-series; use fewer segments")
    say(f"pre-processing and tests ({n} samples)")
    out = replace_outliers(a, o.outlier_k, o.outlier_method)
    det = detrend(out.cleaned, rate, o.detrend_order)
    y = det.residual
    if float(np.std(y)) <= 1e-13 * max(float(np.max(np.abs(a))), 1e-300):
        raise DriftInputError(f"{name}: nothing varies after removing the trend; no drift to model")

    tests = _record_tests(a, y, det.trend, out.replaced, o)
    tones = welch_tones(y, rate, o.tone_alpha)
    tests["welch_periodicity"] = tones
    removed = []
    if o.remove_tones and tones.extra["frequencies"]:
        y, removed = remove_tones(y, rate, tones.extra["frequencies"], rate / tones.extra["nperseg"])

    say(f"fitting ARMA(p, q), p, q <= {o.max_p}, {o.max_q} ({o.fit_method.upper()})")
    sel = select_order(
        y,
        o.max_p,
        o.max_q,
        o.criterion,
        o.fit_method,
        lambda pq, k, tot: say(f"ARMA{pq} fitted ({k}/{tot})"),
        include_mean=o.include_mean,
        p_ge_q=o.p_ge_q,
    )
    model = sel.best
    moments = moment_estimates(y, model.p, model.q)
    centred = y - model.mean  # the model's mean (0 when fixed at zero)
    resid = css_residuals(centred, model.phi, model.theta)
    lb = ljung_box_test(resid, None if o.nlags is None else max(o.nlags, model.p + model.q + 5), model.p + model.q)
    tests["ljung_box"] = lb

    nl = int(o.nlags or min(40, n // 10))
    r = acf(y, nl)
    pr = pacf_from_acf(r)
    band_acf = correlation_bands(n, r, o.alpha)
    band_pacf = float(correlation_bands(n, None, o.alpha)[0])

    online = _online_pass(model, centred, o, say)

    comp, innov, compensated, smoothed = _compensation(model, centred, o, say)

    summary = _summary(
        n, rate, out, det, sel, moments, tests, tones, removed, r, pr, band_acf, band_pacf, online, comp, o
    )
    return ChannelDrift(summary, a, y, innov, compensated, smoothed, r, pr, band_acf, band_pacf)


def analyse_drift(
    channels: Mapping[str, ArrayLike], rate: float, options: DriftOptions | None = None, **overrides: object
) -> dict:
    """Drift analysis of several channels of one static record (for the CLI and the certificate).

    Parameters
    ----------
    channels : mapping
        Channel name → 1-D series, SI (rad/s, m/s²), all at ``rate``.
    rate : float
        Sample rate, Hz.
    options : DriftOptions, optional
        Settings; keyword ``overrides`` replace single fields (e.g. ``criterion="aic"``).

    Returns
    -------
    dict
        ``{"rate_hz": …, "channels": {NAME: {"model": {p, q, phi, theta, sigma2, criterion, …},
        "tests": {NAME: {statistic, threshold, verdict, …}}, …}}}`` (JSON-ready).
    """
    try:
        o = dataclasses.replace(options or DriftOptions(), **overrides)
    except TypeError as exc:
        raise DriftInputError(f"unknown drift option: {exc}") from None
    if not channels:
        raise DriftInputError("no channels given for drift analysis")
    return {
        "rate_hz": float(rate),
        "sign_convention": "x_t - sum phi_j x_(t-j) = e_t - sum theta_j e_(t-j) (Box-Jenkins)",
        "channels": {name: analyse_channel(x, rate, name, o).summary for name, x in channels.items()},
    }
