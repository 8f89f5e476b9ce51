"""ARMA drift in state-space form: Kalman filter, sliding-window Levenberg–Marquardt ("graph") smoother.

Specification: docs/methods/drift.md ("Compensation").

State-space form (Harvey) of the ARMA(p, q) drift d_t (sign convention of :mod:`analysis.drift.arma`),
m = max(p, q + 1):

    X_k = Φ X_{k−1} + G e_k,   Φ = [φ | I_{m−1}; 0],  G = [1, −θ_1, …, −θ_{m−1}]ᵀ,  d_k = H X_k,  H = [1, 0, …, 0]
    Z_k = H X_k + v_k,         v_k ~ N(0, R)   (white measurement noise of the sensor),

Q = σ² G Gᵀ has rank one; the graph cost below needs Q⁻¹, so a small isotropic floor ``process_floor``·σ² I is
added (default 1e-5 of σ²) — the same model is given to the Kalman/RTS reference, so the LM = RTS check is exact.

Graph optimisation over a window k0..k1−1 (variables X_k0 … X_k1−1):

    J(X) = ‖X_k0 − x̄‖²_{P̄⁻¹} + Σ_k ‖X_k − Φ X_{k−1}‖²_{Q⁻¹} + Σ_k (Z_k − H X_k)²/R,

(x̄, P̄) the Kalman prediction for X_k0 from the data before the window. It is minimised by Levenberg–Marquardt
(damped Gauss–Newton with gain-ratio control) on the whitened residual vector with a sparse Jacobian. For this
linear-Gaussian model the window minimum equals the Rauch–Tung–Striebel smoother of the window with the same
prior; :func:`tests.test_drift_smoother` checks this against filterpy's ``rts_smoother`` to 1e-6.

"Compensation" figures: the standard deviation of the record before, of the Kalman one-step prediction
residual Z_k − H Φ X̂_{k−1|k−1} (real-time compensation), and of Z_k − H X̂_k|smoothed (post-processing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy import linalg, signal
from scipy.sparse.linalg import spsolve

from analysis.drift.preprocess import DriftInputError


@dataclass
class StateSpace:
    """Linear-Gaussian state-space model with scalar measurement.

    Attributes
    ----------
    F : ndarray (m, m)
        Transition Φ.
    H : ndarray (1, m)
        Measurement row.
    Q : ndarray (m, m)
        Process-noise covariance (positive definite), measurement unit squared.
    R : float
        Measurement-noise variance, measurement unit squared.
    x0, P0 : ndarray
        Prior mean (m,) and covariance (m, m) of the first state (stationary by default).
    """

    F: NDArray[np.float64]
    H: NDArray[np.float64]
    Q: NDArray[np.float64]
    R: float
    x0: NDArray[np.float64]
    P0: NDArray[np.float64]

    @property
    def m(self) -> int:
        """State dimension."""
        return self.F.shape[0]


def arma_state_space(
    phi: ArrayLike, theta: ArrayLike, sigma2: float, measurement_var: float, process_floor: float = 1e-5
) -> StateSpace:
    """State-space form of an ARMA(p, q) drift observed with white noise (see module docstring).

    Parameters
    ----------
    phi, theta : array_like
        AR and MA coefficients (Box–Jenkins signs, :mod:`analysis.drift.arma`).
    sigma2 : float
        Innovation variance σ² of the ARMA drift, unit².
    measurement_var : float
        R, white measurement-noise variance, unit² (> 0).
    process_floor : float
        Relative isotropic floor added to Q (fraction of σ²).
    """
    ph = np.atleast_1d(np.asarray(phi, dtype=float))
    th = np.atleast_1d(np.asarray(theta, dtype=float))
    if not (sigma2 > 0 and measurement_var > 0 and process_floor > 0):
        raise DriftInputError("state-space model needs sigma2 > 0, measurement_var > 0 and process_floor > 0")
    if ph.size and np.any(np.abs(np.roots(np.r_[1.0, -ph][::-1])) <= 1.0 + 1e-9):
        raise DriftInputError(f"AR part {ph.tolist()} is not stationary; cannot build a stationary prior")
    m = max(ph.size, th.size + 1)
    F = np.zeros((m, m))
    F[: ph.size, 0] = ph
    F[np.arange(m - 1), np.arange(1, m)] = 1.0
    G = np.zeros(m)
    G[0] = 1.0
    G[1 : 1 + th.size] = -th
    Q = sigma2 * (np.outer(G, G) + process_floor * np.eye(m))
    H = np.zeros((1, m))
    H[0, 0] = 1.0
    P0 = linalg.solve_discrete_lyapunov(F, Q)
    return StateSpace(F, H, Q, float(measurement_var), np.zeros(m), 0.5 * (P0 + P0.T))


@dataclass
class FilterResult:
    """Kalman filter output: filtered means (n, m), covariances (n, m, m), predicted means and covariances."""

    x: NDArray[np.float64]
    P: NDArray[np.float64]
    x_pred: NDArray[np.float64]
    P_pred: NDArray[np.float64]


def kalman_filter(
    model: StateSpace, z: ArrayLike, x0: ArrayLike | None = None, P0: ArrayLike | None = None
) -> FilterResult:
    """Exact Kalman filter (predict then update at every sample), prior (x0, P0) for the state *before* z[0].

    With the defaults the prior before z[0] is the stationary one, whose prediction is itself stationary.
    """
    zz = np.asarray(z, dtype=float)
    n, m = zz.size, model.m
    F, H, Q, R = model.F, model.H[0], model.Q, model.R
    x = np.array(model.x0 if x0 is None else x0, dtype=float)
    P = np.array(model.P0 if P0 is None else P0, dtype=float)
    xs = np.empty((n, m))
    Ps = np.empty((n, m, m))
    xp = np.empty((n, m))
    Pp = np.empty((n, m, m))
    for k in range(n):
        x = F @ x
        P = F @ P @ F.T + Q
        xp[k], Pp[k] = x, P
        ph = P @ H
        s = float(H @ ph) + R
        kg = ph / s
        x = x + kg * (zz[k] - float(H @ x))
        P = P - np.outer(kg, ph)
        P = 0.5 * (P + P.T)
        xs[k], Ps[k] = x, P
    return FilterResult(xs, Ps, xp, Pp)


def steady_state_filter(model: StateSpace, z: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Steady-state Kalman filter over a long record, vectorised with ``scipy.signal.lfilter``.

    Returns the filtered states (n, m) and the one-step predictions ẑ_{k|k−1} = H Φ X̂_{k−1|k−1} (n,). The
    gain is the limit of the Riccati recursion (scipy ``solve_discrete_are``), so the first few correlation
    times differ slightly from the exact filter started at the stationary prior.
    """
    zz = np.asarray(z, dtype=float)
    F, H, Q, R = model.F, model.H, model.Q, model.R
    Pp = linalg.solve_discrete_are(F.T, H.T, Q, np.array([[R]]))
    kg = (Pp @ H.T / ((H @ Pp @ H.T).item() + R)).ravel()
    A = (np.eye(model.m) - np.outer(kg, H[0])) @ F
    # s_{k+1} = x_k = A s_k + K z_k  (s_k = x_{k−1});  output x_k = A s_k + K z_k.
    num, den = signal.ss2tf(A, kg[:, None], A, kg[:, None])
    xs = np.stack([signal.lfilter(num[i], den, zz) for i in range(model.m)], axis=1)
    pred = np.zeros(zz.size)
    pred[1:] = xs[:-1] @ (H @ F)[0]
    return xs, pred


def _sqrt_inv(cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """W with WᵀW = cov⁻¹ (upper Cholesky factor of the inverse)."""
    return np.linalg.cholesky(np.linalg.inv(cov)).T


@dataclass
class LMResult:
    """Window solution of the graph optimisation: states (W, m), iterations, final cost and gradient norm."""

    x: NDArray[np.float64]
    iterations: int
    cost: float
    gradient_norm: float


def graph_system(
    model: StateSpace, z: ArrayLike, prior_mean: ArrayLike, prior_cov: ArrayLike
) -> tuple[sp.csr_matrix, NDArray[np.float64]]:
    """Whitened linear system of the window graph cost: r(X) = J X − b, cost = ½‖r‖² (states stacked (W·m,)).

    Rows: prior (m), transitions ((W−1)·m), measurements (W).
    """
    zz = np.asarray(z, dtype=float)
    W, m = zz.size, model.m
    Lp = _sqrt_inv(np.asarray(prior_cov, dtype=float))
    Lq = _sqrt_inv(model.Q)
    lr = 1.0 / math.sqrt(model.R)
    F, h = model.F, model.H[0]
    rows, cols, vals = [], [], []

    def put(r0: int, c0: int, block: NDArray[np.float64]) -> None:
        rr, cc = np.nonzero(np.ones_like(block, dtype=bool))
        rows.append(r0 + rr)
        cols.append(c0 + cc)
        vals.append(block[rr, cc])

    put(0, 0, Lp)
    b = [Lp @ np.asarray(prior_mean, dtype=float)]
    LqF = Lq @ F
    for k in range(1, W):
        r0 = m + (k - 1) * m
        put(r0, k * m, Lq)
        put(r0, (k - 1) * m, -LqF)
    b.append(np.zeros((W - 1) * m))
    r0 = m + (W - 1) * m
    meas_rows = r0 + np.arange(W)
    for j in range(m):
        if h[j] != 0.0:
            rows.append(meas_rows)
            cols.append(np.arange(W) * m + j)
            vals.append(np.full(W, lr * h[j]))
    b.append(lr * zz)
    nrows = r0 + W
    J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nrows, W * m))
    return J, np.concatenate(b)


def lm_window(
    model: StateSpace,
    z: ArrayLike,
    prior_mean: ArrayLike,
    prior_cov: ArrayLike,
    x_init: ArrayLike | None = None,
    max_iter: int = 100,
    tol: float = 1e-13,
) -> LMResult:
    """Minimise the window graph cost (module docstring) by Levenberg–Marquardt.

    Parameters
    ----------
    model : StateSpace
    z : array_like
        Measurements of the window (W,).
    prior_mean, prior_cov : array_like
        Prediction (x̄, P̄) of the first window state.
    x_init : array_like, optional
        Starting states (W, m); zeros by default.
    """
    zz = np.asarray(z, dtype=float)
    W, m = zz.size, model.m
    J, bvec = graph_system(model, zz, prior_mean, prior_cov)
    A = (J.T @ J).tocsc()
    diag = A.diagonal()

    def residual(xv: NDArray[np.float64]) -> NDArray[np.float64]:
        return J @ xv - bvec

    xv = np.zeros(W * m) if x_init is None else np.asarray(x_init, dtype=float).ravel().copy()
    r = residual(xv)
    cost = 0.5 * float(r @ r)
    mu = 1e-3
    it = 0
    g = J.T @ r
    for it in range(1, max_iter + 1):  # noqa: B007 - iterations are reported
        step = spsolve(A + sp.diags(mu * diag), -g)
        x_new = xv + step
        r_new = residual(x_new)
        cost_new = 0.5 * float(r_new @ r_new)
        predicted = -(float(g @ step) + 0.5 * float(step @ (A @ step)))
        small_step = float(np.max(np.abs(step))) <= tol * (1.0 + float(np.max(np.abs(xv))))
        if mu <= 1e-9 and (small_step or predicted <= 1e-15 * max(cost, 1e-300)):
            # undamped Gauss–Newton step below rounding: converged (accept it if it does not increase the cost)
            if cost_new <= cost:
                xv, r, cost = x_new, r_new, cost_new
                g = J.T @ r
            break
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        if rho > 0:  # gain ratio test (Nielsen 1999 damping update)
            xv, r, cost = x_new, r_new, cost_new
            g = J.T @ r
            mu = max(mu * (0.1 if rho > 0.75 else max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)), 1e-12)
        elif predicted <= 1e-13 * max(cost, 1e-300):
            break  # the remaining decrease is below the rounding of the cost: converged
        else:
            mu *= 4.0
    return LMResult(xv.reshape(W, m), it, cost, float(np.max(np.abs(g))))


@dataclass
class SmootherResult:
    """Sliding-window LM smoother output.

    Attributes
    ----------
    x : ndarray (n, m)
        Smoothed states.
    drift : ndarray (n,)
        Smoothed drift H X̂_k (measurement unit).
    windows : int
        Number of windows solved.
    max_iterations : int
        Most LM iterations in one window.
    """

    x: NDArray[np.float64]
    drift: NDArray[np.float64]
    windows: int
    max_iterations: int


def sliding_window_smoother(model: StateSpace, z: ArrayLike, window: int = 400, stride: int = 200) -> SmootherResult:
    """Sliding-window graph smoother: LM on windows of ``window`` samples advancing by ``stride``.

    Each window's prior is the exact Kalman prediction from all data before it; the first ``stride`` states of a
    window (those with at least ``window − stride`` later samples in it) are kept, the last window keeps all.
    With ``window ≥ n`` this is the full-batch graph solution, equal to the RTS smoother.
    """
    zz = np.asarray(z, dtype=float)
    n = zz.size
    if window < 2 or not (1 <= stride <= window):
        raise DriftInputError(f"smoother needs window ≥ 2 and 1 ≤ stride ≤ window; got {window}, {stride}")
    kf = kalman_filter(model, zz)
    out = np.empty((n, model.m))
    k0, count, most = 0, 0, 0
    while k0 < n:
        k1 = min(k0 + window, n)
        if k0 == 0:
            pm, pc = kf.x_pred[0], kf.P_pred[0]
        else:
            pm, pc = kf.x_pred[k0], kf.P_pred[k0]
        res = lm_window(model, zz[k0:k1], pm, pc, x_init=kf.x[k0:k1])
        keep = k1 if k1 == n else min(k0 + stride, n)
        out[k0:keep] = res.x[: keep - k0]
        count += 1
        most = max(most, res.iterations)
        k0 = keep
    return SmootherResult(out, out @ model.H[0], count, most)
