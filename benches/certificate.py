"""The calibration certificate: a content model built from a run folder, rendered to PDF and JSON.

:func:`build_certificate` reads ``RUN/recording.h5`` (``benches/RECORDING.md``), ``RUN/calibration.json``
(``benches/CALIBRATION_FORMAT.md``), the bench file recorded in the recording (pass/fail limits, mounting,
table accuracy, site), and the optional analyses ``RUN/noise/noise.json``, ``RUN/periodic/periodic.json``,
``RUN/drift/drift.json`` (with their PNG plots), and returns a :class:`Certificate`. The PDF
(:mod:`benches.certificate_pdf`) and the JSON (:meth:`Certificate.to_json`) are two renderings of it.

Document control: :func:`issue_certificate` takes the certificate number from the register in the runs
folder (:mod:`benches.certificate_register`: monotonic, never reused); a re-issue gets a new number and names
the one it supersedes; an existing certificate file is never overwritten.

Determinism: everything on the certificate is derived from the run folder except the issue date and the
number (a :class:`Certificate` built by :func:`build_certificate` carries a provisional ``TB-`` + 10 hex digits
of the recording's SHA-256 until it is issued); the PDF's creation date is the recording's creation time and
plots are rendered deterministically, so a pinned ``issue_date`` and number give byte-identical files.

Decision rule (ILAC-G8:09/2019, simple acceptance): a parameter with a limit L passes when |x̂| ≤ L; when
|x̂| ≤ L < |x̂| + U the pass is reported as "PASS (conditional)" (the expanded uncertainty straddles the
limit). A parameter the data do not identify, or whose expanded uncertainty U is not smaller than its limit
(U ≥ L: no measurement outcome could demonstrate conformity), is "NOT VERIFIED". Overall
verdict: FAIL if any parameter exceeds its limit; else INCOMPLETE for an incomplete run; else INCONCLUSIVE
if a limited parameter is not verified (conformity not established, e.g. the size effect at slow spins);
else PASS (NO LIMITS when the bench gives none).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.units import ARCSEC, display_unit, kelvin_to_celsius, to_display
from core.errors import UserError
from core.provenance import file_sha256, software_version

from .uncertainty_budget import PARAM_KINDS, PARAM_NAMES, UncertaintyBudget, build_budget, default_g_uncertainty

FORMAT = "tablebench-certificate"
FORMAT_VERSION = 1
ANALYSES = ("noise", "periodic", "drift")

MODEL_TEXT = "f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω) + v"
SIGN_CONVENTIONS: tuple[str, ...] = (
    "Body frame b: the unit's case axes x, y, z as marked on the unit; navigation frame n: East-North-Up.",
    "f: true specific force at the triad's reference point, body frame; at rest f = C_n^b [0, 0, g]ᵀ, i.e. an "
    "axis pointing up reads +g.",
    "f_out: the unit's output (after its own count scaling), body frame, m/s².",
    "b: bias, added to the output (f_out − f at zero input); shown in µg (1 µg = 9.80665e-6 m/s²).",
    "S = diag(S_x, S_y, S_z): scale-factor errors, f_out,i ∋ (1 + S_i) f_i; shown in ppm.",
    "T: misalignment, off-diagonal; convention δf_i += τ_ij f_j (output axis i senses τ_ij of the input along j); "
    "shown in arcsec (small angles, rad).",
    "D = diag(d): quadratic (second-order) coefficients, δf_i += d_i f_i²; shown in µg/g².",
    "r: size effect, δf_i += r_i c_i(ω) with c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²]; r_i = −ρ_i,i where ρ_i is "
    "the position of accelerometer i relative to the table's rotation centre; shown in mm.",
    "Compensation: f = (I + S + T)⁻¹ (f_out − b − D(f∘f) − diag(r) c(ω)), solved iteratively (first order: "
    "f ≈ f_out − b − (S + T) f_out).",
)


class CertificateError(UserError, RuntimeError):
    """A certificate cannot be issued from this run folder; the message says why and what to do."""


@dataclass(frozen=True)
class BenchInfo:
    """What the certificate needs of the bench file (SI).

    Attributes
    ----------
    limits : dict
        Parameter name → maximum |value| (SI) for pass/fail.
    mounting : (3, 3) list or None
        C_b^t (identity if None).
    attitude_accuracy : float
        Table attitude accuracy bound, rad.
    g, g_uncertainty : float
        Local gravity and its standard uncertainty, m/s².
    bias_instability : (3,) list or None
        The unit's bias instability per body axis, m/s² (budget component; None: not budgeted).
    """

    name: str
    limits: dict[str, float]
    mounting: list[list[float]] | None
    attitude_accuracy: float
    site_name: str
    latitude_deg: float | None
    height_m: float | None
    g: float
    g_source: str
    g_uncertainty: float
    table_model: str
    table_serial: str
    unit_model: str
    unit_serial: str
    source: str
    bias_instability: list[float] | None = None


@dataclass
class ParameterResult:
    """One row of the results table (values SI and in display units)."""

    name: str
    kind: str
    unit: str
    display_unit: str
    value: float
    standard_uncertainty: float
    expanded_uncertainty: float
    display_value: float
    display_expanded: float
    value_text: str
    expanded_text: str
    identifiable: bool
    limit: float | None
    display_limit: float | None
    verdict: str
    budget: dict[str, float]
    display_budget: dict[str, float]


@dataclass
class Certificate:
    """Everything a certificate says; rendered by :mod:`benches.certificate_pdf` and :meth:`to_json`."""

    number: str
    issue_date: str
    verdict: str
    reasons: list[str]
    complete: bool
    incomplete_reason: str
    unit: dict[str, str]
    bench: dict[str, Any]
    procedure: dict[str, str]
    recording: dict[str, Any]
    environment: dict[str, Any]
    identification: dict[str, Any]
    parameters: list[ParameterResult]
    budget_components: list[dict[str, str]]
    budget_notes: list[str]
    coverage_factor: float
    covariance: list[list[float]]
    warnings: list[str]
    analyses: dict[str, list[dict[str, str]]]
    software_version: str
    creation_date: str
    plots: dict[str, bytes] = field(default_factory=dict)
    analysis_plots: list[tuple[str, bytes]] = field(default_factory=list)
    supersedes: str = ""

    def to_dict(self) -> dict[str, Any]:
        """The machine-readable certificate (SI values; plots by name and SHA-256)."""
        d = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "certificate_number": self.number,
            "supersedes": self.supersedes,
            "issue_date": self.issue_date,
            "verdict": self.verdict,
            "reasons": self.reasons,
            "complete": self.complete,
            "incomplete_reason": self.incomplete_reason,
            "unit": self.unit,
            "bench": self.bench,
            "procedure": self.procedure,
            "recording": self.recording,
            "environment": self.environment,
            "identification": self.identification,
            "model": MODEL_TEXT,
            "sign_conventions": list(SIGN_CONVENTIONS),
            "parameter_names": [p.name for p in self.parameters],
            "compensation": {
                "model": MODEL_TEXT,
                "parameter_names": [p.name for p in self.parameters],
                "x_si": [p.value for p in self.parameters],
                "use": [p.identifiable for p in self.parameters],
                "note": "SI values in parameter_names order; entries with use = false are prior-dominated and must "
                "not be used for compensation (set them to 0)",
            },
            "coverage_factor": self.coverage_factor,
            "parameters": {
                p.name: {
                    k: v
                    for k, v in asdict(p).items()
                    if k not in ("name", "value_text", "expanded_text", "display_budget")
                }
                for p in self.parameters
            },
            "uncertainty_budget": {"components": self.budget_components, "notes": self.budget_notes},
            "covariance": self.covariance,
            "warnings": self.warnings,
            "analyses": self.analyses,
            "software_version": self.software_version,
            "plots": {k: hashlib.sha256(v).hexdigest() for k, v in sorted(self.plots.items())},
            "analysis_plots": {k: hashlib.sha256(v).hexdigest() for k, v in self.analysis_plots},
        }
        return d

    def to_json(self) -> str:
        """Deterministic JSON text of :meth:`to_dict`."""
        return json.dumps(_json_safe(self.to_dict()), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def _json_safe(obj: Any) -> Any:
    """Copy of ``obj`` with numpy scalars as Python numbers and non-finite floats as None (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


# ---- helpers -------------------------------------------------------------------------------------------------


def format_with_uncertainty(value: float, expanded: float, digits: int = 2) -> tuple[str, str]:
    """Value and expanded uncertainty as text, U to ``digits`` significant digits, value to the same place.

    GUM 7.2.6: the uncertainty with at most two significant digits, the value rounded consistently.
    """
    if not math.isfinite(expanded) or expanded <= 0:
        return f"{value:.6g}", "—"
    exp = math.floor(math.log10(expanded)) - (digits - 1)
    decimals = max(-exp, 0)
    q = 10.0**exp
    u_r = math.ceil(expanded / q - 1e-9) * q  # round the uncertainty up (never understate it)
    v_r = round(value / q) * q
    v_txt = f"{v_r:.{decimals}f}"
    if v_txt.startswith("-") and float(v_txt) == 0.0:
        v_txt = v_txt[1:]
    return v_txt, f"{u_r:.{decimals}f}"


def _load_bench_config(text: str) -> Any:
    """The recorded bench text through ``benches.bench_config`` (ConfigError names the recording's copy)."""
    from .bench_config import load_bench_text

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
    site = dict(cal_run.get("site") or {})
    table = dict(cal_run.get("table") or {})
    unit = dict(cal_run.get("unit") or {})
    cfg = _load_bench_config(bench_text) if bench_text.strip() else None
    if cfg is not None:
        s, t, u = cfg.site, cfg.turntable, cfg.unit
        g_src = str(s.g_source)
        g_unc = getattr(s, "g_uncertainty", None)
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
            g_uncertainty=float(g_unc) if g_unc else default_g_uncertainty(g_src),
            table_model=str(getattr(t, "model", "") or ""),
            table_serial=str(getattr(t, "serial_number", "") or ""),
            unit_model=str(getattr(u, "model", "") or ""),
            unit_serial=str(getattr(u, "serial_number", "") or ""),
            source="bench file recorded in the recording",
            bias_instability=np.asarray(u.noise.bias_instability, dtype=float).tolist(),
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
        g_uncertainty=float(site.get("g_uncertainty") or default_g_uncertainty(g_src)),
        table_model=str(table.get("model", "")),
        table_serial=str(table.get("serial_number", "")),
        unit_model=str(unit.get("model", "")),
        unit_serial=str(unit.get("serial_number", "")),
        source="calibration.json run block (bench loader not available: no pass/fail limits)",
    )


def _load_json(path: Path, what: str) -> dict[str, Any]:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise CertificateError(f"{path}: cannot read the {what} ({exc}); re-create it") from None


def _fmt(x: Any) -> str:
    try:
        return f"{float(x):.4g}"
    except (TypeError, ValueError):
        return str(x)


def _analysis_rows(kind: str, data: dict[str, Any]) -> list[dict[str, str]]:
    """Summary rows of a noise / periodic / drift JSON (formats in the analysis commands' docs)."""
    rows: list[dict[str, str]] = []
    channels = data.get("channels", {}) if isinstance(data, dict) else {}
    for ch in sorted(channels):
        c = channels[ch] or {}
        if kind == "noise":
            for term, t in sorted((c.get("terms_display") or c.get("terms") or {}).items()):
                t = t or {}
                rows.append(
                    {
                        "channel": ch,
                        "item": str(term),
                        "value": f"{_fmt(t.get('value'))} ± {_fmt(t.get('sigma'))} {t.get('unit', '')}".strip(),
                    }
                )
        elif kind == "periodic":
            for i, t in enumerate(c.get("terms") or []):
                rows.append(
                    {
                        "channel": ch,
                        "item": f"tone {i + 1}",
                        "value": f"{_fmt(t.get('frequency_hz'))} ± {_fmt(t.get('frequency_sigma_hz'))} Hz, "
                        f"amplitude {_fmt(t.get('amplitude'))} {t.get('amplitude_unit', c.get('unit', ''))}".rstrip()
                        + f", phase {_fmt(t.get('phase_rad'))} rad",
                    }
                )
            if "residual_rms_before" in c:
                rows.append(
                    {
                        "channel": ch,
                        "item": "residual RMS",
                        "value": f"{_fmt(c.get('residual_rms_before'))} → {_fmt(c.get('residual_rms_after'))} "
                        f"{c.get('unit', '')}".rstrip(),
                    }
                )
        elif kind == "drift":
            m = c.get("model") or {}
            rows.append(
                {
                    "channel": ch,
                    "item": f"ARMA({m.get('p', '?')},{m.get('q', '?')})",
                    "value": f"φ {[round(float(v), 4) for v in m.get('phi', [])]}, "
                    f"θ {[round(float(v), 4) for v in m.get('theta', [])]}, σ² {_fmt(m.get('sigma2'))}",
                }
            )
            for name, t in sorted((c.get("tests") or {}).items()):
                t = t or {}
                rows.append(
                    {
                        "channel": ch,
                        "item": str(name),
                        "value": f"{_fmt(t.get('statistic'))} (threshold {_fmt(t.get('threshold'))}): "
                        f"{t.get('verdict', '')}",
                    }
                )
    return rows


# ---- the content model ---------------------------------------------------------------------------------------


def build_certificate(
    run_dir: str | Path,
    *,
    issue_date: str | None = None,
    allow_incomplete: bool = False,
    bench: BenchInfo | None = None,
    with_plots: bool = True,
) -> Certificate:
    """Build the certificate of the run in ``run_dir``.

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
        Render the figures (PNG bytes in ``Certificate.plots``).

    Raises
    ------
    CertificateError
        Missing/mismatched inputs, or an incomplete recording without ``allow_incomplete``.
    """
    from .recording import RecordingError, open_recording
    from .uncertainty_budget import step_geometry

    given = Path(run_dir)
    run = given.parent if given.is_file() else given
    rec_path = given if given.is_file() else run / "recording.h5"
    cal_path = run / "calibration.json"
    if not rec_path.exists():
        raise CertificateError(f"{given}: no recording.h5 here; give a run folder printed by 'tablebench run'")
    if issue_date is None:
        issue_date = _dt.datetime.now(_dt.timezone.utc).date().isoformat()
    else:
        try:
            issue_date = _dt.date.fromisoformat(issue_date).isoformat()
        except ValueError:
            raise CertificateError(f"--issue-date {issue_date!r}: expected YYYY-MM-DD") from None
    rec_sha = file_sha256(rec_path)
    try:
        f = open_recording(rec_path)
    except RecordingError as exc:
        raise CertificateError(str(exc)) from None
    with f:
        attrs = f.header.as_dict()
        attrs["seed"] = -1 if attrs.get("seed") is None else attrs["seed"]
        steps = f.steps
        run_status = str(attrs.get("status", "?"))
        bad = [s for s in steps if s.status != "complete"]
        complete = run_status == "complete" and not bad
        reason_parts = []
        if run_status != "complete":
            reason_parts.append(f"the recording's status is {run_status!r}")
        for s in bad:
            reason_parts.append(f"step {s.index} {s.name!r} {s.status}")
        incomplete_reason = "; ".join(reason_parts)
        if not complete and not allow_incomplete:
            raise CertificateError(
                f"{rec_path}: the run is incomplete ({incomplete_reason}); resume it with 'tablebench run --resume "
                f"{run}', or issue a certificate of the completed steps with --allow-incomplete"
            )
        if not cal_path.exists():
            raise CertificateError(f"{run}: no calibration.json; identify first ('tablebench identify {run}')")
        cal = _load_json(cal_path, "calibration")
        if cal.get("format") != "tablebench-calibration":
            raise CertificateError(f"{cal_path}: not a tablebench calibration file (format key)")
        if cal.get("recording_sha256") and cal["recording_sha256"] != rec_sha:
            raise CertificateError(
                f"{cal_path}: was identified from a different recording (SHA-256 differs from recording.h5); "
                f"identify this recording again"
            )
        names = list(cal.get("parameter_names") or PARAM_NAMES)
        if tuple(names) != PARAM_NAMES:
            raise CertificateError(f"{cal_path}: parameter_names must be the 18 names of CALIBRATION_FORMAT.md")
        bench_text = f.bench_text
        binfo = bench or bench_info(bench_text, dict(cal.get("run") or {}), attrs)
        used = [str(p.get("name")) for p in (cal.get("residuals") or {}).get("per_step", [])]
        geometry = step_geometry(f, binfo.g, None if binfo.mounting is None else np.asarray(binfo.mounting),
                                 names=used or None)  # fmt: skip
        temp = f.temperature_stats()
        n_samples = f.n_samples
        ends = f.samples(fields=("time",), index=[0, n_samples - 1]).time if n_samples > 1 else None
        t_span = float(ends[-1] - ends[0]) if ends is not None else 0.0
        event_warnings = [
            f"bench t = {e.time:.1f} s: {e.message}" for e in f.events() if e.level.lower() in ("warning", "error")
        ]
        integrity = {"verified": f.integrity_verified, "note": f.integrity_note}
        overrides = dict(f.header.procedure_overrides)

    params, x, cov, noise_var, per_step = _calibration_arrays(cal, names, cal_path)
    prior = [params[n].get("prior_sigma") for n in names]
    prior_ok = all(isinstance(p, int | float) and p > 0 for p in prior)
    try:
        budget: UncertaintyBudget = build_budget(
            cov,
            geometry,
            noise_var,
            prior_sigma=np.asarray(prior, dtype=float) if prior_ok else None,
            bias_instability=None if binfo.bias_instability is None else np.asarray(binfo.bias_instability),
            g=binfo.g,
            g_uncertainty=binfo.g_uncertainty,
            g_source=binfo.g_source,
            attitude_accuracy=binfo.attitude_accuracy,
            residuals_per_step=per_step,
        )
    except ValueError as exc:
        raise CertificateError(f"{cal_path}: {exc}") from None
    notes = list(budget.notes)

    unc = budget.combined
    exp_u = budget.expanded
    comp_std = {c.key: c.std for c in budget.components}
    results: list[ParameterResult] = []
    reasons: list[str] = []
    unverified: list[str] = []
    for i, (name, kind) in enumerate(zip(names, PARAM_KINDS, strict=True)):
        pr = params[name]
        ident = bool(pr.get("identifiable", True))
        lim = binfo.limits.get(name)
        dv, du = to_display(kind, x[i]), to_display(kind, exp_u[i])
        v_txt, u_txt = format_with_uncertainty(dv, du)
        if lim is None:
            verdict = "—"
        elif not ident:
            verdict = "NOT VERIFIED"
            unverified.append(f"{name}: not identified by this procedure, cannot be verified against its limit")
        elif abs(x[i]) > lim and (exp_u[i] < lim or abs(x[i]) - exp_u[i] > lim):
            verdict = "FAIL"
            reasons.append(
                f"{name} = {v_txt} {display_unit(kind)} exceeds the limit ±{to_display(kind, lim):.4g} "
                f"{display_unit(kind)}"
            )
        elif exp_u[i] >= lim:
            verdict = "NOT VERIFIED"
            unverified.append(
                f"{name}: expanded uncertainty {u_txt} {display_unit(kind)} is not smaller than the limit "
                f"±{to_display(kind, lim):.4g} {display_unit(kind)}; this procedure cannot verify it"
            )
        elif abs(x[i]) + exp_u[i] > lim:
            verdict = "PASS (conditional)"
        else:
            verdict = "PASS"
        results.append(
            ParameterResult(
                name=name,
                kind=kind,
                unit=str(pr.get("unit", "")),
                display_unit=display_unit(kind),
                value=float(x[i]),
                standard_uncertainty=float(unc[i]),
                expanded_uncertainty=float(exp_u[i]),
                display_value=float(dv),
                display_expanded=float(du),
                value_text=v_txt,
                expanded_text=u_txt,
                identifiable=ident,
                limit=None if lim is None else float(lim),
                display_limit=None if lim is None else float(to_display(kind, lim)),
                verdict=verdict,
                budget={k: float(v[i]) for k, v in comp_std.items()},
                display_budget={k: float(to_display(kind, v[i])) for k, v in comp_std.items()},
            )
        )
    if reasons:
        verdict = "FAIL"
    elif not complete:
        verdict = "INCOMPLETE"
    elif unverified:
        verdict = "INCONCLUSIVE"
    else:
        verdict = "PASS" if binfo.limits else "NO LIMITS"
    reasons.extend(unverified)

    warnings = list(dict.fromkeys([*(cal.get("plan") or {}).get("warnings", []), *cal.get("warnings", [])]))
    unident = [p.name for p in results if not p.identifiable]
    if unident:
        warnings.append(
            "not identified (prior-dominated, do not use for compensation): " + ", ".join(unident)
        )  # fmt: skip
    if not binfo.limits:
        warnings.append("the bench file gives no pass/fail limits: no conformity statement")
    warnings.extend(event_warnings)
    if not integrity["verified"]:
        warnings.insert(0, integrity["note"])

    analyses: dict[str, list[dict[str, str]]] = {}
    analysis_plots: list[tuple[str, bytes]] = []
    for kind in ANALYSES:
        p = run / kind / f"{kind}.json"
        if p.exists():
            analyses[kind] = _analysis_rows(kind, _load_json(p, f"{kind} analysis"))
            for png in sorted((run / kind).glob("*.png"))[:6]:
                analysis_plots.append((f"{kind}/{png.name}", png.read_bytes()))

    created = str(attrs.get("created_utc", ""))
    creation = _creation_datetime(created)
    t_unit = {"model": binfo.unit_model, "serial_number": binfo.unit_serial}
    cert = Certificate(
        number=f"TB-{rec_sha[:10].upper()}",
        issue_date=issue_date,
        verdict=verdict,
        reasons=reasons,
        complete=complete,
        incomplete_reason=incomplete_reason,
        unit=t_unit,
        bench={
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
        },
        procedure={
            "name": str(attrs.get("procedure_name", "")),
            "sha256": str(attrs.get("procedure_sha256", "")),
            "procedure_overrides": overrides,
        },
        recording={
            "file": "recording.h5",
            "sha256": rec_sha,
            "status": run_status,
            "created_utc": created,
            "updated_utc": str(attrs.get("updated_utc", "")),
            "software_version": str(attrs.get("software_version", "")),
            "seed": attrs.get("seed", -1),
            "samples": n_samples,
            "duration_s": t_span,
            "sample_rate_hz": float(attrs.get("sample_rate_hz", 0.0) or 0.0),
            "integrity_verified": integrity["verified"],
            "integrity_note": integrity["note"],
            "steps_complete": sum(s.status == "complete" for s in steps),
            "steps": len(steps),
        },
        environment={
            "unit_temperature_k": temp,
            "unit_temperature_c": {k: kelvin_to_celsius(v) for k, v in temp.items()},
        },
        identification={
            "method": str(cal.get("method", "")),
            "calibration_sha256": file_sha256(cal_path),
            "information": cal.get("information", {}),
            "measurement_noise": cal.get("measurement_noise", {}),
            "steps_used": [g.name for g in geometry],
        },
        parameters=results,
        budget_components=[
            {"key": c.key, "label": c.label, "type": c.type, "source": c.source} for c in budget.components
        ],
        budget_notes=notes,
        coverage_factor=budget.coverage_factor,
        covariance=budget.covariance.tolist(),
        warnings=warnings,
        analyses=analyses,
        software_version=software_version(),
        creation_date=creation.isoformat(),
        analysis_plots=analysis_plots,
    )
    if with_plots:
        from .certificate_plots import plot_convergence, plot_coverage, plot_residuals

        cert.plots["residuals"] = plot_residuals(per_step, noise_var)
        if cal.get("history"):
            cert.plots["convergence"] = plot_convergence(cal["history"], names, PARAM_KINDS, x)
        cert.plots["coverage"] = plot_coverage(geometry)
    return cert


def _calibration_arrays(
    cal: dict[str, Any], names: list[str], path: Path
) -> tuple[dict[str, Any], np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """Parameters, estimate (18,), covariance (18, 18), noise variance (3,), per-step residuals; checked."""
    where = "parameters"
    try:
        params = cal["parameters"]
        for n in names:
            where = f"parameters.{n}.value"
            float(params[n]["value"])
        x = np.array([float(params[n]["value"]) for n in names])
        where = "covariance"
        cov = np.asarray(cal["covariance"], dtype=float)
        where = "measurement_noise.variance"
        noise_var = np.asarray(cal["measurement_noise"]["variance"], dtype=float)
        where = "residuals.per_step"
        per_step = list((cal.get("residuals") or {}).get("per_step") or [])
        for row in per_step:
            (
                int(row["samples"]),
                np.asarray(row["mean"], dtype=float).reshape(3),
                np.asarray(row["rms"], float).reshape(3),
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise CertificateError(
            f"{path}: {where} is missing or malformed ({exc.__class__.__name__}: {exc}); see "
            "benches/CALIBRATION_FORMAT.md, or identify the run again"
        ) from None
    if cov.shape != (18, 18) or not np.all(np.isfinite(cov)):
        raise CertificateError(f"{path}: covariance must be a finite 18 × 18 matrix")
    if noise_var.shape != (3,) or not np.all(noise_var > 0):
        raise CertificateError(f"{path}: measurement_noise.variance must be 3 positive numbers")
    if not np.all(np.isfinite(x)):
        raise CertificateError(f"{path}: a parameter value is not finite")
    return params, x, cov, noise_var, per_step


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
) -> tuple[Path, Path, str]:
    """Build and write the certificate of a run: ``RUN/certificate.pdf`` and ``RUN/certificate.json`` by default.

    Returns
    -------
    (pdf_path, json_path, verdict)
        verdict: "PASS", "FAIL", "INCONCLUSIVE", "INCOMPLETE" or "NO LIMITS".
    """
    from .certificate_pdf import render_pdf
    from .certificate_register import CertificateRegister, RegisterError, free_paths, write_new

    given = Path(run_dir)
    run = given.parent if given.is_file() else given
    cert = build_certificate(given, issue_date=issue_date, allow_incomplete=allow_incomplete)

    def paths(number: str) -> tuple[Path, Path]:
        if out_pdf is None:
            return free_paths(run, number)
        pdf = Path(out_pdf)
        return pdf, Path(out_json) if out_json is not None else pdf.with_suffix(".json")

    if out_pdf is not None:
        for p in paths(""):
            if p.exists():
                raise CertificateError(f"{p}: already exists; a certificate is never overwritten (choose another name)")
    try:
        reg = CertificateRegister.for_run(run).allocate(run, str(cert.recording.get("sha256", "")), paths)
        cert.number, cert.supersedes = reg.number, reg.supersedes
        pdf_path, json_path = Path(reg.pdf), Path(reg.json)
        for p in (pdf_path, json_path):
            p.parent.mkdir(parents=True, exist_ok=True)
        write_new(pdf_path, render_pdf(cert))
        write_new(json_path, cert.to_json().encode("utf-8"))
    except (RegisterError, OSError) as exc:
        raise CertificateError(str(exc)) from None
    return pdf_path, json_path, cert.verdict


__all__ = [
    "BenchInfo",
    "Certificate",
    "CertificateError",
    "ParameterResult",
    "bench_info",
    "build_certificate",
    "format_with_uncertainty",
    "issue_certificate",
]
