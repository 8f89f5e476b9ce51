"""Three-axis table gimbal kinematics (pure maths, vectorised over samples).

Gimbal angles (outer ψ about n-Up, middle θ about the outer-gimbal x, inner γ about the middle-gimbal y),
rad. The inner-gimbal frame t relates to the ENU navigation frame n by

    C_t^n = R_z(ψ) R_x(θ) R_y(γ)        (scipy ``Rotation.from_euler('ZXY', [ψ, θ, γ])``)

and the unit's body frame b by the bench mounting: C_b^n = C_t^n C_b^t.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

ENU_DIRECTIONS: dict[str, tuple[int, int, int]] = {
    "East": (1, 0, 0),
    "West": (-1, 0, 0),
    "North": (0, 1, 0),
    "South": (0, -1, 0),
    "Up": (0, 0, 1),
    "Down": (0, 0, -1),
}
"""The direction words of procedure files and summaries → unit vectors in the ENU navigation frame n."""


def direction_word(v: ArrayLike) -> str:
    """A unit vector in n (ENU) in words: ``"East"`` …, or its components like ``"(E +0.71, U -0.71)"``."""
    a = np.asarray(v, dtype=float)
    for word, d in ENU_DIRECTIONS.items():
        if np.allclose(a, d, atol=1e-6):
            return word
    parts = [f"{lab} {c:+.2f}" for lab, c in zip("ENU", a, strict=True) if abs(c) > 5e-3]
    return "(" + ", ".join(parts) + ")"


def _rotation(a: NDArray[np.float64], axis: int) -> NDArray[np.float64]:
    """Elementary rotations (..., 3, 3) about body axis ``axis`` (0 x, 1 y, 2 z) by angles ``a``, rad.

    Filled in place (not stacked from rows: stacking three levels of small arrays cost 20× the arithmetic
    for the simulator's 200-sample blocks); the same entries, so the same products bit for bit."""
    c, s = np.cos(a), np.sin(a)
    m = np.zeros(np.shape(a) + (3, 3))
    i, j = [k for k in range(3) if k != axis]
    m[..., axis, axis] = 1.0
    m[..., i, i] = c
    m[..., j, j] = c
    if axis == 1:  # R_y: [c 0 s; 0 1 0; −s 0 c]
        m[..., i, j] = s
        m[..., j, i] = -s
    else:  # R_x: [1 0 0; 0 c −s; 0 s c], R_z: [c −s 0; s c 0; 0 0 1]
        m[..., i, j] = -s
        m[..., j, i] = s
    return m


def _rz(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return _rotation(a, 2)


def _rx(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return _rotation(a, 0)


def _ry(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return _rotation(a, 1)


Trig = tuple[NDArray[np.float64], ...]
"""cos ψ, sin ψ, cos θ, sin θ, cos γ, sin γ of gimbal angles (..., 3): :func:`angle_trig`."""


def angle_trig(angles: ArrayLike) -> Trig:
    """The gimbal angles' cosines and sines (cos ψ, sin ψ, cos θ, sin θ, cos γ, sin γ), each of shape (...,),
    for the ``trig`` argument of :func:`nav_to_body`, :func:`table_rate`, :func:`body_rate` and
    :func:`gravity_in_body` (one reference computes them once instead of in each; the same values bit for bit)."""
    a = np.asarray(angles, dtype=float)
    return tuple(f(a[..., k]) for k in range(3) for f in (np.cos, np.sin))


def table_to_nav(angles: ArrayLike) -> NDArray[np.float64]:
    """C_t^n for gimbal angles (..., 3) = (ψ, θ, γ), rad; returns (..., 3, 3)."""
    a = np.asarray(angles, dtype=float)
    return _rz(a[..., 0]) @ _rx(a[..., 1]) @ _ry(a[..., 2])


def body_to_nav(angles: ArrayLike, mounting: ArrayLike | None = None) -> NDArray[np.float64]:
    """C_b^n = C_t^n C_b^t for gimbal angles (..., 3), rad, and mounting C_b^t (3, 3) (identity if None)."""
    c = table_to_nav(angles)
    return c if mounting is None else c @ np.asarray(mounting, dtype=float)


def nav_to_body(
    angles: ArrayLike, v: ArrayLike, mounting: ArrayLike | None = None, *, trig: Trig | None = None
) -> NDArray[np.float64]:
    """A navigation-frame (ENU) vector ``v`` (3,) in the body frame b at gimbal angles (..., 3), rad: C_n^b v.

    C_n^b v = C_t^b R_y(γ)ᵀ R_x(θ)ᵀ R_z(ψ)ᵀ v, the three rotations applied to the vector one after the other
    (elementwise over samples: a third of the time of forming C_b^n (n, 3, 3) by :func:`body_to_nav` and
    multiplying; the same vector to rounding, ≤ 1e-15 relative). Returns shape (..., 3). ``trig``: the angles'
    :func:`angle_trig`, when the caller has them.
    """
    a = np.asarray(angles, dtype=float)
    vx, vy, vz = (float(c) for c in np.asarray(v, dtype=float).reshape(3))
    cp, sp, ct, st, cg, sg = angle_trig(a) if trig is None else trig
    # the products of x, y = cp·vx + sp·vy, cp·vy − sp·vx (R_z(ψ)ᵀ); y, z = ct·y + st·vz, ct·vz − st·y (R_x(θ)ᵀ);
    # out = [cg·x − sg·z, y, sg·x + cg·z] (R_y(γ)ᵀ), each written into two scratch arrays and the result's
    # columns instead of a new array per product (the same operations: the same values, less memory traffic)
    out = np.empty(a.shape)
    shape = a.shape[:-1]
    x, p, q = (np.multiply(c, w, out=np.empty(shape)) for c, w in ((cp, vx), (sp, vy), (cp, vy)))
    np.add(x, p, out=x)  # x
    np.multiply(sp, vx, out=p)
    np.subtract(q, p, out=q)  # y (R_z(ψ)ᵀ)
    y = out[..., 1]
    np.multiply(ct, q, out=y)
    np.multiply(st, vz, out=p)
    np.add(y, p, out=y)  # y (R_x(θ)ᵀ)
    z = np.multiply(ct, vz, out=np.empty(shape))
    np.multiply(st, q, out=p)
    np.subtract(z, p, out=z)  # z
    np.multiply(cg, x, out=p)
    np.multiply(sg, z, out=q)
    np.subtract(p, q, out=out[..., 0])
    np.multiply(sg, x, out=p)
    np.multiply(cg, z, out=q)
    np.add(p, q, out=out[..., 2])
    if mounting is None:
        return out
    return out @ np.asarray(mounting, dtype=float)  # (C_b^t)ᵀ v^t, row-vector form


def table_rate(angles: ArrayLike, rates: ArrayLike, *, trig: Trig | None = None) -> NDArray[np.float64]:
    """Angular rate of the inner gimbal relative to the ground, in the inner-gimbal frame t, rad/s.

    ω^t = R_y(γ)ᵀ [R_x(θ)ᵀ (ψ̇ e_z) + θ̇ e_x] + γ̇ e_y, for angles and gimbal rates of shape (..., 3).
    (Earth rotation is not included: add C_n^t Ω^n for what a gyro senses.) ``trig``: the angles'
    :func:`angle_trig`, when the caller has them.
    """
    a = np.asarray(angles, dtype=float)
    r = np.asarray(rates, dtype=float)
    th, ga = a[..., 1], a[..., 2]
    psid, thd, gad = r[..., 0], r[..., 1], r[..., 2]
    # R_x(θ)ᵀ ψ̇ e_z = ψ̇ [0, sin θ, cos θ]
    sin_th, cos_th = (np.sin(th), np.cos(th)) if trig is None else (trig[3], trig[2])
    # R_y(γ)ᵀ v = [c v_x − s v_z, v_y, s v_x + c v_z], v = (θ̇, ψ̇ sin θ, ψ̇ cos θ); each product written into
    # scratch arrays and the result's columns (the same operations, the same values, less memory traffic)
    c, s = (np.cos(ga), np.sin(ga)) if trig is None else (trig[4], trig[5])
    out = np.empty(np.broadcast_shapes(a.shape, r.shape))
    shape = out.shape[:-1]
    v1z = np.multiply(psid, cos_th, out=np.empty(shape))
    p, q = np.multiply(c, thd, out=np.empty(shape)), np.multiply(s, v1z, out=np.empty(shape))
    np.subtract(p, q, out=out[..., 0])
    np.multiply(psid, sin_th, out=p)
    np.add(p, gad, out=out[..., 1])
    np.multiply(s, thd, out=p)
    np.multiply(c, v1z, out=q)
    np.add(p, q, out=out[..., 2])
    return out


def body_rate(
    angles: ArrayLike, rates: ArrayLike, mounting: ArrayLike | None = None, *, trig: Trig | None = None
) -> NDArray[np.float64]:
    """Angular rate of the unit relative to the ground in its body frame b, rad/s: ω^b = C_t^b ω^t
    (``trig``: the angles' :func:`angle_trig`, when the caller has them)."""
    w = table_rate(angles, rates, trig=trig)
    if mounting is None:
        return w
    return w @ np.asarray(mounting, dtype=float)  # (C_b^t)ᵀ ω^t, row-vector form


def gravity_in_body(
    angles: ArrayLike, g: float, mounting: ArrayLike | None = None, *, trig: Trig | None = None
) -> NDArray[np.float64]:
    """Specific force of gravity at rest in the body frame, m/s²: C_n^b [0, 0, g]ᵀ, shape (..., 3).

    Only the third row of C_b^n is needed: e_zᵀ R_z(ψ) R_x(θ) R_y(γ) = [−cos θ sin γ, sin θ, cos θ cos γ]
    (heading does not move the vertical), then times the mounting C_b^t. ``trig``: the angles'
    :func:`angle_trig`, when the caller has them.
    """
    a = np.asarray(angles, dtype=float)
    th, ga = a[..., 1], a[..., 2]
    if trig is None:
        cos_th, sin_th, cos_ga, sin_ga = np.cos(th), np.sin(th), np.cos(ga), np.sin(ga)
    else:
        cos_th, sin_th, cos_ga, sin_ga = trig[2], trig[3], trig[4], trig[5]
    row = np.empty(a.shape)
    np.negative(cos_th, out=row[..., 0])  # (−cos θ) sin γ, in the result's column (no array per product)
    np.multiply(row[..., 0], sin_ga, out=row[..., 0])
    row[..., 1] = sin_th
    np.multiply(cos_th, cos_ga, out=row[..., 2])
    if mounting is not None:
        row = row @ np.asarray(mounting, dtype=float)
    return np.multiply(g, row, out=row)


def euler_from_body_to_nav(c_bn: ArrayLike, mounting: ArrayLike | None = None) -> NDArray[np.float64]:
    """Gimbal angles (ψ, θ, γ), rad, that realise body attitude C_b^n with mounting C_b^t (ZXY Euler).

    Returns the solution with θ in [−π/2, π/2]; at gimbal lock (|θ| = π/2) γ is set to 0.
    """
    c = np.asarray(c_bn, dtype=float)
    if mounting is not None:
        c = c @ np.asarray(mounting, dtype=float).T  # C_t^n = C_b^n C_t^b
    # C = Rz(ψ) Rx(θ) Ry(γ): C[2,1] = sin θ; C[0,1] = −sin ψ cos θ; C[1,1] = cos ψ cos θ;
    # C[2,0] = −cos θ sin γ; C[2,2] = cos θ cos γ
    th = np.arcsin(np.clip(c[..., 2, 1], -1.0, 1.0))
    cth = np.cos(th)
    lock = np.abs(cth) < 1e-9
    psi = np.where(lock, np.arctan2(c[..., 1, 0], c[..., 0, 0]), np.arctan2(-c[..., 0, 1], c[..., 1, 1]))
    ga = np.where(lock, 0.0, np.arctan2(-c[..., 2, 0], c[..., 2, 2]))
    return np.stack([psi, th, ga], -1)
