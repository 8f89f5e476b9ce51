"""The noise report of a static record: what a run that never moves the table can state, instead of a
calibration certificate.

A static record (``procedures/static-noise.yaml``: a warm-up and a long hold at one attitude, no rotation)
cannot identify the error model: bias, scale factor and misalignment need several attitudes, the size effect
needs spins (docs/methods/accelerometer-calibration.md). A calibration certificate of it would be a page of
"not evaluated" lines. What the record does determine is the unit's noise: per channel, the IEEE 952 / 1293
noise terms (quantisation Q, white noise N, bias instability B, random walk K, ramp R) from the overlapping
Allan deviation of the record step (:func:`analysis.noise.terms.analyse_noise`, docs/methods/noise.md), each
with its expanded uncertainty U (k = 2), and the record's mean and standard deviation. The report states no
conformity (there are no noise limits in a bench file) and says what to run for a calibration.

docs/certificate.md says what each document states and why. The report is a
:class:`benches.certificate.content.Certificate` with ``document`` :data:`NOISE_REPORT`:
numbered from the same register, published through the same result sinks (``RUN/noise-report.pdf`` and
``.json``), rendered by :mod:`benches.certificate.pdf`. The same recording gives the same bytes apart from
the issue date (the analysis is deterministic).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from analysis.units import display_unit, from_display, kelvin_to_celsius
from benches.recorded_run import RecordedRun
from benches.recording import StepRecord

from .analyses import noise_rows
from .content import NOISE_REPORT, BenchInfo, Certificate, ambient_text
from .plots import plot_noise_report

STATIC_KINDS = frozenset({"warmup", "hold", "note"})
"""Step kinds of a static record (a soak or a ramp is a thermal procedure: not a noise record)."""
SAME_ATTITUDE_RAD = 1e-5
"""Two steps' gimbal angles closer than this (≈ 2″ per axis) are one attitude."""
CHANNELS = (("accel", "acceleration", "m/s^2"), ("gyro", "gyro_bias", "rad/s"))
"""(recording field, display quantity kind, SI unit label for the noise analysis) per triad."""


def _angle_gap(a: Sequence[float], b: Sequence[float]) -> float:
    d = np.angle(np.exp(1j * (np.asarray(a, dtype=float) - np.asarray(b, dtype=float))))
    return float(np.max(np.abs(d)))


def is_static_record(steps: Sequence[Any]) -> bool:
    """True when the recording (its :class:`StepRecord` rows) or the compiled procedure (its steps) holds one
    attitude and no rotation: only warm-up / hold / note steps, all at the same gimbal angles (within
    :data:`SAME_ATTITUDE_RAD`; unknown angles ignored), at least one hold."""
    if not steps or any(s.kind not in STATIC_KINDS for s in steps):
        return False
    if not any(s.kind == "hold" for s in steps):
        return False
    angles = [s.angles for s in steps if s.angles is not None and all(math.isfinite(a) for a in s.angles)]
    return all(_angle_gap(a, angles[0]) <= SAME_ATTITUDE_RAD for a in angles[1:])


def record_step(steps: Sequence[StepRecord]) -> StepRecord | None:
    """The step the noise is analysed on: the longest complete hold (acquisition window), else None."""
    holds = [s for s in steps if s.kind == "hold" and s.status == "complete" and s.acq_end > s.acq_start]
    return max(holds, key=lambda s: s.acq_end - s.acq_start) if holds else None


def analyse_record(rr: RecordedRun, step: StepRecord, rate: float) -> tuple[dict[str, Any], dict[str, Any]]:
    """Noise terms (overlapping Allan deviation, octave τ, 68.3 % intervals) and mean / standard deviation of
    each channel over ``step``'s acquisition window.

    Returns
    -------
    (noise, stats)
        ``noise``: the :func:`analysis.noise.terms.analyse_noise` result of every channel (``noise.json`` format);
        ``stats``: channel → {"mean", "std"} SI and {"unit"} display.
    """
    from analysis.noise.terms import analyse_noise  # lazy: scipy (--help time)

    f = rr.recording
    channels: dict[str, Any] = {}
    stats: dict[str, Any] = {}
    for field, kind, si_unit in CHANNELS:
        rows = getattr(f.samples(step.acq_start, step.acq_end, fields=(field,)), field)
        if rows is None or rows.size == 0 or not np.all(np.isfinite(rows)):
            continue
        for axis, name in enumerate("xyz"):
            ch = f"{field}_{name}"
            x = np.ascontiguousarray(rows[:, axis], dtype=float)
            one = analyse_noise({ch: x}, rate, {ch: si_unit}, taus="octave", estimators=("oadev",),
                                fit_estimator="oadev")  # fmt: skip
            channels.update(one["channels"])
            stats[ch] = {"mean": float(np.mean(x)), "std": float(np.std(x, ddof=1)), "unit": display_unit(kind),
                         "per_unit": from_display(kind, 1.0)}  # fmt: skip
    return {"rate_hz": rate, "estimators": ["oadev"], "fit_estimator": "oadev", "channels": channels}, stats


def _mean_std(s: dict[str, Any]) -> str:
    """Mean and standard deviation in display units, both to the decimal of the deviation's third digit."""
    mean, std = s["mean"] / s["per_unit"], s["std"] / s["per_unit"]
    d = max(0, 2 - math.floor(math.log10(std))) if std > 0 and math.isfinite(std) else 3
    return f"{mean:.{d}f} {s['unit']}, {std:.{d}f} {s['unit']}"


def build_noise_report(
    rr: RecordedRun,
    binfo: BenchInfo,
    issue_date: str,
    *,
    complete: bool,
    incomplete_reason: str,
    bench_block: dict[str, Any],
    recording_block: dict[str, Any],
    procedure_block: dict[str, Any],
    temperature: dict[str, float],
    creation_date: str,
    software: str,
    with_plots: bool = True,
    analyses: dict[str, list[dict[str, str]]] | None = None,
    analysis_plots: list[tuple[str, bytes]] | None = None,
) -> Certificate:
    """The noise report of the static record ``rr`` (see the module docstring); the blocks it shares with a
    calibration certificate (bench, recording, procedure) are built by :mod:`benches.certificate.build`.
    ``analyses``/``analysis_plots``: the run folder's own analyses (``RUN/noise``, ``periodic``, ``drift``; rows
    of :func:`benches.certificate.analyses.analysis_rows`), quoted after the report's own noise terms."""

    step = record_step(rr.steps)
    rate = float(recording_block.get("sample_rate_hz") or 0.0)
    warnings: list[str] = []
    noise: dict[str, Any] = {"channels": {}}
    stats: dict[str, Any] = {}
    if step is None or rate <= 0:
        warnings.append("the recording has no complete hold step to analyse: no noise terms")
    else:
        noise, stats = analyse_record(rr, step, rate)
    rows: list[dict[str, str]] = []
    for ch, c in noise["channels"].items():
        rows += noise_rows(ch, c)
    stat_rows = [{"channel": ch, "item": "mean, standard deviation", "value": _mean_std(s)} for ch, s in stats.items()]
    if not (binfo.ambient or {}).get("temperature_k"):
        warnings.append(
            "the laboratory's ambient conditions are not stated in the bench file (site.ambient): the report cannot "
            "state the conditions of the measurement; state site.ambient and re-issue"
        )
    warnings.append(
        "a static record (one attitude, no rotation) determines no calibration parameter: bias, scale factor and "
        "misalignment need several attitudes, the size effect needs spins; for a calibration run "
        "'tablebench run --procedure ten-step' (or ten-step-fast-spin)"
    )
    plots: dict[str, Any] = {}
    if with_plots and noise["channels"]:
        plots["noise"] = plot_noise_report(noise, title=f"Overlapping Allan deviation, step {step.name!r}")
    ambient = dict(binfo.ambient or {})
    return Certificate(
        number=f"TB-{str(recording_block.get('sha256', ''))[:10].upper()}",
        issue_date=issue_date,
        verdict=NOISE_REPORT,
        reasons=[],
        complete=complete,
        incomplete_reason=incomplete_reason,
        unit={"model": binfo.unit_model, "serial_number": binfo.unit_serial},
        bench=bench_block,
        procedure=procedure_block,
        recording=recording_block,
        environment={
            "unit_temperature_k": temperature,
            "unit_temperature_c": {k: kelvin_to_celsius(v) for k, v in temperature.items()},
            "laboratory_ambient": {**ambient, "stated": ambient.get("temperature_k") is not None,
                                   "text": ambient_text(ambient)},
        },
        identification={},
        parameters=[],
        budget_components=[],
        budget_notes=[],
        coverage_factor=2.0,
        covariance=[],
        warnings=warnings,
        analyses={"noise": rows, "record": stat_rows, **{f"run folder {k}": v for k, v in (analyses or {}).items()}},
        analysis_plots=list(analysis_plots or []),
        software_version=software,
        creation_date=creation_date,
        plots=plots,
        document=NOISE_REPORT,
        noise={
            "step": None if step is None else step.name,
            "samples": 0 if step is None else int(step.acq_end - step.acq_start),
            "duration_s": 0.0 if step is None or rate <= 0 else (step.acq_end - step.acq_start) / rate,
            "method": "overlapping Allan deviation, octave τ, noise terms by weighted NNLS (IEEE 952 / 1293); "
            "U = 2σ of each term",
            "analysis": noise,
            "statistics": stats,
        },
    )


__all__ = ["NOISE_REPORT", "analyse_record", "build_noise_report", "is_static_record", "record_step"]
