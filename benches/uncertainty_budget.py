"""GUM uncertainty budget of the identified accelerometer parameters (for the calibration certificate).

Method (GUM, JCGM 100:2008, law of propagation of uncertainty, linearised estimator)
------------------------------------------------------------------------------------
The identification (``calibration.json``) solves, in the body frame b, z = f_out − f_ref = H(f, ω) x + v with a
Gaussian prior, so its estimate is the information solution

    x̂ = P (P0⁻¹ x0 + Σ_k H_kᵀ R⁻¹ z_k),      P = (P0⁻¹ + Σ_k H_kᵀ R⁻¹ H_k)⁻¹.

Any small error e_k in the reference specific force f_ref (m/s², body frame) enters z_k with the opposite sign
and moves the estimate by δx̂ = −P Σ_k H_kᵀ R⁻¹ e_k (first order; the change of H with f is second order).
Each budget component is an input quantity with a standard uncertainty and a shape e_k = G_k u, propagated
with the sensitivity matrix C = P Σ_k H_kᵀ R⁻¹ G_k (18 × dim u) as Cov(δx̂) = C Cov(u) Cᵀ:

1. **Estimation** (type A): the white-noise posterior covariance P itself (measurement noise R, prior P0),
   rebuilt from the recorded geometry when the prior is known (and checked against the identification's).
1b. **Unit bias instability** (type B, when the bench gives it): an unmodelled DC offset of σ_bi per step
   and axis (G_k = I₃ per step), the same model as the identification plan's systematic term.
2. **Table attitude accuracy** (type B): each step's reported attitude is off by an unknown small rotation
   δφ_s (navigation frame, rad), independent between steps (every position is a new positioning of the
   gimbals) and constant within a step (for a spin: the tilt of the spin axis). With
   C_b^n,true = (I + [δφ×]) C_b^n,rep the reference error is e_k = −[f_k ×] C_n^b,k δφ_s. The table's
   ``attitude_accuracy`` (bench file) is a specification bound a, taken as a rectangular distribution:
   u(δφ_i) = a / √3 per axis (GUM 4.3.7).
3. **Local gravity** (type B): e_k = f_k δg / g, fully correlated over the whole run (one g for the site).
   u(g) comes from the bench's site (``g_uncertainty`` if it gives one), else 0.1 mGal (1e-6 m/s²) for a
   measured g and 30 mGal (3e-4 m/s², typical free-air anomaly magnitude) for WGS-84 normal gravity.
4. **Model mismatch** (type A, from residuals): what the white-noise model does not explain.
   (a) per-step DC residuals: the per-axis step means m_{s,a} of the residuals scatter more than the noise
   allows (R_a / n_s); the excess σ²_dc,a = Σ_s (m²_{s,a} − R_a/n_s) / (K − 6) (K steps, 6 parameters per
   axis, clipped at 0), less what the bias-instability component already covers (σ²_bi,a), is treated as an
   unknown constant error per step and axis (thermal, unmodelled terms), propagated with G_k = I₃ per step;
   (b) excess scatter: β_s,a = (rms²_{s,a} − m²_{s,a}) / R_a per step; where β > 1 the noise model is optimistic
   for that step and the component adds the sandwich term P (Σ_s Σ_k Hᵀ R⁻¹ diag(β_s − 1)₊ H) P (for a uniform
   β this is the Birge-ratio inflation (β − 1) P of the data part).

The combined standard uncertainty is u_c = √(Σ components), the expanded uncertainty U = k u_c with k = 2
(≈ 95 % coverage for a normal distribution; effective degrees of freedom are large, ≥ 10⁴ samples per step).
The sums Σ_k are evaluated on a decimated set of reference points per step (each weighted by the samples it
stands for): f_ref and ω vary smoothly within a step, so the decimation error is far below the budget's
precision, and the budget compares the rebuilt estimation σ with the identification's (a consistency note).
Where the spec is silent the method follows IEEE Std 1293 (accelerometer test procedures).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from analysis.units import ARCSEC, UG

if TYPE_CHECKING:
    from benches.recording import Recording

PARAM_NAMES: tuple[str, ...] = (
    "b_x", "b_y", "b_z", "S_x", "S_y", "S_z", "tau_xy", "tau_xz", "tau_yx", "tau_yz", "tau_zx", "tau_zy",
    "d_x", "d_y", "d_z", "r_x", "r_y", "r_z",
)  # fmt: skip
"""The 18 accelerometer parameters, in the order of ``benches/CALIBRATION_FORMAT.md``."""

PARAM_KINDS: tuple[str, ...] = (
    ("bias",) * 3 + ("scale",) * 3 + ("misalignment",) * 6 + ("quadratic",) * 3 + ("size_effect",) * 3
)
"""Quantity kind of each parameter (keys of ``analysis.units.DISPLAY_UNITS``)."""

# misalignment columns: (row i, column j) of δf_i += τ_ij f_j, in PARAM_NAMES order (indices 6..11)
_TAU_IJ: tuple[tuple[int, int], ...] = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))

G_UNCERTAINTY_MEASURED: float = 1e-6
"""Default standard uncertainty of a measured local g, m/s² (0.1 mGal, a gravimeter survey)."""
G_UNCERTAINTY_NORMAL: float = 3e-4
"""Default standard uncertainty of WGS-84 normal gravity used as local g, m/s² (30 mGal anomaly)."""


def design_matrix(f: NDArray[np.float64], omega: NDArray[np.float64]) -> NDArray[np.float64]:
    """Jacobian H of z = f_out − f with respect to the 18 parameters, derived from the model.

    f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω), δf_i += τ_ij f_j,
    c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²].

    Parameters
    ----------
    f : (n, 3) array
        Reference specific force, body frame, m/s².
    omega : (n, 3) array
        Body angular rate, body frame, rad/s.

    Returns
    -------
    (n, 3, 18) array
        Rows per body axis, columns in :data:`PARAM_NAMES` order (SI units of the parameters).
    """
    f = np.asarray(f, dtype=float).reshape(-1, 3)
    w2 = np.asarray(omega, dtype=float).reshape(-1, 3) ** 2
    c = np.stack([w2[:, 1] + w2[:, 2], w2[:, 2] + w2[:, 0], w2[:, 0] + w2[:, 1]], axis=1)
    n = f.shape[0]
    h = np.zeros((n, 3, 18))
    ax = np.arange(3)
    h[:, ax, ax] = 1.0
    h[:, ax, 3 + ax] = f
    for col, (i, j) in enumerate(_TAU_IJ):
        h[:, i, 6 + col] = f[:, j]
    h[:, ax, 12 + ax] = f * f
    h[:, ax, 15 + ax] = c
    return h


@dataclass(frozen=True)
class StepGeometry:
    """Reference points of one acquisition step (decimated), for sensitivity sums.

    Attributes
    ----------
    name, kind : str
        Step name and kind (hold | spin).
    f : (m, 3) array
        Reference specific force, body frame, m/s².
    omega : (m, 3) array
        Body angular rate, body frame, rad/s.
    weight : (m,) array
        Number of recorded samples each point stands for (sums to the step's acquisition length).
    c_bn : (m, 3, 3) array or None
        Reported attitude C_b^n per point (for nav-frame attitude errors); None: errors taken in the body frame.
    """

    name: str
    kind: str
    f: NDArray[np.float64]
    omega: NDArray[np.float64]
    weight: NDArray[np.float64]
    c_bn: NDArray[np.float64] | None = None

    @property
    def samples(self) -> int:
        """Acquisition samples of the step."""
        return int(round(float(self.weight.sum())))


def step_geometry(
    f: Recording,
    g: float,
    mounting: NDArray[np.float64] | None,
    *,
    names: Sequence[str] | None = None,
    max_points: int = 400,
) -> list[StepGeometry]:
    """Decimated reference geometry of the complete hold/spin steps of an open recording.

    Parameters
    ----------
    f : benches.recording.Recording
        An open recording (:func:`benches.recording.open_recording`).
    g : float
        Local gravity used by the identification, m/s².
    mounting : (3, 3) array or None
        C_b^t, the unit's mounting on the inner gimbal (identity if None).
    names : sequence of str, optional
        Only these steps (the ones the identification used); default every complete hold and spin.
    max_points : int
        Reference points per step (evenly spaced sample centres).
    """
    from analysis.gimbal import body_to_nav
    from benches.reference import interpolate_table, reference_at

    wanted = set(names) if names is not None else None
    table = f.table()
    tt, ta, tr = table.time, table.angles, table.rates
    out: list[StepGeometry] = []
    n_imu = f.n_samples
    for s in f.steps:
        if s.status != "complete" or s.kind not in ("hold", "spin"):
            continue
        if wanted is not None and s.name not in wanted:
            continue
        a0, a1 = int(s.acq_start), min(int(s.acq_end), n_imu)
        n = a1 - a0
        if n <= 0:
            continue
        m = min(n, max_points)
        edges = a0 + (np.arange(m + 1) * n) // m
        idx = (edges[:-1] + edges[1:] - 1) // 2
        t = f.samples(fields=("time",), index=idx).time
        ang, rat = interpolate_table(t, tt, ta, tr)
        fr, om = reference_at(ang, rat, g, mounting)
        out.append(StepGeometry(s.name, s.kind, fr, om, np.diff(edges).astype(float), body_to_nav(ang, mounting)))
    return out


def _cross_matrices(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """[v×] for rows of v (n, 3) → (n, 3, 3)."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)


def _weighted_ht_rinv(geo: StepGeometry, r_inv: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
    """Per-point Hᵀ R⁻¹ weighted (m, 18, 3) and H (m, 3, 18)."""
    h = design_matrix(geo.f, geo.omega)
    ht_ri = np.transpose(h, (0, 2, 1)) * r_inv[None, None, :] * geo.weight[:, None, None]
    return ht_ri, h


@dataclass(frozen=True)
class BudgetComponent:
    """One line of the budget: an input quantity propagated to the 18 parameters.

    Attributes
    ----------
    key, label : str
        Machine key and the certificate's wording.
    source : str
        How the input's standard uncertainty was obtained (plain words, with its value).
    type : str
        "A" (statistical) or "B" (other means), GUM 4.2 / 4.3.
    covariance : (18, 18) array
        Contribution to the parameters' covariance, SI.
    """

    key: str
    label: str
    source: str
    type: str
    covariance: NDArray[np.float64]

    @property
    def std(self) -> NDArray[np.float64]:
        """Standard uncertainty contributed to each parameter, SI."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))


@dataclass(frozen=True)
class UncertaintyBudget:
    """The combined budget; ``expanded`` = k · ``combined`` (k = 2)."""

    components: list[BudgetComponent]
    coverage_factor: float = 2.0
    notes: list[str] = field(default_factory=list)

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Combined covariance of the 18 parameters, SI."""
        return np.sum([c.covariance for c in self.components], axis=0)

    @property
    def combined(self) -> NDArray[np.float64]:
        """Combined standard uncertainty u_c per parameter, SI."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def expanded(self) -> NDArray[np.float64]:
        """Expanded uncertainty U = k u_c per parameter, SI."""
        return self.coverage_factor * self.combined


def attitude_sensitivity(
    covariance: NDArray[np.float64], geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Sensitivity of x̂ to a constant attitude error δφ_s of each step, (18, 3) each (SI per rad).

    The reported attitude is off by a small nav-frame rotation, C_b^n,true = (I + [δφ×]) C_b^n,rep, constant over
    the step (a tilt of the table for a hold, of the spin axis for a spin). Then f_true = f_rep + [f×] C_n^b δφ
    and C_s = P Σ_k Hᵀ R⁻¹ [f_k×] C_n^b,k (the reference error is −[f×] C_n^b δφ). Without ``c_bn`` the
    error is taken constant in the body frame (identical for holds: an isotropic δφ has the same covariance in
    any frame).
    """
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    out = []
    for geo in geometry:
        ht_ri, _ = _weighted_ht_rinv(geo, r_inv)
        shape = _cross_matrices(geo.f)
        if geo.c_bn is not None:
            shape = shape @ np.transpose(np.asarray(geo.c_bn, dtype=float), (0, 2, 1))
        out.append(covariance @ np.einsum("kpa,kab->pb", ht_ri, shape))
    return out


def gravity_sensitivity(
    covariance: NDArray[np.float64], geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64], g: float
) -> NDArray[np.float64]:
    """Sensitivity of x̂ to the local gravity, ∂x̂/∂g = −P Σ_k Hᵀ R⁻¹ f_k / g, (18,) SI per m/s²."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    acc = np.zeros(18)
    for geo in geometry:
        ht_ri, _ = _weighted_ht_rinv(geo, r_inv)
        acc += np.einsum("kpa,ka->p", ht_ri, geo.f)
    return -(covariance @ acc) / g


def step_offset_sensitivity(
    covariance: NDArray[np.float64], geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Sensitivity of x̂ to a constant error of z per step and axis: B_s = P Σ_k Hᵀ R⁻¹, (18, 3) each."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    return [covariance @ _weighted_ht_rinv(geo, r_inv)[0].sum(axis=0) for geo in geometry]


def data_information(geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ_k Hᵀ R⁻¹ H over the (decimated, weighted) geometry, (18, 18) SI."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    info = np.zeros((18, 18))
    for geo in geometry:
        ht_ri, h = _weighted_ht_rinv(geo, r_inv)
        info += np.einsum("kpa,kaq->pq", ht_ri, h)
    return info


def residual_mismatch(
    per_step: Sequence[Mapping[str, object]], noise_var: NDArray[np.float64], n_params_per_axis: int = 6
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Excess per-step DC variance σ²_dc (3,) (m/s²)² and white-scatter ratio β (3,) from residual statistics.

    ``per_step`` rows as in ``calibration.json`` ``residuals.per_step`` (samples, mean (3), rms (3), SI).
    """
    r = np.asarray(noise_var, dtype=float)
    rows = [p for p in per_step if int(p.get("samples", 0)) > 0]  # type: ignore[call-overload]
    if not rows:
        return np.zeros(3), np.ones(3)
    n = np.array([float(p["samples"]) for p in rows])  # type: ignore[arg-type]
    mean = np.array([p["mean"] for p in rows], dtype=float).reshape(-1, 3)
    rms = np.array([p["rms"] for p in rows], dtype=float).reshape(-1, 3)
    dof = max(len(rows) - n_params_per_axis, 1)
    excess = (mean**2 - r[None, :] / n[:, None]).sum(axis=0) / dof
    var_within = np.clip(rms**2 - mean**2, 0.0, None)
    beta = (n[:, None] * var_within).sum(axis=0) / (r * n.sum())
    return np.clip(excess, 0.0, None), beta


def step_scatter_ratios(
    per_step: Sequence[Mapping[str, object]], noise_var: NDArray[np.float64]
) -> dict[str, NDArray[np.float64]]:
    """Per step: within-step residual variance over the noise variance, β_s (3,) = (rms² − mean²) / R."""
    r = np.asarray(noise_var, dtype=float)
    out = {}
    for row in per_step:
        if int(row.get("samples", 0)) <= 0:  # type: ignore[call-overload]
            continue
        mean = np.asarray(row["mean"], dtype=float).reshape(3)
        rms = np.asarray(row["rms"], dtype=float).reshape(3)
        out[str(row.get("name"))] = np.clip(rms**2 - mean**2, 0.0, None) / r
    return out


def scatter_excess_covariance(
    covariance: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    per_step: Sequence[Mapping[str, object]],
) -> NDArray[np.float64]:
    """Covariance added by residual scatter beyond the noise model (sandwich form), (18, 18) SI.

    If the samples of step s have variance β_s,a R_a instead of R_a, the estimator's true covariance is
    P (P0⁻¹ + Σ_s Σ_k Hᵀ R⁻¹ diag(β_s) H) P instead of P; the excess P (Σ_s Σ_k Hᵀ R⁻¹ diag(β_s − 1)₊ H) P is
    returned (steps with less scatter than the model are not credited). Treats the excess as white within the
    step (the white-equivalent of, e.g., a periodic residual during a spin).
    """
    ratios = step_scatter_ratios(per_step, noise_var)
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    acc = np.zeros((18, 18))
    for geo in geometry:
        beta = ratios.get(geo.name)
        if beta is None:
            continue
        ex = np.clip(beta - 1.0, 0.0, None)
        if not np.any(ex > 0):
            continue
        ht_ri, h = _weighted_ht_rinv(geo, r_inv * ex)
        acc += np.einsum("kpa,kaq->pq", ht_ri, h)
    return covariance @ acc @ covariance


def build_budget(
    covariance: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    *,
    g: float,
    g_uncertainty: float,
    g_source: str,
    attitude_accuracy: float,
    prior_sigma: NDArray[np.float64] | None = None,
    bias_instability: NDArray[np.float64] | None = None,
    residuals_per_step: Sequence[Mapping[str, object]] = (),
    coverage_factor: float = 2.0,
) -> UncertaintyBudget:
    """The GUM budget of the 18 parameters (see the module docstring for the method).

    Parameters
    ----------
    covariance : (18, 18) array
        Covariance reported by the identification (``calibration.json``), SI. Used as the estimation
        component only when ``prior_sigma`` is not given; otherwise it is the consistency reference.
    geometry : sequence of StepGeometry
        Reference points of the steps the identification used.
    noise_var : (3,) array
        Measurement noise variance per body axis used by the identification, (m/s²)².
    g, g_uncertainty : float
        Local gravity and its standard uncertainty, m/s².
    g_source : str
        How g was obtained (for the budget's wording).
    attitude_accuracy : float
        Table attitude accuracy bound a, rad (u = a/√3 per axis).
    prior_sigma : (18,) array, optional
        The identification's prior 1σ (SI). Given: the white-noise covariance is rebuilt from the recorded
        geometry, P = (P0⁻¹ + Σ HᵀR⁻¹H)⁻¹, and used for the estimation component and every sensitivity.
    bias_instability : (3,) array, optional
        The unit's bias instability per body axis, m/s² (bench file): an unmodelled DC offset per step,
        propagated as its own component; the residual DC excess counts as model mismatch only beyond it.
    residuals_per_step : sequence of mapping
        ``calibration.json`` ``residuals.per_step``.
    coverage_factor : float
        k of the expanded uncertainty.
    """
    p_rep = np.asarray(covariance, dtype=float)
    if p_rep.shape != (18, 18) or not np.all(np.isfinite(p_rep)):
        raise ValueError("the covariance must be a finite 18 × 18 matrix")
    nv = np.asarray(noise_var, dtype=float).reshape(3)
    if np.any(nv <= 0) or not np.all(np.isfinite(nv)):
        raise ValueError("the measurement noise variances must be positive and finite")
    notes: list[str] = []
    if prior_sigma is not None and geometry:
        ps = np.asarray(prior_sigma, dtype=float).reshape(18)
        p = np.linalg.inv(np.diag(1.0 / ps**2) + data_information(geometry, nv))
        p = 0.5 * (p + p.T)
        est_source = "white-noise covariance (P0⁻¹ + ΣHᵀR⁻¹H)⁻¹ on the recorded geometry"
    else:
        p = p_rep.copy()
        est_source = "posterior covariance reported by the identification"
    comps = [BudgetComponent("estimation", "Estimation (measurement noise, from the covariance)", est_source, "A", p)]
    sbi = np.zeros(3) if bias_instability is None else np.asarray(bias_instability, dtype=float).reshape(3)
    b_s = step_offset_sensitivity(p, geometry, nv)
    if bias_instability is not None:
        cov_bi = sum((b @ np.diag(sbi**2) @ b.T for b in b_s), np.zeros((18, 18)))
        comps.append(
            BudgetComponent(
                "bias_instability",
                "Unit bias instability (per-step DC)",
                "σ_bi = [" + ", ".join(f"{v / UG:.2f}" for v in sbi) + "] µg per axis (bench file), independent "
                "per step",
                "B",
                cov_bi,
            )
        )
    u_att = attitude_accuracy / math.sqrt(3.0)
    c_att = attitude_sensitivity(p, geometry, nv)
    cov_att = sum((c @ c.T for c in c_att), np.zeros((18, 18))) * u_att**2
    comps.append(
        BudgetComponent(
            "attitude",
            "Table attitude accuracy",
            f"±{attitude_accuracy / ARCSEC:.2f}″ per axis, rectangular, u = {u_att / ARCSEC:.2f}″, "
            "independent per step",
            "B",
            cov_att,
        )
    )
    s_g = gravity_sensitivity(p, geometry, nv, g)
    comps.append(
        BudgetComponent(
            "local_g",
            "Local gravity",
            f"g = {g:.6f} m/s² ({g_source}), u(g) = {g_uncertainty:.1e} m/s²",
            "B",
            np.outer(s_g, s_g) * g_uncertainty**2,
        )
    )
    dc, beta = residual_mismatch(residuals_per_step, nv)
    dc_excess = np.clip(dc - sbi**2, 0.0, None)
    cov_mm = sum((b @ np.diag(dc_excess) @ b.T for b in b_s), np.zeros((18, 18)))
    cov_mm = cov_mm + scatter_excess_covariance(p, geometry, nv, residuals_per_step)
    ratios = step_scatter_ratios(residuals_per_step, nv)
    by_kind = {
        k: [float(v.max()) for name, v in ratios.items() if name in {g.name for g in geometry if g.kind == k}]
        for k in ("hold", "spin")
    }
    kind_txt = "; ".join(f"{k}s {min(v):.2f}–{max(v):.2f}" for k, v in by_kind.items() if v)
    comps.append(
        BudgetComponent(
            "model_mismatch",
            "Model mismatch (from residuals)",
            "per-step DC residual scatter σ_dc = ["
            + ", ".join(f"{math.sqrt(v) / UG:.2f}" for v in dc)
            + "] µg, beyond bias instability ["
            + ", ".join(f"{math.sqrt(v) / UG:.2f}" for v in dc_excess)
            + "] µg; residual variance / noise variance β = ["
            + ", ".join(f"{b:.3f}" for b in beta)
            + "] overall"
            + (f" ({kind_txt})" if kind_txt else ""),
            "A",
            cov_mm,
        )
    )
    if not residuals_per_step:
        notes.append("no per-step residual statistics: the model-mismatch component is zero (not evaluated)")
    if prior_sigma is not None and geometry:
        ident = np.sqrt(np.clip(np.diag(p_rep), 0, None))
        mine = np.sqrt(np.diag(sum(c.covariance for c in comps[: 2 if bias_instability is not None else 1])))
        rel = float(np.max(np.abs(mine - ident) / np.maximum(ident, 1e-300)))
        notes.append(
            "consistency: estimation"
            + (" ⊕ bias instability" if bias_instability is not None else "")
            + f" rebuilt from the recorded table readings agrees with the identification's reported σ to "
            f"{100 * rel:.2g} % (largest relative difference over the 18 parameters)"
        )
    return UncertaintyBudget(comps, coverage_factor, notes)


def default_g_uncertainty(g_source: str) -> float:
    """Standard uncertainty of local g when the bench gives none, m/s² (see the module docstring)."""
    return G_UNCERTAINTY_MEASURED if g_source.strip().lower().startswith("measured") else G_UNCERTAINTY_NORMAL


__all__ = [
    "PARAM_KINDS",
    "PARAM_NAMES",
    "BudgetComponent",
    "StepGeometry",
    "UncertaintyBudget",
    "attitude_sensitivity",
    "build_budget",
    "data_information",
    "default_g_uncertainty",
    "design_matrix",
    "gravity_sensitivity",
    "residual_mismatch",
    "step_geometry",
    "scatter_excess_covariance",
    "step_offset_sensitivity",
    "step_scatter_ratios",
]
