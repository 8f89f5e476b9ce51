"""ARMA(p, q) modelling of a drift residual: moment estimates, least-squares refinement, order selection.

Specification: ``shared/spec/drift-timeseries.md`` ("ARMA modelling").

Sign convention (Box–Jenkins, as the spec's moment equations and the simulated unit ``drivers.sim``):

    x_t − φ_1 x_{t−1} − … − φ_p x_{t−p} = e_t − θ_1 e_{t−1} − … − θ_q e_{t−q},   e_t ~ N(0, σ²) white,

so γ_Y(k) = σ²(−θ_k + Σ_{j=1}^{q−k} θ_j θ_{j+k}). statsmodels (and most software) write "+ θ_j e_{t−j}": its
MA coefficients are the negatives of these. x is a zero-mean scalar series (the input's mean is removed) in
any unit; σ² is in that unit squared.

- :func:`moment_estimates`: modified Yule–Walker (ρ_k = Σ φ_j ρ_{k−j}, k = q+1..q+p) for the AR part, then the
  MA part and σ² by the classical fixed-point iteration on the autocovariances of Y_t = x_t − Σ φ_j x_{t−j}
  (spectral factorisation when the iteration does not converge).
- :func:`fit_arma`: exact Gaussian maximum likelihood (default; :mod:`analysis.drift.arma_likelihood`) or
  conditional least squares (CSS), by Levenberg–Marquardt kept in the stationary/invertible region, started
  from the moment estimates (CSS) and the CSS solution (ML); standard errors σ² (JᵀJ)⁻¹ of the residual
  Jacobian.
- :func:`select_order`: all p, q ≤ 3 with p ≥ q by AIC = n ln σ̂² + 2(p+q+1) or BIC = n ln σ̂² + (p+q+1) ln n.
  The spec does not say how σ̂² is estimated; by default it is the exact-ML prediction-error variance, for which
  n ln σ̂² = −2 ln L − n(1 + ln 2π), i.e. the standard AIC/BIC (Akaike 1974; Box, Jenkins, Reinsel & Ljung
  §6.2.1).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal

from analysis.drift.arma_likelihood import exact_residuals
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
        ``"moments"`` or ``"css"``.
    aic, bic : float
        n ln σ̂² + 2(p+q+1), n ln σ̂² + (p+q+1) ln n.
    criterion : str
        Criterion by which the order was chosen ("aic", "bic" or "given").
    note : str
        Warnings (e.g. MA iteration fell back to spectral factorisation).
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

    def to_dict(self) -> dict:
        """JSON-ready dictionary: p, q, phi, theta, sigma2, criterion, then standard errors and criteria."""
        return {
            "p": self.p,
            "q": self.q,
            "phi": [float(v) for v in self.phi],
            "theta": [float(v) for v in self.theta],
            "sigma2": float(self.sigma2),
            "criterion": self.criterion,
            "se_phi": [float(v) for v in self.se_phi],
            "se_theta": [float(v) for v in self.se_theta],
            "se_sigma2": float(self.se_sigma2),
            "aic": float(self.aic),
            "bic": float(self.bic),
            "n": self.n,
            "method": self.method,
            "sign_convention": "x_t - sum phi_j x_(t-j) = e_t - sum theta_j e_(t-j)",
            "note": self.note,
        }


def _criteria(n: int, sigma2: float, k: int) -> tuple[float, float]:
    ls = n * math.log(max(sigma2, np.finfo(float).tiny))
    return ls + 2.0 * k, ls + k * math.log(n)


def _check_orders(x: NDArray[np.float64], p: int, q: int) -> None:
    if p < 0 or q < 0 or p > 10 or q > 10:
        raise DriftInputError(f"ARMA orders must be 0..10, got p={p}, q={q}")
    need = max(10 * (p + q + 1), 2 * (p + q) + 20)
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
        Zero-mean scalar series (its mean is removed), any unit.
    p, q : int
        Orders.
    """
    a = check_series(x)
    _check_orders(a, p, q)
    a = a - a.mean()
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
    aic, bic = _criteria(n, s2, p + q + 1)
    nan = np.full
    return ArmaModel(
        p, q, phi, theta, s2, nan(p, np.nan), nan(q, np.nan), s2 * math.sqrt(2.0 / n), n, "moments", aic, bic,
        note=note,
    )  # fmt: skip


# --- stationary / invertible parametrisation ---------------------------------------------------------------


def _pacf_to_poly(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Partial autocorrelations (|r| < 1) → AR coefficients of a stationary 1 − Σ φ_j B^j (Monahan 1984)."""
    phi = np.zeros(0)
    for k, rk in enumerate(r, start=1):
        new = np.empty(k)
        new[: k - 1] = phi - rk * phi[::-1]
        new[k - 1] = rk
        phi = new
    return phi


def _poly_to_pacf(phi: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Inverse of :func:`_pacf_to_poly`; None when the polynomial is not stationary."""
    phi = np.array(phi, dtype=float)
    k = phi.size
    r = np.zeros(k)
    while k > 0:
        rk = phi[k - 1]
        if abs(rk) >= 1.0:
            return None
        r[k - 1] = rk
        prev = phi[: k - 1]
        phi = (prev + rk * prev[::-1]) / (1.0 - rk * rk)
        k -= 1
    return r


def _admissible(phi: NDArray[np.float64], theta: NDArray[np.float64], margin: float = 1e-6) -> bool:
    """True when 1 − Σ φ_j B^j is stationary and 1 − Σ θ_j B^j invertible (partial autocorrelations < 1)."""
    for poly in (phi, theta):
        if poly.size:
            r = _poly_to_pacf(poly)
            if r is None or np.max(np.abs(r)) >= 1.0 - margin:
                return False
    return True


def _shrink_to_admissible(poly: NDArray[np.float64]) -> NDArray[np.float64]:
    """Scale coefficient j by s^j (roots pushed outward) until the polynomial is stationary/invertible."""
    out = poly.copy()
    s = 1.0
    while out.size and not _admissible(out, np.zeros(0), 1e-3):
        s *= 0.95
        out = poly * s ** np.arange(1, poly.size + 1)
    return out


def css_residuals(
    x: NDArray[np.float64], phi: NDArray[np.float64], theta: NDArray[np.float64], start: int | None = None
) -> NDArray[np.float64]:
    """Conditional residuals e_t, t = start..n−1, with e_t = 0 before ``start`` (default and minimum: p).

    The first ``start`` samples are conditioned on; comparing models of different orders on the same
    ``start`` makes their σ̂² (and AIC/BIC) refer to the same samples.
    """
    p = phi.size
    s0 = p if start is None else max(int(start), p)
    w = signal.lfilter(np.r_[1.0, -phi], [1.0], x)[s0:]
    return signal.lfilter([1.0], np.r_[1.0, -theta], w) if theta.size else w


def _jacobian(
    x: NDArray[np.float64], phi: NDArray[np.float64], theta: NDArray[np.float64], start: int, e: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Columns ∂e_t/∂(φ, θ) of the CSS residuals e (:func:`css_residuals` at the same point and ``start``).

    ∂e_t/∂φ_j = −θ(B)⁻¹ x_{t−j} and ∂e_t/∂θ_j = +θ(B)⁻¹ e_{t−j}, θ(B) = 1 − Σ θ_j B^j.
    """
    p, q = phi.size, theta.size
    m = e.size
    cols = []
    den = np.r_[1.0, -theta]
    for j in range(1, p + 1):
        xs = x[start - j : start - j + m]
        cols.append(-signal.lfilter([1.0], den, xs))
    for j in range(1, q + 1):
        es = np.concatenate((np.zeros(j), e[: m - j]))
        cols.append(signal.lfilter([1.0], den, es))
    return cols


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Σ a_i b_i without BLAS (see :func:`_normal_equations`)."""
    return float(np.einsum("i,i->", a, b))


def _normal_equations(cols: list[NDArray[np.float64]], e: NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
    """JᵀJ and Jᵀe for a tall, thin J given as its (≤ 6) contiguous columns, by 1-D dot products.

    numpy's einsum loops avoid OpenBLAS, whose threaded GEMM/DOT is up to 100× slower for n × 6 on a loaded
    2-core machine (measured); keeping J as separate columns avoids copying it.
    """
    k = len(cols)
    A = np.empty((k, k))
    for i in range(k):
        for j in range(i, k):
            A[i, j] = A[j, i] = _dot(cols[i], cols[j])
    g = np.array([_dot(c, e) for c in cols])
    return A, g


Residuals = Callable[[NDArray[np.float64]], NDArray[np.float64]]
Jacobian = Callable[[NDArray[np.float64], NDArray[np.float64]], list[NDArray[np.float64]]]


def _levenberg_marquardt(
    residuals: Residuals, jacobian: Jacobian, params: NDArray[np.float64], p: int, max_iter: int = 60
) -> tuple[NDArray[np.float64], float, int, bool]:
    """Minimise Σ e(params)² over params = (φ, θ) by Levenberg–Marquardt, staying stationary/invertible.

    Steps leaving the stationary/invertible region are rejected like cost increases. Converged when the
    relative cost decrease of an accepted step is below 1e-10 (a parameter error of ~0.01 standard error
    for n ~ 10⁴) or the step is below 1e-10.

    Returns
    -------
    params, cost (Σ e² at params), iterations, converged
    """
    e = residuals(params)
    cost = _dot(e, e)
    mu = 1e-3
    for it in range(1, max_iter + 1):
        A, g = _normal_equations(jacobian(params, e), e)
        d = np.diag(A).copy()
        d[d <= 0.0] = 1.0
        accepted = False
        for _ in range(30):
            try:
                step = np.linalg.solve(A + mu * np.diag(d), -g)
            except np.linalg.LinAlgError:
                mu *= 10.0
                continue
            new = params + step
            if _admissible(new[:p], new[p:]):
                e_new = residuals(new)
                cost_new = _dot(e_new, e_new)
                if cost_new <= cost:
                    accepted = True
                    break
            mu *= 10.0
        if not accepted:
            return params, cost, it, True  # no decrease possible: at the (boundary) minimum
        rel = (cost - cost_new) / max(cost, 1e-300)
        params, e, cost = new, e_new, cost_new
        mu = max(mu / 10.0, 1e-12)
        if rel < 1e-10 or float(np.max(np.abs(step))) < 1e-10:
            return params, cost, it, True
    return params, cost, max_iter, False


def _css_problem(x: NDArray[np.float64], p: int, start: int) -> tuple[Residuals, Jacobian]:
    """CSS residuals e_t (t ≥ start) and their analytic Jacobian as functions of (φ, θ)."""

    def residuals(par: NDArray[np.float64]) -> NDArray[np.float64]:
        return css_residuals(x, par[:p], par[p:], start)

    def jacobian(par: NDArray[np.float64], e: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        return _jacobian(x, par[:p], par[p:], start, e)

    return residuals, jacobian


def _ml_problem(x: NDArray[np.float64], p: int) -> tuple[Residuals, Jacobian]:
    """Exact-likelihood residual vector (:mod:`analysis.drift.arma_likelihood`) and its Jacobian.

    The Jacobian is by forward differences (backward where the forward point leaves the admissible region),
    step 1e-7 in the coefficients: a relative error of ~1e-7/σ_coefficient ≪ 1. The most probable pre-sample
    values are re-solved at each point; by the envelope theorem this does not bias the gradient.
    """

    def residuals(par: NDArray[np.float64]) -> NDArray[np.float64]:
        return exact_residuals(x, par[:p], par[p:]).weighted()

    def jacobian(par: NDArray[np.float64], e: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        cols = []
        for i in range(par.size):
            bumped = par.copy()
            h = 1e-7
            bumped[i] += h
            if not _admissible(bumped[:p], bumped[p:], 0.0):
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


def fit_arma(
    x: ArrayLike,
    p: int,
    q: int,
    start: ArmaModel | None = None,
    condition: int | None = None,
    method: str = "ml",
    nested: ArmaModel | None = None,
) -> ArmaModel:
    """Fit ARMA(p, q) with standard errors: exact Gaussian maximum likelihood (default) or conditional least squares.

    Parameters
    ----------
    x : array_like
        Scalar series (mean removed here), any unit.
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
    nested : ArmaModel, optional
        ML only: a fitted model of orders p' ≤ p, q' ≤ q, used (zero-padded) as a second start, so the
        likelihood is never below that of a model it contains — order criteria then compare true maxima.

    Returns
    -------
    ArmaModel
        σ² = mean squared (prediction) residual; standard errors σ²(JᵀJ)⁻¹ from the residual Jacobian; ``aic``
        and ``bic`` from n ln σ̂² (ML: σ̂²_eff, so n ln σ̂²_eff = −2 ln L − n(1 + ln 2π)); ``n`` = residuals used.
    """
    if method not in ("ml", "css"):
        raise DriftInputError(f"ARMA fit method must be 'ml' or 'css', got {method!r}")
    a = check_series(x)
    _check_orders(a, p, q)
    a = a - a.mean()
    if start is None:
        start = moment_estimates(a, p, q)
    note = start.note
    s0 = p if condition is None or method == "ml" else max(int(condition), p)
    if p + q == 0:
        tail = a[s0:]
        s2 = _dot(tail, tail) / tail.size
        aic, bic = _criteria(tail.size, s2, 1)
        z = np.zeros(0)
        return ArmaModel(0, 0, z, z, s2, z, z, s2 * math.sqrt(2.0 / tail.size), tail.size, method, aic, bic, note=note)
    scale = math.sqrt(float(np.mean(a * a)))
    scaled = a / scale
    css = _css_problem(scaled, p, s0)
    params, _, it, converged = _levenberg_marquardt(
        *css, np.r_[_shrink_to_admissible(start.phi), _shrink_to_admissible(start.theta)], p
    )
    if method == "ml":
        ml = _ml_problem(scaled, p)
        starts = [params] + ([_pad(nested, p, q)] if nested is not None else [])
        fits = [_levenberg_marquardt(*ml, s, p) for s in starts if _admissible(s[:p], s[p:])]
        params, _, it, converged = min(fits, key=lambda fit: fit[1])
        phi, theta = params[:p], params[p:]
        ex = exact_residuals(a, phi, theta)
        e = ex.weighted()
        s2, s2_crit = ex.sigma2, ex.sigma2_eff
        jac = [c * scale for c in ml[1](params, e / scale)]
        m = ex.n
    else:
        phi, theta = params[:p], params[p:]
        e = css_residuals(a, phi, theta, s0)
        s2 = s2_crit = _dot(e, e) / e.size
        jac = _jacobian(a, phi, theta, s0, e)
        m = e.size
    info, _ = _normal_equations(jac, e)
    se = np.full(p + q, np.nan)
    try:
        cov = s2 * np.linalg.inv(info)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        note = _note(note, "information matrix singular (over-parametrised model)")
    if not converged:
        note = _note(note, f"least squares stopped after {it} iterations without converging")
    aic, bic = _criteria(m, s2_crit, p + q + 1)
    return ArmaModel(p, q, phi, theta, s2, se[:p], se[p:], s2 * math.sqrt(2.0 / m), m, method, aic, bic, note=note)


@dataclass
class OrderSelection:
    """Result of :func:`select_order`.

    Attributes
    ----------
    best : ArmaModel
        Model chosen by ``criterion`` (its ``criterion`` field set).
    table : list of dict
        One row per (p, q): p, q, sigma2, aic, bic.
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


def candidate_orders(max_p: int = 3, max_q: int = 3) -> list[tuple[int, int]]:
    """All (p, q) with p ≤ max_p, q ≤ max_q, p ≥ q."""
    return [(p, q) for p in range(max_p + 1) for q in range(max_q + 1) if p >= q]


def select_order(
    x: ArrayLike,
    max_p: int = 3,
    max_q: int = 3,
    criterion: str = "bic",
    method: str = "ml",
    progress: Callable[[tuple[int, int], int, int], None] | None = None,
) -> OrderSelection:
    """Fit every ARMA(p, q), p ≤ max_p, q ≤ max_q, p ≥ q, and pick the order minimising AIC or BIC.

    Parameters
    ----------
    x : array_like
        Scalar series (mean removed), any unit.
    max_p, max_q : int
        Largest orders (spec: 3).
    criterion : {"bic", "aic"}
        Which criterion chooses ``best``; both choices are returned.
    method : {"ml", "css"}
        ``"ml"`` (default): exact maximum likelihood on the whole record, each model also started from the
        best nested model already fitted, so a larger model's likelihood is never below a model it contains.
        ``"css"``: conditional least squares with every candidate conditioned on the first max_p + max_q
        samples (same residual samples for all). Exact ML is the default because CSS over-fits under AIC
        (measured: AIC picks the true ARMA(1,1) in ~50 % of runs with CSS, see ``benchmarks/RESULTS.md``).

    progress : callable, optional
        Called as ``progress((p, q), k, total)`` after the k-th of ``total`` candidate fits (long records take
        seconds per model).

    Orders too large for the record length are skipped (at least ARMA(0,0) is always fitted).
    """
    if criterion not in ("aic", "bic"):
        raise DriftInputError(f"criterion must be 'aic' or 'bic', got {criterion!r}")
    a = check_series(x)
    # CSS: every candidate is conditioned on the same first samples, so σ̂² and the criteria compare like with
    # like (otherwise a higher p silently drops early, transient-affected residuals and looks better).
    common = max_p + max_q
    models: dict[tuple[int, int], ArmaModel] = {}
    orders = candidate_orders(max_p, max_q)
    for index, (p, q) in enumerate(orders, start=1):
        try:
            _check_orders(a, p, q)
        except DriftInputError:
            continue
        inner = [m for (pp, qq), m in models.items() if pp <= p and qq <= q]
        nested = min(inner, key=lambda m: m.aic - 2.0 * (m.p + m.q + 1)) if inner else None
        models[(p, q)] = fit_arma(a, p, q, condition=common, method=method, nested=nested)
        if progress is not None:
            progress((p, q), index, len(orders))
    if not models:
        raise DriftInputError(f"series of {a.size} samples is too short for any ARMA model")
    by_aic = min(models, key=lambda k: models[k].aic)
    by_bic = min(models, key=lambda k: models[k].bic)
    best = models[by_bic if criterion == "bic" else by_aic]
    best.criterion = criterion
    table = [{"p": k[0], "q": k[1], "sigma2": m.sigma2, "aic": m.aic, "bic": m.bic} for k, m in models.items()]
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
