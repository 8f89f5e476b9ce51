"""The certificate's use of the GUM budget: a recording's step geometry and the bench's stated inputs.

The maths lives in :mod:`analysis.identification.budget` (one model, one set of sensitivities). This
module only gathers its inputs from a run: the reference points of the identified steps, built with THE
reference function (:func:`benches.reference.reference_for_samples`: table at t − latency, never across a
motion boundary), the identification's own covariance (calibration.json), and the bench's stated
uncertainties (table attitude and rate accuracy, local g, unit bias instability).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from analysis.gimbal import body_to_nav
from analysis.identification.bias_drift import flicker_components, window_mean_covariance
from analysis.identification.budget import (
    BudgetComponent,
    StepGeometry,
    UncertaintyBudget,
    build_budget,
    default_g_uncertainty,
)
from benches.calibration_result import CalibrationResult
from benches.identify import acquisition_span
from benches.reference import reference_for_samples

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
    """
    wanted = set(names) if names is not None else None
    table = f.table()
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
        fr, om, ang = reference_for_samples(
            t, tt, ta, tr, g=g, mounting=mounting, latency=latency,
            span=acquisition_span(t_first, t_last, latency, rate),
        )  # fmt: skip
        spin_axis = None
        if s.kind == "spin":
            sel = (tt >= t_first) & (tt <= t_last)
            rates = tr[sel] if np.any(sel) else tr
            spin_axis = int(np.argmax(np.abs(np.mean(rates, axis=0))))
        out.append(
            StepGeometry(
                s.name, s.kind, fr, om, np.diff(edges).astype(float), body_to_nav(ang, mounting), spin_axis,
                (t_first, t_last),
            )
        )  # fmt: skip
    return out


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
    out = np.zeros((len(geometry), 3))
    b = np.asarray(bias_instability, dtype=float).reshape(3)
    for axis in range(3):
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
    rate_accuracy: float,
    bias_instability: NDArray[np.float64] | None,
) -> UncertaintyBudget:
    """The budget of one identified run (calibration.json mapping + its step geometry + bench inputs).

    The identification's covariance and its white-noise part come from calibration.json (typed).
    """
    x = cal.x
    p_id = cal.covariance
    nv = cal.noise_variance
    notes: list[str] = []
    p_w = cal.covariance_white
    per_step = cal.per_step
    budget = build_budget(
        p_id,
        p_w,
        geometry,
        nv,
        x_hat=x,
        g=g,
        g_uncertainty=g_uncertainty,
        g_source=g_source,
        attitude_accuracy=attitude_accuracy,
        rate_accuracy=rate_accuracy,
        flicker_step_variance=None if bias_instability is None else flicker_step_variance(geometry, bias_instability),
        residuals_per_step=per_step,
        model=cal.error_model,
    )
    budget.notes.extend(notes)
    return budget
