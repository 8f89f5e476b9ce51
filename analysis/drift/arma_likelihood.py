"""Exact Gaussian likelihood of an ARMA(p, q) series (zero mean, or mean profiled out), by regression on the
pre-sample values.

Specification: docs/methods/drift.md ("ARMA modelling"). The spec is silent on how σ̂² is
estimated for the order criteria; the standard exact maximum-likelihood form is used (Box, Jenkins, Reinsel &
Ljung, *Time Series Analysis*, 5th ed., §7.1.4 and appendix A7.3: the unconditional sum of squares).

Model (Box–Jenkins signs, as :mod:`analysis.drift.arma`), x in any unit, e_t ~ N(0, σ²) white:

    x_t − Σ φ_j x_{t−j} = e_t − Σ θ_j e_{t−j}.

Given the pre-sample vector u = (x_{−1}, …, x_{−p}, e_{−1}, …, e_{−q}), the recursion maps x_0..x_{n−1} to
e_0..e_{n−1} = e_c + B u with unit Jacobian: e_c is the conditional (CSS) residual with u = 0 and the columns of
B are the responses of the inverse filter to each pre-sample value. u is itself Gaussian, u ~ N(0, σ² Σ_u), Σ_u
the stationary covariance of the recursion's state (a discrete Lyapunov equation). With Σ_u = L Lᵀ, C = B L,
M = I + CᵀC, integrating u out gives exactly

    −2 ln L = n ln(2π σ²) + ln det M + S/σ²,   S = min_w ‖e_c + C w‖² + ‖w‖² = e_cᵀe_c − (Cᵀe_c)ᵀ M⁻¹ Cᵀe_c,

so σ̂² = S/n and, concentrated, −2 ln L = n ln σ̂²_eff + n(1 + ln 2π) with σ̂²_eff = σ̂² (det M)^{1/n}. This is the
same likelihood as the Kalman filter's prediction-error decomposition (Σ ln f_t = ln det M, Σ v_t²/f_t = S;
``tests/test_drift_arma_likelihood.py`` checks both, and statsmodels), but needs no per-sample Python loop:
p + q + 1 ``scipy.signal.lfilter`` passes and an (p+q)×(p+q) solve.

The residual vector r = (det M)^{1/(2n)} [e_c + C w*; w*] has ‖r‖² = n σ̂²_eff, so maximising the exact
likelihood is a nonlinear least-squares problem in r (Box–Jenkins' unconditional least squares with the
determinant factor), solved by :func:`analysis.drift.arma.fit_arma`.

Mean: when x − μ is the ARMA process, r is linear in x, r(x − μ) = r(x) − μ r(1), and ln det M does not depend on
μ; the exact maximum over μ at given coefficients is therefore the generalised-least-squares mean
μ̂ = ⟨r(x), r(1)⟩ / ‖r(1)‖² (``estimate_mean=True``), and the profiled vector r(x) − μ̂ r(1) is the objective.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import signal


@dataclass
class ExactResiduals:
    """Exact-likelihood quantities of a zero-mean series under an ARMA(p, q) model.

    Attributes
    ----------
    residuals : ndarray (n,)
        e_c + C w*: the innovations e_t given the data and the most probable pre-sample values, unit of x.
    presample : ndarray (p+q,)
        w*, the whitened most probable pre-sample values (dimensionless).
    log_det : float
        ln det M (= Σ ln f_t of the Kalman prediction-error decomposition).
    mean : float
        μ̂, the generalised-least-squares (= exact-ML) mean at these coefficients, unit of x (0 if not estimated).
    mean_direction : ndarray (n + p + q,) or None
        r(1), the whitened response to a unit mean: ∂(unweighted residual vector)/∂μ = −r(1).
    """

    residuals: NDArray[np.float64]
    presample: NDArray[np.float64]
    log_det: float
    mean: float = 0.0
    mean_direction: NDArray[np.float64] | None = None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.residuals.size)

    @property
    def sum_of_squares(self) -> float:
        """S = ‖e_c + C w*‖² + ‖w*‖² (unit of x squared)."""
        r, w = self.residuals, self.presample
        return float(np.einsum("i,i->", r, r) + w @ w)

    @property
    def sigma2(self) -> float:
        """Maximum-likelihood innovation variance for these coefficients, S/n, unit of x squared."""
        return self.sum_of_squares / self.n

    @property
    def sigma2_eff(self) -> float:
        """σ̂² (det M)^{1/n}: n ln σ̂²_eff = −2 ln L − n(1 + ln 2π) at the concentrated maximum."""
        return self.sigma2 * float(np.exp(self.log_det / self.n))

    def minus_two_log_likelihood(self) -> float:
        """−2 ln L at σ² = σ̂² (concentrated)."""
        return self.n * (np.log(self.sigma2_eff) + 1.0 + np.log(2.0 * np.pi))

    @property
    def weight(self) -> float:
        """(det M)^{1/(2n)}: the factor making the residual vector's sum of squares n σ̂²_eff."""
        return float(np.exp(self.log_det / (2.0 * self.n)))

    def weighted(self) -> NDArray[np.float64]:
        """Residual vector whose sum of squares is n σ̂²_eff (the exact-ML least-squares objective)."""
        return np.concatenate((self.residuals, self.presample)) * self.weight


def lag_polynomial(c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Coefficients (1, −c₁, …, −c_k) of 1 − Σ c_j B^j (``np.r_[1.0, -c]`` without its indexing overhead)."""
    out = np.empty(c.size + 1)
    out[0] = 1.0
    np.negative(c, out=out[1:])
    return out


def presample_covariance(phi: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """Stationary covariance / σ² of u = (x_{t−1}, …, x_{t−p}, e_{t−1}, …, e_{t−q}) for a stationary ARMA.

    The vector obeys s_{t+1} = A s_t + b e_t with x_t = Σ φ_j x_{t−j} − Σ θ_j e_{t−j} + e_t, so
    Σ_u = A Σ_u Aᵀ + b bᵀ.
    """
    p, q = phi.size, theta.size
    r = p + q
    A = np.zeros((r, r))
    b = np.zeros(r)
    if p:
        A[0, :p] = phi
        A[0, p:] = -theta
        A[np.arange(1, p), np.arange(p - 1)] = 1.0
        b[0] = 1.0
    if q:
        b[p] = 1.0
        A[np.arange(p + 1, r), np.arange(p, r - 1)] = 1.0
    # vec Σ = (I − A⊗A)⁻¹ vec(bbᵀ), r ≤ 20: plain numpy (scipy's wrappers cost more than the solve here).
    kron = (A[:, None, :, None] * A[None, :, None, :]).reshape(r * r, r * r)  # A ⊗ A (np.kron costs more here)
    cov = np.linalg.solve(np.eye(r * r) - kron, np.outer(b, b).ravel()).reshape(r, r)
    return 0.5 * (cov + cov.T)


def _factor(cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """L with L Lᵀ = cov for a positive semi-definite cov (Cholesky, eigen-decomposition if singular)."""
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        w, vecs = np.linalg.eigh(cov)
        return vecs * np.sqrt(np.clip(w, 0.0, None))


def _response_to_ones(num: NDArray[np.float64], den: NDArray[np.float64], n: int, span: int) -> NDArray[np.float64]:
    """e_c of a constant unit series: the filter's transient over ``span`` samples, then its DC gain."""
    head = signal.lfilter(num, den, np.ones(min(n, span)))
    if span >= n:
        return head
    out = np.empty(n)
    out[:span] = head
    out[span:] = float(np.sum(num) / np.sum(den))
    return out


def exact_residuals(
    x: NDArray[np.float64],
    phi: NDArray[np.float64],
    theta: NDArray[np.float64],
    estimate_mean: bool = False,
) -> ExactResiduals:
    """Exact-likelihood residuals of a series under a stationary, invertible ARMA(p, q), mean zero or estimated.

    Parameters
    ----------
    x : ndarray (n,)
        Scalar series, any unit (not demeaned here).
    phi, theta : ndarray
        AR and MA coefficients (Box–Jenkins signs); φ must be stationary (the caller keeps it so).
    estimate_mean : bool
        False: x is taken as zero-mean. True: x − μ is the ARMA process and μ is profiled out by generalised
        least squares at these coefficients, μ̂ = ⟨r(x), r(1)⟩ / ‖r(1)‖² with r(·) the (linear) whitening map
        below; the determinant term does not depend on μ, so this is the exact joint maximum over μ.

    Returns
    -------
    ExactResiduals
        With ``mean`` = μ̂ (0 when not estimated) and ``mean_direction`` = r(1) (for the mean's standard error).
    """
    phi = np.asarray(phi, dtype=float)
    theta = np.asarray(theta, dtype=float)
    p, q = phi.size, theta.size
    n = x.size
    num = lag_polynomial(phi)
    den = lag_polynomial(theta)
    r = p + q
    # Responses decay like ρᵗ (ρ the largest reciprocal MA root), so only their first `span` samples are non-zero
    # in double precision (e^{−40} ≈ 4e-18).
    # (q = 1: the one root is θ₁ itself, as np.roots finds it, without its eigenvalue solver)
    rho = (abs(float(theta[0])) if q == 1 else float(np.max(np.abs(np.roots(den))))) if q else 0.0
    span = n if rho >= 1.0 - 1e-12 else min(n, max(p, q) + 1 + int(np.ceil(40.0 / -np.log(max(rho, 1e-300)))))
    e_c = signal.lfilter(num, den, x)
    ones = _response_to_ones(num, den, n, span) if estimate_mean else None
    if r == 0:
        mean = 0.0
        if ones is not None:
            mean = float(np.einsum("i,i->", e_c, ones) / np.einsum("i,i->", ones, ones))
            e_c = e_c - mean * ones
        return ExactResiduals(e_c, np.zeros(0), 0.0, mean, ones)
    # Response of the inverse filter to each unit pre-sample value (zero data): x_{−j} enters e_t as −φ_{t+j}
    # and e_{−j} as +θ_{t+j} for t + j within the orders, both then through 1/θ(B).
    V = np.zeros((r, span))
    for j in range(1, p + 1):
        V[j - 1, : p - j + 1] = -phi[j - 1 :]
    for j in range(1, q + 1):
        V[p + j - 1, : q - j + 1] = theta[j - 1 :]
    B = signal.lfilter([1.0], den, V, axis=1) if q else V
    C = _factor(presample_covariance(phi, theta)).T @ B  # rows: columns of C = B L
    ctc = np.einsum("in,jn->ij", C, C)
    M = np.eye(r) + ctc
    chol = np.linalg.cholesky(M)
    log_det = 2.0 * float(np.sum(np.log(np.diag(chol))))

    def whiten(e: NDArray[np.float64]) -> NDArray[np.float64]:
        """w* = argmin ‖e + C w‖² + ‖w‖²; e is updated in place to e + C w*."""
        w = -np.linalg.solve(M, np.einsum("in,n->i", C, e[:span]))
        e[:span] += w @ C
        return w

    w = whiten(e_c)
    mean = 0.0
    if ones is not None:
        w1 = whiten(ones)
        mean = float((np.einsum("i,i->", e_c, ones) + w @ w1) / (np.einsum("i,i->", ones, ones) + w1 @ w1))
        e_c -= mean * ones
        w = w - mean * w1
        ones = np.concatenate((ones, w1))
    return ExactResiduals(e_c, w, log_det, mean, ones)
