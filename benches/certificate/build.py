"""The calibration certificate: a content model built from a run folder, rendered to PDF and JSON.

:func:`build_certificate` reads ``RUN/recording.h5`` (``benches/RECORDING.md``), ``RUN/calibration.json``
(``benches/CALIBRATION_FORMAT.md``), the bench file recorded in the recording (pass/fail limits, mounting,
table accuracy, site), and the optional analyses ``RUN/noise/noise.json``, ``RUN/periodic/periodic.json``,
``RUN/drift/drift.json`` (with their PNG plots), and returns a :class:`Certificate`. The PDF
(:mod:`benches.certificate.pdf`) and the JSON (:meth:`Certificate.to_json`) are two renderings of it.

Document control: :func:`issue_certificate` publishes the certificate through the result sinks
(:mod:`benches.results`); the first, the run folder, takes the number from the register in the runs folder
(:mod:`benches.certificate_register`: monotonic, never reused); a re-issue gets a new number and names the one
it supersedes; an existing certificate file is never overwritten.

Determinism: everything on the certificate is derived from the run folder except the issue date and the
number (a :class:`Certificate` built by :func:`build_certificate` carries a provisional ``TB-`` + 10 hex digits
of the recording's SHA-256 until it is issued); the PDF's creation date is the recording's creation time and
plots are rendered deterministically, so a pinned ``issue_date`` and number give byte-identical files.

Decision rule: :mod:`analysis.identification.decision` (ILAC-G8:09/2019, guarded acceptance with w = U):
per parameter PASS / FAIL / UNDECIDED (U straddles the limit) / NOT EVALUATED (the procedure cannot identify
it) / INVALID (non-finite, failed integrity); overall PASS only when every limited parameter passes.
"""


from __future__ import annotations

import contextlib
import datetime as _dt
import gc
import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.identification.decision import (
    FAIL,
    INVALID,
    NOT_EVALUATED,
    UNDECIDED,
    decide,
    overall_verdict,
)
from analysis.units import ARCSEC, display_unit, kelvin_to_celsius, to_display
from benches.bench_config import BenchConfig, load_bench_text
from benches.calibration_integrity import load_verified
from benches.calibration_result import SI_UNITS, CalibrationFormatError, CalibrationResult
from benches.recorded_run import RecordedRun, run_of
from benches.recording import RecordingError, StepRecord, file_identity
from benches.results.chain import sinks_for_run
from benches.results.sink import CertificateDocument, ResultSinks
from core.provenance import file_sha256, software_version

from .analyses import analysis_rows
from .budget import (
    StepGeometry,
    UncertaintyBudget,
    budget_for_run,
    default_g_uncertainty,
    step_geometry,
)
from .content import (
    AMBIENT_NOT_STATED,
    ANALYSES,
    BenchInfo,
    Certificate,
    CertificateError,
    ParameterResult,
    ambient_text,
    format_with_uncertainty,
)
from .noise_report import build_noise_report, is_static_record
from .plots import plot_convergence, plot_coverage, plot_residuals


def _load_bench_config(text: str) -> BenchConfig:
    """The recorded bench text through ``benches.bench_config`` (ConfigError names the recording's copy)."""
    return load_bench_text(text, "recording.h5:/bench_yaml")


def bench_info(bench_text: str, cal_run: dict[str, Any], rec_attrs: dict[str, Any]) -> BenchInfo:
    """Bench identity, limits and accuracy: from the recorded bench file, else ``calibration.json`` ``run``.

    Parameters
    ----------
    bench_text : str
        The bench file recorded at ``/bench_yaml`` (empty: fall back to ``cal_run``, without limits).
    cal_run : dict
        ``calibration.json`` ``run`` block.
    rec_attrs : dict
        The recording's root attributes.
    """
    cfg = _load_bench_config(bench_text) if bench_text.strip() else None
    return bench_info_of(cfg, cal_run, rec_attrs)


def bench_info_of(cfg: BenchConfig | None, cal_run: dict[str, Any], rec_attrs: dict[str, Any]) -> BenchInfo:
    """:func:`bench_info` from the parsed bench (None: fall back to ``calibration.json`` ``run``)."""
    site = dict(cal_run.get("site") or {})
    table = dict(cal_run.get("table") or {})
    unit = dict(cal_run.get("unit") or {})
    if cfg is not None:
        s, t, u = cfg.site, cfg.turntable, cfg.unit
        g_src = str(s.g_source)
        g_unc = float(s.g_uncertainty)
        return BenchInfo(
            name=str(cfg.name),
            limits={str(k): float(v) for k, v in dict(cfg.limits or {}).items()},
            mounting=np.asarray(u.mounting, dtype=float).tolist() if getattr(u, "mounting", None) is not None else None,
            attitude_accuracy=float(t.attitude_accuracy),
            site_name=str(getattr(s, "name", "")),
            latitude_deg=math.degrees(float(s.latitude)),
            height_m=float(s.height),
            g=float(s.g),
            g_source=g_src,
            g_uncertainty=g_unc,
            table_model=str(getattr(t, "model", "") or ""),
            table_serial=str(getattr(t, "serial_number", "") or ""),
            unit_model=str(getattr(u, "model", "") or ""),
            unit_serial=str(getattr(u, "serial_number", "") or ""),
            source="bench file recorded in the recording",
            bias_instability=np.asarray(u.noise.bias_instability, dtype=float).tolist(),
            gyro_bias_instability=np.asarray(u.noise.gyro_bias_instability, dtype=float).tolist(),
            azimuth_uncertainty=getattr(t, "azimuth_uncertainty", None),
            rate_accuracy=float(getattr(t, "rate_accuracy", 0.0) or 0.0),
            reference_standards=[
                {"name": r.name, "serial_number": r.serial_number, "certificate": r.certificate,
                 "calibrated_by": r.calibrated_by, "due": r.due.isoformat()}
                for r in getattr(cfg, "reference_standards", ())
            ],  # fmt: skip
            latency=float(getattr(u, "latency", 0.0) or 0.0),
            ambient=_ambient_si(getattr(s, "ambient", None)),
        )
    g = float(site.get("g") or rec_attrs.get("site_g") or 0.0)
    if not g > 0:
        raise CertificateError("local g unknown: neither the bench loader nor calibration.json run.site.g gives it")
    g_src = str(site.get("g_source") or rec_attrs.get("site_g_source") or "unknown")
    return BenchInfo(
        name=str(cal_run.get("bench_name") or rec_attrs.get("bench_name", "")),
        limits={},
        mounting=None,
        attitude_accuracy=float(table.get("attitude_accuracy") or 0.0),
        site_name=str(site.get("name", "")),
        latitude_deg=site.get("latitude_deg"),
        height_m=site.get("height_m"),
        g=g,
        g_source=g_src,
        g_uncertainty=float(site.get("g_uncertainty") or default_g_uncertainty(g_src.startswith("measured"))),
        table_model=str(table.get("model", "")),
        table_serial=str(table.get("serial_number", "")),
        unit_model=str(unit.get("model", "")),
        unit_serial=str(unit.get("serial_number", "")),
        source="calibration.json run block (bench loader not available: no pass/fail limits)",
    )


def _ambient_si(ambient: Any) -> dict[str, float | None]:
    """The bench's ``site.ambient`` (:class:`benches.bench_config.Ambient`) as the certificate keeps it (SI)."""
    if ambient is None:
        return {}
    return {
        "temperature_k": ambient.temperature,
        "temperature_tolerance_k": ambient.temperature_tolerance,
        "relative_humidity": ambient.relative_humidity,
        "pressure_pa": ambient.pressure,
    }


def _load_json(path: Path, what: str) -> dict[str, Any]:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise CertificateError(f"{path}: cannot read the {what} ({exc}); re-create it") from None


# ---- the content model: gather / decide / assemble ---------------------------------------------------------


@dataclass
class Gathered:
    """Everything the certificate states, read from the run folder (recording, calibration.json, analyses)."""

    run: Path
    rec_path: Path
    cal_path: Path
    rec_sha: str
    attrs: dict[str, Any]
    steps: tuple[StepRecord, ...]
    run_status: str
    complete: bool
    incomplete_reason: str
    cal: CalibrationResult | None  # None: a noise report (no calibration is stated)
    procedure_steps: int | None
    binfo: BenchInfo
    geometry: list[StepGeometry]
    temperature: dict[str, float]
    n_samples: int
    duration_s: float
    event_warnings: list[str]
    integrity: dict[str, Any]
    overrides: dict[str, float]
    per_step: list[dict[str, Any]]
    analyses: dict[str, list[dict[str, str]]] = field(default_factory=dict)
    analysis_plots: list[tuple[str, bytes]] = field(default_factory=list)


@dataclass
class Decision:
    """The uncertainty budget, the per-parameter results with their verdicts, and the overall verdict."""

    budget: UncertaintyBudget
    results: list[ParameterResult]
    verdict: str
    reasons: list[str]
    warnings: list[str]


def _run_paths(run_dir: str | Path) -> tuple[Path, Path, Path]:
    given = Path(run_dir)
    run = given.parent if given.is_file() else given
    rec_path = given if given.is_file() else run / "recording.h5"
    if not rec_path.exists():
        raise CertificateError(f"{given}: no recording.h5 here; give a run folder printed by 'tablebench run'")
    return run, rec_path, run / "calibration.json"


def _completeness(rr: RecordedRun, allow_incomplete: bool, run: Path) -> tuple[bool, str]:
    run_status = str(rr.header.status or "?")
    bad = rr.incomplete_steps()
    reason_parts = []
    if run_status != "complete":
        reason_parts.append(f"the recording's status is {run_status!r}")
    for s in bad:
        reason_parts.append(f"step {s.index} {s.name!r} {s.status}")
    complete = run_status == "complete" and not bad
    incomplete_reason = "; ".join(reason_parts)
    if not complete and not allow_incomplete:
        raise CertificateError(
            f"{rr.path}: the run is incomplete ({incomplete_reason}); resume it with 'tablebench run --resume "
            f"{run}', or issue a certificate of the completed steps with --allow-incomplete"
        )
    return complete, incomplete_reason


def _load_calibration(cal_path: Path, run: Path, rec_sha: str) -> CalibrationResult:
    if not cal_path.exists():
        raise CertificateError(f"{run}: no calibration.json; identify first ('tablebench identify {run}')")
    try:
        cal, _digest = load_verified(cal_path)  # format, integrity digest, plausible values
    except CalibrationFormatError as exc:
        raise CertificateError(str(exc)) from None
    if cal.recording_sha256 and cal.recording_sha256 != rec_sha:
        raise CertificateError(
            f"{cal_path}: was identified from a different recording (SHA-256 differs from recording.h5); "
            f"identify this recording again"
        )
    return cal


def _gather_analyses(run: Path) -> tuple[dict[str, list[dict[str, str]]], list[tuple[str, bytes]]]:
    analyses: dict[str, list[dict[str, str]]] = {}
    analysis_plots: list[tuple[str, bytes]] = []
    for kind in ANALYSES:
        p = run / kind / f"{kind}.json"
        if p.exists():
            analyses[kind] = analysis_rows(kind, _load_json(p, f"{kind} analysis"))
            for png in sorted((run / kind).glob("*.png"))[:6]:
                analysis_plots.append((f"{kind}/{png.name}", png.read_bytes()))
    return analyses, analysis_plots


def gather(
    run_dir: str | Path,
    *,
    allow_incomplete: bool = False,
    bench: BenchInfo | None = None,
    recorded: RecordedRun | None = None,
) -> Gathered:
    """Read what the certificate states from the run folder (see :func:`build_certificate`)."""
    run, rec_path, cal_path = _run_paths(run_dir)
    with contextlib.ExitStack() as stack:
        try:
            rr = stack.enter_context(run_of(recorded if recorded is not None else rec_path))
        except RecordingError as exc:
            raise CertificateError(str(exc)) from None
        return _gather_open(rr, run, rec_path, cal_path, rr.sha256, allow_incomplete, bench)


def _gather_open(
    rr: RecordedRun,
    run: Path,
    rec_path: Path,
    cal_path: Path,
    rec_sha: str,
    allow_incomplete: bool,
    bench: BenchInfo | None,
    calibration: bool = True,
) -> Gathered:
    """What the document states, from the open run; ``calibration`` False (a noise report): no calibration.json
    is read (``cal`` None, no step geometry)."""
    f = rr.recording
    attrs = rr.header.as_dict()
    attrs["seed"] = -1 if attrs.get("seed") is None else attrs["seed"]
    complete, incomplete_reason = _completeness(rr, allow_incomplete, run)
    cal = _load_calibration(cal_path, run, rec_sha) if calibration else None
    bench_text = rr.bench_text
    compiled = rr.compiled
    cal_run = cal.run.to_mapping() if cal is not None and cal.run is not None else {}
    binfo = bench or bench_info_of(rr.config if bench_text.strip() else None, cal_run, attrs)
    geometry = _geometry(rr, binfo, cal) if cal is not None else []
    n_samples = f.n_samples
    # the first and the last sample's times, each read alone (an index spanning the file put the whole verified
    # time column together first: 23 MB copied for two numbers, issue 32)
    ends = (f.samples(0, 1, ("time",)).time[0], f.samples(n_samples - 1, n_samples, ("time",)).time[0]) if (
        n_samples > 1) else None  # fmt: skip
    analyses, analysis_plots = _gather_analyses(run)
    return Gathered(
        run=run,
        rec_path=rec_path,
        cal_path=cal_path,
        rec_sha=rec_sha,
        attrs=attrs,
        steps=rr.steps,
        run_status=str(attrs.get("status", "?")),
        complete=complete,
        incomplete_reason=incomplete_reason,
        cal=cal,
        procedure_steps=None if compiled is None else len(compiled.steps),
        binfo=binfo,
        geometry=geometry,
        temperature=f.temperature_stats(),
        n_samples=n_samples,
        duration_s=float(ends[-1] - ends[0]) if ends is not None else 0.0,
        event_warnings=[
            f"bench t = {e.time:.1f} s: {e.message}" for e in f.events() if e.level.lower() in ("warning", "error")
        ],
        integrity={"verified": f.integrity_verified, "note": f.integrity_note},
        overrides=dict(rr.header.procedure_overrides),
        per_step=_per_step_rows(cal, cal_path) if cal is not None else [],
        analyses=analyses,
        analysis_plots=analysis_plots,
    )


def _parameter_result(
    g: Gathered, budget: UncertaintyBudget, i: int, name: str, kind: str, integrity_ok: bool
) -> tuple[ParameterResult, str | None, str | None]:
    """One parameter's row, its decision, and a reason (FAIL/INVALID) or an unverified note."""
    x, unc, exp_u = g.cal.x, budget.combined, budget.expanded
    comp_std = {c.key: c.std for c in budget.components}
    pr = g.cal.parameters[name]
    lim = g.binfo.limits.get(name)
    dv, du = to_display(kind, x[i]), to_display(kind, exp_u[i])
    v_txt, u_txt = format_with_uncertainty(dv, du)
    conf = decide(float(x[i]), float(exp_u[i]), lim, identified=pr.identified, integrity_ok=integrity_ok,
                  full_rank=True)  # fmt: skip
    verdict = conf.verdict
    lim_txt = "" if lim is None else f"±{to_display(kind, lim):.4g} {display_unit(kind)}"
    reason = unverified = None
    if verdict == FAIL:
        reason = f"{name} = {v_txt} ± {u_txt} {display_unit(kind)} (U, k = 2) exceeds the limit {lim_txt}"
    elif verdict == INVALID:
        reason = f"{name}: {conf.reason}"
    elif verdict in (UNDECIDED, NOT_EVALUATED) and lim is not None:
        unverified = f"{name} ({verdict.lower()}): {conf.reason}; limit {lim_txt}"
    row = ParameterResult(
        name=name,
        kind=kind,
        unit=SI_UNITS[kind],
        display_unit=display_unit(kind),
        value=float(x[i]),
        standard_uncertainty=float(unc[i]),
        expanded_uncertainty=float(exp_u[i]),
        display_value=float(dv),
        display_expanded=float(du),
        value_text=v_txt,
        expanded_text=u_txt,
        identifiable=pr.identified,
        limit=None if lim is None else float(lim),
        display_limit=None if lim is None else float(to_display(kind, lim)),
        verdict=verdict,
        budget={k: float(v[i]) for k, v in comp_std.items()},
        display_budget={k: float(to_display(kind, v[i])) for k, v in comp_std.items()},
    )
    return row, reason, unverified


_RECENT: dict[str, Any] = {}
"""The step geometry and GUM budget last formed in this process, with their key (:func:`_budget_key`): the
certificate of the run just identified takes them from the NEES line's :func:`combined_covariance` instead of
forming them a second time (the same recording, calibration and bench: the same numbers)."""


def _budget_key(rr: RecordedRun, binfo: BenchInfo, cal: CalibrationResult) -> tuple | None:
    """(recording file and its identity, :func:`benches.recording.file_identity`; the SHA-256 of the calibration
    as calibration.json states it; the bench's certificate inputs); None when it cannot be stated."""
    try:
        path = Path(rr.path)
        ident = file_identity(path)
        doc = json.dumps(cal.to_dict(), sort_keys=True, default=str)
    except (OSError, TypeError, ValueError):
        return None
    return (str(path.resolve()), ident, hashlib.sha256(doc.encode()).hexdigest(), repr(binfo))


def _geometry(rr: RecordedRun, binfo: BenchInfo, cal: CalibrationResult) -> list[StepGeometry]:
    """The reference of each step the identification used (THE reference function, the bench's mounting)."""
    key = _budget_key(rr, binfo, cal)
    if key is not None and _RECENT.get("key") == key:
        return _RECENT["geometry"]
    used = [str(p.get("name")) for p in cal.per_step]
    lat = None if binfo.latitude_deg is None else math.radians(float(binfo.latitude_deg))
    tb = cal.time_base.estimate if cal.time_base is not None else None
    geometry = step_geometry(rr.recording, binfo.g, None if binfo.mounting is None else np.asarray(binfo.mounting),
                             latency=binfo.latency, names=used or None, latitude=lat, time_base=tb)  # fmt: skip
    _RECENT.clear()
    if key is not None:
        _RECENT.update(key=key, geometry=geometry)
    return geometry


def _budget(cal: CalibrationResult, geometry: list[StepGeometry], binfo: BenchInfo, where: Path) -> UncertaintyBudget:
    """The GUM budget of a calibration: its own covariance plus the bench's type-B components (formed once per
    geometry of :func:`_geometry`: the NEES line and the certificate of one run share it)."""
    if _RECENT.get("geometry") is geometry and "budget" in _RECENT:
        return _RECENT["budget"]
    budget = _form_budget(cal, geometry, binfo, where)
    if _RECENT.get("geometry") is geometry:
        _RECENT["budget"] = budget
    return budget


def _form_budget(
    cal: CalibrationResult, geometry: list[StepGeometry], binfo: BenchInfo, where: Path
) -> UncertaintyBudget:
    try:
        return budget_for_run(
            cal,
            geometry,
            g=binfo.g,
            g_uncertainty=binfo.g_uncertainty,
            g_source=binfo.g_source,
            attitude_accuracy=binfo.attitude_accuracy,
            bias_instability=None if binfo.bias_instability is None else np.asarray(binfo.bias_instability),
            gyro_bias_instability=None if binfo.gyro_bias_instability is None else np.asarray(
                binfo.gyro_bias_instability
            ),
            latitude=None if binfo.latitude_deg is None else math.radians(float(binfo.latitude_deg)),
            azimuth_uncertainty=binfo.azimuth_uncertainty,
        )
    except ValueError as exc:
        raise CertificateError(f"{where}: {exc}") from None


def combined_covariance(cal: CalibrationResult, run: str | Path | RecordedRun) -> np.ndarray:
    """The covariance a certificate of ``cal`` would state (type A + B, SI, the calibration's names order),
    without issuing one: what ``run`` and ``identify`` judge their NEES against the simulator truth with.

    Raises
    ------
    CertificateError
        The recording cannot be read or the budget cannot be formed.
    """
    try:
        with run_of(run) as rr:
            cal_run = cal.run.to_mapping() if cal.run is not None else {}
            binfo = bench_info_of(rr.config if rr.bench_text.strip() else None, cal_run, rr.header.as_dict())
            return _budget(cal, _geometry(rr, binfo, cal), binfo, rr.path).covariance
    except RecordingError as exc:
        raise CertificateError(str(exc)) from None


def decide_conformity(g: Gathered) -> Decision:
    """The GUM budget and the ILAC-G8 decision per parameter and overall (see the module docstring)."""
    assert g.cal is not None, "a calibration certificate needs the calibration (a noise report has none)"
    binfo = g.binfo
    integrity_ok = True  # open_recording() verified every checksum (a damaged recording raised above)
    budget = _budget(g.cal, g.geometry, binfo, g.cal_path)
    results: list[ParameterResult] = []
    reasons: list[str] = []
    unverified: list[str] = []
    model = g.cal.error_model
    n_states = model.n_params
    for i, (name, kind) in enumerate(zip(model.names, model.kinds, strict=True)):
        row, reason, note = _parameter_result(g, budget, i, name, kind, integrity_ok)
        results.append(row)
        reasons += [reason] if reason else []
        unverified += [note] if note else []
    info = g.cal.information
    rank = int((info.rank if info is not None and info.rank is not None else n_states) or 0)
    verdict = overall_verdict(
        [p.verdict for p in results],
        [p.limit is not None for p in results],
        complete=g.complete,
        integrity_ok=integrity_ok,
        full_rank=rank == n_states,
    )
    if rank != n_states:
        unverified.append(f"the identification has information rank {rank} < {n_states}: no overall PASS is possible")
    reasons.extend(unverified)
    plan_warnings = (g.cal.plan.warnings if g.cal.plan is not None else None) or []
    warnings = list(dict.fromkeys([*plan_warnings, *g.cal.warnings]))
    unident = [p.name for p in results if not p.identifiable]
    if unident:
        warnings.append("not identified (prior-dominated, do not use for compensation): " + ", ".join(unident))
    if not binfo.limits:
        warnings.append("the bench file gives no pass/fail limits: no conformity statement")
    if (binfo.ambient or {}).get("temperature_k") is None:
        warnings.append(
            f"the laboratory's ambient conditions are {AMBIENT_NOT_STATED}: the certificate cannot state the "
            "conditions of the calibration (ISO/IEC 17025 7.8.4.1); state site.ambient and re-issue"
        )
    warnings.extend(g.event_warnings)
    if not g.integrity["verified"]:
        warnings.insert(0, g.integrity["note"])
    return Decision(budget, results, verdict, reasons, warnings)


def _bench_block(g: Gathered) -> dict[str, Any]:
    binfo, attrs = g.binfo, g.attrs
    return {
        "name": binfo.name,
        "table_model": binfo.table_model,
        "table_serial_number": binfo.table_serial,
        "attitude_accuracy": binfo.attitude_accuracy,
        "attitude_accuracy_arcsec": binfo.attitude_accuracy / ARCSEC,
        "site": binfo.site_name,
        "latitude_deg": binfo.latitude_deg,
        "height_m": binfo.height_m,
        "g": binfo.g,
        "g_source": binfo.g_source,
        "g_uncertainty": binfo.g_uncertainty,
        "simulated": bool(attrs.get("simulated", False)),
        "transport": str(attrs.get("transport", "")),
        "limits": binfo.limits,
        "source": binfo.source,
        "rate_accuracy_ppm": binfo.rate_accuracy * 1e6,
        "reference_standards": [
            {**r, "overdue": bool(r["due"] < str(attrs.get("created_utc", ""))[:10])}
            for r in binfo.reference_standards
        ],
    }


def _recording_block(g: Gathered) -> dict[str, Any]:
    attrs = g.attrs
    return {
        "file": "recording.h5",
        "sha256": g.rec_sha,
        "status": g.run_status,
        "created_utc": str(attrs.get("created_utc", "")),
        "updated_utc": str(attrs.get("updated_utc", "")),
        "software_version": str(attrs.get("software_version", "")),
        "seed": attrs.get("seed", -1),
        "samples": g.n_samples,
        "duration_s": g.duration_s,
        "sample_rate_hz": float(attrs.get("sample_rate_hz", 0.0) or 0.0),
        "integrity_verified": g.integrity["verified"],
        "integrity_note": g.integrity["note"],
        "steps_complete": sum(s.status == "complete" for s in g.steps),
        "steps": g.procedure_steps if g.procedure_steps is not None else len(g.steps),
        "steps_recorded": len(g.steps),
    }


def relative_misalignment(names: list[str], x: np.ndarray, cov: np.ndarray) -> dict[str, Any]:
    """The gyro triad's misalignment relative to the accelerometer triad, τ_g,ij − τ_a,ij, with U (k = 2).

    Both come from one recording against one table, so the table's own non-orthogonality and the unit's
    mounting cancel in the difference (docs/methods/gyro-calibration.md); u from the certificate's full
    covariance (the two triads' terms are correlated through the shared type-B inputs).
    """
    pairs = [p for p in ("xy", "xz", "yx", "yz", "zx", "zy") if f"gyro_tau_{p}" in names and f"tau_{p}" in names]
    if not pairs:
        return {}
    out = {}
    for p in pairs:
        i, j = names.index(f"gyro_tau_{p}"), names.index(f"tau_{p}")
        var = cov[i, i] + cov[j, j] - 2 * cov[i, j]
        u = float(np.sqrt(max(var, 0.0)))
        out[f"tau_{p}"] = {"value": float(x[i] - x[j]), "u": u, "expanded_uncertainty": 2 * u,
                           "display_value": float((x[i] - x[j]) / ARCSEC), "display_expanded": 2 * u / ARCSEC,
                           "display_unit": "arcsec"}  # fmt: skip
    return {"gyro_to_accelerometer_misalignment": out}


def assemble(g: Gathered, d: Decision, issue_date: str, with_plots: bool = True) -> Certificate:
    """The certificate's content model from what was gathered and decided (figures when ``with_plots``)."""
    cal, budget = g.cal, d.budget
    assert cal is not None
    created = str(g.attrs.get("created_utc", ""))
    written = cal.to_dict()  # as calibration.json states them
    ambient = dict(g.binfo.ambient or {})
    cert = Certificate(
        number=f"TB-{g.rec_sha[:10].upper()}",
        issue_date=issue_date,
        verdict=d.verdict,
        reasons=d.reasons,
        complete=g.complete,
        incomplete_reason=g.incomplete_reason,
        unit={"model": g.binfo.unit_model, "serial_number": g.binfo.unit_serial},
        bench=_bench_block(g),
        procedure=_procedure_block(g),
        recording=_recording_block(g),
        environment={
            "unit_temperature_k": g.temperature,
            "unit_temperature_c": {k: kelvin_to_celsius(v) for k, v in g.temperature.items()},
            "laboratory_ambient": {**ambient, "stated": ambient.get("temperature_k") is not None,
                                   "text": ambient_text(ambient)},
        },
        identification={
            "method": cal.method,
            "calibration_sha256": file_sha256(g.cal_path),
            "information": written.get("information", {}),
            "measurement_noise": written["measurement_noise"],
            "steps_used": [geo.name for geo in g.geometry],
            **relative_misalignment(list(cal.names), cal.x, budget.covariance),
        },
        parameters=d.results,
        budget_components=[
            {"key": c.key, "label": c.label, "type": c.type, "source": c.source} for c in budget.components
        ],
        budget_notes=list(budget.notes),
        coverage_factor=budget.coverage_factor,
        covariance=budget.covariance.tolist(),
        warnings=d.warnings,
        analyses=g.analyses,
        software_version=software_version(),
        creation_date=_creation_datetime(created).isoformat(),
        analysis_plots=g.analysis_plots,
    )
    if with_plots:
        cert.plots["residuals"] = plot_residuals(g.per_step, cal.noise_variance[:3])
        if cal.noise_variance.size == 6:
            cert.plots["gyro_residuals"] = plot_residuals(g.per_step, cal.noise_variance[3:], triad="gyro")
        hist = cal.history.to_mapping() if cal.history is not None else {}
        if len(hist.get("time") or []) >= 2:  # a single update has nothing to converge
            ident = list(cal.identified)
            for part, grp in zip(cal.error_model.parts, cal.error_model.groups, strict=True):
                key = "convergence" if grp.start == 0 else f"{part.name}_convergence"
                sub = {**hist, "estimate": [row[grp] for row in hist["estimate"]],
                       "sigma": [row[grp] for row in hist["sigma"]]}  # fmt: skip
                cert.plots[key] = plot_convergence(
                    sub, list(cal.names[grp]), part.kinds, cal.x[grp], identified=ident[grp]
                )
        cert.plots["coverage"] = plot_coverage(g.geometry)
    return cert


def _issue_date(issue_date: str | None) -> str:
    if issue_date is None:
        return _dt.datetime.now(_dt.timezone.utc).date().isoformat()
    try:
        return _dt.date.fromisoformat(issue_date).isoformat()
    except ValueError:
        raise CertificateError(f"--issue-date {issue_date!r}: expected YYYY-MM-DD") from None


def build_certificate(
    run_dir: str | Path,
    *,
    issue_date: str | None = None,
    allow_incomplete: bool = False,
    bench: BenchInfo | None = None,
    with_plots: bool = True,
    recorded: RecordedRun | None = None,
) -> Certificate:
    """Build the certificate of the run in ``run_dir``: :func:`gather`, :func:`decide_conformity`, :func:`assemble`.

    Parameters
    ----------
    run_dir : path
        Run folder holding ``recording.h5`` and ``calibration.json`` (or the recording file itself).
    issue_date : str, optional
        ``YYYY-MM-DD``; default today (UTC). The only field that varies between two issues of one run.
    allow_incomplete : bool
        Issue a certificate for an interrupted/failed recording (marked on its first page).
    bench : BenchInfo, optional
        Override the bench information read from the recording (tests, re-issues against other limits).
    with_plots : bool
        Draw the figures (vector drawings in ``Certificate.plots``).
    recorded : RecordedRun, optional
        The run's recording already opened (``tablebench run``); default: opened here.

    Raises
    ------
    CertificateError
        Missing/mismatched inputs, or an incomplete recording without ``allow_incomplete``.
    """
    run, rec_path, cal_path = _run_paths(run_dir)  # a missing recording is named before a bad --issue-date
    date = _issue_date(issue_date)
    with contextlib.ExitStack() as stack:
        try:
            rr = stack.enter_context(run_of(recorded if recorded is not None else rec_path))
        except RecordingError as exc:
            raise CertificateError(str(exc)) from None
        if is_static_record(rr.steps):  # one attitude, no rotation: a noise report, not a calibration
            g = _gather_open(rr, run, rec_path, cal_path, rr.sha256, allow_incomplete, bench, calibration=False)
            return build_noise_report(
                rr, g.binfo, date, complete=g.complete, incomplete_reason=g.incomplete_reason,
                bench_block=_bench_block(g), recording_block=_recording_block(g),
                procedure_block=_procedure_block(g), temperature=g.temperature,
                creation_date=_creation_datetime(str(g.attrs.get("created_utc", ""))).isoformat(),
                software=software_version(), with_plots=with_plots, analyses=g.analyses,
                analysis_plots=g.analysis_plots,
            )  # fmt: skip
        g = _gather_open(rr, run, rec_path, cal_path, rr.sha256, allow_incomplete, bench)
    return assemble(g, decide_conformity(g), date, with_plots)


def _procedure_block(g: Gathered) -> dict[str, Any]:
    return {
        "name": str(g.attrs.get("procedure_name", "")),
        "sha256": str(g.attrs.get("procedure_sha256", "")),
        "procedure_overrides": g.overrides,
    }


def _per_step_rows(cal: CalibrationResult, path: Path) -> list[dict[str, Any]]:
    """calibration.json residuals.per_step, checked (name, samples, mean (axes), rms (axes), SI)."""
    try:
        per_step = cal.per_step
        for row in per_step:
            ok = (
                int(row["samples"]) >= 0
                and np.all(np.isfinite(np.asarray(row["mean"], dtype=float).reshape(-1)))
                and np.all(np.isfinite(np.asarray(row["rms"], dtype=float).reshape(-1)))
            )
            if not ok:
                raise ValueError(f"row {row.get('name')!r} has non-finite statistics")
    except (KeyError, TypeError, ValueError) as exc:
        raise CertificateError(
            f"{path}: residuals.per_step is missing or malformed ({exc.__class__.__name__}: {exc}); see "
            "benches/CALIBRATION_FORMAT.md, or identify the run again"
        ) from None
    return per_step


def _creation_datetime(created_utc: str) -> _dt.datetime:
    """The recording's creation time (fixed PDF creation date); the epoch if unreadable."""
    try:
        t = _dt.datetime.fromisoformat(created_utc.replace("Z", "+00:00"))
        return (t if t.tzinfo else t.replace(tzinfo=_dt.timezone.utc)).replace(microsecond=0)
    except ValueError:
        return _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)


def issue_certificate(
    run_dir: str | Path,
    out_pdf: str | Path | None = None,
    out_json: str | Path | None = None,
    issue_date: str | None = None,
    allow_incomplete: bool = False,
    recorded: RecordedRun | None = None,
    sinks: ResultSinks | None = None,
) -> tuple[Path, Path, str]:
    """Build the certificate of a run and publish it through the result sinks (:mod:`benches.results`).

    The run folder sink allocates the number and writes ``RUN/certificate.pdf`` and ``RUN/certificate.json``
    by default (or ``out_pdf``/``out_json``); further sinks (the calibration registry) record it.

    Returns
    -------
    (pdf_path, json_path, verdict)
        verdict: "PASS", "FAIL", "INCONCLUSIVE", "INCOMPLETE" or "NO LIMITS".
    """
    with _heap_frozen():
        cert = build_certificate(run_dir, issue_date=issue_date, allow_incomplete=allow_incomplete, recorded=recorded)
        pdf, js = publish_certificate(cert, run_dir, out_pdf, out_json, sinks)
    return pdf, js, cert.verdict


@contextlib.contextmanager
def _heap_frozen() -> Any:
    """The objects alive on entry kept out of the garbage collector's scans until exit (``gc.freeze``).

    Rendering parses three TrueType fonts (hundreds of thousands of small objects): the collections that
    triggers scanned everything a ``tablebench run`` process holds by then (recording, identification, live
    view), 0.1–0.3 s of a run's certificate (issue 32). Nothing is lost: ``gc.unfreeze`` hands the objects back
    to the oldest generation, and what the certificate allocates is collected as usual.
    """
    if gc.get_freeze_count():  # inside another freeze (issue → publish, or the caller's own): leave it to that one
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def publish_certificate(
    cert: Certificate,
    run_dir: str | Path,
    out_pdf: str | Path | None = None,
    out_json: str | Path | None = None,
    sinks: ResultSinks | None = None,
) -> tuple[Path, Path]:
    """Publish a built certificate through the result sinks (numbered, rendered, written; never overwriting).
    The second half of :func:`issue_certificate` (``tablebench certificate`` builds interruptibly, then
    publishes). Returns (pdf_path, json_path)."""
    given = Path(run_dir)
    run = given.parent if given.is_file() else given
    sinks = sinks if sinks is not None else sinks_for_run(run)
    with _heap_frozen():
        doc = sinks.certificate(
            CertificateDocument(
                run=run,
                certificate=cert,
                out_pdf=None if out_pdf is None else Path(out_pdf),
                out_json=None if out_json is None else Path(out_json),
            )
        )
    assert doc.pdf is not None and doc.json is not None  # the run folder sink always writes both
    return doc.pdf, doc.json


__all__ = ["Decision", "Gathered", "assemble", "bench_info", "build_certificate", "combined_covariance",
           "decide_conformity", "gather",
           "issue_certificate", "publish_certificate"]
