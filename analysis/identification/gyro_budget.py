"""Type-B inputs of the gyro triad's uncertainty budget (GUM), as :class:`~.budget.BudgetInput` s.

The gyro reference is ω_ib = ω_table + C_n^b Ω^n (``docs/methods/gyro-calibration.md``). Besides the
inputs every model shares (table attitude per step — which turns the Earth rate in the body frame —, local
g, the identification's own covariance and the model mismatch, :mod:`.budget`), the gyro's reference
depends on

* **table azimuth alignment** δψ (one for the run): the outer gimbal's zero is off East by δψ, a rotation
  about the local vertical that turns Ω^n's horizontal part: e_k = [ω_e×] C_n^b e_Up δψ (the accelerometer
  is blind to it: f is vertical). Mainly b_g of the horizontal axes (Ω cos φ δψ).
* **latitude** δφ (one): Ω^n = Ω [0, cos φ, sin φ] moves by Ω [0, −sin φ, cos φ] δφ: e_k = C_n^b that.
* **time base**, when the identification inputs carry an estimate (the time-base analysis): a unit clock
  off by a relative ε scales every gyro output by 1 + ε (e_k = ω_ib,k per unit ε: S_g 1:1), and a residual
  offset δt turns the reference during a spin by ω δt (gyro rows: the Earth rate turned, [Ω_b×] ω δt; the
  accelerometer rows are the time-base analysis's own, already in the identification's covariance).
The table's axis non-orthogonality tilts the spin axes of the outer and middle gimbals in the body frame and
turns the holds' attitude for both triads: :mod:`analysis.identification.table_axes`.

Each returns the error shape per step for the model's measurement axes; the rows of other triads are 0.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from analysis.earth import EARTH_RATE
from analysis.identification.budget import AttitudeShape, BudgetInput, DerivedShape, StepGeometry
from analysis.identification.specification import ModelSpec
from analysis.units import ARCSEC, PPM


def _gyro_axes(model: ModelSpec) -> slice | None:
    """The measurement-axis slice of the model's gyro triad (None: the model has no gyro)."""
    off = 0
    for p in model.parts:
        if p.output == "gyro":
            return slice(off, off + p.n_axes)
        off += p.n_axes
    return None


def _place(model: ModelSpec, rows: slice, e: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.zeros((e.shape[0], model.n_axes, e.shape[2]))
    out[:, rows, :] = e
    return out


def earth_rate_inputs(
    model: ModelSpec, latitude: float, u_azimuth: float, u_latitude: float, azimuth_source: str = "bench file"
) -> list[BudgetInput]:
    """Azimuth alignment and latitude inputs (standard uncertainties in rad) for a model with a gyro triad."""
    g = _gyro_axes(model)
    if g is None:
        return []
    up = np.array([0.0, 0.0, 1.0])
    d_omega = EARTH_RATE * np.array([0.0, -math.sin(latitude), math.cos(latitude)])

    def azimuth(attitude: NDArray[np.float64]) -> NDArray[np.float64]:  # the attitude shape about the vertical
        return (attitude @ up)[:, :, None]

    def lat(geo: StepGeometry) -> NDArray[np.float64] | None:
        if geo.c_bn is None:
            return None
        e = np.einsum("kab,a->kb", np.asarray(geo.c_bn, dtype=float), d_omega)  # C_n^b dΩ^n/dφ
        return _place(model, g, e[:, :, None])

    return [
        BudgetInput(
            "azimuth", "Table azimuth alignment (Earth rate)",
            f"u = {u_azimuth / ARCSEC:.3g}″ about the vertical ({azimuth_source}), one for the run",
            np.array([[u_azimuth**2]]),
            DerivedShape(AttitudeShape(model), azimuth),
        ),
        BudgetInput(
            "latitude", "Site latitude (Earth rate)", f"u = {u_latitude / ARCSEC:.3g}″ of latitude, one for the run",
            np.array([[u_latitude**2]]), lat,
        ),
    ]  # fmt: skip


def time_base_inputs(model: ModelSpec, u_rate: float, u_offset: float, source: str) -> list[BudgetInput]:
    """Unit clock rate (relative, u) → gyro scale 1:1; clock offset (s, u) → the spins' reference turns."""
    out: list[BudgetInput] = []
    g = _gyro_axes(model)
    if u_rate > 0 and g is not None:

        def rate(geo: StepGeometry) -> NDArray[np.float64]:
            w = geo.omega + (0.0 if geo.earth is None else geo.earth)
            return _place(model, g, w[:, :, None])

        out.append(
            BudgetInput(
                "time_base_rate", "Time base: unit clock rate", f"u(ε) = {u_rate / PPM:.3g} ppm ({source})",
                np.array([[u_rate**2]]), rate,
            )
        )  # fmt: skip
    if u_offset > 0:

        def offset(geo: StepGeometry) -> NDArray[np.float64] | None:
            if geo.spin_axis is None or g is None or geo.earth is None:
                return None
            return _place(model, g, np.cross(geo.earth, geo.omega)[:, :, None])  # Ω_b turned by ω δt

        out.append(
            BudgetInput(
                "time_base_offset", "Time base: unit-to-table clock offset",
                f"u(δt) = {u_offset * 1e3:.3g} ms ({source})", np.array([[u_offset**2]]), offset,
            )
        )  # fmt: skip
    return out


__all__ = ["earth_rate_inputs", "time_base_inputs"]
