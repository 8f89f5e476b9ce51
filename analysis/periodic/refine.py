"""Frequency refinement by Levenberg–Marquardt on the exact model (the default identification method).

Parameters p = (c₀, a_1, b_1, f_1, …, a_N, b_N, f_N) of ``v = c₀ + Σ a_i cos 2πf_i t + b_i sin 2πf_i t``,
started from the coarse peak frequencies with the linear least-squares a_i, b_i. The Jacobian is analytic
(∂/∂f_i = 2πt (−a_i sin + b_i cos)); each step solves ``(JᵀJ + λ diag JᵀJ) δ = Jᵀr`` (Marquardt's scaling),
accepting steps that lower the residual sum of squares. Gauss–Newton is quadratically convergent here:
from the coarse peaks (within ~0.1/T) 3–5 iterations reach the optimum.

Convergence is decided by the step relative to the parameters' own standard errors (the Cramér–Rao
standard deviations, from σ̂² (JᵀJ)⁻¹): the fit has converged when an accepted step moves every parameter by
less than ``xtol`` of its standard error (or by less than a few ulps, for noise-free data), or when no step
can lower the cost any more (a numerical optimum). Hitting ``max_iter`` is reported, never silent.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.periodic.linear import design_matrix, solve_lsq
from analysis.periodic.model import FitReport, refinement_start

__all__ = ["refine_lm"]

_EPS = np.finfo(np.float64).eps


def _residual(
    p: NDArray[np.float64], t: NDArray[np.float64], v: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Residual ``v − model(p)`` and the tones' cos / sin rows (N × n), reused by :func:`_normal_equations`."""
    th = (2.0 * np.pi * p[3::3])[:, None] * t[None, :]
    c, s = np.cos(th), np.sin(th)
    return v - p[0] - p[1::3] @ c - p[2::3] @ s, c, s


def _normal_equations(
    p: NDArray[np.float64], t: NDArray[np.float64], r: NDArray[np.float64], c: NDArray, s: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """JᵀJ and Jᵀr of the Jacobian ∂model/∂p (n × (1 + 3N)) at ``p``."""
    a, b = p[1::3], p[2::3]
    jac = np.empty((t.size, p.size))
    jac[:, 0] = 1.0
    jac[:, 1::3] = c.T
    jac[:, 2::3] = s.T
    jac[:, 3::3] = ((2.0 * np.pi * t)[None, :] * (b[:, None] * c - a[:, None] * s)).T
    return jac.T @ jac, jac.T @ r


def refine_lm(
    x: ArrayLike,
    rate_hz: float,
    frequencies_hz: Sequence[float],
    halfwidths_hz: Sequence[float] | None = None,
    xtol: float = 1e-4,
    max_iter: int = 50,
) -> tuple[NDArray[np.float64], FitReport]:
    """Levenberg–Marquardt refinement of the tone frequencies from coarse values.

    Parameters
    ----------
    x : array_like
        1-D calibration samples (channel SI unit), sample 0 at t = 0.
    rate_hz : float
        Sample rate, Hz.
    frequencies_hz : sequence of float
        Coarse frequencies, Hz.
    halfwidths_hz : sequence of float, optional
        Half-widths of the search intervals D_i, Hz (default 1/T). A frequency that leaves ``f_i ± 2 D_i`` is
        reported (``report.converged`` False, message says which) so the caller can fall back.
    xtol : float
        Convergence when every parameter's accepted step is below ``xtol`` × its standard error.
    max_iter : int
        Iteration cap (reported when hit).

    Returns
    -------
    frequencies : ndarray
        Refined frequencies, Hz (the starting values when the fit failed).
    report : FitReport
        ``method="lm"``.
    """
    v, f0, half, report = refinement_start(x, rate_hz, frequencies_hz, halfwidths_hz, "lm")
    n, k = v.size, f0.size
    if k == 0:
        return f0, report
    t = np.arange(n) / rate_hz
    coef = solve_lsq(design_matrix(t, f0), v)
    p = np.empty(1 + 3 * k)
    p[0] = coef[0]
    p[1::3], p[2::3], p[3::3] = coef[1::2], coef[2::2], f0
    r, c, s = _residual(p, t, v)
    h, g = _normal_equations(p, t, r, c, s)
    cost = float(r @ r)
    report.evaluations = 1
    lam = 1e-4
    dof = max(n - p.size, 1)
    linear = np.ones(p.size, dtype=bool)
    linear[3::3] = False
    for it in range(1, max_iter + 1):
        report.iterations = it
        d = np.diag(h).copy()
        d[d <= 0] = 1.0
        accepted = False
        for _ in range(30):
            try:
                step = np.linalg.solve(h + lam * np.diag(d), g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            trial = p + step
            r_try, c_try, s_try = _residual(trial, t, v)
            report.evaluations += 1
            cost_try = float(r_try @ r_try)
            if cost_try <= cost:
                accepted = True
                break
            lam *= 10.0
        if not accepted:
            report.converged = True
            report.message = f"numerical optimum after {it} iteration(s) (no step lowers the cost)"
            break
        p, cost, r, c, s = trial, cost_try, r_try, c_try, s_try
        lam = max(lam / 10.0, 1e-12)
        report.final_step_hz = [float(s) for s in np.abs(step[3::3])]
        if np.any(np.abs(p[3::3] - f0) > 2.0 * half):
            bad = int(np.argmax(np.abs(p[3::3] - f0) / half))
            report.message = (
                f"the tone started at {f0[bad]:.6g} Hz left its search interval (now {p[3 + 3 * bad]:.6g} Hz)"
            )
            return f0, report
        h, g = _normal_equations(p, t, r, c, s)
        # standard errors from σ̂² (JᵀJ)⁻¹ at the new point (scaled for conditioning)
        sc = np.sqrt(np.diag(h))
        sc[sc == 0] = 1.0
        try:
            inv_diag = np.diag(np.linalg.inv(h / np.outer(sc, sc))) / sc**2
        except np.linalg.LinAlgError:
            inv_diag = np.full(p.size, np.inf)
        se = np.sqrt(np.maximum(cost / dof * inv_diag, 0.0))
        # numerical resolution: a few ulps of each frequency, of the largest linear coefficient for the others
        tiny = np.where(linear, 8.0 * _EPS * float(np.abs(p[linear]).max()), 8.0 * _EPS * np.abs(p))
        if np.all(np.abs(step) <= np.maximum(xtol * se, tiny)):
            report.converged = True
            report.message = f"step below {xtol:g} standard error after {it} iteration(s)"
            break
    else:
        report.message = f"iteration cap {max_iter} reached (last frequency steps {report.final_step_hz} Hz)"
    return p[3::3].copy(), report
