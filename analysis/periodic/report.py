"""One channel's periodic error analysis as ``tablebench periodic`` reports it: identify on the first seconds,
compensate the rest, compare with averaging / low-pass, and the ``periodic.json`` structure with explicit
SI units on every quantity and the list of what could not be settled."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.periodic.comparison import COMPARISON_UNITS, smoothing_comparison, welch_psd
from analysis.periodic.identify import identify_periodic
from analysis.periodic.model import PeriodicInputError, PeriodicModel, PeriodicTerm
from analysis.units import magnitude_problem

__all__ = ["ChannelAnalysis", "analyse_channel", "analyse_periodic", "term_json", "psd_unit"]

MIN_CALIBRATION_SAMPLES = 64
MIN_COMPENSATED_SAMPLES = 64


def psd_unit(unit: str) -> str:
    """The PSD unit of a channel in ``unit``: ``(unit)^2/Hz``."""
    return f"({unit})^2/Hz"


def term_json(term: PeriodicTerm, unit: str) -> dict[str, float | str | bool]:
    """JSON-ready dict of one term; fixed units in the key names (Hz, rad, dB), the amplitude's unit given."""
    return {
        "frequency_hz": term.frequency_hz,
        "frequency_sigma_hz": term.frequency_sigma_hz,
        "frequency_crb_sigma_hz": term.frequency_crb_sigma_hz,
        "amplitude": term.amplitude,
        "amplitude_sigma": term.amplitude_sigma,
        "amplitude_unit": unit,
        "phase_rad": term.phase_rad,
        "phase_sigma_rad": term.phase_sigma_rad,
        "snr_db": term.snr_db,
        "noise_psd_ratio": term.noise_psd_ratio,
        "significance": term.significance,
        "significance_threshold": term.significance_threshold,
        "detection_probability": term.detection_probability,
        "near_detection_limit": term.near_detection_limit,
    }


@dataclass
class ChannelAnalysis:
    """Everything ``tablebench periodic`` reports for one channel.

    Attributes
    ----------
    model : PeriodicModel
    calibration_samples : int
        Samples used for identification (raw indices 0 … n_cal−1).
    before, after : ndarray
        The rest of the record (raw indices n_cal …) before and after compensation, offset removed (channel SI
        unit).
    comparison : list of dict
        :func:`~analysis.periodic.comparison.smoothing_comparison` rows.
    unit : str
        The channel's SI unit ("rad/s", "m/s^2", or "SI" when the input did not say).
    """

    model: PeriodicModel
    calibration_samples: int
    before: NDArray[np.float64]
    after: NDArray[np.float64]
    comparison: list[dict[str, float | str]]
    unit: str = "SI"

    def unsettled(self) -> list[str]:
        """What the identification could not settle (see :meth:`PeriodicModel.unsettled`)."""
        return self.model.unsettled()

    def to_json(self, rate_hz: float) -> dict:
        """The per-channel structure of ``periodic.json``: SI values, every unit explicit (``units``)."""
        m, u = self.model, self.unit
        pu = psd_unit(u)
        fb, pb = welch_psd(self.before, rate_hz)
        _, pa = welch_psd(self.after, rate_hz)
        df = fb[1] - fb[0]
        psd_rows = []
        for term in m.terms:
            k = int(round(term.frequency_hz / df))
            sl = slice(max(k - 1, 0), min(k + 2, fb.size))
            psd_rows.append(
                {"frequency_hz": term.frequency_hz, "before": float(pb[sl].max()), "after": float(pa[sl].max())}
            )
        r = m.report
        units = {
            "offset": u,
            "offset_sigma": u,
            "noise_sigma": u,
            "residual_rms_before": u,
            "residual_rms_after": u,
            "psd_median_after": pu,
            "psd_at_terms[].before": pu,
            "psd_at_terms[].after": pu,
            "terms[].amplitude": u,
            "terms[].amplitude_sigma": u,
            "terms[].noise_psd_ratio": "1",
            "terms[].significance": "1",
            "terms[].significance_threshold": "1",
            "terms[].detection_probability": "1",
            "dropped[].amplitude": u,
            "dropped[].amplitude_sigma": u,
            **{f"comparison[].{k}": (u if v == "channel" else v) for k, v in COMPARISON_UNITS.items()},
        }
        return {
            "unit": u,
            "psd_unit": pu,
            "units": units,
            "terms": [term_json(t, u) for t in m.terms],
            "offset": m.offset,
            "offset_sigma": m.offset_sigma,
            "noise_sigma": m.noise_sigma,
            "residual_rms_before": float(np.sqrt(np.mean(self.before**2))),
            "residual_rms_after": float(np.sqrt(np.mean(self.after**2))),
            "psd_at_terms": psd_rows,
            "psd_median_after": float(np.median(pa[1:])),
            "comparison": self.comparison,
            "identification": {
                "method": r.method,
                "calibration_samples": self.calibration_samples,
                "calibration_seconds": self.calibration_samples / rate_hz,
                "false_alarm": m.false_alarm,
                "search_band_hz": list(m.search_band_hz),
                "converged": r.converged,
                "iterations": r.iterations,
                "evaluations": r.evaluations,
                "fallback": r.fallback,
                "edge_limited": any(r.edge_limited),
                "message": r.message,
            },
            "dropped": [
                {
                    "frequency_hz": d.frequency_hz,
                    "amplitude": d.amplitude,
                    "amplitude_sigma": d.amplitude_sigma,
                    "significance": d.significance,
                    "significance_threshold": d.significance_threshold,
                }
                for d in m.dropped
            ],
            "unsettled": self.unsettled(),
        }


def analyse_channel(
    x: ArrayLike,
    rate_hz: float,
    calibrate_seconds: float,
    terms: int | None = None,
    false_alarm: float = 1e-3,
    method: str = "lm",
    unit: str = "SI",
) -> ChannelAnalysis:
    """Identify on the first ``calibrate_seconds``, compensate the rest, compare with averaging / low-pass.

    Parameters
    ----------
    x : array_like
        1-D record of one channel (SI unit ``unit``).
    rate_hz : float
        Sample rate, Hz.
    calibrate_seconds : float
        Length of the calibration sample, s (the spec: 5–20 s).
    terms : int, optional
        Force the number of terms.
    false_alarm : float
        Whole-band false-alarm probability of the detection and the post-fit test.
    method : {"lm", "grid"}
        Frequency refinement (see :func:`~analysis.periodic.identify.identify_periodic`).
    unit : str
        The channel's SI unit label, carried into the JSON.
    """
    v = np.asarray(x, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise PeriodicInputError("the record contains NaN/inf values; remove or interpolate them")
    too_large = magnitude_problem(v, "periodic")
    if too_large:
        raise PeriodicInputError(too_large)
    if not math.isfinite(calibrate_seconds) or calibrate_seconds <= 0:
        raise PeriodicInputError(
            f"the calibration length must be a positive number of seconds, got {calibrate_seconds}",
            "calibrate_seconds",
        )
    n_cal = int(round(calibrate_seconds * rate_hz))
    if n_cal < MIN_CALIBRATION_SAMPLES:
        raise PeriodicInputError(
            f"a calibration of {calibrate_seconds} s gives only {n_cal} samples at {rate_hz} Hz; use at least "
            f"{math.ceil(MIN_CALIBRATION_SAMPLES / rate_hz * 100) / 100} s",
            "calibrate_seconds",
        )
    if v.size < n_cal + MIN_COMPENSATED_SAMPLES:
        raise PeriodicInputError(
            f"the record has {v.size} samples ({v.size / rate_hz:.3g} s), not enough to calibrate on "
            f"{calibrate_seconds} s and compensate at least {MIN_COMPENSATED_SAMPLES} more samples; shorten the "
            "calibration",
            "calibrate_seconds",
        )
    model = identify_periodic(v[:n_cal], rate_hz, n_terms=terms, false_alarm=false_alarm, method=method)
    rest = v[n_cal:]
    before = rest - model.offset
    after = model.compensator(start_index=n_cal).process(before)
    comparison = smoothing_comparison(rest, rate_hz, model, n_cal)
    return ChannelAnalysis(model, n_cal, before, after, comparison, unit)


def analyse_periodic(
    channels: Mapping[str, ArrayLike],
    rate: float,
    calibrate_seconds: float = 8.0,
    terms: int | None = None,
    units: Mapping[str, str] | None = None,
    method: str = "lm",
) -> dict:
    """Periodic error analysis of several channels, as the ``periodic.json`` structure (SI, units explicit).

    Parameters
    ----------
    channels : mapping of str to array_like
        Channel name → 1-D record (SI unit: rad/s for gyro axes, m/s² for accelerometer axes, body frame).
    rate : float
        Sample rate, Hz.
    calibrate_seconds : float
        Calibration sample length, s.
    terms : int, optional
        Force the number of terms per channel.
    units : mapping of str to str, optional
        Channel name → SI unit label (default "SI").
    method : {"lm", "grid"}
        Frequency refinement.

    Returns
    -------
    dict
        ``{"rate_hz", "calibrate_seconds", "channels": {NAME: ChannelAnalysis.to_json()}, "unsettled": [...]}``.
    """
    out: dict = {"rate_hz": float(rate), "calibrate_seconds": float(calibrate_seconds), "channels": {}}
    unsettled = []
    for name, data in channels.items():
        try:
            res = analyse_channel(
                data, rate, calibrate_seconds, terms, method=method, unit=(units or {}).get(name, "SI")
            )
        except PeriodicInputError as exc:
            raise PeriodicInputError(f"channel {name}: {exc}", exc.parameter) from None
        out["channels"][name] = res.to_json(rate)
        unsettled += [f"{name}: {s}" for s in res.unsettled()]
    out["unsettled"] = unsettled
    return out
