"""ARMA(p, q) modelling of a drift residual: moment estimates, exact maximum likelihood, order selection.

Specification: docs/methods/drift.md ("ARMA modelling").

Sign convention (Box–Jenkins, as the spec's moment equations and the simulated unit ``drivers.sim``):

    (x_t − μ) − φ_1 (x_{t−1} − μ) − … − φ_p (x_{t−p} − μ) = e_t − θ_1 e_{t−1} − … − θ_q e_{t−q},   e_t ~ N(0, σ²),

so γ_Y(k) = σ²(−θ_k + Σ_{j=1}^{q−k} θ_j θ_{j+k}). statsmodels (and most software) write "+ θ_j e_{t−j}": its
MA coefficients are the negatives of these. x is a scalar series in any unit; μ (its mean) is estimated jointly
(default) or fixed at zero; σ² is in the unit squared.

- :func:`moment_estimates`: modified Yule–Walker (ρ_k = Σ φ_j ρ_{k−j}, k = q+1..q+p) for the AR part, then the
  MA part and σ² by the classical fixed-point iteration on the autocovariances of Y_t = x_t − Σ φ_j x_{t−j}
  (spectral factorisation when the iteration does not converge).
- :func:`fit_arma`: exact Gaussian maximum likelihood (default; :mod:`analysis.drift.arma_likelihood`, the mean
  profiled out by generalised least squares) or conditional least squares (CSS), by Levenberg–Marquardt kept in
  the stationary/invertible region from several starts (CSS solution, Hannan–Rissanen, nested model), with a
  BFGS fallback when it stalls (:mod:`analysis.drift.arma_optimiser`); convergence is decided by gradient and
  step criteria and reported; standard errors σ² (JᵀJ)⁻¹ of the residual Jacobian in (φ, θ, μ).
- :func:`select_order`: all p, q ≤ 3 (p ≥ q only as an option) by BIC = n ln σ̂² + k ln n (the spec's choice)
  with AIC = n ln σ̂² + 2k reported beside it, k = p + q + 1 (+ 1 for an estimated mean). The spec does not say
  how σ̂² is estimated; it is the exact-ML prediction-error variance, for which n ln σ̂² = −2 ln L − n(1 + ln 2π),
  i.e. the standard AIC/BIC up to a constant (Akaike 1974; Box, Jenkins, Reinsel & Ljung §6.2.1).
- :func:`redundant_root_pairs`: near-cancelling AR/MA root pairs (the spec's parameter-redundancy flag).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from analysis.drift.arma_likelihood import exact_residuals, lag_polynomial
from analysis.drift.arma_optimiser import (
    Convergence,
    Jacobian,
    Optimum,
    Residuals,
    admissible,
    convergence,
    dot,
    lagged_normal_equations,
    levenberg_marquardt,
    normal_equations,
    quasi_newton,
)
from analysis.drift.hypothesis_tests import autocovariance
from analysis.drift.preprocess import DriftInputError, check_series


@dataclass
class ArmaModel:
    """A fitted ARMA(p, q) model (sign convention in the module docstring).

    Attributes
    ----------
    p, q : int
        Orders.
    phi, theta : ndarray
        AR and MA coefficients (dimensionless).
    sigma2 : float
        Innovation variance, input unit squared.
    se_phi, se_theta : ndarray
        Standard errors (NaN for moment estimates).
    se_sigma2 : float
        Standard error of σ² (√(2/n) σ², Gaussian).
    n : int
        Samples used.
    method : str
        ``"moments"``, ``"css"`` or ``"ml"``.
    aic, bic : float
        n ln σ̂² + 2k, n ln σ̂² + k ln n, k = p + q + 1 (+ 1 when the mean is estimated).
    criterion : str
        Criterion by which the order was chosen ("aic", "bic" or "given").
    note : str
        Warnings (e.g. MA iteration fell back to spectral factorisation, fit not converged).
    include_mean : bool
        True when the mean was estimated (jointly, by the fit's criterion); False when fixed at zero.
    mean, se_mean : float
        Estimated mean and its standard error, input unit (0 and NaN when fixed at zero).
    log_likelihood : float
        Maximised Gaussian log-likelihood (exact for ML; conditional for CSS, moments: at σ̂²).
    converged : bool
        Whether the gradient and step criteria hold at the reported optimum (:mod:`analysis.drift.arma_optimiser`).
    status : str
        ``"converged"``; ``"boundary"`` (not converged, the best point within :data:`BOUNDARY_MARGIN` of a unit
        AR/MA root: the likelihood rises toward the edge of the stationary/invertible region); ``"not converged"``.
    gradient_norm : float
        ‖∇ ln L‖ with respect to (φ, θ) at the reported optimum.
    likelihood_gap : float
        Log-likelihood a Gauss–Newton step would still gain there (≤ 1e-6 when converged).
    iterations : int
        Optimiser iterations used (all starts).
    optimiser : str
        ``"levenberg-marquardt"`` or ``"levenberg-marquardt + bfgs from N starts"`` (the fallback was needed).
    redundant_pairs : list of dict
        AR/MA root pairs that nearly cancel (:func:`redundant_root_pairs`): parameter redundancy.
    """

    p: int
    q: int
    phi: NDArray[np.float64]
    theta: NDArray[np.float64]
    sigma2: float
    se_phi: NDArray[np.float64]
    se_theta: NDArray[np.float64]
    se_sigma2: float
    n: int
    method: str
    aic: float
    bic: float
    criterion: str = "given"
    note: str = ""
    include_mean: bool = False
    mean: float = 0.0
    se_mean: float = math.nan
    log_likelihood: float = math.nan
    converged: bool = True
    status: str = "converged"
    gradient_norm: float = 0.0
    likelihood_gap: float = 0.0
    iterations: int = 0
    optimiser: str = ""
    redundant_pairs: list[dict] = field(default_factory=list)

    @property
    def k(self) -> int:
        """Number of estimated parameters counted by AIC/BIC: φ, θ, σ² and the mean when estimated."""
        return self.p + self.q + 1 + int(self.include_mean)

    def to_dict(self) -> dict:
        """JSON-ready dictionary: p, q, phi, theta, sigma2, criterion, then standard errors, criteria, convergence."""
        return {
            "p": self.p,
            "q": self.q,
            "phi": [float(v) for v in self.phi],
            "theta": [float(v) for v in self.theta],
            "sigma2": float(self.sigma2),
            "criterion": self.criterion,
            "include_mean": self.include_mean,
            "mean": float(self.mean),
            "se_mean": float(self.se_mean) if math.isfinite(self.se_mean) else None,
            "se_phi": [float(v) for v in self.se_phi],
            "se_theta": [float(v) for v in self.se_theta],
            "se_sigma2": float(self.se_sigma2),
            "log_likelihood": float(self.log_likelihood),
            "aic": float(self.aic),
            "bic": float(self.bic),
            "k": self.k,
            "n": self.n,
            "method": self.method,
            "converged": self.converged,
            "status": self.status,
            "gradient_norm": float(self.gradient_norm),
            "likelihood_gap": float(self.likelihood_gap),
            "iterations": self.iterations,
            "optimiser": self.optimiser,
            "parameter_redundancy": bool(self.redundant_pairs),
            "redundant_root_pairs": self.redundant_pairs,
            "sign_convention": "x_t - mean - sum phi_j (x_(t-j) - mean) = e_t - sum theta_j e_(t-j)",
            "note": self.note,
        }


BOUNDARY_MARGIN = 1e-4
"""A fit whose largest |partial autocorrelation| (AR or MA) exceeds 1 − BOUNDARY_MARGIN is on the boundary."""

REDUNDANCY_DISTANCE = 0.1
"""AR/MA reciprocal roots (poles and zeros, inside the unit circle) closer than this in the complex plane are
flagged as a near-cancelling pair (parameter redundancy). The spec asks for the flag without a threshold; 0.1
separates the spurious lines measured on ARMA(1,1) records (pairs 0.005–0.05 apart near the unit circle) from the
acceptance model's genuine pole and zero (0.9 and ±0.4: 0.5 and 1.3 apart)."""


def redundant_root_pairs(
    phi: NDArray[np.float64], theta: NDArray[np.float64], threshold: float = REDUNDANCY_DISTANCE
) -> list[dict]:
    """AR/MA reciprocal-root pairs closer than ``threshold`` (each root used once, closest pairs first).

    Poles are the roots of z^p − Σ φ_j z^{p−j}, zeros those of z^q − Σ θ_j z^{q−j} (both inside the unit circle
    for a stationary, invertible model); a pole and a zero that coincide cancel, so the model is then
    over-parametrised. A slow Gauss–Markov drift under strong white noise also gives a close pole–zero pair, so
    the flag is a prompt to compare with the model without the pair, not a verdict.

    Returns
    -------
    list of dict
        ``{"pole": [re, im], "zero": [re, im], "distance": d}`` per pair.
    """
    if phi.size == 0 or theta.size == 0:
        return []
    poles = np.roots(np.r_[1.0, -np.asarray(phi, float)])
    zeros = np.roots(np.r_[1.0, -np.asarray(theta, float)])
    d = np.abs(poles[:, None] - zeros[None, :])
    pairs = []
    used_p: set[int] = set()
    used_z: set[int] = set()
    for flat in np.argsort(d, axis=None):
        i, j = divmod(int(flat), zeros.size)
        if d[i, j] >= threshold:
            break
        if i in used_p or j in used_z:
            continue
        used_p.add(i)
        used_z.add(j)
        pairs.append(
            {
                "pole": [float(poles[i].real), float(poles[i].imag)],
                "zero": [float(zeros[j].real), float(zeros[j].imag)],
                "distance": float(d[i, j]),
            }
        )
    return pairs


def _criteria(n: int, sigma2: float, k: int) -> tuple[float, float]:
    ls = n * math.log(max(sigma2, np.finfo(float).tiny))
    return ls + 2.0 * k, ls + k * math.log(n)


def _check_orders(x: NDArray[np.float64], p: int, q: int, include_mean: bool = False) -> None:
    if p < 0 or q < 0 or p > 10 or q > 10:
        raise DriftInputError(f"ARMA orders must be 0..10, got p={p}, q={q}")
    k = p + q + 1 + int(include_mean)
    need = max(10 * k, 2 * (p + q) + 20)
    if x.size < need:
        raise DriftInputError(
            f"series of {x.size} samples is too short for ARMA({p},{q}); need at least {need} "
            "(record longer or lower the order)"
        )


def simulate_arma(
    phi: ArrayLike, theta: ArrayLike, sigma2: float, n: int, rng: np.random.Generator, burn: int = 1000
) -> NDArray[np.float64]:
    """Simulate n samples of the zero-mean ARMA process (module convention), discarding ``burn`` start-up samples."""
    ph = np.atleast_1d(np.asarray(phi, dtype=float))
    th = np.atleast_1d(np.asarray(theta, dtype=float))
    e = rng.standard_normal(n + burn) * math.sqrt(sigma2)
    x = signal.lfilter(np.r_[1.0, -th], np.r_[1.0, -ph], e)
    return x[burn:]


def _ma_from_acvf(g: NDArray[np.float64], max_iter: int = 500, tol: float = 1e-12) -> tuple[np.ndarray, float, str]:
    """MA(q) coefficients c of Y_t = e_t + Σ c_j e_{t−j} (c = −θ) and σ² from γ_0..γ_q.

    Fixed-point iteration σ² = γ_0/(1 + Σc²), c_k = γ_k/σ² − Σ c_j c_{j+k}; spectral factorisation when it does
    not converge to an invertible solution.
    """
    q = len(g) - 1
    if q == 0:
        return np.zeros(0), float(g[0]), ""
    th = np.zeros(q)
    s2 = float(g[0])
    converged = False
    for _ in range(max_iter):
        s2 = float(g[0] / (1.0 + th @ th))
        new = np.empty(q)
        for k in range(1, q + 1):
            new[k - 1] = g[k] / s2 - float(th[: q - k] @ th[k:]) if k < q else g[k] / s2
        if not np.all(np.isfinite(new)) or np.max(np.abs(new)) > 1e6:
            break
        step = float(np.max(np.abs(new - th)))
        th = new
        if step < tol:
            converged = True
            break
    if converged and np.all(np.abs(np.roots(np.r_[1.0, th][::-1])) > 1.0):
        return th, float(g[0] / (1.0 + th @ th)), ""
    # Spectral factorisation: z^q G(z) has roots in pairs (z, 1/z); the invertible factor uses |z| > 1.
    coeffs = np.r_[g[::-1], g[1:]]  # γ_q … γ_0 … γ_q
    roots = np.roots(coeffs[::-1])
    outside = roots[np.abs(roots) > 1.0]
    note = "MA iteration did not converge; spectral factorisation used"
    if outside.size != q:
        # The sample autocovariances are not those of an MA(q) (spectrum negative somewhere): take the q
        # largest-modulus roots pushed just outside the unit circle.
        order = np.argsort(-np.abs(roots))
        outside = roots[order[:q]]
        outside = outside / np.minimum(np.abs(outside), 1.0) * 1.0001
        note = "sample autocovariances are not MA(q)-valid; MA part projected to the invertible region"
    # θ(z) = ∏(1 − z/ρ_i); np.poly(1/ρ) = coefficients of ∏(x − 1/ρ_i) = x^q θ(1/x), so θ_k = poly[k].
    poly = np.real(np.poly(1.0 / outside))
    th = poly[1:]
    s2 = float(g[0] / (1.0 + th @ th))
    return np.real(th), s2, note


def moment_estimates(x: ArrayLike, p: int, q: int) -> ArmaModel:
    """Moment estimates of ARMA(p, q): modified Yule–Walker for φ, MA iteration for θ and σ².

    Parameters
    ----------
    x : array_like
        Scalar series (the sample mean is removed and reported as ``mean``), any unit.
    p, q : int
        Orders.
    """
    a = check_series(x)
    _check_orders(a, p, q)
    centre = float(a.mean())
    a = a - centre
    n = a.size
    g = autocovariance(a, p + q + 1)
    if p > 0:
        # γ_k = Σ_j φ_j γ_{k−j}, k = q+1..q+p (γ_{−m} = γ_m).
        mat = np.array([[g[abs(q + i - j)] for j in range(1, p + 1)] for i in range(1, p + 1)])
        rhs = g[q + 1 : q + p + 1]
        try:
            phi = np.linalg.solve(mat, rhs)
        except np.linalg.LinAlgError:
            raise DriftInputError(
                f"modified Yule-Walker system for ARMA({p},{q}) is singular; lower the order"
            ) from None
    else:
        phi = np.zeros(0)
    y = signal.lfilter(np.r_[1.0, -phi], [1.0], a)[p:]
    gy = autocovariance(y, q) if q > 0 else np.array([float(np.mean((y - y.mean()) ** 2))])
    c, s2, note = _ma_from_acvf(gy)
    theta = -c
    aic, bic = _criteria(n, s2, p + q + 2)
    nan = np.full
    return ArmaModel(
        p, q, phi, theta, s2, nan(p, np.nan), nan(q, np.nan), s2 * math.sqrt(2.0 / n), n, "moments", aic, bic,
        note=note, include_mean=True, mean=centre, log_likelihood=-0.5 * n * (math.log(2.0 * math.pi * s2) + 1.0),
        optimiser="moments", redundant_pairs=redundant_root_pairs(phi, theta),
    )  # fmt: skip


# --- stationary / invertible parametrisation ---------------------------------------------------------------


def _shrink_to_admissible(poly: NDArray[np.float64]) -> NDArray[np.float64]:
    """Scale coefficient j by s^j (roots pushed outward) until the polynomial is stationary/invertible."""
    out = poly.copy()
    s = 1.0
    while out.size and not admissible(out, np.zeros(0), 1e-3):
        s *= 0.95
        out = poly * s ** np.arange(1, poly.size + 1)
    return out


def hannan_rissanen(x: NDArray[np.float64], p: int, q: int, long_order: int | None = None) -> NDArray[np.float64]:
    """Hannan–Rissanen preliminary (φ, θ) of a zero-mean series: an AR(m) by least squares gives innovation
    estimates ê, then x_t is regressed on x_{t−1..t−p} and ê_{t−1..t−q} (Hannan & Rissanen 1982; Brockwell &
    Davis §5.1.4). m = ``long_order`` (default ⌈10 log₁₀ n⌉, at least p + q + 1). Used as starts of the likelihood
    maximisation (a long and a short m reach different modes of a multimodal likelihood); pushed inside the
    admissible region. No BLAS on tall matrices (see :func:`analysis.drift.arma_optimiser.normal_equations`).
    """
    n = x.size
    m = long_order if long_order is not None else max(p + q + 1, round(10 * math.log10(n)))
    m = int(min(max(m, 1), n // 4))
    s = m + max(p, q)
    if n - s <= 2 * (p + q):
        return np.zeros(p + q)
    A, b = lagged_normal_equations(x, m)
    try:
        a_long = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.zeros(p + q)
    ehat = np.r_[np.zeros(m), signal.lfilter(np.r_[1.0, -a_long], [1.0], x)[m:]]
    cols = [x[s - j : n - j] for j in range(1, p + 1)] + [ehat[s - j : n - j] for j in range(1, q + 1)]
    A, b = normal_equations(cols, x[s:])
    try:
        coef = np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.zeros(p + q)
    return np.r_[_shrink_to_admissible(coef[:p]), _shrink_to_admissible(-coef[p:])]


def css_residuals(
    x: NDArray[np.float64], phi: NDArray[np.float64], theta: NDArray[np.float64], start: int | None = None
) -> NDArray[np.float64]:
    """Conditional residuals e_t, t = start..n−1, with e_t = 0 before ``start`` (default and minimum: p).

    The first ``start`` samples are conditioned on; comparing models of different orders on the same
    ``start`` makes their σ̂² (and AIC/BIC) refer to the same samples.
    """
    p = phi.size
    s0 = p if start is None else max(int(start), p)
    w = signal.lfilter(lag_polynomial(phi), [1.0], x)[s0:]
    return signal.lfilter([1.0], lag_polynomial(theta), w) if theta.size else w


def _jacobian(
    x: NDArray[np.float64], phi: NDArray[np.float64], theta: NDArray[np.float64], start: int, e: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Columns ∂e_t/∂(φ, θ) of the CSS residuals e (:func:`css_residuals` at the same point and ``start``).

    ∂e_t/∂φ_j = −θ(B)⁻¹ x_{t−j} and ∂e_t/∂θ_j = +θ(B)⁻¹ e_{t−j}, θ(B) = 1 − Σ θ_j B^j.
    """
    p, q = phi.size, theta.size
    m = e.size
    cols = []
    den = lag_polynomial(theta)
    for j in range(1, p + 1):
        xs = x[start - j : start - j + m]
        cols.append(-signal.lfilter([1.0], den, xs))
    for j in range(1, q + 1):
        es = np.concatenate((np.zeros(j), e[: m - j]))
        cols.append(signal.lfilter([1.0], den, es))
    return cols


def _css_mean(
    x: NDArray[np.float64], phi: NDArray[np.float64], theta: NDArray[np.float64], start: int
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Conditional-least-squares mean at given coefficients: μ̂, the residuals of x − μ̂ and of a unit mean."""
    e = css_residuals(x, phi, theta, start)
    e1 = css_residuals(np.ones_like(x), phi, theta, start)
    mu = dot(e, e1) / dot(e1, e1)
    return mu, e - mu * e1, e1


def _css_problem(x: NDArray[np.float64], p: int, start: int, include_mean: bool) -> tuple[Residuals, Jacobian]:
    """CSS residuals e_t (t ≥ start; mean profiled out when estimated) and their analytic Jacobian in (φ, θ)."""

    def residuals(par: NDArray[np.float64]) -> NDArray[np.float64]:
        if include_mean:
            return _css_mean(x, par[:p], par[p:], start)[1]
        return css_residuals(x, par[:p], par[p:], start)

    def jacobian(par: NDArray[np.float64], e: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        mu = _css_mean(x, par[:p], par[p:], start)[0] if include_mean else 0.0
        return _jacobian(x - mu, par[:p], par[p:], start, e)

    return residuals, jacobian


def _ml_problem(x: NDArray[np.float64], p: int, include_mean: bool) -> tuple[Residuals, Jacobian]:
    """Exact-likelihood residual vector (:mod:`analysis.drift.arma_likelihood`, mean profiled out when estimated)
    and its Jacobian in (φ, θ).

    The Jacobian is by forward differences (backward where the forward point leaves the admissible region),
    step 1e-7 in the coefficients: a relative error of ~1e-7/σ_coefficient ≪ 1. The most probable pre-sample
    values (and the mean) are re-solved at each point: the Jacobian of the profiled residuals.
    """

    def residuals(par: NDArray[np.float64]) -> NDArray[np.float64]:
        return exact_residuals(x, par[:p], par[p:], include_mean).weighted()

    def jacobian(par: NDArray[np.float64], e: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        cols = []
        for i in range(par.size):
            bumped = par.copy()
            h = 1e-7
            bumped[i] += h
            if not admissible(bumped[:p], bumped[p:], 0.0):
                h = -h
                bumped[i] = par[i] + h
            cols.append((residuals(bumped) - e) / h)
        return cols

    return residuals, jacobian


def _pad(model: ArmaModel, p: int, q: int) -> NDArray[np.float64]:
    """Parameters of a nested ARMA(p', q') model as an ARMA(p, q) start (zero-padded; the same process)."""
    return np.r_[model.phi, np.zeros(p - model.p), model.theta, np.zeros(q - model.q)]


def _note(*parts: str) -> str:
    return "; ".join(s for s in parts if s)


def _check_point(problem: tuple[Residuals, Jacobian], best: Optimum) -> Convergence:
    """The convergence measures at an optimum (those its optimiser computed there, else computed here)."""
    if best.check is not None:
        return best.check
    residuals, jacobian = problem
    params = best.params
    e = residuals(params)
    A, g = normal_equations(jacobian(params, e), e)
    return convergence(A, g, dot(e, e), e.size)


BASIN_SE = 10.0
"""Farthest start (in standard errors of the optimum, Mahalanobis) that :func:`_in_basin` may skip."""
BASIN_TOL = 0.1
"""Largest relative disagreement of a start's (and its midpoint's) cost excess with the optimum's quadratic model
for :func:`_in_basin` to skip the start."""


def _in_basin(residuals: Residuals, best: Optimum, start: NDArray[np.float64], cost: float, m: int, p: int) -> bool:
    """True when Levenberg–Marquardt from ``start`` (cost ‖r‖² there: ``cost``; m residuals) would only return to
    ``best``'s optimum: ``best`` met the convergence criteria, ``start`` lies within :data:`BASIN_SE` standard
    errors of it, and the cost excess over the optimum at ``start`` and at the midpoint both agree with the
    Gauss–Newton quadratic model dᵀ(JᵀJ)d within :data:`BASIN_TOL` — along the way the cost is the one convex
    bowl whose minimum the damped steps descend to. Anything else (another mode, a ridge of nearly cancelling
    roots, a stall) answers False."""
    if not best.stopped_by_criteria or best.normal is None:
        return False
    d = start - best.params
    quad = float(d @ best.normal @ d)
    if not (0.0 < quad <= BASIN_SE**2 * best.cost / m):
        return False
    mid = best.params + 0.5 * d
    if not admissible(mid[:p], mid[p:]):
        return False
    e_mid = residuals(mid)
    for excess, model in ((cost - best.cost, quad), (dot(e_mid, e_mid) - best.cost, 0.25 * quad)):
        if abs(excess - model) > BASIN_TOL * model + 1e-12 * best.cost:
            return False
    return True


def _maximise(
    problem: tuple[Residuals, Jacobian], starts: list[NDArray[np.float64]], p: int
) -> tuple[NDArray[np.float64], Convergence, int, str]:
    """Levenberg–Marquardt from each start, the best kept; if its point fails the convergence criteria,
    BFGS from three starts (the stalled point, the last given start, zero), each polished by LM, and the best of
    all kept.

    The starts are ranked by their cost first; LM runs from the best one, and from each other start unless
    :func:`_in_basin` shows it would return to the same optimum (then its run is skipped: the reported optimum is
    the same, to the convergence tolerance).

    Returns the parameters, the convergence measures there, the iterations used, the optimiser description, and
    JᵀJ there when the optimiser computed it (else None).
    """
    residuals = problem[0]
    starts = [s for s in starts if admissible(s[:p], s[p:])]
    e0 = [residuals(s) for s in starts]
    costs = [dot(e, e) for e in e0]
    order = sorted(range(len(starts)), key=lambda i: costs[i])
    runs = [levenberg_marquardt(*problem, starts[order[0]], p, e0=e0[order[0]])]
    for i in order[1:]:
        if not _in_basin(residuals, runs[0], starts[i], costs[i], e0[i].size, p):
            runs.append(levenberg_marquardt(*problem, starts[i], p, e0=e0[i]))
    best = min(runs, key=lambda r: r.cost)
    iterations = sum(r.iterations for r in runs)
    conv = _check_point(problem, best)
    optimiser = "levenberg-marquardt"
    if conv.converged:
        return best.params, conv, iterations, optimiser, best.normal
    # The stalled point, the last given start (the nested model or the short Hannan–Rissanen one) and white noise.
    fallback_starts = [best.params, starts[-1], np.zeros_like(best.params)]
    for s in fallback_starts:
        qn = quasi_newton(problem[0], s, p)
        polished = levenberg_marquardt(*problem, qn.params, p) if admissible(qn.params[:p], qn.params[p:]) else qn
        iterations += qn.iterations + polished.iterations
        runs.append(polished)
    best = min(runs, key=lambda r: r.cost)
    optimiser = f"levenberg-marquardt + bfgs from {len(fallback_starts)} starts (levenberg-marquardt stalled)"
    return best.params, _check_point(problem, best), iterations, optimiser, best.normal


def fit_arma(
    x: ArrayLike,
    p: int,
    q: int,
    start: ArmaModel | None = None,
    condition: int | None = None,
    method: str = "ml",
    nested: ArmaModel | None = None,
    include_mean: bool = True,
) -> ArmaModel:
    """Fit ARMA(p, q) with standard errors: exact Gaussian maximum likelihood (default) or conditional least squares.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    p, q : int
        Orders.
    start : ArmaModel, optional
        Starting point of the CSS fit (default: :func:`moment_estimates`).
    condition : int, optional
        CSS only: number of initial samples conditioned on (default p); σ² and the criteria use the
        n − condition residuals.
    method : {"ml", "css"}
        ``"css"``: conditional least squares (e_t = 0 before the conditioning samples), Levenberg–Marquardt with
        the analytic residual Jacobian from ``start``. ``"ml"``: exact likelihood
        (:mod:`analysis.drift.arma_likelihood`), Levenberg–Marquardt on the weighted prediction errors started
        from the CSS solution and, when given, from the ``nested`` model; the higher likelihood is kept.
        Either way, when the best point fails the gradient/step convergence criteria, BFGS is run from several
        starts (:func:`analysis.drift.arma_optimiser.quasi_newton`) and the best optimum of all is reported with
        its convergence measures (``converged``, ``gradient_norm``, ``likelihood_gap``) and a note if it still
        fails them.
    nested : ArmaModel, optional
        ML only: a fitted model of orders p' ≤ p, q' ≤ q, used (zero-padded) as a second start, so the
        likelihood is never below that of a model it contains — order criteria then compare true maxima.
    include_mean : bool
        True (default): x − μ is the ARMA process and μ is estimated jointly (exact ML: generalised least
        squares profiled at every coefficient value; CSS: least squares on the conditional residuals), counted
        in AIC/BIC's k. False: the record is taken as already centred, μ = 0.

    Returns
    -------
    ArmaModel
        σ² = mean squared (prediction) residual; standard errors σ²(JᵀJ)⁻¹ from the residual Jacobian in
        (φ, θ, μ); ``aic`` and ``bic`` from n ln σ̂² (ML: σ̂²_eff, so n ln σ̂²_eff = −2 ln L − n(1 + ln 2π));
        ``n`` = residuals used.
    """
    if method not in ("ml", "css"):
        raise DriftInputError(f"ARMA fit method must be 'ml' or 'css', got {method!r}")
    a = check_series(x)
    _check_orders(a, p, q, include_mean)
    centre = float(a.mean()) if include_mean else 0.0  # conditioning only: the mean is re-estimated around it
    ac = a - centre
    if start is None:
        start = moment_estimates(ac, p, q)
    note = start.note
    s0 = p if condition is None or method == "ml" else max(int(condition), p)
    k = p + q + 1 + int(include_mean)
    if p + q == 0:
        return _white_noise_model(ac[s0:], centre, method, include_mean, note)
    scale = math.sqrt(float(np.mean(ac * ac)))
    scaled = ac / scale
    x0 = np.r_[_shrink_to_admissible(start.phi), _shrink_to_admissible(start.theta)]
    css = _css_problem(scaled, p, s0, include_mean)
    if method == "ml":
        css_fit = levenberg_marquardt(*css, x0, p)
        problem = _ml_problem(scaled, p, include_mean)
        starts = [css_fit.params, hannan_rissanen(scaled, p, q), hannan_rissanen(scaled, p, q, max(p, q))]
        starts += [_pad(nested, p, q)] if nested is not None else []
        params, conv, iterations, optimiser, normal = _maximise(problem, starts, p)
        iterations += css_fit.iterations
    else:
        params, conv, iterations, optimiser, normal = _maximise(css, [x0], p)
    phi, theta = params[:p], params[p:]
    if method == "ml":
        # mean fixed: the optimiser's own JᵀJ at this point is the information (× scale²: it ran on x/scale)
        known = None if include_mean or normal is None else normal * scale**2
        mu, e, s2, s2_crit, ll, jac, m = _ml_statistics(ac, scale, params, p, include_mean, known is None)
    else:
        known = None
        mu, e, s2, s2_crit, ll, jac, m = _css_statistics(ac, scale, params, p, s0, include_mean)
    info = known if known is not None else normal_equations(jac, e)[0]
    se = np.full(k - 1, np.nan)
    try:
        cov = s2 * np.linalg.inv(info)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        note = _note(note, "information matrix singular (over-parametrised model)")
    status, note = _convergence_status(conv, phi, theta, method, iterations, note)
    aic, bic = _criteria(m, s2_crit, k)
    return ArmaModel(
        p, q, phi, theta, s2, se[:p], se[p : p + q], s2 * math.sqrt(2.0 / m), m, method, aic, bic, note=note,
        include_mean=include_mean, mean=centre + mu, se_mean=float(se[-1]) if include_mean else math.nan,
        log_likelihood=ll, converged=conv.converged, status=status, gradient_norm=conv.gradient_norm,
        likelihood_gap=conv.gain,
        iterations=iterations, optimiser=optimiser, redundant_pairs=redundant_root_pairs(phi, theta),
    )  # fmt: skip


def _white_noise_model(
    tail: NDArray[np.float64], centre: float, method: str, include_mean: bool, note: str
) -> ArmaModel:
    """ARMA(0, 0) in closed form: the mean and the variance of the (conditioned) record."""
    z = np.zeros(0)
    k = 1 + int(include_mean)
    mu = float(tail.mean()) if include_mean else 0.0
    s2 = dot(tail - mu, tail - mu) / tail.size
    aic, bic = _criteria(tail.size, s2, k)
    se_mu = math.sqrt(s2 / tail.size) if include_mean else math.nan
    ll = -0.5 * tail.size * (math.log(2.0 * math.pi * s2) + 1.0)
    return ArmaModel(
        0, 0, z, z, s2, z, z, s2 * math.sqrt(2.0 / tail.size), tail.size, method, aic, bic, note=note,
        include_mean=include_mean, mean=centre + mu, se_mean=se_mu, log_likelihood=ll, optimiser="closed form",
    )  # fmt: skip


def _ml_statistics(
    ac: NDArray[np.float64], scale: float, params: NDArray[np.float64], p: int, include_mean: bool,
    jacobian: bool = True,
):  # fmt: skip
    """Exact-likelihood residual statistics at ``params``: (μ, weighted prediction errors, σ², σ²_eff, ln L,
    residual Jacobian columns in (φ, θ, μ) — None when ``jacobian`` is False —, residuals used)."""
    phi, theta = params[:p], params[p:]
    ex = exact_residuals(ac, phi, theta, include_mean)
    mu = ex.mean
    e = ex.weighted()
    ll = -0.5 * ex.minus_two_log_likelihood()
    if not jacobian:
        return mu, e, ex.sigma2, ex.sigma2_eff, ll, None, ex.n
    fixed = _ml_problem(ac / scale - mu / scale, p, False)  # Jacobian at fixed μ: full (φ, θ, μ) information
    jac = [c * scale for c in fixed[1](params, e / scale)]
    if include_mean:
        jac.append(-ex.weight * ex.mean_direction)
    return mu, e, ex.sigma2, ex.sigma2_eff, ll, jac, ex.n


def _css_statistics(
    ac: NDArray[np.float64], scale: float, params: NDArray[np.float64], p: int, s0: int, include_mean: bool
):
    """Conditional-least-squares residual statistics at ``params`` (as :func:`_ml_statistics`)."""
    phi, theta = params[:p], params[p:]
    if include_mean:
        mu_s, e, e1 = _css_mean(ac / scale, phi, theta, s0)
        mu = mu_s * scale
        e = e * scale
    else:
        mu, e = 0.0, css_residuals(ac, phi, theta, s0)
    s2 = dot(e, e) / e.size
    ll = -0.5 * e.size * (math.log(2.0 * math.pi * s2) + 1.0)
    jac = _jacobian(ac - mu, phi, theta, s0, e)
    if include_mean:
        jac.append(-e1)
    return mu, e, s2, s2, ll, jac, e.size


def _convergence_status(conv, phi, theta, method: str, iterations: int, note: str) -> tuple[str, str]:
    """("converged" | "not converged" | "boundary", the note with the non-convergence message added)."""
    if conv.converged:
        return "converged", note
    p, q = len(phi), len(theta)
    status = "not converged" if admissible(phi, theta, BOUNDARY_MARGIN) else "boundary"
    where = (
        ""
        if status == "not converged"
        else " (the likelihood rises toward the stationarity/invertibility boundary: a unit AR or MA root)"
    )
    note = _note(
        note,
        f"ARMA({p},{q}) {method.upper()} fit did not converge{where}: gradient norm {conv.gradient_norm:.3g}, "
        f"{conv.gain:.3g} log-likelihood still to gain, step {conv.step_se:.3g} s.e. after {iterations} "
        "iterations; the best point found is reported",
    )
    return status, note


@dataclass
class OrderSelection:
    """Result of :func:`select_order`.

    Attributes
    ----------
    best : ArmaModel
        Model chosen by ``criterion`` (its ``criterion`` field set).
    table : list of dict
        One row per (p, q): p, q, sigma2, log_likelihood, aic, bic, converged, parameter_redundancy.
    by_aic, by_bic : tuple[int, int]
        Orders minimising each criterion.
    models : dict
        (p, q) → fitted ArmaModel.
    """

    best: ArmaModel
    table: list[dict]
    by_aic: tuple[int, int]
    by_bic: tuple[int, int]
    models: dict = field(default_factory=dict)

    @property
    def unconverged(self) -> list[ArmaModel]:
        """Candidate fits whose optimum failed the convergence criteria."""
        return [m for m in self.models.values() if not m.converged]


def candidate_orders(max_p: int = 3, max_q: int = 3, p_ge_q: bool = False) -> list[tuple[int, int]]:
    """All (p, q) with p ≤ max_p, q ≤ max_q (and p ≥ q only when ``p_ge_q``, the published method's rule), in
    lexicographic order, so every model's nested models come before it."""
    return [(p, q) for p in range(max_p + 1) for q in range(max_q + 1) if p >= q or not p_ge_q]


def select_order(
    x: ArrayLike,
    max_p: int = 3,
    max_q: int = 3,
    criterion: str = "bic",
    method: str = "ml",
    progress: Callable[[tuple[int, int], int, int], None] | None = None,
    include_mean: bool = True,
    p_ge_q: bool = False,
) -> OrderSelection:
    """Fit every ARMA(p, q), p ≤ max_p, q ≤ max_q, and pick the order minimising BIC (default) or AIC.

    Parameters
    ----------
    x : array_like
        Scalar series, any unit.
    max_p, max_q : int
        Largest orders (spec: 3).
    criterion : {"bic", "aic"}
        Which criterion chooses ``best`` (spec: BIC; AIC over-fits near-cancelling root pairs, see the spec's
        decision); both choices are returned.
    method : {"ml", "css"}
        ``"ml"`` (default): exact maximum likelihood on the whole record, each model also started from the
        best nested model already fitted, so a larger model's likelihood is never below a model it contains.
        ``"css"``: conditional least squares with every candidate conditioned on the first max_p + max_q
        samples (same residual samples for all).
    progress : callable, optional
        Called as ``progress((p, q), k, total)`` after the k-th of ``total`` candidate fits (long records take
        seconds per model).
    include_mean : bool
        Estimate the mean jointly (default) or fix it at zero.
    p_ge_q : bool
        Only p ≥ q (the published method's rule; off by default so a pure MA(q) is reachable).

    Orders too large for the record length are skipped (at least ARMA(0,0) is always fitted).
    """
    if criterion not in ("aic", "bic"):
        raise DriftInputError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    a = check_series(x)
    # CSS: every candidate is conditioned on the same first samples, so σ̂² and the criteria compare like with
    # like (otherwise a higher p silently drops early, transient-affected residuals and looks better).
    common = max_p + max_q
    models: dict[tuple[int, int], ArmaModel] = {}
    orders = candidate_orders(max_p, max_q, p_ge_q)
    for index, (p, q) in enumerate(orders, start=1):
        try:
            _check_orders(a, p, q, include_mean)
        except DriftInputError:
            continue
        inner = [m for (pp, qq), m in models.items() if pp <= p and qq <= q]
        nested = max(inner, key=lambda m: m.log_likelihood) if inner else None
        models[(p, q)] = fit_arma(a, p, q, condition=common, method=method, nested=nested, include_mean=include_mean)
        if progress is not None:
            progress((p, q), index, len(orders))
    if not models:
        raise DriftInputError(f"series of {a.size} samples is too short for any ARMA model")
    by_aic = min(models, key=lambda k: models[k].aic)
    by_bic = min(models, key=lambda k: models[k].bic)
    best = models[by_bic if criterion == "bic" else by_aic]
    best.criterion = criterion
    table = [
        {
            "p": k[0], "q": k[1], "sigma2": m.sigma2, "log_likelihood": m.log_likelihood, "aic": m.aic,
            "bic": m.bic, "converged": m.converged, "parameter_redundancy": bool(m.redundant_pairs),
        }
        for k, m in models.items()
    ]  # fmt: skip
    return OrderSelection(best, table, by_aic, by_bic, models)


def arma_acvf(phi: ArrayLike, theta: ArrayLike, sigma2: float, nlags: int) -> NDArray[np.float64]:
    """Theoretical autocovariances γ_0..γ_nlags of the ARMA model (via its long MA(∞) expansion)."""
    ph = np.atleast_1d(np.asarray(phi, dtype=float))
    th = np.atleast_1d(np.asarray(theta, dtype=float))
    m = 20000
    imp = np.zeros(m)
    imp[0] = 1.0
    psi = signal.lfilter(np.r_[1.0, -th], np.r_[1.0, -ph], imp)
    return np.array([sigma2 * float(psi[: m - k] @ psi[k:]) for k in range(nlags + 1)])
