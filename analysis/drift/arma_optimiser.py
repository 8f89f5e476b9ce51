"""Maximisers of an ARMA likelihood written as a nonlinear least-squares problem ‖r(β)‖², β = (φ, θ).

Used by :func:`analysis.drift.arma.fit_arma` (specification docs/methods/drift.md: "optimiser
convergence must be checked, not capped silently"):

- :func:`levenberg_marquardt` in the coefficients themselves, steps leaving the stationary/invertible region
  rejected like cost increases;
- :func:`quasi_newton` (BFGS) on ln ‖r‖² in an unconstrained parametrisation (partial autocorrelations
  through tanh, Monahan 1984; Jones 1980), used from several starts when Levenberg–Marquardt stalls;
- :func:`convergence`: the criteria deciding whether a point is the maximum.

Convergence (both must hold at the reported point, m residuals, cost C = ‖r‖², g = Jᵀr, A = JᵀJ):

- gradient: the log-likelihood still to gain by a Gauss–Newton step, ½ m gᵀA⁻¹g / C, below :data:`GAIN_TOL`
  (ln L = −½ m ln C + const, so this is the quadratic model's predicted increase of ln L);
- step: that step, in standard errors (s_i / √((C/m)(A⁻¹)_ii)), below :data:`STEP_TOL` in every coefficient.

The reported gradient norm is ‖∇ ln L‖ = (m/C)‖g‖ with respect to (φ, θ) (1/coefficient unit).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

Residuals = Callable[[NDArray[np.float64]], NDArray[np.float64]]
Jacobian = Callable[[NDArray[np.float64], NDArray[np.float64]], list[NDArray[np.float64]]]

GAIN_TOL = 1e-5
"""Largest log-likelihood still to gain (Gauss–Newton prediction) at a converged point (1000× below the 0.01
agreement asked of the fits against reference results)."""
STEP_TOL = 5e-3
"""Largest Gauss–Newton step, in standard errors, at a converged point (10× below the 0.05 s.e. agreement)."""


def pacf_to_poly(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Partial autocorrelations (|r| < 1) → coefficients of a stationary 1 − Σ φ_j B^j (Monahan 1984)."""
    phi = np.zeros(0)
    for k, rk in enumerate(r, start=1):
        new = np.empty(k)
        new[: k - 1] = phi - rk * phi[::-1]
        new[k - 1] = rk
        phi = new
    return phi


def poly_to_pacf(phi: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Inverse of :func:`pacf_to_poly`; None when the polynomial is not stationary."""
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


def admissible(phi: NDArray[np.float64], theta: NDArray[np.float64], margin: float = 1e-6) -> bool:
    """True when 1 − Σ φ_j B^j is stationary and 1 − Σ θ_j B^j invertible (partial autocorrelations < 1)."""
    for poly in (phi, theta):
        if poly.size:
            r = poly_to_pacf(poly)
            if r is None or np.max(np.abs(r)) >= 1.0 - margin:
                return False
    return True


def dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Σ a_i b_i without BLAS (see :func:`normal_equations`)."""
    return float(np.einsum("i,i->", a, b))


def normal_equations(cols: list[NDArray[np.float64]], e: NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
    """JᵀJ and Jᵀe for a tall, thin J given as its (≤ 7) contiguous columns, by 1-D dot products.

    numpy's einsum loops avoid OpenBLAS, whose threaded GEMM/DOT is up to 100× slower for n × 6 on a loaded
    2-core machine (measured); keeping J as separate columns avoids copying it.
    """
    k = len(cols)
    A = np.empty((k, k))
    for i in range(k):
        for j in range(i, k):
            A[i, j] = A[j, i] = dot(cols[i], cols[j])
    g = np.array([dot(c, e) for c in cols])
    return A, g


def lagged_normal_equations(x: NDArray[np.float64], m: int) -> tuple[np.ndarray, np.ndarray]:
    """JᵀJ and Jᵀy of the autoregression of y = x[m:] on its m lags (columns x[m − j : n − j], j = 1..m), n ≥ 2m + 1.

    Equal to :func:`normal_equations` of those columns (to rounding) without its m(m + 3)/2 passes over the
    record: entry (i, j) (0 ≤ i ≤ j ≤ m, lag 0 being y) is Σ_{u=m−j}^{n−1−j} x_u x_{u+j−i}, the full lag-(j − i)
    product sum (m + 1 dot products) less its first m − j and its last i terms (sums of at most m products).
    """
    n = x.size
    full = np.array([dot(x[: n - k], x[k:]) for k in range(m + 1)])
    win = np.lib.stride_tricks.sliding_window_view
    xr = x[::-1]
    # cum[s, k] = Σ_{u<s} x_u x_{u+k} (head) and Σ of the last s lag-k products (tail), s = 0..m
    head = np.vstack((np.zeros(m + 1), np.cumsum(x[:m, None] * win(x[: 2 * m], m + 1), axis=0)))
    tail = np.vstack((np.zeros(m + 1), np.cumsum(xr[:m, None] * win(xr[: 2 * m], m + 1), axis=0)))
    i, k = np.nonzero(np.add.outer(np.arange(m + 1), np.arange(m + 1)) <= m)
    G = np.empty((m + 1, m + 1))
    G[i, i + k] = full[k] - head[m - i - k, k] - tail[i, k]
    G[i + k, i] = G[i, i + k]
    return G[1:, 1:], G[0, 1:]


@dataclass
class Convergence:
    """Convergence measures at a point (module docstring).

    Attributes
    ----------
    gain : float
        Log-likelihood still to gain by a Gauss–Newton step (inf when JᵀJ is singular).
    step_se : float
        Largest Gauss–Newton step component, in standard errors.
    gradient_norm : float
        ‖∇ ln L‖ with respect to the coefficients.
    converged : bool
        gain < :data:`GAIN_TOL` and step_se < :data:`STEP_TOL`.
    """

    gain: float
    step_se: float
    gradient_norm: float
    converged: bool


def convergence(A: NDArray[np.float64], g: NDArray[np.float64], cost: float, m: int) -> Convergence:
    """Gradient and step criteria from JᵀJ = A and Jᵀr = g at a point of cost ‖r‖² over m residuals."""
    cost = max(cost, 1e-300)
    grad = m / cost * float(np.sqrt(g @ g))
    try:
        inv = np.linalg.inv(A)
        step = -inv @ g
        gain = 0.5 * m * float(g @ inv @ g) / cost
        var = np.clip(np.diag(inv), 1e-300, None) * cost / m
        step_se = float(np.max(np.abs(step) / np.sqrt(var))) if step.size else 0.0
    except np.linalg.LinAlgError:
        gain, step_se = math.inf, math.inf
    if not (math.isfinite(gain) and math.isfinite(step_se)):
        return Convergence(math.inf, math.inf, grad, False)
    return Convergence(gain, step_se, grad, gain < GAIN_TOL and step_se < STEP_TOL)


@dataclass
class Optimum:
    """A point reached by an optimiser: parameters, cost ‖r‖², iterations used, whether it stopped by its criteria."""

    params: NDArray[np.float64]
    cost: float
    iterations: int
    stopped_by_criteria: bool
    check: Convergence | None = None
    """The convergence measures at ``params`` when the optimiser computed them there (saves recomputing them)."""
    normal: NDArray[np.float64] | None = None
    """JᵀJ at ``params`` when the optimiser computed it there (the cost's Gauss–Newton curvature, ½ ∇²‖r‖²)."""


def levenberg_marquardt(
    residuals: Residuals,
    jacobian: Jacobian,
    params: NDArray[np.float64],
    p: int,
    max_iter: int = 200,
    e0: NDArray[np.float64] | None = None,
) -> Optimum:
    """Minimise ‖r(params)‖² over params = (φ, θ) by Levenberg–Marquardt, staying stationary/invertible.

    Stops when the gradient and step criteria (:func:`convergence`) hold at the current point
    (``stopped_by_criteria`` True), or when no step decreases the cost, or when five accepted steps in a row
    gained less than 1e-14 of the cost, or after ``max_iter`` iterations (False: a stall, which the caller must
    resolve or report). ``e0``: r(params) when the caller has it already.
    """
    e = residuals(params) if e0 is None else e0
    cost = dot(e, e)
    m = e.size
    mu = 1e-3
    flat = 0
    for it in range(1, max_iter + 1):
        A, g = normal_equations(jacobian(params, e), e)
        conv = convergence(A, g, cost, m)
        if conv.converged:
            return Optimum(params, cost, it - 1, True, conv, A)
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
            if admissible(new[:p], new[p:]):
                e_new = residuals(new)
                cost_new = dot(e_new, e_new)
                if cost_new <= cost:
                    accepted = True
                    break
            mu *= 10.0
        if not accepted:
            return Optimum(params, cost, it, False)
        flat = flat + 1 if cost - cost_new <= 1e-14 * cost else 0
        params, e, cost = new, e_new, cost_new
        mu = max(mu / 10.0, 1e-12)
        if flat >= 5:
            return Optimum(params, cost, it, False)
    return Optimum(params, cost, max_iter, False)


def _to_unconstrained(params: NDArray[np.float64], p: int) -> NDArray[np.float64] | None:
    out = []
    for poly in (params[:p], params[p:]):
        r = poly_to_pacf(poly) if poly.size else np.zeros(0)
        if r is None:
            return None
        out.append(np.arctanh(np.clip(r, -1.0 + 1e-9, 1.0 - 1e-9)))
    return np.concatenate(out)


def _from_unconstrained(u: NDArray[np.float64], p: int) -> NDArray[np.float64]:
    return np.concatenate((pacf_to_poly(np.tanh(u[:p])), pacf_to_poly(np.tanh(u[p:]))))


def quasi_newton(residuals: Residuals, params: NDArray[np.float64], p: int, max_iter: int = 60) -> Optimum:
    """BFGS on m ln ‖r‖² (= −2 ln L + const) in the unconstrained partial-autocorrelation parametrisation.

    Slower than Levenberg–Marquardt near an optimum but not held back by its damping on curved ridges (nearly
    cancelling AR/MA roots) or by the region's boundary, which the parametrisation keeps at infinity. It is
    used as an explorer: ``max_iter`` iterations, then the caller polishes its point with Levenberg–Marquardt.
    """
    u0 = _to_unconstrained(params, p)
    if u0 is None:
        u0 = np.zeros(params.size)
    m = residuals(params).size

    def f(u: NDArray[np.float64]) -> float:
        if not np.all(np.isfinite(u)):
            return math.inf
        par = _from_unconstrained(u, p)
        if not admissible(par[:p], par[p:], 1e-12):
            return math.inf
        try:
            e = residuals(par)
        except np.linalg.LinAlgError:  # a root numerically on the unit circle
            return math.inf
        c = dot(e, e)
        return m * math.log(c) if c > 0 and math.isfinite(c) else math.inf

    with np.errstate(invalid="ignore", over="ignore"):  # inf outside the region: the line search backs off
        res = optimize.minimize(f, u0, method="BFGS", options={"maxiter": max_iter, "gtol": 1e-7})
    par = _from_unconstrained(res.x, p)
    cost = math.exp(res.fun / m) if math.isfinite(res.fun) else math.inf
    if not math.isfinite(cost):
        par = params
        e = residuals(par)
        cost = dot(e, e)
    return Optimum(par, cost, int(res.nit), bool(res.success))
