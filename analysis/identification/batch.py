"""Batch least-squares identification of a sensor-error model, with information rank.

The model is a :class:`analysis.identification.specification.ModelSpec` (default: the 18-parameter
accelerometer model; the whole unit's is accelerometer + gyro): body frame, z = y − y_ref = H x + v,
per-axis white v.
With a Gaussian prior (x0, P0) the estimate is the maximum a-posteriori / regularised least squares::

    x̂ = (P0⁻¹ + Σ HᵀR⁻¹H)⁻¹ (P0⁻¹ x0 + Σ HᵀR⁻¹z),      cov = (P0⁻¹ + Σ HᵀR⁻¹H)⁻¹

and without a prior the plain weighted least squares (only when the data information has full rank).
Two methods: ``"normal"`` (default) solves the normal equations built from
:meth:`~.specification.ModelSpec.regressor_gram` (fast, the same sums the Kalman filter uses) with a
Jacobi-equilibrated Cholesky factorisation; ``"qr"`` is an independent **stacked QR** of the whitened design
(chunked: a running (n+1)×(n+1) triangular factor [U | w] with UᵀU = Σ HᵀR⁻¹H, Uᵀw = Σ HᵀR⁻¹z, prior appended as
square-root rows), which never squares the condition number. Both work in the per-kind scaled parameters
of the model's ``reference_scale``; they agree to ~1e-12 relative on the ten-step sequence.

Information rank and condition (:func:`information_rank`)
----------------------------------------------------------
Rank is a structural property of the *motion*, so it is computed on the data information with the noise
weighting removed and every parameter scaled by its reference magnitude (effect of 1 m/s² at |f| = 1 g,
|ω| = 1 rad/s): Γ = K Λ_R K with Λ_R = Σ HᵀH per axis, K = diag(reference_scale). Γ's columns are then
dimensionless and O(1) per sample (1, f/g, f²/g², c/Ω²). An eigenvalue of Γ counts if it exceeds
``RANK_TOL = 1e-10`` × the largest one (singular values of the scaled design: 1e-5). Reasons:

* floating-point error of the accumulated information is ~1e-16 × λ_max, far below the threshold;
* the reference specific force is known no better than ~1e-5 relative (≈ 2 arcsec of table attitude,
  10 ppm of local g): directions excited only at that level (e.g. arcsec table jitter at one position)
  carry no usable information and must not raise the rank;
* a genuine but weak excitation still counts: a 1.6 °/s spin gives c/Ω² = 7.8e-4, i.e. an eigenvalue
  ratio ~1e-8 for r (rank 18 for the ten-step sequence even at the published rate — whether r is
  *identified* to a useful accuracy is the planner's question, :mod:`analysis.identification.plan`).

The condition number reported is λ_max/λ_min of Γ (∞ when rank-deficient). For a model of several triads
(accelerometer + gyro) Γ is judged part by part (the parts share no state and their reference scales are
in different units): the rank is the sum of the parts' ranks, the condition the largest of theirs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from analysis.identification.specification import ModelSpec, resolve

RANK_TOL: float = 1e-10
"""Relative eigenvalue threshold of the scaled, unweighted data information (see module docstring)."""


def _prior_arrays(
    x0: ArrayLike | None, p0: ArrayLike | None, model: ModelSpec
) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    n_p = model.n_params
    if p0 is None:
        if x0 is not None:
            raise ValueError("a prior mean x0 was given without its covariance P0")
        return None
    p = np.asarray(p0, dtype=float)
    if p.shape != (n_p, n_p) or not np.all(np.isfinite(p)):
        raise ValueError(f"prior covariance P0 must be a finite ({n_p}, {n_p}) matrix, got {p.shape}")
    if not np.allclose(p, p.T, rtol=1e-12, atol=0.0):
        raise ValueError("prior covariance P0 must be symmetric")
    xm = np.zeros(n_p) if x0 is None else model.as_state(x0, "x0")
    return xm, p


def scaled_information(info: ArrayLike, r_var: ArrayLike, model: ModelSpec | None = None) -> NDArray[np.float64]:
    """Γ = K (Σ HᵀH) K: the data information unweighted by noise and scaled per parameter kind (dimensionless).

    ``info`` is Σ HᵀR⁻¹H (n×n, SI) for per-axis noise variances ``r_var`` (n_axes,).
    """
    m = resolve(model)
    lam = np.asarray(info, dtype=float)
    if lam.shape != (m.n_params, m.n_params):
        raise ValueError(f"information must be ({m.n_params}, {m.n_params}), got {lam.shape}")
    r = m.as_noise_variance(r_var)
    k = m.reference_scale * np.sqrt(r[m.param_axis])
    return lam * np.outer(k, k)


def information_rank(
    info: ArrayLike, r_var: ArrayLike, tol: float = RANK_TOL, *, model: ModelSpec | None = None
) -> tuple[int, float]:
    """Numerical rank and condition number of the data information (see the module docstring).

    Returns
    -------
    rank : int
        Number of eigenvalues of Γ above ``tol`` × the largest (0 for no data), summed over the model's parts.
    condition : float
        λ_max/λ_min of Γ (the largest over the parts), ``inf`` when the rank is below the state count.
    """
    m = resolve(model)
    gam = scaled_information(info, r_var, m)
    rank = 0
    cond = 0.0
    for g in m.groups:
        ev = np.linalg.eigvalsh(gam[g, g])
        top = float(ev[-1])
        if top <= 0.0:
            cond = float("inf")
            continue
        rk = int(np.sum(ev > tol * top))
        rank += rk
        cond = max(cond, top / float(ev[0]) if rk == ev.size else float("inf"))
    return rank, cond


def unobservable_parameters(
    info: ArrayLike, r_var: ArrayLike, tol: float = RANK_TOL, *, model: ModelSpec | None = None
) -> tuple[str, ...]:
    """Names of the parameters involved in the numerical null space of the data information.

    A parameter is listed when more than 1 % of its (scaled) unit vector lies in the null space.
    """
    m = resolve(model)
    gam = scaled_information(info, r_var, m)
    weight = np.zeros(m.n_params)
    for g in m.groups:
        ev, vec = np.linalg.eigh(gam[g, g])
        top = float(ev[-1])
        null = vec[:, ev <= tol * top] if top > 0 else np.eye(ev.size)
        weight[g] = np.sum(null**2, axis=1)
    return tuple(n for n, w in zip(m.names, weight, strict=True) if w > 0.01)


@dataclass(frozen=True)
class BatchResult:
    """Result of :func:`batch_identify` (SI, in the model's name order).

    Attributes
    ----------
    x : ndarray (n,)
        Estimate.
    covariance : ndarray (n, n)
        Posterior covariance (with the prior) or the least-squares covariance (without).
    information : ndarray (n, n)
        Data information Σ HᵀR⁻¹H (without the prior).
    rank, condition : int, float
        Numerical rank and condition of the data information (:func:`information_rank`).
    n_samples : float
        Number of samples used (sum of weights).
    residual_rms : ndarray (n_axes,)
        Per-axis RMS of z − H x̂, SI.
    used_prior : bool
    """

    x: NDArray[np.float64]
    covariance: NDArray[np.float64]
    information: NDArray[np.float64]
    rank: int
    condition: float
    n_samples: float
    residual_rms: NDArray[np.float64]
    used_prior: bool

    @property
    def sigma(self) -> NDArray[np.float64]:
        """1σ per parameter, SI."""
        return np.sqrt(np.diag(self.covariance))


def solve_information(
    info: ArrayLike,
    eta: ArrayLike,
    r_var: ArrayLike,
    x0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    *,
    model: ModelSpec | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve the (regularised) normal equations: x̂ and its covariance from Λ = ΣHᵀR⁻¹H, η = ΣHᵀR⁻¹z.

    Works in the per-kind scaled parameters (the model's ``reference_scale``) for numerical balance.
    Without a prior the data information must have full rank, otherwise a ``ValueError`` names the
    unobservable parameters.
    """
    m = resolve(model)
    lam = np.asarray(info, dtype=float)
    e = np.asarray(eta, dtype=float).reshape(-1)
    s = m.reference_scale
    a = lam * np.outer(s, s)
    rhs = e * s
    prior = _prior_arrays(x0, p0, m)
    if prior is None:
        rank, _ = information_rank(lam, r_var, model=m)
        if rank < m.n_params:
            raise ValueError(
                f"data information has rank {rank} < {m.n_params}: "
                f"{', '.join(unobservable_parameters(lam, r_var, model=m))} cannot be identified without a prior; "
                "give a prior covariance P0 or add orientations/rotations that excite them"
            )
    else:
        xm, p = prior
        p_s = p / np.outer(s, s)
        p_inv = np.linalg.inv(p_s)
        a = a + p_inv
        rhs = rhs + p_inv @ (xm / s)
    # Jacobi equilibration before the Cholesky factorisation (van der Sluis: near-optimal diagonal scaling).
    dj = 1.0 / np.sqrt(np.diag(a))
    cf = scipy.linalg.cho_factor(a * np.outer(dj, dj))
    x_s = dj * scipy.linalg.cho_solve(cf, rhs * dj)
    cov_s = scipy.linalg.cho_solve(cf, np.eye(m.n_params)) * np.outer(dj, dj)
    cov_s = 0.5 * (cov_s + cov_s.T)
    return x_s * s, cov_s * np.outer(s, s)


def _solve_triangular_factor(
    u: NDArray[np.float64],
    wv: NDArray[np.float64],
    prior: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
    s: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """x̂ and covariance (scaled parameters) from a data factor [U | w] and optional prior square-root rows."""
    n_p = s.size
    if prior is not None:
        xm, p = prior
        c = np.linalg.cholesky(p / np.outer(s, s))  # P0_s = C Cᵀ
        c_inv = scipy.linalg.solve_triangular(c, np.eye(n_p), lower=True)
        rows = np.vstack([np.column_stack([u, wv]), np.column_stack([c_inv, c_inv @ (xm / s)])])
        tri = np.linalg.qr(rows, mode="r")
        u, wv = tri[:n_p, :n_p], tri[:n_p, n_p]
    x_s = scipy.linalg.solve_triangular(u, wv, lower=False)
    u_inv = scipy.linalg.solve_triangular(u, np.eye(n_p), lower=False)
    cov_s = u_inv @ u_inv.T
    return x_s * s, cov_s * np.outer(s, s)


def batch_identify(
    f_out: ArrayLike,
    f_ref: ArrayLike,
    omega: ArrayLike,
    r_var: ArrayLike,
    x0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    *,
    weights: ArrayLike | None = None,
    method: str = "normal",
    chunk: int = 1 << 15,
    model: ModelSpec | None = None,
    earth: ArrayLike | None = None,
) -> BatchResult:
    """Batch (regularised) least squares of a model's parameters over all samples at once.

    Parameters
    ----------
    f_out : array_like (n, n_axes)
        Sensor output (the model's channels side by side: accelerometer m/s², gyro rad/s), body frame.
    f_ref : array_like (n, 3)
        Reference specific force from the table's angles (and local g), body frame, m/s².
    omega : array_like (n, 3)
        Body angular rate from the table, body frame, rad/s.
    r_var : array_like (n_axes,)
        White-noise variance per sample and axis, SI².
    x0, p0 : array_like (n,), (n, n), optional
        Prior mean (default 0) and covariance. Without ``p0`` the plain least-squares solution is returned
        (requires full rank).
    weights : array_like (n,), optional
        Sample weights (e.g. counts of averaged samples; the row's noise variance is R / w).
    method : {"normal", "qr"}
        Normal equations from the regressor Gram (default; fast, Jacobi-equilibrated Cholesky) or the
        stacked QR of the whitened design (never squares the condition number; the numerically robust
        reference, ~10× slower — LAPACK QR of tall blocks is also sensitive to BLAS thread contention).
    chunk : int
        Samples per chunk (bounds memory: the QR path holds a (n_axes·chunk, n+1) block).
    model : ModelSpec, optional
        The error model (default: the accelerometer model).
    earth : array_like (n, 3), optional
        Earth rate in the body frame, rad/s (gyro reference ω_ib = omega + earth; None = 0).
    """
    m = resolve(model)
    fo = np.asarray(f_out, dtype=float)
    fr = np.asarray(f_ref, dtype=float)
    om = np.asarray(omega, dtype=float)
    n = fo.shape[0] if fo.ndim == 2 else -1
    ea = None if earth is None else np.asarray(earth, dtype=float)
    if fo.ndim != 2 or fo.shape[1] != m.n_axes or fr.shape != (n, 3) or om.shape != (n, 3):
        raise ValueError(
            f"f_out, f_ref and omega must have shapes (n, {m.n_axes}), (n, 3), (n, 3); "
            f"got {fo.shape}, {fr.shape}, {om.shape}"
        )
    r = m.as_noise_variance(r_var)
    z = fo - m.ideal(fr, om, ea)
    w = None if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    prior = _prior_arrays(x0, p0, m)
    if method == "normal":
        gram = m.regressor_gram(fr, om, z, w, earth=ea)
        info, eta = m.information_from_gram(gram, r)
        assert eta is not None
        rank, cond = information_rank(info, r, model=m)
        x, cov = solve_information(info, eta, r, x0, p0, model=m)
        n_used, _, rms = m.residual_moments(gram, x)
    elif method == "qr":
        u, wv = _qr_factor(m, fr, om, ea, z, r, w, chunk)
        s = m.reference_scale
        info = (u.T @ u) / np.outer(s, s)
        rank, cond = information_rank(info, r, model=m)
        if prior is None and rank < m.n_params:
            solve_information(info, u.T @ wv / s, r, model=m)  # raises the explanatory error
        x, cov = _solve_triangular_factor(u, wv, prior, s)
        acc = np.zeros(m.n_axes)
        for a0 in range(0, fo.shape[0], chunk):
            sl = slice(a0, a0 + chunk)
            h = m.design_matrix(fr[sl], om[sl], None if ea is None else ea[sl])
            e = z[sl] - np.einsum("nij,j->ni", h, x)
            acc += np.sum(e**2 if w is None else e**2 * w[sl, None], axis=0)
        n_used = float(fo.shape[0] if w is None else w.sum())
        rms = np.sqrt(acc / max(n_used, 1.0))
    else:
        raise ValueError(f"unknown method {method!r}; use 'qr' or 'normal'")
    return BatchResult(
        x=x,
        covariance=cov,
        information=info,
        rank=rank,
        condition=cond,
        n_samples=float(n_used),
        residual_rms=rms,
        used_prior=p0 is not None,
    )


def _qr_factor(
    model: ModelSpec,
    fr: NDArray[np.float64],
    om: NDArray[np.float64],
    ea: NDArray[np.float64] | None,
    z: NDArray[np.float64],
    r: NDArray[np.float64],
    w: NDArray[np.float64] | None,
    chunk: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Running QR factor [U | w] of the whitened, kind-scaled design [H K | z] (UᵀU = K ΣHᵀR⁻¹H K)."""
    s = model.reference_scale
    n_p = model.n_params
    sd = 1.0 / np.sqrt(r)
    tri = np.zeros((0, n_p + 1))
    for a in range(0, fr.shape[0], chunk):
        e = min(fr.shape[0], a + chunk)
        h = model.design_matrix(fr[a:e], om[a:e], None if ea is None else ea[a:e]) * s  # (m, axes, n) scaled
        rows = np.concatenate([h, z[a:e, :, None]], axis=2) * sd[None, :, None]
        if w is not None:
            rows = rows * np.sqrt(w[a:e])[:, None, None]
        stacked = np.asfortranarray(np.vstack([tri, rows.reshape(-1, n_p + 1)]))
        tri = scipy.linalg.qr(stacked, mode="r", overwrite_a=True, check_finite=False)[0][: n_p + 1]
    if tri.shape[0] < n_p + 1:
        tri = np.vstack([tri, np.zeros((n_p + 1 - tri.shape[0], n_p + 1))])
    return tri[:n_p, :n_p], tri[:n_p, n_p]
