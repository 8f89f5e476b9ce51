"""Types of the periodic error model (``docs/methods/periodic.md``): terms, the identified model, fit diagnostics.

Model of one channel (any SI unit, e.g. rad/s for a gyro axis in the body frame)::

    v_j = c₀ + Σ_{i=1}^{N} A_i cos(2π f_i t_j + φ_i) + e_j,   t_j = j T_s,   j = 0 … n−1

with the phase reference at sample 0 of the calibration record. This module holds only the types and the
Cramér–Rao bound; the algorithms are in :mod:`~analysis.periodic.detection` (coarse peaks),
:mod:`~analysis.periodic.refine` (Levenberg–Marquardt, the default), :mod:`~analysis.periodic.grid` (the
published grid search) and :mod:`~analysis.periodic.identify` (the whole identification).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.periodic.compensator import PeriodicCompensator
from core.errors import UserError

__all__ = [
    "PeriodicInputError",
    "PeriodicTerm",
    "DroppedTone",
    "FitReport",
    "PeriodicModel",
    "crb_frequency_sigma",
]


class PeriodicInputError(UserError, ValueError):
    """The data cannot be analysed as asked (too short, bad rate, bad parameter); the message says the fix.

    Messages speak of the analysis parameters, never of command-line options; ``parameter`` names the
    parameter at fault (e.g. ``"calibrate_seconds"``, ``"n_terms"``) so a command can map it to its option.
    """

    def __init__(self, message: str, parameter: str | None = None) -> None:
        super().__init__(message)
        self.parameter = parameter


def crb_frequency_sigma(sigma: float, amplitude: float, rate_hz: float, n: int) -> float:
    """Cramér–Rao bound on the standard deviation of a real tone's frequency estimate, Hz.

    ``var f̂ ≥ 24 σ² / ((2π)² A² T_s² n (n² − 1))`` for white noise of standard deviation ``sigma`` and a tone of
    amplitude ``amplitude`` (same unit) sampled ``n`` times at ``rate_hz``.
    """
    if amplitude <= 0 or n < 2:
        return math.inf
    ts = 1.0 / rate_hz
    var = 24.0 * sigma**2 / ((2.0 * math.pi) ** 2 * amplitude**2 * ts**2 * n * (float(n) ** 2 - 1.0))
    return math.sqrt(var)


@dataclass(frozen=True)
class PeriodicTerm:
    """One identified term ``A cos(2π f t + φ)``, t from sample 0 of the calibration record.

    Attributes
    ----------
    frequency_hz, frequency_sigma_hz : float
        Frequency and its standard error (u, k = 1), Hz.
    amplitude, amplitude_sigma : float
        Amplitude and its standard error, channel SI unit (e.g. rad/s).
    phase_rad, phase_sigma_rad : float
        Phase at t = 0 and its standard error, rad.
    frequency_crb_sigma_hz : float
        Cramér–Rao σ_f for this tone at the estimated σ and A, Hz.
    snr_db : float
        Coarse peak level above the periodogram floor, dB.
    noise_psd_ratio : float
        Local residual PSD at the tone / white level of σ̂ (dimensionless); ≠ 1 only when the noise is
        significantly coloured, in which case the tone's standard errors use the local level.
    significance : float
        Post-fit statistic ``u = (A/σ_A)²/2`` (exponentially distributed with mean 1 for a pure-noise tone at a
        fixed frequency), dimensionless.
    significance_threshold : float
        The value of ``u`` a tone must exceed for the whole-band false-alarm probability (dimensionless).
    detection_probability : float
        Probability that a tone of the fitted amplitude would pass the post-fit test again (dimensionless);
        below 0.95 the tone is *near the detection limit*.
    """

    frequency_hz: float
    frequency_sigma_hz: float
    amplitude: float
    amplitude_sigma: float
    phase_rad: float
    phase_sigma_rad: float
    frequency_crb_sigma_hz: float
    snr_db: float = math.nan
    noise_psd_ratio: float = 1.0
    significance: float = math.inf
    significance_threshold: float = 0.0
    detection_probability: float = 1.0

    NEAR_LIMIT_PROBABILITY = 0.95
    """A kept tone whose re-detection probability is below this is reported as near the detection limit."""

    @property
    def near_detection_limit(self) -> bool:
        """Whether a repeat measurement would miss this tone with probability above 5 %."""
        return self.detection_probability < self.NEAR_LIMIT_PROBABILITY


@dataclass(frozen=True)
class DroppedTone:
    """A coarse peak whose fitted amplitude was not significant (post-fit test), dropped from the model.

    Attributes
    ----------
    frequency_hz : float
        Fitted frequency, Hz.
    amplitude, amplitude_sigma : float
        Fitted amplitude and its standard error, channel SI unit.
    significance, significance_threshold : float
        Post-fit statistic ``u`` and its threshold (dimensionless).
    """

    frequency_hz: float
    amplitude: float
    amplitude_sigma: float
    significance: float
    significance_threshold: float


@dataclass
class FitReport:
    """Diagnostics of the frequency refinement.

    Attributes
    ----------
    method : str
        ``"lm"`` (Levenberg–Marquardt on the exact model, the default) or ``"grid"`` (the published search).
    converged : bool
        LM: the step and gradient criteria were met before the iteration cap. Grid: a sweep moved no
        frequency by more than its final grid step.
    iterations : int
        LM iterations, or grid sweeps over all tones.
    evaluations : int
        Model/Jacobian evaluations (LM) or grid-point refits (grid).
    fallback : bool
        LM did not converge inside the tones' search intervals and the grid search was used instead.
    edge_limited : list of bool
        Grid: tones whose minimum stayed on an interval edge after the allowed shifts.
    final_step_hz : list of float
        Grid: final grid step of each tone, Hz; LM: last frequency step of each tone, Hz.
    message : str
        Why the refinement stopped, in words.
    """

    method: str = "lm"
    converged: bool = False
    iterations: int = 0
    evaluations: int = 0
    fallback: bool = False
    edge_limited: list[bool] = field(default_factory=list)
    final_step_hz: list[float] = field(default_factory=list)
    message: str = ""


def refinement_start(
    x: ArrayLike, rate_hz: float, frequencies_hz: Sequence[float], halfwidths_hz: Sequence[float] | None, method: str
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], FitReport]:
    """What both frequency refinements (``"lm"``, ``"grid"``) start from: the samples as float64, the coarse
    frequencies (Hz), the half-widths of their search intervals D_i (Hz; default 1/T) and an empty report
    (already converged, "no tone", when there is no frequency to refine)."""
    v = np.asarray(x, dtype=np.float64)
    freqs = np.array(frequencies_hz, dtype=np.float64)
    k = freqs.size
    duration = v.size / rate_hz
    half = np.full(k, 1.0 / duration) if halfwidths_hz is None else np.array(halfwidths_hz, dtype=np.float64)
    report = FitReport(method=method, final_step_hz=[0.0] * k, edge_limited=[False] * k)
    if k == 0:
        report.converged = True
        report.message = "no tone"
    return v, freqs, half, report


@dataclass
class PeriodicModel:
    """Identified periodic error model of one channel.

    Attributes
    ----------
    terms : list of PeriodicTerm
    offset, offset_sigma : float
        c₀ and its standard error (channel SI unit).
    rate_hz : float
        Sample rate, Hz.
    n_samples : int
        Calibration sample length.
    noise_sigma : float
        σ̂ of the calibration residual (channel SI unit).
    covariance : ndarray
        Covariance of (c₀, A_1, φ_1, f_1, …, A_N, φ_N, f_N) (SI: unit, unit, rad, Hz).
    report : FitReport
        Refinement diagnostics.
    false_alarm : float
        Whole-band false-alarm probability used for detection and the post-fit test.
    dropped : list of DroppedTone
        Coarse peaks removed by the post-fit significance test.
    search_band_hz : tuple of float
        The band searched for tones, Hz (tones outside it cannot be found).
    """

    terms: list[PeriodicTerm]
    offset: float
    offset_sigma: float
    rate_hz: float
    n_samples: int
    noise_sigma: float
    covariance: NDArray[np.float64]
    report: FitReport
    false_alarm: float = 1e-3
    dropped: list[DroppedTone] = field(default_factory=list)
    search_band_hz: tuple[float, float] = (math.nan, math.nan)

    def unsettled(self) -> list[str]:
        """What the identification could not settle, one short phrase each (empty when all is settled)."""
        out = []
        if not self.report.converged:
            out.append(f"{self.report.method} refinement did not converge ({self.report.message})")
        if self.report.fallback:
            out.append("Levenberg–Marquardt left the search intervals; the grid search was used")
        if any(self.report.edge_limited):
            out.append("grid minimum on an interval edge")
        for t in self.terms:
            if t.near_detection_limit:
                out.append(
                    f"tone at {t.frequency_hz:.4f} Hz near the detection limit "
                    f"(re-detection probability {t.detection_probability:.2f})"
                )
        for d in self.dropped:
            out.append(
                f"peak at {d.frequency_hz:.4f} Hz dropped: fitted amplitude not significant "
                f"({d.amplitude / d.amplitude_sigma:.1f} standard errors)"
            )
        return out

    def _jacobian(self, indices: ArrayLike) -> NDArray[np.float64]:
        j = np.asarray(indices, dtype=np.float64).reshape(-1)
        t = j / self.rate_hz
        cols = [np.ones_like(t)]
        for term in self.terms:
            th = 2.0 * np.pi * term.frequency_hz * t + term.phase_rad
            s = np.sin(th)
            cols += [np.cos(th), -term.amplitude * s, -2.0 * np.pi * t * term.amplitude * s]
        return np.stack(cols, axis=1)

    def compensator(self, start_index: int = 0, decimation: int = 1) -> PeriodicCompensator:
        """An online :class:`~analysis.periodic.compensator.PeriodicCompensator` for this model."""
        return PeriodicCompensator(
            [t.frequency_hz for t in self.terms],
            [t.amplitude for t in self.terms],
            [t.phase_rad for t in self.terms],
            self.rate_hz,
            start_index=start_index,
            decimation=decimation,
        )

    def evaluate(self, indices: ArrayLike, include_offset: bool = False) -> NDArray[np.float64]:
        """Model at raw sample indices (relative to calibration sample 0), phase-accurate; channel SI unit."""
        value = self.compensator().model(np.asarray(indices, dtype=np.int64))
        return value + self.offset if include_offset else value

    def prediction_sigma(self, indices: ArrayLike) -> NDArray[np.float64]:
        """Standard deviation of the model's periodic part at raw sample indices, from the parameter covariance.

        Inside the calibration window it stays near σ̂·√(p/n); beyond it the frequency errors dominate and it
        grows like 2π t A_i σ_f,i — the spec's extrapolation bound.
        """
        g = self._jacobian(indices)[:, 1:]
        cov = self.covariance[1:, 1:]
        return np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", g, cov, g), 0.0))
