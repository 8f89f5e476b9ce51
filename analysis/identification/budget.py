"""GUM uncertainty budget of the 18 identified accelerometer parameters (pure maths).

Method (GUM, JCGM 100:2008, law of propagation of uncertainty for the linear estimator)
-----------------------------------------------------------------------------------------
The identification solves, in the body frame b, z = f_out − f_ref = H(f, ω) x + v with a Gaussian prior,
x̂ = A⁻¹ (P0⁻¹ x0 + Σ_k H_kᵀ R⁻¹ z_k), A = P0⁻¹ + Σ_k H_kᵀ R⁻¹ H_k, H from the ONE model
(the model specification's ``design_matrix``, :mod:`analysis.identification.specification`). An error e_k
of the measurement equation (a reference error, an unmodelled term) moves the estimate by
δx̂ = A⁻¹ Σ_k H_kᵀ R⁻¹ e_k. Each type-B input is a quantity u with a standard uncertainty and a shape
e_k = G_k u; its contribution is C Cov(u) Cᵀ with the sensitivity C = A⁻¹ Σ_k H_kᵀ R⁻¹ G_k.

Components (all SI, n × n covariances, n the model's state count; each type-B input is a
:class:`BudgetInput` — a shape per step and a covariance — so a model of several triads and inputs fed in
from elsewhere, e.g. the time base, enter the same way):

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
5. The table's **rate accuracy** is not an input: a table with a rate error turns at (1 + ε) × its command,
   and the reference rate of a spin is the encoder angle over time (both triads; the centripetal term and
   the gyro scale), which sees that motion (docs/methods/gyro-calibration.md).
6. **Model mismatch** (type A, from the residuals): the per-step mean residuals scatter more than the
   claimed components explain (noise R/n, the per-step part of the flicker, the per-step inputs such as the
   attitude error, and what the run-common inputs leave after the fit): the excess variance per axis
   σ²_mm = (Σ_s (m²_{s,a} − fitted_{s,a}) − (K − 6)/K Σ_s expected_{s,a}) / (K − 6) (clipped at 0) is
   propagated as an unknown constant error per step and axis. ``expected`` is the pre-fit variance of an
   independent per-step error (noise, flicker, attitude); ``fitted`` the squared step-mean residual a
   run-common input u (one draw for the run, e.g. the table's axis non-orthogonality) leaves after the fit,
   r_s = mean_s(e_k − H_k C) with C its sensitivity, E[r_s²] = diag(r_s Cov(u) r_sᵀ): that input is already
   claimed by its own component, and counting its residual as mismatch too would count it twice.

Combined standard uncertainty u = √diag(Σ components); expanded uncertainty U = k u with k = 2 (≈ 95 %
for a normal distribution; the effective degrees of freedom are large). Where the spec is silent the
method follows IEEE Std 1293.

Evaluation: one budget forms each step's H and Hᵀ R⁻¹, and each input's shapes and sensitivities, once
(:class:`StepTerms`, a memo of that one evaluation, shared by the components and the mismatch test); nothing is
kept between budgets.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from analysis.identification.specification import ModelSpec, resolve
from analysis.units import DISPLAY_UNITS

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
        Reference specific force, body frame, m/s² (from :func:`benches.reference.reference_for_window`).
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
    earth : (m, 3) array or None
        Earth rate in the body frame, rad/s (gyro models; None = 0).
    angles, rates : (m, 3) arrays or None
        Reported gimbal angles (ψ, θ, γ), rad, and gimbal rates, rad/s, per point (the table-axis inputs,
        :mod:`analysis.identification.table_axes`; None: those inputs are not evaluated).
    held_angle_u : (3,) array or None
        Spins only: standard uncertainty of the mean angle reading of each gimbal held in position during the
        spin (its readings' scatter over √count), rad; 0 for the spinning gimbal; None: not evaluated.
    """

    name: str
    kind: str
    f: NDArray[np.float64]
    omega: NDArray[np.float64]
    weight: NDArray[np.float64]
    c_bn: NDArray[np.float64] | None = None
    spin_axis: int | None = None
    window: tuple[float, float] = (0.0, 0.0)
    earth: NDArray[np.float64] | None = None
    angles: NDArray[np.float64] | None = None
    rates: NDArray[np.float64] | None = None
    held_angle_u: NDArray[np.float64] | None = None

    @property
    def samples(self) -> int:
        """Acquisition samples of the step."""
        return int(round(float(self.weight.sum())))


@dataclass(frozen=True)
class BudgetComponent:
    """One line of the budget: an input quantity propagated to the model's parameters.

    Attributes
    ----------
    key, label : str
        Machine key and the certificate's wording.
    source : str
        How the input's standard uncertainty was obtained (plain words, with its value).
    type : str
        "A" (statistical) or "B" (other means), GUM 4.2 / 4.3.
    covariance : (n, n) array
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
        """Combined covariance of the parameters, SI."""
        return np.sum([c.covariance for c in self.components], axis=0)

    @property
    def combined(self) -> NDArray[np.float64]:
        """Combined standard uncertainty u per parameter, SI."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    @property
    def expanded(self) -> NDArray[np.float64]:
        """Expanded uncertainty U = k·u per parameter, SI."""
        return self.coverage_factor * self.combined


@dataclass(frozen=True)
class BudgetInput:
    """A type-B input quantity u: its error shape in the measurement equation per step, and Cov(u).

    ``shape(geo)`` returns e_k per unit input, (m, n_axes, k) for the step's m points (or None when the
    step does not see it); the component is C Cov(u) Cᵀ with C = A⁻¹ Σ_k Hᵀ R⁻¹ e_k. With ``per_step`` the
    input is an independent realisation per step (each step its own u, same Cov), otherwise one for the run.
    """

    key: str
    label: str
    source: str
    covariance: NDArray[np.float64]
    shape: Callable[[StepGeometry], NDArray[np.float64] | None]
    per_step: bool = False
    type: str = "B"


def _cross_matrices(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """[v×] for rows of v (n, 3) → (n, 3, 3)."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    o = np.zeros_like(x)
    return np.stack([np.stack([o, -z, y], -1), np.stack([z, o, -x], -1), np.stack([-y, x, o], -1)], -2)


def _ht_rinv(
    geo: StepGeometry, r_inv: NDArray[np.float64], model: ModelSpec | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-point weighted R⁻¹ H (m, n_axes, n) and H (m, n_axes, n) from the model's design matrix.

    The first is Hᵀ R⁻¹ of every point, weighted, stored untransposed: its (m·n_axes, n) reshape is the left
    factor of every sum Σ_k Hᵀ R⁻¹ X_k over a step's points as ONE matrix product (:func:`_sum_ht_rinv`)."""
    h = resolve(model).design_matrix(geo.f, geo.omega, geo.earth)
    return h * (geo.weight[:, None] * r_inv[None, :])[:, :, None], h


def _sum_ht_rinv(rh: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Σ_k H_kᵀ R⁻¹ X_k (n, b) over a step's points, weighted: ``rh`` the weighted R⁻¹ H (m, n_axes, n) of
    :func:`_ht_rinv`, ``x`` (m, n_axes, b). One BLAS product of the (m·n_axes, n) and (m·n_axes, b) reshapes: the
    sum over points and axes at once (an einsum over both indices, looped in numpy's own kernel, is about 40×
    slower at m = 400; the same sum to rounding)."""
    m, a, n = rh.shape
    return rh.reshape(m * a, n).T @ x.reshape(m * a, x.shape[-1])


Shape = Callable[[StepGeometry], NDArray[np.float64] | None]
"""An input's error shape per step (:attr:`BudgetInput.shape`)."""


class StepTerms:
    """The per-step terms of ONE budget evaluation, each computed once and reused (a memo, not a cache across runs).

    One object belongs to one (A⁻¹, geometry, noise variance, model): :func:`build_budget` makes a fresh one per
    call and hands it to every component and to the mismatch test, so the same step's design matrix, its Hᵀ R⁻¹
    and an input's shapes and sensitivity are formed once instead of up to four times. What is kept, and on what
    key:

    * H and Hᵀ R⁻¹ of step k: keyed by k, the step's position in this object's geometry;
    * an input's shapes e_k (one per step) and its per-step sensitivities: keyed by the shape callable itself
      (held here, so its identity cannot be reused by another function while this object lives); a
      :class:`DerivedShape` is formed from its base's memoised shapes.

    Nothing is keyed by the step's values: another geometry, noise or A⁻¹ means another object. The arithmetic
    is the uncached one's, operation for operation (the same numbers bit for bit).
    """

    def __init__(
        self,
        a_inv: NDArray[np.float64],
        geometry: Sequence[StepGeometry],
        noise_var: NDArray[np.float64],
        model: ModelSpec | None = None,
    ) -> None:
        self.a_inv = np.asarray(a_inv, dtype=float)
        self.geometry = tuple(geometry)
        self.noise_var = noise_var
        self.r_inv = 1.0 / np.asarray(noise_var, dtype=float)
        self.model = resolve(model)
        self._ht: list[tuple[NDArray[np.float64], NDArray[np.float64]] | None] = [None] * len(self.geometry)
        self._shapes: dict[Shape, list[NDArray[np.float64] | None]] = {}
        self._sens: dict[Shape, list[NDArray[np.float64] | None]] = {}

    def matches(
        self,
        a_inv: NDArray[np.float64],
        geometry: Sequence[StepGeometry],
        noise_var: NDArray[np.float64],
        model: ModelSpec | None,
    ) -> bool:
        """Whether this memo was made for exactly these arguments (the same objects)."""
        same_geo = len(geometry) == len(self.geometry) and all(
            a is b for a, b in zip(geometry, self.geometry, strict=True)
        )
        return same_geo and a_inv is self.a_inv and noise_var is self.noise_var and resolve(model) is self.model

    def ht_rinv(self, k: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(weighted R⁻¹ H (m, n_axes, n), H (m, n_axes, n)) of step k (:func:`_ht_rinv`)."""
        got = self._ht[k]
        if got is None:
            got = self._ht[k] = _ht_rinv(self.geometry[k], self.r_inv, self.model)
        return got

    def shapes(self, shape: Shape) -> list[NDArray[np.float64] | None]:
        """``shape(geo)`` for every step (None where the step does not see the input)."""
        got = self._shapes.get(shape)
        if got is None:
            if isinstance(shape, DerivedShape):  # its base formed once for every input derived from it
                got = [None if e is None else shape.transform(e) for e in self.shapes(shape.base)]
            else:
                got = [shape(geo) for geo in self.geometry]
            self._shapes[shape] = got
        return got

    def sensitivity(self, shape: Shape) -> list[NDArray[np.float64] | None]:
        """Per step, A⁻¹ Σ_k Hᵀ R⁻¹ e_k (n, k) of the input of error shape ``shape`` (None where unseen)."""
        got = self._sens.get(shape)
        if got is None:
            got = self._sens[shape] = [
                None if e is None else self.a_inv @ _sum_ht_rinv(self.ht_rinv(k)[0], e)
                for k, e in enumerate(self.shapes(shape))
            ]
        return got


def _terms(
    terms: StepTerms | None,
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    model: ModelSpec | None,
) -> StepTerms:
    """``terms`` when it was made for these arguments, else a fresh memo (the uncached computation)."""
    if terms is not None and terms.matches(a_inv, geometry, noise_var, model):
        return terms
    return StepTerms(a_inv, geometry, noise_var, model)


def data_information(
    geometry: Sequence[StepGeometry], noise_var: NDArray[np.float64], model: ModelSpec | None = None
) -> NDArray[np.float64]:
    """Σ_k Hᵀ R⁻¹ H over the (decimated, weighted) geometry, (n, n) SI."""
    m = resolve(model)
    r_inv = 1.0 / np.asarray(noise_var, dtype=float)
    info = np.zeros((m.n_params, m.n_params))
    for geo in geometry:
        rh, h = _ht_rinv(geo, r_inv, m)
        info += _sum_ht_rinv(rh, h)
    return info


def input_sensitivity(
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    shape: Callable[[StepGeometry], NDArray[np.float64] | None],
    model: ModelSpec | None = None,
    *,
    terms: StepTerms | None = None,
) -> list[NDArray[np.float64] | None]:
    """Per step, ∂x̂/∂u = A⁻¹ Σ_k Hᵀ R⁻¹ e_k, (n, k), for an input of error shape e_k = ``shape(geo)``.

    ``terms``: the evaluation's memo (:class:`StepTerms`), used only when made for these same arguments."""
    return list(_terms(terms, a_inv, geometry, noise_var, model).sensitivity(shape))


def attitude_shape(geo: StepGeometry, model: ModelSpec | None = None) -> NDArray[np.float64]:
    """e_k per nav-frame tilt δφ (m, n_axes, 3): the model's reference vectors v turned, [v×] C_n^b.

    C_b^n,true = (I + [δφ×]) C_b^n,rep moves a body-frame vector v = C_n^b v_n by [v×] C_n^b δφ. The
    accelerometer's v is f, the gyro's the Earth rate (the table rate is measured in the body frame).
    """
    m = resolve(model)
    vecs = m.attitude_vectors(geo.f, geo.omega, geo.earth)  # (m, n_axes // 3, 3)
    rot = None if geo.c_bn is None else np.transpose(np.asarray(geo.c_bn, dtype=float), (0, 2, 1))
    blocks = []
    for t in range(vecs.shape[1]):
        sh = _cross_matrices(vecs[:, t, :])
        blocks.append(sh if rot is None else sh @ rot)
    return np.concatenate(blocks, axis=1)


@dataclass(frozen=True)
class AttitudeShape:
    """The attitude input's shape function of ``model`` (:func:`attitude_shape`) as a value: two are equal, and so
    share one entry of a budget's memo (:class:`StepTerms`, keyed by the shape function), when they are of the same
    model object; the attitude input and the inputs derived from it (:class:`DerivedShape`, the gyro's azimuth)
    then form it once per step."""

    model: ModelSpec

    def __call__(self, geo: StepGeometry) -> NDArray[np.float64]:
        return attitude_shape(geo, self.model)


@dataclass(frozen=True)
class DerivedShape:
    """An input's error shape computed from another input's: ``transform(base(geo))`` (None where base is None).

    A budget's memo (:class:`StepTerms`) forms ``base`` once per step for every input that uses it, and applies
    ``transform`` to that same array (the same numbers as calling it directly).
    """

    base: Shape
    transform: Callable[[NDArray[np.float64]], NDArray[np.float64]]

    def __call__(self, geo: StepGeometry) -> NDArray[np.float64] | None:
        e = self.base(geo)
        return None if e is None else self.transform(e)


def attitude_sensitivity(
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    model: ModelSpec | None = None,
) -> list[NDArray[np.float64]]:
    """∂x̂/∂δφ_s per step, (n, 3) each (SI per rad): A⁻¹ Σ_k Hᵀ R⁻¹ [v_k×] C_n^b,k."""
    return input_sensitivity(a_inv, geometry, noise_var, lambda g: attitude_shape(g, model), model)  # type: ignore[return-value]


def gravity_sensitivity(
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    g: float,
    model: ModelSpec | None = None,
) -> NDArray[np.float64]:
    """∂x̂/∂g = A⁻¹ Σ_k Hᵀ R⁻¹ ∂y_ref/∂g, (n,) SI per m/s² (the accelerometer's f/g; 0 for a gyro)."""
    m = resolve(model)
    sens = input_sensitivity(a_inv, geometry, noise_var, lambda geo: m.gravity_shape(geo.f, geo.omega, g), m)
    return sum((c[:, 0] for c in sens if c is not None), np.zeros(m.n_params))


def step_offset_sensitivity(
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    model: ModelSpec | None = None,
    *,
    terms: StepTerms | None = None,
) -> list[NDArray[np.float64]]:
    """∂x̂/∂β_s for a constant error β_s of z per step and axis: A⁻¹ Σ_k Hᵀ R⁻¹, (n, n_axes) each."""
    t = _terms(terms, a_inv, geometry, noise_var, model)
    return [t.a_inv @ t.ht_rinv(k)[0].sum(axis=0).T for k in range(len(t.geometry))]


def _step_mean(geo: StepGeometry, e: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sample-weighted mean over the step's points of a per-point array (m, ...) → (...)."""
    return np.einsum("k,k...->...", geo.weight, e) / max(float(geo.weight.sum()), 1.0)


def attitude_step_variance(geo: StepGeometry, u_att: float, model: ModelSpec | None = None) -> NDArray[np.float64]:
    """Variance (n_axes,) of the step-mean reference error per axis from an attitude error of u per axis."""
    return u_att**2 * np.sum(_step_mean(geo, attitude_shape(geo, model)) ** 2, axis=1)


def input_step_variance(
    inp: BudgetInput,
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    model: ModelSpec | None = None,
    *,
    terms: StepTerms | None = None,
) -> tuple[dict[str, NDArray[np.float64]], dict[str, NDArray[np.float64]]]:
    """What one type-B input adds to the step-mean residuals, per step name, (n_axes,) each, SI².

    Returns (pre-fit, post-fit). A per-step input (an independent draw per step) gives the pre-fit variance
    diag(ē_s Cov ē_sᵀ) of its step-mean error ē_s; the fit removes its share of it like that of any independent
    per-step error. A run-common input (one draw for the run) gives the post-fit variance diag(r̄_s Cov r̄_sᵀ) of
    the step-mean residual it leaves, r̄_s = mean_s(e_k − H_k C), C = A⁻¹ Σ_k Hᵀ R⁻¹ e_k its sensitivity over
    the whole run (the identification's estimate moves by C u and the residual keeps the rest). ``terms``: the
    evaluation's memo (:class:`StepTerms`; its shapes, sensitivities and H are reused).
    """
    t = _terms(terms, a_inv, geometry, noise_var, model)
    m = t.model
    pre: dict[str, NDArray[np.float64]] = {}
    post: dict[str, NDArray[np.float64]] = {}
    cov = np.asarray(inp.covariance, dtype=float)
    shapes = t.shapes(inp.shape)
    if inp.per_step:
        for geo, e in zip(t.geometry, shapes, strict=True):
            if e is not None:
                mean = _step_mean(geo, e)
                pre[geo.name] = np.einsum("ab,bc,ac->a", mean, cov, mean)
        return pre, post
    sens = t.sensitivity(inp.shape)
    if all(c is None for c in sens):
        return pre, post
    c_run = sum((c for c in sens if c is not None), np.zeros((m.n_params, cov.shape[0])))
    for k, (geo, e) in enumerate(zip(t.geometry, shapes, strict=True)):
        h = t.ht_rinv(k)[1]
        res = -(h.reshape(-1, h.shape[-1]) @ c_run).reshape(h.shape[0], h.shape[1], -1)  # H_k C, one product
        if e is not None:
            res = res + e
        mean = _step_mean(geo, res)
        post[geo.name] = np.einsum("ab,bc,ac->a", mean, cov, mean)
    return pre, post


def mismatch_variance(
    geometry: Sequence[StepGeometry],
    per_step: Sequence[Mapping[str, object]],
    noise_var: NDArray[np.float64],
    expected_extra: Mapping[str, NDArray[np.float64]],
    n_params_per_axis: int | Sequence[int] = 6,
    expected_fitted: Mapping[str, NDArray[np.float64]] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Observed per-step DC residual variance (n_axes,) and its excess over what the budget already claims.

    ``per_step`` rows as in ``calibration.json`` ``residuals.per_step`` (name, samples, mean (n_axes), SI);
    ``expected_extra`` per step name: the claimed pre-fit variance of the step mean beyond white noise
    (flicker share, attitude error; independent per step). ``n_params_per_axis``: the fitted parameters per
    axis (a K-step fit removes that many of the K degrees of freedom of the step means).
    ``expected_fitted`` per step name: the claimed squared step-mean residual left AFTER the fit by the
    run-common inputs (:func:`input_step_variance`), taken off the observed sum as it is. The returned
    observed variance is the raw Σ m² / (K − p).
    """
    r = np.asarray(noise_var, dtype=float).reshape(-1)
    n_ax = r.size
    npa = np.broadcast_to(np.asarray(n_params_per_axis, dtype=float), (n_ax,))
    names = {g.name for g in geometry}
    rows = [p for p in per_step if int(p.get("samples", 0)) > 0 and str(p.get("name")) in names]  # type: ignore[call-overload]
    if len(rows) <= npa.max():
        return np.zeros(n_ax), np.zeros(n_ax)
    dof = len(rows) - npa
    obs = np.zeros(n_ax)
    exp = np.zeros(n_ax)
    for p in rows:
        n = float(p["samples"])  # type: ignore[arg-type]
        m = np.asarray(p["mean"], dtype=float).reshape(n_ax)
        obs += m**2
        exp += r / n + np.asarray(expected_extra.get(str(p["name"]), np.zeros(n_ax)), dtype=float)
    fitted = np.zeros(n_ax)
    for p in rows:
        fitted += np.asarray((expected_fitted or {}).get(str(p["name"]), np.zeros(n_ax)), dtype=float)
    obs_var = obs / dof
    exp_var = exp / len(rows) + fitted / dof
    return obs_var, np.clip(obs_var - exp_var, 0.0, None)


def reference_inputs(
    model: ModelSpec,
    geometry: Sequence[StepGeometry],
    *,
    g: float,
    g_uncertainty: float,
    g_source: str,
    attitude_accuracy: float,
) -> list[BudgetInput]:
    """The bench's type-B inputs common to every model: table attitude and local g."""
    from analysis.units import ARCSEC

    u_att = attitude_accuracy / math.sqrt(3.0)
    out = [
        BudgetInput(
            "attitude", "Table attitude accuracy",
            f"±{attitude_accuracy / ARCSEC:.3g}″ per axis (bench file), rectangular, u = {u_att / ARCSEC:.3g}″, "
            "independent per step",
            np.eye(3) * u_att**2, AttitudeShape(model), per_step=True,
        ),
        BudgetInput(
            "local_g", "Local gravity",
            f"g = {g:.6f} m/s² ({g_source}), u(g) = {g_uncertainty:.2g} m/s² ({g_uncertainty / 1e-5:.3g} mGal)",
            np.array([[g_uncertainty**2]]), lambda geo: model.gravity_shape(geo.f, geo.omega, g),
        ),
    ]  # fmt: skip
    return out


def input_component(
    inp: BudgetInput,
    a_inv: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    model: ModelSpec | None = None,
    *,
    terms: StepTerms | None = None,
) -> BudgetComponent:
    """The covariance contribution of one type-B input (module docstring: C Cov(u) Cᵀ); ``terms``: the
    evaluation's memo (:class:`StepTerms`)."""
    t = _terms(terms, a_inv, geometry, noise_var, model)
    sens = [c for c in t.sensitivity(inp.shape) if c is not None]
    n = a_inv.shape[0]
    if inp.per_step:
        cov = sum((c @ inp.covariance @ c.T for c in sens), np.zeros((n, n)))
    else:
        c = sum(sens, np.zeros((n, inp.covariance.shape[0])))
        cov = c @ inp.covariance @ c.T
    return BudgetComponent(inp.key, inp.label, inp.source, inp.type, cov)


def build_budget(
    ident_covariance: NDArray[np.float64],
    white_covariance: NDArray[np.float64],
    geometry: Sequence[StepGeometry],
    noise_var: NDArray[np.float64],
    *,
    g: float,
    g_uncertainty: float,
    g_source: str,
    attitude_accuracy: float,
    flicker_step_variance: Mapping[str, NDArray[np.float64]] | None = None,
    residuals_per_step: Sequence[Mapping[str, object]] = (),
    coverage_factor: float = COVERAGE_FACTOR,
    model: ModelSpec | None = None,
    extra_inputs: Sequence[BudgetInput] = (),
) -> UncertaintyBudget:
    """The GUM budget of the model's parameters (module docstring).

    Parameters
    ----------
    ident_covariance, white_covariance : (n, n)
        The identification's covariance (white noise + correlated bias instability) and its white-noise
        part A⁻¹ (the estimator's gain; used for every sensitivity), SI.
    geometry : sequence of StepGeometry
        Reference points of the steps the identification used.
    noise_var : (n_axes,)
        Per-sample white-noise variance per axis used by the identification, SI².
    g, g_uncertainty, g_source
        Local gravity and its standard uncertainty, m/s², and how g was obtained (wording).
    attitude_accuracy : float
        Table attitude accuracy bound, rad (rectangular; 0: not claimed).
    flicker_step_variance : mapping, optional
        Per step name, the flicker variance (n_axes,) of its mean not common to all steps, for the
        model-mismatch test.
    residuals_per_step : sequence of mapping
        ``calibration.json`` ``residuals.per_step``.
    model : ModelSpec, optional
        The identified model (default: the accelerometer model).
    extra_inputs : sequence of BudgetInput
        Further type-B inputs (the gyro's Earth-rate and time-base inputs, :func:`gyro_inputs`-style).
    """
    m = resolve(model)
    p_id = np.asarray(ident_covariance, dtype=float)
    a_inv = np.asarray(white_covariance, dtype=float)
    n = m.n_params
    for nm, mat in (("identification covariance", p_id), ("white-noise covariance", a_inv)):
        if mat.shape != (n, n) or not np.all(np.isfinite(mat)):
            raise ValueError(f"the {nm} must be a finite {n} × {n} matrix")
    nv = m.as_noise_variance(noise_var)
    flick = 0.5 * ((p_id - a_inv) + (p_id - a_inv).T)
    comps = [
        BudgetComponent(
            "white_noise", "Identification: white measurement noise",
            "the identification's posterior covariance (Kalman/least squares, prior included)", "A", a_inv,
        ),
        BudgetComponent(
            "bias_instability", "Identification: unit bias instability (correlated flicker)",
            "the unit's datasheet bias instability as flicker noise, correlated between the steps, exactly as "
            "the identification propagated it", "B", flick,
        ),
    ]  # fmt: skip
    inputs = reference_inputs(
        m, geometry, g=g, g_uncertainty=g_uncertainty, g_source=g_source,
        attitude_accuracy=attitude_accuracy,
    )  # fmt: skip
    inputs = [*inputs, *extra_inputs]
    terms = StepTerms(a_inv, geometry, nv, m)  # this evaluation's memo: every step term formed once
    comps += [input_component(i, a_inv, geometry, nv, m, terms=terms) for i in inputs]
    notes: list[str] = []
    comps.append(_mismatch_component(terms, inputs, flicker_step_variance, residuals_per_step))
    if not residuals_per_step:
        notes.append("no per-step residual statistics: the model-mismatch component is zero (not evaluated)")
    return UncertaintyBudget(comps, coverage_factor, notes)


def _mismatch_component(
    terms: StepTerms,
    inputs: Sequence[BudgetInput],
    flicker_step_variance: Mapping[str, NDArray[np.float64]] | None,
    residuals_per_step: Sequence[Mapping[str, object]],
) -> BudgetComponent:
    """Model mismatch: per-step residual scatter beyond noise, flicker and the claimed type-B inputs (the
    per-step ones before the fit, the run-common ones after it), as a constant per step (``terms``: the
    evaluation's memo)."""
    m, a_inv, geometry, nv = terms.model, terms.a_inv, terms.geometry, terms.noise_var
    fl = dict(flicker_step_variance or {})
    zero = np.zeros(m.n_axes)
    expected = {geo.name: fl.get(geo.name, zero) for geo in geometry}
    fitted = {geo.name: zero for geo in geometry}
    if residuals_per_step:
        for inp in inputs:
            pre, post = input_step_variance(inp, a_inv, geometry, nv, m, terms=terms)
            expected = {k: v + pre.get(k, zero) for k, v in expected.items()}
            fitted = {k: v + post.get(k, zero) for k, v in fitted.items()}
    npa = [len(ax) for ax in m.axis_params]
    obs, excess = mismatch_variance(geometry, residuals_per_step, nv, expected, npa, fitted)
    b_s = step_offset_sensitivity(a_inv, geometry, nv, m, terms=terms)
    cov_mm = sum((b @ np.diag(excess) @ b.T for b in b_s), np.zeros((m.n_params, m.n_params)))
    scale = [DISPLAY_UNITS[m.kinds[ax[0]]] for ax in m.axis_params]  # the axis's bias kind
    fmt = ", ".join(f"{math.sqrt(v) / one:.2f} {u}" for v, (u, one) in zip(obs, scale, strict=True))
    fmt_x = ", ".join(f"{math.sqrt(v) / one:.2f} {u}" for v, (u, one) in zip(excess, scale, strict=True))
    return BudgetComponent(
        "model_mismatch", "Model mismatch (from residuals)",
        f"per-step mean residual scatter [{fmt}] per axis, beyond noise, flicker and the claimed inputs "
        f"(attitude, axis orthogonality, …) [{fmt_x}], an unknown constant per step", "A", cov_mm,
    )  # fmt: skip


__all__ = [
    "COVERAGE_FACTOR",
    "AttitudeShape",
    "BudgetComponent",
    "BudgetInput",
    "DerivedShape",
    "StepGeometry",
    "StepTerms",
    "UncertaintyBudget",
    "attitude_sensitivity",
    "build_budget",
    "data_information",
    "default_g_uncertainty",
    "gravity_sensitivity",
    "input_component",
    "input_sensitivity",
    "reference_inputs",
    "step_offset_sensitivity",
]
