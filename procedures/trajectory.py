"""Nominal (ideal) table trajectory of a compiled procedure, sampled compactly for the pre-run plan.

For every acquisition step (warmup, hold, spin) :func:`nominal_samples` gives a few weighted points that
stand for the real samples the unit will deliver: a static hold is one point weighted by its number of
samples; a spin is sampled at ``points_per_revolution`` points per revolution of the counted window,
each weighted by the samples it stands for. The weights sum to ``duration × sample_rate``, so an
information matrix Σ wₖ Hₖᵀ R⁻¹ Hₖ over the points approximates the one over all samples (exact for holds;
for spins to the quadrature error of the midpoint rule, negligible at 720 points per revolution).

Gimbal angles (outer ψ, middle θ, inner γ), rad, unwrapped; gimbal rates rad/s; use
:func:`analysis.gimbal.body_to_nav` / :func:`analysis.gimbal.body_rate` with the bench mounting for C_b^n
and ω^b.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.protocols import AxisLimits

from .steps import CompiledProcedure, Hold, Spin, Step, Warmup


@dataclass(frozen=True)
class NominalSamples:
    """Weighted nominal points of one acquisition step.

    Attributes
    ----------
    step : Step
    t : ndarray (m,)
        Time of each point from the start of the counted window, s (centre of the interval it stands for).
    angles : ndarray (m, 3)
        Nominal gimbal angles, rad (NaN for a warm-up at the table's unknown initial attitude).
    rates : ndarray (m, 3)
        Nominal gimbal rates, rad/s.
    weights : ndarray (m,)
        Number of real samples each point stands for; sums to ``step.duration × sample_rate``.
    """

    step: Step
    t: NDArray[np.float64]
    angles: NDArray[np.float64]
    rates: NDArray[np.float64]
    weights: NDArray[np.float64]

    @property
    def n_samples(self) -> float:
        """Number of real samples the step stands for."""
        return float(self.weights.sum())


def nominal_samples(
    compiled: CompiledProcedure,
    sample_rate: float,
    *,
    max_points_per_step: int = 20_000,
    points_per_revolution: int = 720,
    limits: Sequence[AxisLimits] | None = None,
) -> list[NominalSamples]:
    """Weighted nominal points of every acquisition step of ``compiled``.

    Parameters
    ----------
    compiled : CompiledProcedure
    sample_rate : float
        The unit's sample rate, Hz.
    max_points_per_step : int
        Cap on the points of one spin (never more than its real samples either).
    points_per_revolution : int
        Spin sampling density over the counted window.
    limits : sequence of AxisLimits, optional
        If given, the phase at which a spin's counted window starts includes the acceleration ramp
        (rate²/2a); otherwise the ramp is taken as instantaneous (phase off by a few degrees at most).

    Returns
    -------
    list of NominalSamples
        In step order, one per warmup/hold/spin.
    """
    if not sample_rate > 0:
        raise ValueError(f"sample_rate: expected Hz > 0, got {sample_rate!r}")
    if max_points_per_step < 1 or points_per_revolution < 1:
        raise ValueError("max_points_per_step and points_per_revolution must be >= 1")
    starts = compiled.start_angles or (None,) * len(compiled.steps)
    out: list[NominalSamples] = []
    for step, start in zip(compiled.steps, starts, strict=True):
        if not step.acquires:
            continue
        n_real = step.duration * sample_rate
        if isinstance(step, (Hold, Warmup)):
            ang = np.full((1, 3), np.nan) if step.angles is None else np.asarray(step.angles, dtype=float)[None, :]
            out.append(
                NominalSamples(step, np.array([step.duration / 2]), ang, np.zeros((1, 3)), np.array([float(n_real)]))
            )
            continue
        assert isinstance(step, Spin), f"no nominal trajectory for a {type(step).__name__} step"
        revs = abs(step.rate) * step.duration / (2 * math.pi)
        m = int(min(max_points_per_step, max(1, math.ceil(revs * points_per_revolution)), max(1, math.floor(n_real))))
        t = (np.arange(m) + 0.5) * (step.duration / m)
        base = np.full(3, np.nan) if start is None else np.asarray(start, dtype=float)
        phase0 = base[step.axis] + step.rate * step.settle
        if limits is not None:
            phase0 += math.copysign(step.rate**2 / (2 * limits[step.axis].accel_max), step.rate)
        ang = np.repeat(base[None, :], m, axis=0)
        ang[:, step.axis] = phase0 + step.rate * t
        rates = np.zeros((m, 3))
        rates[:, step.axis] = step.rate
        out.append(NominalSamples(step, t, ang, rates, np.full(m, n_real / m)))
    return out
