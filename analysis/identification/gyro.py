"""Gyro-triad error model for rate-table calibration (a :class:`~.specification.ModelSpec`, pure maths).

Model (per sample, **body frame b**, SI; ``docs/methods/gyro-calibration.md``, IEEE Std 952 / 1431 where
the project's method notes are silent)::

    ω_out = (I + S_g + T_g) ω_ib + b_g + G f + S2 (ω_ib ∘ ω_ib) + A |ω_ib| + v_g

* ``ω_ib`` (rad/s): the reference angular rate relative to inertial space = the table's body rate from the
  gimbal readings (``omega``) + the Earth rate in the body frame (``earth`` = C_n^b Ω [0, cos φ, sin φ]).
* ``S_g = diag(S_x, S_y, S_z)``: scale-factor errors (dimensionless; certificates ppm).
* ``T_g``: misalignment, off-diagonal, **δω_i += τ_ij ω_j** — the accelerometer's convention, so the two
  triads' misalignments compare term by term.
* ``b_g`` (rad/s; certificates °/h): bias.
* ``G`` (rad/s per m/s²; certificates °/h/g): g-sensitivity; 3 diagonal terms by default (δω_i += G_ii f_i),
  the full 9 on request (δω_i += G_ij f_j), f the specific force at the reference point.
* ``S2`` (s/rad; certificates ppm/(°/s)) and ``A`` (dimensionless; certificates ppm), optional, for
  rate-transfer runs: quadratic scale (δω_i += S2_i ω_i²) and scale asymmetry (δω_i += A_i |ω_i|: the
  scale factor is 1 + S + A for positive and 1 + S − A for negative rates about axis i).
* ``v_g``: angle random walk plus bias instability (the noise analysis measures them).

Measurement for identification: z = ω_out − ω_ib = H x + v. Axis i depends only on its own parameters
``[b_i, S_i, τ_ij, τ_ik, G_ii (G_ij, G_ik), S2_i, A_i]`` with regressors ``[1, ω_i, ω_j, ω_k, f_i (f_j, f_k),
ω_i², |ω_i|]`` taken from the base regressors ``[1, ω_x, ω_y, ω_z, f_x, f_y, f_z (, ω², |ω|)]``.

Parameter names (calibration.json, certificate.json, the simulator's ``/truth``): ``gyro_b_x …``,
``gyro_S_x …``, ``gyro_tau_xy gyro_tau_xz gyro_tau_yx gyro_tau_yz gyro_tau_zx gyro_tau_zy``,
``gyro_G_xx gyro_G_yy gyro_G_zz`` (full: then ``gyro_G_xy gyro_G_xz gyro_G_yx gyro_G_yz gyro_G_zx gyro_G_zy``),
and when enabled ``gyro_S2_x …``, ``gyro_A_x …``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.identification.specification import ModelSpec, as_n3, register
from analysis.units import G0

AXES = "xyz"
_OTHERS = ((1, 2), (0, 2), (0, 1))
OMEGA_REF: float = 1.0
"""Reference rate (rad/s) of the per-kind parameter scaling (effect of 1 rad/s at |ω| = 1 rad/s, |f| = 1 g)."""


class GyroModel(ModelSpec):
    """The gyro-triad model (module docstring); build variants with :func:`build`.

    Parameters
    ----------
    full_g : bool
        Identify the full 3 × 3 g-sensitivity matrix (9 terms) instead of its diagonal (3).
    quadratic : bool
        Add the quadratic scale terms S2 (rate-transfer runs).
    asymmetry : bool
        Add the scale-asymmetry terms A (rate-transfer runs).
    """

    output = "gyro"
    si_units = {
        "gyro_bias": "rad/s",
        "gyro_scale": "1",
        "gyro_misalignment": "rad",
        "g_sensitivity": "rad/s/(m/s^2)",
        "gyro_quadratic": "s/rad",
        "gyro_asymmetry": "1",
    }
    kind_labels = {
        "gyro_bias": "gyro bias",
        "gyro_scale": "gyro scale factor",
        "gyro_misalignment": "gyro misalignment",
        "g_sensitivity": "gyro g-sensitivity",
        "gyro_quadratic": "gyro quadratic scale",
        "gyro_asymmetry": "gyro scale asymmetry",
    }
    unobservable_fix = {
        "gyro_bias": "add static holds (the bias is the hold mean less Earth rate)",
        "gyro_scale": "add constant-rate spins about each body axis, over whole revolutions, in both directions",
        "gyro_misalignment": "add constant-rate spins about each body axis, over whole revolutions, in both directions",
        "g_sensitivity": "add static holds that put +g and −g (and 45° tilts) on each body axis",
        "gyro_quadratic": "add spins at several rates up to the bench limit (the gyro-rate-transfer procedure)",
        "gyro_asymmetry": "add spins in both directions at the same rates (the gyro-rate-transfer procedure)",
    }
    rate_power = {"gyro_scale": 1, "gyro_misalignment": 1}
    default_fix = "the motion does not excite it"
    bias_kind = "gyro_bias"

    def __init__(self, *, full_g: bool = False, quadratic: bool = False, asymmetry: bool = False) -> None:
        self.full_g, self.quadratic, self.asymmetry = bool(full_g), bool(quadratic), bool(asymmetry)
        self.name = "gyro"
        names = [f"gyro_b_{a}" for a in AXES] + [f"gyro_S_{a}" for a in AXES]
        names += [f"gyro_tau_{AXES[i]}{AXES[j]}" for i in range(3) for j in _OTHERS[i]]
        names += [f"gyro_G_{a}{a}" for a in AXES]
        kinds = ["gyro_bias"] * 3 + ["gyro_scale"] * 3 + ["gyro_misalignment"] * 6 + ["g_sensitivity"] * 3
        scale = [1.0] * 3 + [1.0 / OMEGA_REF] * 9 + [1.0 / G0] * 3
        axp = [[i, 3 + i, 6 + 2 * i, 7 + 2 * i, 12 + i] for i in range(3)]
        axb = [[0, 1 + i, 1 + _OTHERS[i][0], 1 + _OTHERS[i][1], 4 + i] for i in range(3)]
        nb = 7
        if full_g:
            off = len(names)
            names += [f"gyro_G_{AXES[i]}{AXES[j]}" for i in range(3) for j in _OTHERS[i]]
            kinds += ["g_sensitivity"] * 6
            scale += [1.0 / G0] * 6
            for i in range(3):
                axp[i] += [off + 2 * i, off + 2 * i + 1]
                axb[i] += [4 + _OTHERS[i][0], 4 + _OTHERS[i][1]]
        for flag, tag, kind, sc in (
            (quadratic, "S2", "gyro_quadratic", 1.0 / OMEGA_REF**2),
            (asymmetry, "A", "gyro_asymmetry", 1.0 / OMEGA_REF),
        ):
            if flag:
                off = len(names)
                names += [f"gyro_{tag}_{a}" for a in AXES]
                kinds += [kind] * 3
                scale += [sc] * 3
                for i in range(3):
                    axp[i].append(off + i)
                    axb[i].append(nb + i)
                nb += 3
        self.names = tuple(names)
        self.kinds = tuple(kinds)
        self.reference_scale = np.array(scale)
        self.axis_params = tuple(tuple(a) for a in axp)
        self.axis_base = tuple(tuple(b) for b in axb)
        self.n_base = nb
        terms = ["(I + S_g + T_g) ω_ib", "b_g", "G f" + (" (full 3×3)" if full_g else " (diagonal)")]
        terms += ["S2 (ω_ib∘ω_ib)"] * quadratic + ["A |ω_ib|"] * asymmetry
        self.equation = (
            "ω_out = " + " + ".join(terms) + ", body frame; ω_ib = table rate from the gimbal readings + Earth rate; "
            "misalignment convention δω_i += τ_ij ω_j"
        )

    # ---- regressors ------------------------------------------------------------------------------------------
    def fill_base(self, out, f, omega, earth) -> None:  # type: ignore[no-untyped-def]
        """[1, ω_x, ω_y, ω_z, f_x, f_y, f_z (, ω_x², ω_y², ω_z²) (, |ω_x|, |ω_y|, |ω_z|)], ω = ω_ib."""
        out[:, 0] = 1.0
        c = 7
        for k in range(3):  # column by column (an (n, 3) operation into the wide block loops three values at a time)
            w = out[:, 1 + k]
            if earth is None:
                w[:] = omega[:, k]
            else:
                np.add(omega[:, k], earth[:, k], out=w)
            out[:, 4 + k] = f[:, k]
            if self.quadratic:
                np.multiply(w, w, out=out[:, c + k])
            if self.asymmetry:
                np.abs(w, out=out[:, c + 3 * self.quadratic + k])

    def ideal(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        """An error-free gyro reads ω_ib = table body rate + Earth rate (body frame, rad/s)."""
        om = as_n3(omega, "omega")
        return om.copy() if earth is None else om + as_n3(earth, "earth", om.shape[0])

    def fill_measurement(self, out, y, f, omega, earth, base) -> None:  # type: ignore[no-untyped-def]
        """z = y − ω_ib, column by column, ω_ib from the regressors (:meth:`fill_base` formed it as :meth:`ideal`)."""
        for k in range(3):
            np.subtract(y[:, k], base[:, 1 + k], out=out[:, k])

    # ---- the model's matrices --------------------------------------------------------------------------------
    def error_matrices(self, x: ArrayLike) -> dict[str, NDArray[np.float64]]:
        """M = I + S_g + T_g (T[i, j] = τ_ij), b_g, G (3 × 3), S2 (3,), A (3,) from a state vector."""
        xs = self.as_state(x)
        m = np.eye(3)
        g = np.zeros((3, 3))
        b = np.zeros(3)
        s2 = np.zeros(3)
        a = np.zeros(3)
        for i in range(3):
            p = self.axis_params[i]
            b[i] = xs[p[0]]
            m[i, i] += xs[p[1]]
            m[i, _OTHERS[i][0]] = xs[p[2]]
            m[i, _OTHERS[i][1]] = xs[p[3]]
            g[i, i] = xs[p[4]]
            k = 5
            if self.full_g:
                g[i, _OTHERS[i][0]], g[i, _OTHERS[i][1]] = xs[p[5]], xs[p[6]]
                k = 7
            if self.quadratic:
                s2[i] = xs[p[k]]
                k += 1
            if self.asymmetry:
                a[i] = xs[p[k]]
        return {"M": m, "b": b, "G": g, "S2": s2, "A": a}

    def predict(
        self, x: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Gyro output (n, 3), rad/s, body frame, for the reference (f, table rate, Earth rate)."""
        e = self.error_matrices(x)
        w = self.ideal(f, omega, earth)
        ff = as_n3(f, "f", w.shape[0])
        return w @ e["M"].T + e["b"] + ff @ e["G"].T + e["S2"] * w * w + e["A"] * np.abs(w)

    def correct(
        self,
        x: ArrayLike,
        y: ArrayLike,
        f: ArrayLike,
        omega: ArrayLike | None = None,
        earth: ArrayLike | None = None,
        *,
        max_iter: int = 30,
    ) -> NDArray[np.float64]:
        """The exact inverse: ω_ib (n, 3), rad/s, whose modelled output is y, given the specific force f.

        Solves ``(I + S_g + T_g) ω + S2∘ω² + A∘|ω| = y − b_g − G f`` per sample: the linear solution when
        S2 = A = 0, otherwise Newton's iteration with the exact Jacobian (sign(ω) for |ω|), vectorised,
        until the step is at the rounding level. ``omega``/``earth`` are not used (the output is inverted).
        """
        e = self.error_matrices(x)
        yy = as_n3(y, "gyro output")
        ff = as_n3(f, "f", yy.shape[0])
        rhs = yy - e["b"] - ff @ e["G"].T
        w = rhs @ np.linalg.inv(e["M"]).T
        if not (np.any(e["S2"]) or np.any(e["A"])):
            return w
        eps = np.finfo(float).eps
        for _ in range(max_iter):
            g = w @ e["M"].T + e["S2"] * w * w + e["A"] * np.abs(w) - rhs
            jac = np.broadcast_to(e["M"], (w.shape[0], 3, 3)).copy()
            jac[:, [0, 1, 2], [0, 1, 2]] += 2.0 * e["S2"] * w + e["A"] * np.sign(w)
            step = np.linalg.solve(jac, g[..., None])[..., 0]
            w = w - step
            if np.all(np.abs(step) <= 4.0 * eps * np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-300)):
                return w
        raise ValueError("gyro correct(): Newton iteration did not converge; check the S2/A units (s/rad, 1)")

    # ---- budget shapes ---------------------------------------------------------------------------------------
    def attitude_vectors(self, f, omega, earth=None):  # type: ignore[no-untyped-def]
        """The Earth rate in the body frame turns with the table attitude (the table rate does not)."""
        ff = as_n3(f, "f")
        ea = np.zeros_like(ff) if earth is None else as_n3(earth, "earth", ff.shape[0])
        return ea[:, None, :]


def build(*, full_g: bool = False, quadratic: bool = False, asymmetry: bool = False) -> GyroModel:
    """A gyro model variant (full G and/or the rate-transfer terms S2, A)."""
    return GyroModel(full_g=full_g, quadratic=quadratic, asymmetry=asymmetry)


def model_for_names(names: Sequence[str]) -> GyroModel:
    """The gyro variant whose state names are ``names`` (in order)."""
    for full_g in (False, True):
        for quadratic in (False, True):
            for asymmetry in (False, True):
                m = build(full_g=full_g, quadratic=quadratic, asymmetry=asymmetry)
                if m.names == tuple(names):
                    return m
    raise ValueError(f"no gyro model variant has the states {', '.join(names)}")


GYRO: GyroModel = register(GyroModel())  # type: ignore[assignment]
"""The registered default gyro model (diagonal G, no S2/A)."""

__all__ = ["GYRO", "GyroModel", "build", "model_for_names"]
