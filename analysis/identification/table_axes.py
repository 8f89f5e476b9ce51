"""Type-B input of the budget: the table's axis non-orthogonality (GUM; pure maths).

A real three-axis table's gimbal axes are not exactly perpendicular. With the gimbal chain of the project
(``docs/methods/simulation.md``, ``analysis.gimbal``) the two angles that matter are

    C_t^n = R_z(ψ) E1 R_x(θ) E2 R_y(γ),  E1 = R_y(ε₁) (middle axis tilted about the outer frame's y),
    E2 = R_z(ε₂) (inner axis tilted about the middle frame's z);

the outer axis's own tilt from the vertical is a levelling (attitude) error and the rotations about the
axes themselves are encoder zeros, both in the per-step attitude input. The reported reference assumes
ε₁ = ε₂ = 0, so the true reference differs, for both triads, by

* accelerometers: f_true − f_rep = g (C_n^b,true − C_n^b,rep) e_Up (the holds' gravity turned);
* gyros: ω_ib,true − ω_ib,rep = (ω^b,true − ω^b,rep) + (C_n^b,true − C_n^b,rep) Ω^n: during a spin of the
  outer or middle gimbal its axis is tilted in the body frame by about |ω| ε (T_g against the table frame),
  and the Earth rate turns with the attitude. A spin of the inner gimbal is about the body's own mounting
  axis and sees neither angle.

The error shapes are the exact first-order derivatives (central differences of the chain above at
ε = 0, step 1e-6 rad: the linearisation error is ~1e-12 relative). One input for the run with two
components, each ε uniform within ± the bound (rectangular, u = a/√3, GUM 4.3.7). The centripetal size
effect's change with the tilted rate (r ω² ε, < 1e-7 m/s² at 60 °/s) is neglected. Frames: n = ENU,
b = body, t = inner gimbal.

A second input of the same chain (:func:`held_angle_input`, type A, per spin): the gimbals held in position
during a spin are referenced by their readings, whose mean over the spin is off by δ_j (u_j = the readings'
scatter over √count). The shape is the exact first-order derivative of the same references with respect to
the gimbal angle j; for the inner gimbal during a middle-axis spin it turns the spin axis in the body frame
(|ω| δ in the cross axes, T_g), which the per-step attitude input (a rotation of the whole table) does not.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from analysis import gimbal
from analysis.identification.budget import BudgetInput, StepGeometry
from analysis.identification.specification import ModelSpec
from analysis.units import ARCSEC

_STEP = 1e-6
"""Half step of the central difference, rad."""


Rotations = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
"""R_z(ψ), R_x(θ), R_y(γ) of gimbal angles (m, 3), each (m, 3, 3)."""


def _rotations(angles: NDArray[np.float64]) -> Rotations:
    a = np.asarray(angles, dtype=float)
    return gimbal._rz(a[:, 0]), gimbal._rx(a[:, 1]), gimbal._ry(a[:, 2])


@functools.lru_cache(maxsize=64)
def _tilt(axis: int, angle_hex: str) -> NDArray[np.float64]:
    """The elementary rotation (3, 3) about ``axis`` (1 y, 2 z) by the angle whose ``float.hex`` is ``angle_hex``
    (cached on that exact value, −0.0 apart from 0.0; read-only): the chain's tilt matrices E1, E2, of which one
    budget uses five values."""
    m = (gimbal._ry if axis == 1 else gimbal._rz)(np.array(float.fromhex(angle_hex)))
    m.flags.writeable = False
    return m


def _chain(
    rot: Rotations, rates: NDArray[np.float64], e1: float, e2: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`tilted_chain` from the gimbals' elementary rotations (the same products in the same order)."""
    rz, rx, ry = rot
    r = np.asarray(rates, dtype=float)
    e_1 = _tilt(1, float(e1).hex())
    e_2 = _tilt(2, float(e2).hex())
    inner = e_2 @ ry  # C_t^m
    mid = e_1 @ rx @ inner  # C_t^o
    c_tn = rz @ mid
    omega_t = (
        r[:, 0:1] * mid[:, 2, :]  # ψ̇ (C_t^o)ᵀ e_z
        + r[:, 1:2] * inner[:, 0, :]  # θ̇ (C_t^m)ᵀ e_x
        + r[:, 2:3] * np.array([0.0, 1.0, 0.0])
    )
    return c_tn, omega_t


def tilted_chain(
    angles: NDArray[np.float64], rates: NDArray[np.float64], e1: float, e2: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """C_t^n (m, 3, 3) and ω^t (m, 3) (rad/s, inner-gimbal frame, relative to the ground) of a table whose
    middle axis is tilted by ``e1`` (about the outer frame's y) and inner axis by ``e2`` (about the middle
    frame's z), rad, at gimbal angles and rates (m, 3)."""
    return _chain(_rotations(angles), rates, e1, e2)


class _StepChain:
    """What every reference of one step shares, formed once per shape evaluation of that step: the reported
    angles' elementary rotations, the mounting C_b^t (from the untilted chain and the reported C_b^n) and the
    Earth rate in n. Kept only for the duration of one :func:`orthogonality_shape` / :func:`held_angle_shape`
    call (nothing outlives it, so nothing can be reused for another step or mounting)."""

    def __init__(self, geo: StepGeometry) -> None:
        assert geo.angles is not None and geo.rates is not None and geo.c_bn is not None
        self.angles = np.asarray(geo.angles, dtype=float)
        self.rates = geo.rates
        self.rot = _rotations(self.angles)
        c_tn0, _ = _chain(self.rot, geo.rates, 0.0, 0.0)
        c_bn = np.asarray(geo.c_bn, dtype=float)
        self.mount = np.transpose(c_tn0, (0, 2, 1)) @ c_bn  # C_b^t (the same at every point)
        self.earth_n = None if geo.earth is None else np.einsum("nij,nj->ni", c_bn, geo.earth)  # C_b^n Ω^b

    def rotations_at(self, angles: NDArray[np.float64]) -> Rotations:
        """Elementary rotations of other angles (m, 3), reusing each gimbal's whose angles are the same bits."""
        a = np.asarray(angles, dtype=float)
        out = []
        for j, (base, fn) in enumerate(zip(self.rot, (gimbal._rz, gimbal._rx, gimbal._ry), strict=True)):
            same = a[:, j].tobytes() == self.angles[:, j].tobytes()
            out.append(base if same else fn(a[:, j]))
        return out[0], out[1], out[2]

    def references(
        self, e1: float, e2: float, g: float, rot: Rotations | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(f, ω_ib) in the body frame on a table with tilts e1, e2 (and, when given, the rotations ``rot`` of
        other gimbal angles instead of the reported ones)."""
        c_tn, omega_t = _chain(self.rot if rot is None else rot, self.rates, e1, e2)
        c_bn = c_tn @ self.mount
        f = g * c_bn[:, 2, :]
        omega = np.einsum("ni,nij->nj", omega_t, self.mount)
        if self.earth_n is not None:
            omega = omega + np.einsum("ni,nij->nj", self.earth_n, c_bn)
        return f, omega


def orthogonality_shape(geo: StepGeometry, model: ModelSpec, g: float) -> NDArray[np.float64] | None:
    """e_k per unit (ε₁, ε₂) for the model's measurement axes, (m, n_axes, 2); None without gimbal angles.

    The step's untilted chain (rotations, mounting) is formed once for the four differences (:class:`_StepChain`)."""
    if geo.angles is None or geo.rates is None or geo.c_bn is None:
        return None
    ch = _StepChain(geo)
    cols = []
    for k in range(2):
        d = np.zeros(2)
        d[k] = _STEP
        fp, wp = ch.references(d[0], d[1], g)
        fm, wm = ch.references(-d[0], -d[1], g)
        cols.append(_both_triads(model, (fp - fm) / (2 * _STEP), (wp - wm) / (2 * _STEP)))
    return np.stack(cols, axis=2)


def orthogonality_input(model: ModelSpec, bound: float, g: float, source: str) -> list[BudgetInput]:
    """The table's axis non-orthogonality (ε₁, ε₂), each uniform within ±``bound`` rad, one for the run."""
    if bound <= 0:
        return []
    u = bound / np.sqrt(3.0)
    return [
        BudgetInput(
            "axis_orthogonality", "Table axis orthogonality",
            f"±{bound / ARCSEC:.3g}″ for each of the middle and inner axes ({source}), rectangular, "
            f"u = {u / ARCSEC:.3g}″, one for the run",
            np.eye(2) * u**2, lambda geo: orthogonality_shape(geo, model, g),
        )
    ]  # fmt: skip


def _both_triads(model: ModelSpec, df: NDArray[np.float64], dw: NDArray[np.float64]) -> NDArray[np.float64]:
    """The model's measurement axes (m, n_axes) of a reference change: ``df`` (specific force) for each accelerometer
    part, ``dw`` (body rate) for each gyro part, zeros for any other."""
    rows = [df if p.output == "accel" else dw if p.output == "gyro" else np.zeros_like(df) for p in model.parts]
    return np.concatenate(rows, axis=1)


def held_angle_shape(geo: StepGeometry, model: ModelSpec, g: float) -> NDArray[np.float64] | None:
    """e_k per unit input (m, n_axes, 3) of the held gimbals' mean angle-reading errors during a spin: column j is
    the reference's derivative with respect to gimbal angle j times u_j (``geo.held_angle_u``); None for a hold or
    without gimbal angles."""
    if geo.held_angle_u is None or geo.angles is None or geo.rates is None or geo.c_bn is None:
        return None
    u = np.asarray(geo.held_angle_u, dtype=float)
    ch = _StepChain(geo)
    cols = []
    for j in range(3):
        if not u[j] > 0:
            cols.append(np.zeros((geo.angles.shape[0], model.n_axes)))
            continue
        d = np.zeros(3)
        d[j] = _STEP
        fp, wp = ch.references(0.0, 0.0, g, ch.rotations_at(geo.angles + d))
        fm, wm = ch.references(0.0, 0.0, g, ch.rotations_at(geo.angles - d))
        cols.append(_both_triads(model, (fp - fm) / (2 * _STEP), (wp - wm) / (2 * _STEP)) * u[j])
    return np.stack(cols, axis=2)


def held_angle_input(model: ModelSpec, g: float) -> list[BudgetInput]:
    """The held gimbals' angle readings during spins (type A, per step): each spin's reference takes the held
    axes' angles from their readings, whose noise averages to u_j = s_j/√N over the N readings of the spin (s_j
    their scatter, ``StepGeometry.held_angle_u``); an error δ_j of that mean turns the spin axis in the body frame
    by δ_j, so the cross axes' gyro reference is off by |ω| δ_j (T_g) and gravity turns (both triads)."""
    return [
        BudgetInput(
            "held_angles", "Table angle readings of the held axes during spins",
            "the held gimbals' reading scatter during each spin over √(number of readings), per spin and axis",
            np.eye(3), lambda geo: held_angle_shape(geo, model, g), per_step=True, type="A",
        )
    ]  # fmt: skip


__all__ = ["held_angle_input", "held_angle_shape", "orthogonality_input", "orthogonality_shape", "tilted_chain"]
