"""GUM uncertainty budget of the 18 identified accelerometer parameters (pure maths).

Method (GUM, JCGM 100:2008, law of propagation of uncertainty for the linear estimator)
-----------------------------------------------------------------------------------------
The identification solves, in the body frame b, z = f_out − f_ref = H(f, ω) x + v with a Gaussian prior,
x̂ = A⁻¹ (P0⁻¹ x0 + Σ_k H_kᵀ R⁻¹ z_k), A = P0⁻¹ + Σ_k H_kᵀ R⁻¹ H_k, H from the ONE model
(:func:`analysis.identification.model.design_matrix`). An error e_k of the measurement equation (a
reference error, an unmodelled term) moves the estimate by δx̂ = A⁻¹ Σ_k H_kᵀ R⁻¹ e_k. Each type-B input
is a quantity u with a standard uncertainty and a shape e_k = G_k u; its contribution is C Cov(u) Cᵀ with
the sensitivity C = A⁻¹ Σ_k H_kᵀ R⁻¹ G_k.

Components (all SI, 18 × 18 covariances):

1. **Identification, white noise** (type A): A⁻¹, the identification's own posterior covariance.
2. **Identification, bias instability** (type B, the unit's datasheet): the correlated flicker between the
   steps, exactly as the identification propagated it (its reported covariance minus A⁻¹;
   :mod:`analysis.identification.bias_drift`). Components 1 + 2 are the identification's covariance, used
   as it is: the budget starts from it, it does not re-derive it.
3. **Table attitude accuracy** (type B): each step's true attitude differs from the reported one by a
   small navigation-frame rotation δφ_s, C_b^n,true = (I + [δφ_s×]) C_b^n,rep, independent between steps
   (every step is a new positioning or a new spin) and constant within a step. The reference error is
   f_true − f_rep = C_n^b [g_n×] δφ_s = [f×] C_n^b δφ_s. The table's stated accuracy ±a is taken as a
   rectangular distribution per axis: u = a/√3 (GUM 4.3.7).
4. **Local gravity** (type B): f_true = f_rep (1 + δg/g), one δg for the whole run; u(g) from the bench.
5. **Table rate accuracy** (type B, the size effect r): the reported rate of gimbal axis j is off by a
   relative ε_j (rectangular ±a_rate, one per axis and run). The centripetal regressor scales with ω², so
   during a spin about j the unmodelled term is −2 ε_j r ∘ c(ω); its sensitivity uses the identified r̂.
6. **Model mismatch** (type A, from the residuals): the per-step mean residuals scatter more than the
   claimed components explain (noise R/n, the per-step part of the flicker, the attitude error): the excess
   variance per axis σ²_mm = Σ_s (m²_{s,a} − expected_{s,a}) / (K − 6) (clipped at 0) is propagated as an
   unknown constant error per step and axis.

Combined standard uncertainty u = √diag(Σ components); expanded uncertainty U = k u with k = 2 (≈ 95 %
for a normal distribution; the effective degrees of freedom are large). Where the spec is silent the
method follows IEEE Std 1293.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from analysis.identification.model import N_PARAMS, SIZE_EFFECT, design_matrix

COVERAGE_FACTOR: float = 2.0
"""k of the expanded uncertainty U = k·u."""

G_UNCERTAINTY_MEASURED: float = 1e-6
"""Default standard uncertainty of a measured local g, m/s² (0.1 mGal, a gravimeter survey)."""
G_UNCERTAINTY_NORMAL: float = 3e-4
"""Default standard uncertainty of WGS-84 normal gravity used as local g, m/s² (30 mGal anomaly)."""


def default_g_uncertainty(measured: bool) -> float:
    """Standard uncertainty of local g when the bench states none, m/s²."""
    return G_UNCERTAINTY_MEASURED if measured else G_UNCERTAINTY_NORMAL


@dataclass(frozen=True)
class StepGeometry:
    """Reference points of one acquisition step (decimated), for sensitivity sums.

    Attributes
    ----------
    name, kind : str
        Step name and kind (hold | spin).
    f : (m, 3) array
        Reference specific force, body frame, m/s² (from :func:`benches.reference.reference_for_samples`).
    omega : (m, 3) array
        Body angular rate, body frame, rad/s.
    weight : (m,) array
        Number of recorded samples each point stands for.
    c_bn : (m, 3, 3) array or None
        Reported attitude C_b^n per point; None: attitude errors taken in the body frame.
    spin_axis : int or None
        Gimbal axis (0 outer, 1 middle, 2 inner) spinning during the step, None for a hold.
    window : (float, float)
        Acquisition window in bench time, s (for the flicker correlation).
    """

    name: str
    kind: str
    f: NDArray[np.float64]
    omega: NDArray[np.float64]
    weight: NDArray[np.float64]
    c_bn: NDArray[np.float64] | None = None
    spin_axis: int | None = None
    window: tuple[float, float] = (0.0, 0.0)

    @property
    def samples(self) -> int:
        """Acquisition samples of the step."""
        return int(round(float(self.weight.sum())))


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
    """The combined budget: ``combined`` = u (standard), ``expanded`` = U = k·u (k = 2)."""

    components: list[BudgetComponent]
    coverage_factor: float = COVERAGE_FACTOR
    notes: list[str] = field(default_factory=list)

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Combined covariance of the 18 parameters, SI."""
        return np.sum([c.covariance for c in self.components], axis=0)

    @property
    def combined(self) -> NDArray[np.float64]:
        """Combined standard uncertainty u per parameter, SI."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def expanded(self) -> NDArray[np.float64]:
        """Expanded uncertainty U = k·u per parameter, SI."""
        return self.coverage_factor * self.combined


def _cross_matrices(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """[v×] for rows of v (n, 3) → (n, 3, 3)."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)


def _ht_rinv(geo: StepGeometry, r_inv: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-point weighted Hᵀ R⁻¹ (m, 18, 3) and H (m, 3, 18) from the model's design matrix."""
    h = design_matrix(geo.f, geo.omega)
    return np.transpose(h, (0, 2, 1)) * r_inv[None, None, :] * geo.weight[:, None, None], h


def data_information(geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ_k Hᵀ R⁻¹ H over the (decimated, weighted) geometry, (18, 18) SI."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    info = np.zeros((N_PARAMS, N_PARAMS))
    for geo in geometry:
        ht_ri, h = _ht_rinv(geo, r_inv)
        info += np.einsum("kpa,kaq->pq", ht_ri, h)
    return info


def attitude_sensitivity(
    a_inv: NDArray[np.float64], geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """∂x̂/∂δφ_s per step, (18, 3) each (SI per rad): A⁻¹ Σ_k Hᵀ R⁻¹ [f_k×] C_n^b,k."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    out = []
    for geo in geometry:
        ht_ri, _ = _ht_rinv(geo, r_inv)
        shape = _cross_matrices(geo.f)
        if geo.c_bn is not None:
            shape = shape @ np.transpose(np.asarray(geo.c_bn, dtype=float), (0, 2, 1))
        out.append(a_inv @ np.einsum("kpa,kab->pb", ht_ri, shape))
    return out


def gravity_sensitivity(
    a_inv: NDArray[np.float64], geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64], g: float
) -> NDArray[np.float64]:
    """∂x̂/∂g = A⁻¹ Σ_k Hᵀ R⁻¹ f_k / g, (18,) SI per m/s²."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    acc = np.zeros(N_PARAMS)
    for geo in geometry:
        ht_ri, _ = _ht_rinv(geo, r_inv)
        acc += np.einsum("kpa,ka->p", ht_ri, geo.f)
    return (a_inv @ acc) / g


def rate_sensitivity(
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    r_hat: NDArray[np.float64],
) -> NDArray[np.float64]:
    """∂x̂/∂ε_j for a relative rate error ε_j of gimbal axis j, (18, 3): −2 A⁻¹ Σ_{spins about j} Hᵀ R⁻¹ (r̂∘c_k)."""
    from analysis.identification.model import centripetal

    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    out = np.zeros((N_PARAMS, 3))
    for geo in geometry:
        if geo.spin_axis is None:
            continue
        ht_ri, _ = _ht_rinv(geo, r_inv)
        e = -2.0 * np.asarray(r_hat, dtype=float)[None, :] * centripetal(geo.omega)
        out[:, geo.spin_axis] += a_inv @ np.einsum("kpa,ka->p", ht_ri, e)
    return out


def step_offset_sensitivity(
    a_inv: NDArray[np.float64], geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """∂x̂/∂β_s for a constant error β_s of z per step and axis: A⁻¹ Σ_k Hᵀ R⁻¹, (18, 3) each."""
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    return [a_inv @ _ht_rinv(geo, r_inv)[0].sum(axis=0) for geo in geometry]


def attitude_step_variance(geo: StepGeometry, u_att: float) -> NDArray[np.float64]:
    """Variance (3,) of the step-mean reference error per body axis from an attitude error of u per axis."""
    shape = _cross_matrices(geo.f)
    if geo.c_bn is not None:
        shape = shape @ np.transpose(np.asarray(geo.c_bn, dtype=float), (0, 2, 1))
    mean_shape = np.einsum("k,kab->ab", geo.weight, shape) / max(float(geo.weight.sum()), 1.0)
    return u_att**2 * np.sum(mean_shape**2, axis=1)


def mismatch_variance(
    geometry: Sequence[StepGeometry],
    per_step: Sequence[Mapping[str, object]],
    noise_var: NDArray[np.float64],
    expected_extra: Mapping[str, NDArray[np.float64]],
    n_params_per_axis: int = 6,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Observed per-step DC residual variance (3,) and its excess (3,) over what the budget already claims.

    ``per_step`` rows as in ``calibration.json`` ``residuals.per_step`` (name, samples, mean (3), SI);
    ``expected_extra`` per step name: the claimed variance (3,) of the step mean beyond white noise
    (flicker share, attitude error).
    """
    r = np.asarray(noise_var, dtype=float)
    names = {g.name for g in geometry}
    rows = [p for p in per_step if int(p.get("samples", 0)) > 0 and str(p.get("name")) in names]  # type: ignore[call-overload]
    if len(rows) <= n_params_per_axis:
        return np.zeros(3), np.zeros(3)
    dof = len(rows) - n_params_per_axis
    obs = np.zeros(3)
    exp = np.zeros(3)
    for p in rows:
        n = float(p["samples"])  # type: ignore[arg-type]
        m = np.asarray(p["mean"], dtype=float).reshape(3)
        obs += m**2
        exp += r / n + np.asarray(expected_extra.get(str(p["name"]), np.zeros(3)), dtype=float)
    # a K-step fit removes 6 of K degrees of freedom: the residual means carry (K−6)/K of the variance
    obs_var = obs / dof
    exp_var = exp / len(rows)
    return obs_var, np.clip(obs_var - exp_var, 0.0, None)


def build_budget(
    ident_covariance: NDArray[np.float64],
    white_covariance: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    *,
    x_hat: NDArray[np.float64],
    g: float,
    g_uncertainty: float,
    g_source: str,
    attitude_accuracy: float,
    rate_accuracy: float = 0.0,
    flicker_step_variance: Mapping[str, NDArray[np.float64]] | None = None,
    residuals_per_step: Sequence[Mapping[str, object]] = (),
    coverage_factor: float = COVERAGE_FACTOR,
) -> UncertaintyBudget:
    """The GUM budget of the 18 parameters (module docstring).

    Parameters
    ----------
    ident_covariance : (18, 18)
        The identification's covariance (white noise + correlated bias instability), SI.
    white_covariance : (18, 18)
        Its white-noise part A⁻¹ (the estimator's gain; used for every sensitivity).
    geometry : sequence of StepGeometry
        Reference points of the steps the identification used.
    noise_var : (3,)
        Per-sample white-noise variance per body axis used by the identification, (m/s²)².
    x_hat : (18,)
        The identified parameters, SI (the rate component needs r̂).
    g, g_uncertainty : float
        Local gravity and its standard uncertainty, m/s².
    g_source : str
        How g was obtained (wording).
    attitude_accuracy : float
        Table attitude accuracy bound a, rad (rectangular, u = a/√3 per axis).
    rate_accuracy : float
        Table rate accuracy bound, relative (rectangular, u = a/√3 per gimbal axis); 0: not claimed.
    flicker_step_variance : mapping, optional
        Per step name, the flicker variance (3,) of its mean not common to all steps ((m/s²)²), for the
        model-mismatch test.
    residuals_per_step : sequence of mapping
        ``calibration.json`` ``residuals.per_step``.
    """
    from analysis.units import ARCSEC, PPM, UG

    p_id = np.asarray(ident_covariance, dtype=float)
    a_inv = np.asarray(white_covariance, dtype=float)
    for nm, m in (("identification covariance", p_id), ("white-noise covariance", a_inv)):
        if m.shape != (N_PARAMS, N_PARAMS) or not np.all(np.isfinite(m)):
            raise ValueError(f"the {nm} must be a finite 18 × 18 matrix")
    nv = np.asarray(noise_var, dtype=float).reshape(3)
    if np.any(nv <= 0) or not np.all(np.isfinite(nv)):
        raise ValueError("the measurement noise variances must be positive and finite")
    flick = p_id - a_inv
    flick = 0.5 * (flick + flick.T)
    comps = [
        BudgetComponent(
            "white_noise",
            "Identification: white measurement noise",
            "the identification's posterior covariance (Kalman/least squares, prior included)",
            "A",
            a_inv,
        ),
        BudgetComponent(
            "bias_instability",
            "Identification: unit bias instability (correlated flicker)",
            "the unit's datasheet bias instability as flicker noise, correlated between the steps, exactly as "
            "the identification propagated it",
            "B",
            flick,
        ),
    ]
    u_att = attitude_accuracy / math.sqrt(3.0)
    c_att = attitude_sensitivity(a_inv, geometry, nv)
    comps.append(
        BudgetComponent(
            "attitude",
            "Table attitude accuracy",
            f"±{attitude_accuracy / ARCSEC:.3g}″ per axis (bench file), rectangular, u = {u_att / ARCSEC:.3g}″, "
            "independent per step",
            "B",
            sum((c @ c.T for c in c_att), np.zeros((N_PARAMS, N_PARAMS))) * u_att**2,
        )
    )
    s_g = gravity_sensitivity(a_inv, geometry, nv, g)
    comps.append(
        BudgetComponent(
            "local_g",
            "Local gravity",
            f"g = {g:.6f} m/s² ({g_source}), u(g) = {g_uncertainty:.2g} m/s² ({g_uncertainty / 1e-5:.3g} mGal)",
            "B",
            np.outer(s_g, s_g) * g_uncertainty**2,
        )
    )
    if rate_accuracy > 0 and any(geo.spin_axis is not None for geo in geometry):
        u_rate = rate_accuracy / math.sqrt(3.0)
        s_r = rate_sensitivity(a_inv, geometry, nv, np.asarray(x_hat, dtype=float)[SIZE_EFFECT])
        comps.append(
            BudgetComponent(
                "rate",
                "Table rate accuracy (size effect)",
                f"±{rate_accuracy / PPM:.3g} ppm of rate per gimbal axis (bench file), rectangular, "
                f"u = {u_rate / PPM:.3g} ppm, one per axis and run",
                "B",
                (s_r @ s_r.T) * u_rate**2,
            )
        )
    notes: list[str] = []
    fl = dict(flicker_step_variance or {})
    expected = {geo.name: attitude_step_variance(geo, u_att) + fl.get(geo.name, np.zeros(3)) for geo in geometry}
    obs, excess = mismatch_variance(geometry, residuals_per_step, nv, expected)
    b_s = step_offset_sensitivity(a_inv, geometry, nv)
    cov_mm = sum((b @ np.diag(excess) @ b.T for b in b_s), np.zeros((N_PARAMS, N_PARAMS)))
    comps.append(
        BudgetComponent(
            "model_mismatch",
            "Model mismatch (from residuals)",
            "per-step mean residual scatter ["
            + ", ".join(f"{math.sqrt(v) / UG:.2f}" for v in obs)
            + "] µg per axis, beyond noise, flicker and attitude ["
            + ", ".join(f"{math.sqrt(v) / UG:.2f}" for v in excess)
            + "] µg, an unknown constant per step",
            "A",
            cov_mm,
        )
    )
    if not residuals_per_step:
        notes.append("no per-step residual statistics: the model-mismatch component is zero (not evaluated)")
    return UncertaintyBudget(comps, coverage_factor, notes)


__all__ = [
    "COVERAGE_FACTOR",
    "BudgetComponent",
    "StepGeometry",
    "UncertaintyBudget",
    "attitude_sensitivity",
    "build_budget",
    "data_information",
    "default_g_uncertainty",
    "gravity_sensitivity",
    "rate_sensitivity",
    "step_offset_sensitivity",
]
