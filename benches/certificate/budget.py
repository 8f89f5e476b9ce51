"""The certificate's use of the GUM budget: a recording's step geometry and the bench's stated inputs.

The maths lives in :mod:`analysis.identification.budget` (one model, one set of sensitivities). This
module only gathers its inputs from a run: the reference points of the identified steps, built with THE
reference function (:func:`benches.reference.reference_for_window`: table at t − latency, never across a motion
boundary; each window interpolated once, for the reference and its gimbal rates), the identification's
own covariance (calibration.json), and the bench's stated uncertainties (table attitude and rate accuracy,
local g, unit bias instability).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from analysis.earth import DEFAULT_LATITUDE_U
from analysis.gimbal import body_to_nav
from analysis.identification.bias_drift import flicker_components, window_mean_covariance
from analysis.identification.budget import (
    BudgetComponent,
    BudgetInput,
    StepGeometry,
    UncertaintyBudget,
    build_budget,
    default_g_uncertainty,
)
from analysis.identification.gyro_budget import earth_rate_inputs, time_base_inputs
from analysis.identification.specification import ModelSpec
from analysis.identification.table_axes import held_angle_input, orthogonality_input
from analysis.timebase import TimeBase
from analysis.units import ARCSEC
from benches.calibration_result import CalibrationResult
from benches.reference import acquisition_span, earth_in_body, reference_for_window
from benches.timebase import reference_rate_covariance, reference_rate_u, table_in_unit_time

if TYPE_CHECKING:  # pragma: no cover
    from benches.recording import Recording

__all__ = [
    "BudgetComponent",
    "StepGeometry",
    "UncertaintyBudget",
    "budget_for_run",
    "default_g_uncertainty",
    "flicker_step_variance",
    "step_geometry",
]


def step_geometry(
    f: Recording,
    g: float,
    mounting: NDArray[np.float64] | None,
    *,
    latency: float = 0.0,
    names: Sequence[str] | None = None,
    max_points: int = 400,
    latitude: float | None = None,
    time_base: TimeBase | None = None,
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
    latency : float
        The unit's output latency, s (the reference is the table at t − latency).
    names : sequence of str, optional
        Only these steps (the ones the identification used); default every complete hold and spin.
    max_points : int
        Reference points per step (evenly spaced sample centres).
    latitude : float, optional
        Site latitude, rad: the geometry then carries the Earth rate in the body frame (gyro budgets).
    time_base : analysis.timebase.TimeBase, optional
        The run's time base (calibration.json): the readings are put on the unit's clock with it, as the
        identification did (benches.timebase.table_in_unit_time).
    """
    wanted = set(names) if names is not None else None
    table = f.table() if time_base is None else table_in_unit_time(f.table(), time_base)
    tt, ta, tr = table.time, table.angles, table.rates
    fs = float(f.header.sample_rate_hz)
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
        ends = f.samples(fields=("time",), index=np.array([a0, a1 - 1])).time
        assert ends is not None
        t_first, t_last = float(ends[0]), float(ends[1])
        rate = fs if fs > 0 else max((n - 1) / max(t_last - t_first, 1e-12), 1.0)
        m = min(n, max_points)
        edges = a0 + (np.arange(m + 1) * n) // m
        idx = (edges[:-1] + edges[1:] - 1) // 2
        t = f.samples(fields=("time",), index=idx).time
        assert t is not None
        span = acquisition_span(t_first, t_last, latency, rate)
        fr, om, ang, trig, gimbal_rates = reference_for_window(  # the window interpolated once for both
            t, tt, ta, tr, g=g, mounting=mounting, latency=latency, span=span
        )
        spin_axis, held_u = None, None
        if s.kind == "spin":
            sel = (tt >= t_first) & (tt <= t_last)
            rates = tr[sel] if np.any(sel) else tr
            spin_axis = int(np.argmax(np.abs(np.mean(rates, axis=0))))
            held_u = _held_angle_u(ta[sel], spin_axis)
        out.append(
            StepGeometry(
                s.name, s.kind, fr, om, np.diff(edges).astype(float), body_to_nav(ang, mounting), spin_axis,
                (t_first, t_last), None if latitude is None else earth_in_body(ang, latitude, mounting, trig=trig),
                ang, gimbal_rates, held_u,
            )
        )  # fmt: skip
    return out


def _held_angle_u(angles: NDArray[np.float64], spin_axis: int) -> NDArray[np.float64] | None:
    """(3,) u of the mean reading of each gimbal held during a spin: the readings' scatter over √count, rad (type
    A; the readings' noise taken as independent between readings); 0 for the spinning gimbal. None: < 3 readings."""
    n = angles.shape[0]
    if n < 3:
        return None
    u = np.std(angles, axis=0, ddof=1) / np.sqrt(n)
    u[spin_axis] = 0.0
    return u


def flicker_step_variance(
    geometry: Sequence[StepGeometry], bias_instability: NDArray[np.float64]
) -> dict[str, NDArray[np.float64]]:
    """Per step, the variance (3,) of its mean bias-instability offset not common to all steps, (m/s²)².

    Flicker as in the identification (:mod:`analysis.identification.bias_drift`); the common part is
    absorbed by the bias estimate and does not show in the residuals.
    """
    if not geometry:
        return {}
    starts = np.array([g.window[0] for g in geometry])
    ends = np.array([g.window[1] for g in geometry])
    b = np.asarray(bias_instability, dtype=float).reshape(-1)
    out = np.zeros((len(geometry), b.size))
    for axis in range(b.size):
        if b[axis] > 0:
            c = window_mean_covariance(starts, ends, *flicker_components(float(b[axis])))
            out[:, axis] = np.clip(np.diag(c) - c.mean(), 0.0, None)
    return {g.name: out[k] for k, g in enumerate(geometry)}


def budget_for_run(
    cal: CalibrationResult,
    geometry: Sequence[StepGeometry],
    *,
    g: float,
    g_uncertainty: float,
    g_source: str,
    attitude_accuracy: float,
    bias_instability: NDArray[np.float64] | None,
    gyro_bias_instability: NDArray[np.float64] | None = None,
    latitude: float | None = None,
    azimuth_uncertainty: float | None = None,
) -> UncertaintyBudget:
    """The budget of one identified run (calibration.json mapping + its step geometry + bench inputs).

    The identification's covariance and its white-noise part come from calibration.json (typed). With the
    gyro model the gyro's inputs join (:mod:`analysis.identification.gyro_budget`): azimuth alignment and
    latitude through the Earth rate, the time base (from the calibration result's ``time_base`` when the
    time-base analysis produced one). For every model the table's axis non-orthogonality (middle and inner
    axis tilts, each bounded by the attitude accuracy; :mod:`analysis.identification.table_axes`) joins.
    """
    p_id = cal.covariance
    nv = cal.noise_variance
    notes: list[str] = []
    p_w = cal.covariance_white
    per_step = cal.per_step
    p_tb, tb_source = time_base_covariance(cal)
    model = cal.error_model
    extra = []
    if model.n_axes == 6:
        if bias_instability is not None and gyro_bias_instability is not None:
            bias_instability = np.concatenate([np.asarray(bias_instability), np.asarray(gyro_bias_instability)])
        elif bias_instability is not None:
            bias_instability = None
            notes.append("the unit's gyro bias instability is unknown: no flicker share in the mismatch test")
        covered = bool(tb_source) and cal.time_base is not None and "gyro_S_x" in (cal.time_base.sensitivity or {})
        extra = _gyro_inputs(cal, latitude, azimuth_uncertainty, attitude_accuracy, notes, covered, model)
    # the table's axis non-orthogonality, bounded by its stated attitude accuracy: both triads (table_axes)
    extra += orthogonality_input(model, attitude_accuracy, g, "bounded by the table's attitude accuracy")
    extra += held_angle_input(model, g)  # the held gimbals' angle readings during spins (table_axes)
    budget = build_budget(
        p_id - p_tb,
        p_w,
        geometry,
        nv,
        g=g,
        g_uncertainty=g_uncertainty,
        g_source=g_source,
        attitude_accuracy=attitude_accuracy,
        flicker_step_variance=None if bias_instability is None else flicker_step_variance(geometry, bias_instability),
        residuals_per_step=per_step,
        model=model,
        extra_inputs=extra,
    )
    if tb_source:
        label = "Time base (unit clock vs table clock)"
        budget.components.append(BudgetComponent("time_base", label, tb_source, "A", p_tb))
    budget.notes.extend(notes)
    return budget


DEFAULT_AZIMUTH_U: float = 20.0 * ARCSEC
"""Standard uncertainty of the table's azimuth alignment when the bench states none (a theodolite/gyrocompass
survey to ±35″, rectangular); the certificate says that it was assumed."""


def _gyro_inputs(
    cal: CalibrationResult,
    latitude: float | None,
    u_az: float | None,
    attitude_accuracy: float,
    notes: list[str],
    time_base_covered: bool = False,
    model: ModelSpec | None = None,
) -> list[BudgetInput]:
    """The gyro's type-B inputs (:mod:`analysis.identification.gyro_budget`) for ``model`` (default the calibration's
    error model; the budget passes its own object, so the inputs derived from the attitude share its shapes)."""
    model = cal.error_model if model is None else model
    if latitude is None:
        notes.append("site latitude unknown: the Earth-rate inputs (azimuth, latitude) are not evaluated")
        out: list[BudgetInput] = []
    else:
        src = "bench file"
        if u_az is None:
            u_az, src = DEFAULT_AZIMUTH_U, "assumed: the bench file states no azimuth alignment"
            notes.append(f"table azimuth alignment not stated by the bench: u = {u_az / ARCSEC:.3g}″ assumed")
        out = earth_rate_inputs(model, latitude, u_az, DEFAULT_LATITUDE_U, src)
    tb = getattr(cal, "time_base", None)
    u_rate = getattr(tb, "u_rate", None) if tb is not None else None
    u_c = (getattr(tb, "check", None) or {}).get("u_controller_vs_host_rate") if tb is not None else None
    if u_rate is not None and isinstance(u_c, int | float) and np.isfinite(u_c):
        u_rate = float(np.hypot(u_rate, u_c))  # the gyro's rate reference: controller clock against the host's
    u_off = getattr(tb, "u_offset_s", None) if tb is not None else None
    if time_base_covered:
        pass  # the time-base component (its sensitivities cover every state, the gyro's scale included)
    elif u_rate is not None or u_off is not None:
        out += time_base_inputs(model, float(u_rate or 0.0), float(u_off or 0.0), "time-base estimate of this run")
    else:
        notes.append("no time-base estimate in the calibration result: one clock assumed (time base not budgeted)")
    return out


def time_base_covariance(cal: CalibrationResult) -> tuple[NDArray[np.float64], str]:
    """The parameters' covariance from the run's estimated time base (J Σ Jᵀ, J = ∂x/∂(t₀, ε) from
    calibration.json's ``time_base.sensitivity``; included in its covariance) and the budget line's source text
    ("" when the file has none)."""
    names = cal.names
    z = np.zeros((len(names), len(names)))
    blk = cal.time_base
    if blk is None or not blk.sensitivity:
        return z, ""
    tb = blk.estimate
    cov = np.asarray(tb.covariance, dtype=float)
    if not np.all(np.isfinite(cov)):
        return z, ""
    if not any(n in blk.sensitivity for n in names):
        return z, ""
    # states the time-base analysis did not propagate to (e.g. the gyro's) get zero rows here; the gyro's
    # own time-base inputs then carry them (analysis.identification.gyro_budget.time_base_inputs)
    jac = np.array([blk.sensitivity.get(n, [0.0, 0.0]) for n in names], dtype=float)
    src = (
        f"t_table = t0 + (1 + eps) t_unit estimated from the run ({tb.method}, {len(tb.events)} motions): "
        f"t0 = {tb.offset * 1e3:.4f} ms, u = {tb.u_offset * 1e6:.3g} µs; eps = {tb.rate * 1e6:+.3f} ppm, "
        f"u = {tb.u_rate * 1e6:.3g} ppm; offset → misalignment and size effect through the spins"
    )
    p_ref = reference_rate_covariance(list(names), tb.check) if "gyro_S_x" in blk.sensitivity else z
    if np.any(p_ref):
        src += (
            f"; the reference second (controller clock against the host's), u = "
            f"{reference_rate_u(tb.check) * 1e6:.3g} ppm → gyro scale factor 1:1"
        )
    return jac @ cov @ jac.T + p_ref, src
