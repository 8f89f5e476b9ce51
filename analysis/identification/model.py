"""Accelerometer-triad error model (18 parameters) for turntable calibration (pure maths, vectorised).

Registered as the model ``accelerometer`` (:class:`AccelerometerModel`, :data:`ACCELEROMETER`) of
:mod:`analysis.identification.specification`; the estimators take that object, not these constants.

Model (per sample, **body frame b**; see ``docs/methods/accelerometer-calibration.md``, IEEE 1293 where silent)::

    f_out = f + (S + T) f + b + D (f ∘ f) + diag(r) c(ω) + v

* ``f`` (m/s²): true specific force at the triad's reference point, body frame.
* ``S = diag(S_x, S_y, S_z)``: scale-factor errors (dimensionless).
* ``T``: misalignment, off-diagonal only, with the convention **δf_i += τ_ij f_j** (the published equation
  transposes the indices in one place; only this convention is consistent with the published procedure,
  where steps about body y identify the couplings into x and z).
* ``b`` (m/s²): bias.  ``D = diag(d)`` (s²/m): quadratic (second-order) coefficients.
* ``c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²]`` (s⁻²), ω (rad/s) the body angular rate: centripetal size
  effect with ``r_i = −ρ_{i,i}`` (m), ρ_i the position of accelerometer i relative to the rotation centre.
  For a spin about an axis j ≠ i, [ω×(ω×ρ_i)]_i = −ω²ρ_{i,i} = +r_i c_i, hence the **+** sign.
* ``v``: white measurement noise.

State vector x (18,), SI units, ordering :data:`PARAM_NAMES`::

    [b_x b_y b_z | S_x S_y S_z | τ_xy τ_xz τ_yx τ_yz τ_zx τ_zy | d_x d_y d_z | r_x r_y r_z]

The identification works in the body frame: ``z = f_out − f_ref = H(f_ref, ω) x + v``. The measurement
rows are derived from the model: axis i depends only on its own six parameters
``[b_i, S_i, τ_ij, τ_ik, d_i, r_i]`` with regressors ``[1, f_i, f_j, f_k, f_i², c_i]`` (j < k the other
two axes). Because the three axes share no parameter, the information matrix of per-axis white noise is
block diagonal, and every sum the estimators need is a sub-block of the Gram matrix of ten *base
regressors* ``[1, f_x, f_y, f_z, f_x², f_y², f_z², c_x, c_y, c_z]`` (plus the three measurements), which
:func:`regressor_gram` accumulates in chunks with one matrix product each.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.identification.specification import ModelSpec, register
from analysis.units import G0

PARAM_NAMES: tuple[str, ...] = (
    "b_x",
    "b_y",
    "b_z",
    "S_x",
    "S_y",
    "S_z",
    "tau_xy",
    "tau_xz",
    "tau_yx",
    "tau_yz",
    "tau_zx",
    "tau_zy",
    "d_x",
    "d_y",
    "d_z",
    "r_x",
    "r_y",
    "r_z",
)
"""Names of the 18 states, in state-vector order."""

N_PARAMS: int = len(PARAM_NAMES)

PARAM_KINDS: tuple[str, ...] = (
    ("bias",) * 3 + ("scale",) * 3 + ("misalignment",) * 6 + ("quadratic",) * 3 + ("size_effect",) * 3
)
"""Quantity kind of each state (a key of :data:`analysis.units.DISPLAY_UNITS`), for display."""

KIND_LABELS: dict[str, str] = {
    "bias": "bias",
    "scale": "scale factor",
    "misalignment": "misalignment",
    "quadratic": "quadratic",
    "size_effect": "size effect",
}
"""Plain-words name of each parameter kind (for messages and certificates)."""

BIAS = slice(0, 3)
SCALE = slice(3, 6)
MISALIGNMENT = slice(6, 12)
QUADRATIC = slice(12, 15)
SIZE_EFFECT = slice(15, 18)

# Base regressors: [1, f_x, f_y, f_z, f_x², f_y², f_z², c_x, c_y, c_z]; measurement columns follow (10, 11, 12).
N_BASE: int = 10
Z_COLUMNS: tuple[int, int, int] = (10, 11, 12)

_OTHERS = ((1, 2), (0, 2), (0, 1))
AXIS_PARAMS: tuple[tuple[int, ...], ...] = tuple((i, 3 + i, 6 + 2 * i, 7 + 2 * i, 12 + i, 15 + i) for i in range(3))
"""State indices of the six parameters of axis i: (b_i, S_i, τ_ij, τ_ik, d_i, r_i)."""
AXIS_BASE: tuple[tuple[int, ...], ...] = tuple(
    (0, 1 + i, 1 + _OTHERS[i][0], 1 + _OTHERS[i][1], 4 + i, 7 + i) for i in range(3)
)
"""Base-regressor columns matching :data:`AXIS_PARAMS`: (1, f_i, f_j, f_k, f_i², c_i)."""
PARAM_AXIS: NDArray[np.int64] = np.empty(N_PARAMS, dtype=np.int64)
for _i, _idx in enumerate(AXIS_PARAMS):
    PARAM_AXIS[list(_idx)] = _i

OMEGA_REF: float = 1.0
"""Reference body rate (rad/s) used to make the size-effect column dimensionless (see :data:`REFERENCE_SCALE`)."""

REFERENCE_SCALE: NDArray[np.float64] = np.array(
    [1.0] * 3 + [1.0 / G0] * 3 + [1.0 / G0] * 6 + [1.0 / G0**2] * 3 + [1.0 / OMEGA_REF**2] * 3
)
"""Parameter scale (SI) whose effect is 1 m/s² at the reference condition |f| = 1 g, |ω| = 1 rad/s.

Multiplying the H columns by this scale makes them dimensionless and O(1) (1, f/g, f²/g², c/Ω_ref²): it is
the per-kind scaling used for ranks, condition numbers and internal numerics.
"""


def _as_n3(a: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3) (one body-frame vector per sample), got {arr.shape}")
    return arr


def as_state(x: ArrayLike, name: str = "x") -> NDArray[np.float64]:
    """Validate a state vector: shape (18,), finite, SI units in :data:`PARAM_NAMES` order."""
    arr = np.asarray(x, dtype=float).reshape(-1)
    if arr.shape != (N_PARAMS,):
        raise ValueError(f"{name} must have {N_PARAMS} entries ({', '.join(PARAM_NAMES)}), got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains non-finite values")
    return arr


def as_noise_variance(r_var: ArrayLike) -> NDArray[np.float64]:
    """Validate per-axis white-noise variances (3,), (m/s²)² per sample; a scalar applies to all axes."""
    r = np.broadcast_to(np.asarray(r_var, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(r)) or np.any(r <= 0.0):
        raise ValueError(f"measurement noise variance must be finite and > 0 per axis, got {r}")
    return r


def centripetal(omega: ArrayLike) -> NDArray[np.float64]:
    """Centripetal regressor c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²], s⁻².

    Parameters
    ----------
    omega : array_like, shape (n, 3) or (3,)
        Body angular rate relative to inertial space (in practice: the table rate), body frame b, rad/s.

    Returns
    -------
    ndarray, shape (n, 3)
    """
    w2 = _as_n3(omega, "omega") ** 2
    return w2.sum(axis=1, keepdims=True) - w2


def error_matrices(
    x: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Split a state vector into the model's matrices.

    Returns
    -------
    M : ndarray (3, 3)
        I + S + T, with T[i, j] = τ_ij (δf_i += τ_ij f_j).
    b : ndarray (3,)
        Bias, m/s².
    d : ndarray (3,)
        Quadratic coefficients, s²/m.
    r : ndarray (3,)
        Size-effect coefficients, m (r_i = −ρ_{i,i}).
    """
    xs = as_state(x)
    m = np.eye(3) + np.diag(xs[SCALE])
    tau = xs[MISALIGNMENT]
    for i in range(3):
        m[i, _OTHERS[i][0]] = tau[2 * i]
        m[i, _OTHERS[i][1]] = tau[2 * i + 1]
    return m, xs[BIAS].copy(), xs[QUADRATIC].copy(), xs[SIZE_EFFECT].copy()


def predict(x: ArrayLike, f: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """Accelerometer output for true specific force: f_out = (I+S+T) f + b + D(f∘f) + diag(r) c(ω).

    Parameters
    ----------
    x : array_like (18,)
        Error parameters, SI, :data:`PARAM_NAMES` order.
    f : array_like (n, 3)
        True specific force at the reference point, body frame, m/s².
    omega : array_like (n, 3)
        Body angular rate, body frame, rad/s.

    Returns
    -------
    ndarray (n, 3)
        Modelled output (noise-free), body frame, m/s².
    """
    m, b, d, r = error_matrices(x)
    ff = _as_n3(f, "f")
    c = centripetal(omega)
    if c.shape != ff.shape:
        raise ValueError(f"f and omega must have the same shape (n, 3), got {ff.shape} and {c.shape}")
    return ff @ m.T + b + d * ff * ff + r * c


def mean_model_error(x: ArrayLike, f_mean: ArrayLike, ff_mean: ArrayLike, c_mean: ArrayLike) -> NDArray[np.float64]:
    """mean(predict(x, f, ω) − f) over samples, from their means alone: (S+T) mean(f) + b + D mean(f∘f) +
    diag(r) mean(c(ω)) (body frame, m/s²). :func:`predict` is affine in f, f∘f and c(ω), so the window means
    of those three give the window's mean modelled error for any x without the samples (equal to the mean of
    the per-sample values up to rounding).

    Parameters
    ----------
    x : array_like (18,)
        Error parameters, SI, :data:`PARAM_NAMES` order.
    f_mean, ff_mean, c_mean : array_like (3,)
        Sample means of the true specific force f, of f∘f (m²/s⁴) and of :func:`centripetal` (ω), body frame.
    """
    m, b, d, r = error_matrices(x)
    return (
        (m - np.eye(3)) @ np.asarray(f_mean, dtype=float)
        + b
        + d * np.asarray(ff_mean, dtype=float)
        + r * (np.asarray(c_mean, dtype=float))
    )


def correct(
    x: ArrayLike, f_out: ArrayLike, omega: ArrayLike, *, max_iter: int = 20, chunk: int = 1 << 18
) -> NDArray[np.float64]:
    """Invert the model: the specific force f that produces the output f_out (compensation).

    Solves ``(I+S+T) f + D(f∘f) = f_out − b − diag(r) c(ω)`` per sample by Newton iteration with the exact
    Jacobian ``J = I+S+T + 2 diag(d∘f)``, started from the linear solution, vectorised over samples and
    iterated until the step is at the rounding level (|Δf_i| ≤ 4 ε ‖f‖, ε the machine epsilon).

    Parameters
    ----------
    x : array_like (18,)
        Error parameters, SI.
    f_out : array_like (n, 3)
        Accelerometer output, body frame, m/s².
    omega : array_like (n, 3)
        Body angular rate, body frame, rad/s.
    max_iter : int
        Iteration cap; a ``ValueError`` is raised if the iteration has not converged (only possible for
        absurd quadratic coefficients, |d f| ≳ 0.5).

    Returns
    -------
    ndarray (n, 3)
        Compensated specific force, body frame, m/s².
    """
    m, b, d, r = error_matrices(x)
    fo = _as_n3(f_out, "f_out")
    c = centripetal(omega)
    if c.shape != fo.shape:
        raise ValueError(f"f_out and omega must have the same shape (n, 3), got {fo.shape} and {c.shape}")
    rhs = fo - b - r * c
    minv_t = np.linalg.inv(m).T
    out = np.empty_like(rhs)
    eps = np.finfo(float).eps
    for s in range(0, rhs.shape[0], chunk):
        y = rhs[s : s + chunk]
        f = y @ minv_t
        if np.any(d != 0.0):
            for _ in range(max_iter):
                g = f @ m.T + d * f * f - y
                jac = np.broadcast_to(m, (f.shape[0], 3, 3)).copy()
                jac[:, [0, 1, 2], [0, 1, 2]] += 2.0 * d * f
                step = np.linalg.solve(jac, g[..., None])[..., 0]
                f = f - step
                size = np.maximum(np.linalg.norm(f, axis=1, keepdims=True), 1e-300)
                if np.all(np.abs(step) <= 4.0 * eps * size):
                    break
            else:
                raise ValueError(
                    "correct(): Newton iteration did not converge; the quadratic coefficients are too large "
                    "for the model to be invertible near these readings (check d units: s²/m)"
                )
        out[s : s + chunk] = f
    return out


def base_regressors(f: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """Base regressors B (n, 10) = [1, f_x, f_y, f_z, f_x², f_y², f_z², c_x, c_y, c_z] (body frame, SI)."""
    return ACCELEROMETER.base_regressors(f, omega)


def design_matrix(f: ArrayLike, omega: ArrayLike) -> NDArray[np.float64]:
    """Measurement matrix H (n, 3, 18) of z = f_out − f = H x (body frame), derived from the model.

    Row i of sample n holds, at the state indices :data:`AXIS_PARAMS` [i], the regressors
    ``[1, f_i, f_j, f_k, f_i², c_i]``. Exactly linear: ``predict(x, f, ω) − f == H x`` for any x.
    """
    return ACCELEROMETER.design_matrix(f, omega)


def regressor_gram(
    f: ArrayLike,
    omega: ArrayLike,
    z: ArrayLike | None = None,
    weights: ArrayLike | None = None,
    *,
    chunk: int = 1 << 17,
) -> NDArray[np.float64]:
    """Weighted Gram matrix of the base regressors and (optionally) the measurements (13×13 with z, else 10×10).

    ``G = Σ_n w_n a_n a_nᵀ`` with ``a_n = [1, f_x, f_y, f_z, f_x², f_y², f_z², c_x, c_y, c_z, z_x, z_y, z_z]``;
    see :meth:`analysis.identification.specification.ModelSpec.regressor_gram`.
    """
    return ACCELEROMETER.regressor_gram(f, omega, z, weights, chunk=chunk)


def information_from_gram(
    gram: NDArray[np.float64], r_var: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """Data information Λ = Σ HᵀR⁻¹H (18×18) and η = Σ HᵀR⁻¹z (18,) from a :func:`regressor_gram`."""
    return ACCELEROMETER.information_from_gram(gram, r_var)


def residual_moments(gram: NDArray[np.float64], x: ArrayLike) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Count, per-axis mean and RMS of the residual e = z − H x, exactly, from a 13×13 Gram."""
    return ACCELEROMETER.residual_moments(gram, x)


def to_display(x: ArrayLike) -> NDArray[np.float64]:
    """State (or 1σ) vector in SI → display units per kind (µg, ppm, arcsec, µg/g², mm)."""
    return ACCELEROMETER.to_display(x)


def from_display(x_display: ArrayLike) -> NDArray[np.float64]:
    """State (or 1σ) vector in display units → SI."""
    return ACCELEROMETER.from_display(x_display)


def display_units() -> tuple[str, ...]:
    """Display unit label of each state, e.g. ('µg', 'µg', 'µg', 'ppm', …)."""
    return ACCELEROMETER.display_units()


def sigma_from_display(values: Mapping[str, float]) -> NDArray[np.float64]:
    """Per-parameter SI values (e.g. prior 1σ) from display-unit values given per kind or per name.

    Example: ``{"bias": 1000, "scale": 1000, "misalignment": 100, "quadratic": 50, "size_effect": 30}``
    (µg, ppm, arcsec, µg/g², mm); see :meth:`~analysis.identification.specification.ModelSpec.sigma_from_display`.
    """
    return ACCELEROMETER.sigma_from_display(values)


class AccelerometerModel(ModelSpec):
    """The 18-parameter accelerometer-triad model as a :class:`~analysis.identification.specification.ModelSpec`."""

    name = "accelerometer"
    output = "accel"
    names = PARAM_NAMES
    kinds = PARAM_KINDS
    si_units = {"bias": "m/s^2", "scale": "1", "misalignment": "rad", "quadratic": "s^2/m", "size_effect": "m"}
    kind_labels = KIND_LABELS
    axis_params = AXIS_PARAMS
    axis_base = AXIS_BASE
    n_base = N_BASE
    reference_scale = REFERENCE_SCALE
    equation = (
        "f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω), body frame; c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²]; "
        "misalignment convention δf_i += τ_ij f_j"
    )
    unobservable_fix = {
        "size_effect": (
            "the motion has no rotation that excites it (c = ω² = 0); add constant-rate spins about "
            "each body axis, at ≥ 30 °/s and in both directions"
        ),
        "bias": "add static holds in orientations that separate bias from scale/misalignment (±g on each axis)",
    }
    rate_power = {"size_effect": 2}
    default_fix = (
        "the orientations do not separate it; add positions with ±g and 45° tilts along each body "
        "axis (e.g. the ten-step sequence or 24 cube orientations)"
    )
    bias_kind = "bias"

    def fill_base(self, out, f, omega, earth) -> None:  # type: ignore[no-untyped-def]
        """[1, f_x, f_y, f_z, f_x², f_y², f_z², c_x, c_y, c_z]; Earth rate is not used (< 1e-8 m/s² in c).

        Written column by column: an (n, 3) operation into the wide row-major block loops three values at a time
        (3× slower); c = Σω² − ω_i² with Σω² = (ω_x² + ω_y²) + ω_z², the additions of ``w2.sum(axis=1)`` in its
        order, so the same values bit for bit as :func:`centripetal` (a test checks both); ω_i² and Σω² are formed
        in the rows of one (4, n) scratch array (ω² as an (n, 3) array is another three-wide loop per row)."""
        out[:, 0] = 1.0
        sq = np.empty((4, out.shape[0]))
        w2, s = sq[:3], sq[3]
        for k in range(3):
            np.multiply(omega[:, k], omega[:, k], out=w2[k])
        np.add(w2[0], w2[1], out=s)
        np.add(s, w2[2], out=s)
        for k in range(3):
            out[:, 1 + k] = f[:, k]
            np.multiply(f[:, k], f[:, k], out=out[:, 4 + k])
            np.subtract(s, w2[k], out=out[:, 7 + k])

    def ideal(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        """An error-free accelerometer reads the specific force f."""
        return _as_n3(f, "f").copy()

    def fill_measurement(self, out, y, f, omega, earth, base) -> None:  # type: ignore[no-untyped-def]
        """z = y − f, column by column."""
        for k in range(3):
            np.subtract(y[:, k], f[:, k], out=out[:, k])

    def predict(
        self, x: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        return predict(x, f, omega)

    def correct(
        self, x: ArrayLike, y: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Compensated specific force (:func:`correct`); ``f`` is not used (the output is inverted)."""
        return correct(x, y, omega)

    def attitude_vectors(self, f, omega, earth=None):  # type: ignore[no-untyped-def]
        """The specific force f (gravity's direction follows the table attitude)."""
        return _as_n3(f, "f")[:, None, :]

    def gravity_shape(self, f, omega, g):  # type: ignore[no-untyped-def]
        """f_true = f_rep (1 + δg/g): ∂f/∂g = f/g."""
        return (_as_n3(f, "f") / g)[:, :, None]


ACCELEROMETER: AccelerometerModel = register(AccelerometerModel())  # type: ignore[assignment]
"""The registered accelerometer model (``get_model("accelerometer")``)."""
