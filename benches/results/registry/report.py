"""What the ``registry`` commands show: history tables, trend figures, comparisons, due dates, exports.

Values are SI inside; tables and figures use the one display unit per quantity (:mod:`analysis.units`),
every uncertainty shown is U (k = 2). Export JSON is SI and carries the model and the compensation equation
of ``tablebench correct`` (:func:`analysis.identification.model.correct`): f = (I + S + T)⁻¹ (f_out − b −
D(f∘f) − diag(r) c(ω)), solved iteratively, with the parameters whose ``use`` is false set to 0.
"""

from __future__ import annotations

import csv
import datetime as _dt
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from analysis.units import DISPLAY_UNITS
from core.jsonio import dumps

from .queries import CalibrationRow, loads
from .stats import (
    IntervalSettings,
    control_chart_interval,
    control_limits,
    in_tolerance,
    normalised_error,
    parse_time,
    precision,
    staircase,
)

EXPORT_FORMAT = "tablebench-registry-export"
EXPORT_VERSION = 1
MODEL_TEXT = (
    "accelerometer: f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω) + v; gyro (whole-unit calibrations): "
    "ω_out = (I + S_g + T_g) ω_ib + b_g + G f + S2 (ω_ib∘ω_ib) + A |ω_ib| + v_g"
)
EQUATION = (
    "f = (I + S + T)⁻¹ (f_out − b − D (f∘f) − diag(r) c(ω)), c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²], solved "
    "iteratively (tablebench correct); gyro: ω_ib = (I + S_g + T_g)⁻¹ (ω_out − b_g − G f) when S2 = A = 0, "
    "else Newton's iteration on (I + S_g + T_g) ω + S2∘ω² + A∘|ω| = ω_out − b_g − G f; x_si in "
    "parameter_names order, S = diag(S_x, S_y, S_z), T the misalignments τ_ij at row i, column j, D = diag(d) "
    "(the gyro's likewise with the gyro_ names); entries with use = false are set to 0"
)
UNITS_TEXT = (
    "SI: b m/s², S 1, τ rad, d s²/m, r m; gyro_b rad/s, gyro_S 1, gyro_tau rad, gyro_G rad/s per m/s², "
    "gyro_S2 s/rad, gyro_A 1; u standard, U = 2u expanded (k = 2); null where a calibration lacks a parameter"
)


def _disp(kind: str) -> tuple[str, float]:
    """Display unit and its size in SI of a quantity kind (SI itself for a kind without a display unit)."""
    return DISPLAY_UNITS.get(kind, ("SI", 1.0))


def _rms_text(as_json: str | None) -> str:
    d = loads(as_json)
    if not d:
        return "—"
    unit, one = DISPLAY_UNITS["bias"]
    return "/".join(f"{v / one:.0f}" for v in d["rms"]) + f" {unit}"


def history_table(rows: Sequence[CalibrationRow]) -> str:
    """The history of one unit: one line per calibration, then precision (s_r, s_R) per parameter."""
    if not rows:
        return "no calibrations"
    r0 = rows[0]
    out = [f"unit {r0.serial} ({r0.model})", ""]
    head = f"{'run (UTC)':20s} {'cfg':4s} {'bench':18s} {'procedure':18s} {'certificate':12s} {'decision':13s} "
    out.append(head + "as found rms (x/y/z)   as left rms (x/y/z)")
    for r in rows:
        out.append(
            f"{r.run_utc[:19]:20s} {r.configuration[:4]:4s} {r.bench[:18]:18s} {r.procedure_name[:18]:18s} "
            f"{(r.certificate_number or '—'):12s} {(r.decision or 'not certified')[:13]:13s} "
            f"{_rms_text(r.as_found):22s} {_rms_text(r.as_left)}"
        )
    out += ["", "parameter values (display units), last calibration ± U (k = 2), and the unit's precision:"]
    out.append(f"{'param':11s} {'unit':8s} {'last':>12s} {'U':>10s} {'s_r':>10s} {'s_R':>10s}  n  benches")
    for i, n in enumerate(r0.names):
        unit, one = _disp(r0.kinds[i])
        groups: dict[str, list[float]] = {}
        for r in rows:
            if r.identified[i]:
                groups.setdefault(r.bench, []).append(float(r.values[i]))
        pr = precision(list(groups.values()))
        last = rows[-1]
        sr = "—" if pr.s_r is None else f"{pr.s_r / one:.4g}"
        sR = "—" if pr.s_R is None else f"{pr.s_R / one:.4g}"  # noqa: N806 - ISO 5725 symbol
        if math.isnan(last.values[i]):  # the last calibration's model lacks it (an accelerometer-only run)
            val, big_u = f"{'—':>12s}", f"{'—':>10s}"
        else:
            val, big_u = f"{last.values[i] / one:12.4f}", f"{last.expanded[i] / one:10.4f}"
        out.append(f"{n:11s} {unit:8s} {val} {big_u} {sr:>10s} {sR:>10s} {pr.calibrations:2d}  {pr.benches}")
    out.append(
        "s_r: repeatability on one bench (pooled), s_R: reproducibility across benches (ISO 5725-2); — : not "
        "enough calibrations (s_r needs 2 on one bench, s_R 2 benches)"
    )
    return "\n".join(out)


def en_between(a: CalibrationRow, b: CalibrationRow) -> dict[str, float | None]:
    """E_n per parameter between two calibrations (None where either did not identify it); the parameters of
    ``a`` that ``b`` has too."""
    b_at = {n: k for k, n in enumerate(b.names)}
    return {
        n: (normalised_error(a.values[i], a.expanded[i], b.values[b_at[n]], b.expanded[b_at[n]])
            if a.identified[i] and b.identified[b_at[n]] else None)  # fmt: skip
        for i, n in enumerate(a.names)
        if n in b_at
    }


def compare_table(a: CalibrationRow, b: CalibrationRow) -> str:
    """E_n per parameter of two calibrations, as text."""
    en = en_between(a, b)
    out = [
        f"A: {a.run_folder} ({a.serial}, {a.run_utc[:19]}, {a.certificate_number or 'not certified'})",
        f"B: {b.run_folder} ({b.serial}, {b.run_utc[:19]}, {b.certificate_number or 'not certified'})",
        f"{'param':11s} {'unit':8s} {'A':>12s} {'U_A':>9s} {'B':>12s} {'U_B':>9s} {'B − A':>11s} {'E_n':>7s}",
    ]
    worst = 0.0
    b_at = {n: k for k, n in enumerate(b.names)}
    for i, n in enumerate(a.names):
        if n not in en:
            continue
        j = b_at[n]
        unit, one = _disp(a.kinds[i])
        e = en[n]
        e_txt = "—" if e is None else f"{e:7.2f}"
        flag = "" if e is None or e <= 1 else "  disagree"
        worst = max(worst, e or 0.0)
        out.append(
            f"{n:11s} {unit:8s} {a.values[i] / one:12.4f} {a.expanded[i] / one:9.4f} {b.values[j] / one:12.4f} "
            f"{b.expanded[j] / one:9.4f} {(b.values[j] - a.values[i]) / one:11.4f} {e_txt:>7s}{flag}"
        )
    verdict = "agree" if worst <= 1 else "DISAGREE"
    out.append(f"E_n = |B − A| / √(U_A² + U_B²), U at k = 2; max E_n {worst:.2f} ({verdict})")
    return "\n".join(out)


def plot_trend(rows: Sequence[CalibrationRow], param: str, out: Path) -> Path:
    """values ± U over time, control limits from the unit's history, E_n between consecutive calibrations."""
    # the object API without pyplot (less start-up for a one-figure command)
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # lazy: matplotlib (--help time)
    from matplotlib.figure import Figure  # lazy: matplotlib (--help time)

    i = rows[0].names.index(param)
    unit, one = _disp(rows[0].kinds[i])
    t = [parse_time(r.run_utc) for r in rows]
    v = np.array([r.values[i] for r in rows]) / one
    u = np.array([r.expanded[i] for r in rows]) / one
    ok = np.array([bool(r.identified[i]) for r in rows])
    fig = Figure(figsize=(8, 6))
    FigureCanvasAgg(fig)
    ax, ax2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    ax.errorbar([t[k] for k in np.flatnonzero(ok)], v[ok], yerr=u[ok], fmt="o", capsize=3, label="value ± U (k = 2)")
    if np.any(~ok):
        ax.plot([t[k] for k in np.flatnonzero(~ok)], v[~ok], "x", color="grey", label="not identified")
    lim = control_limits(v[ok].tolist())
    if lim is not None:
        ax.axhline(lim.centre, color="k", lw=0.8, label=f"centre ({lim.points} calibrations)")
        for lo_hi, style, name in ((lim.warning, ":", "±2σ̂ warning"), (lim.action, "--", "±3σ̂ action")):
            for k, y in enumerate(lo_hi):
                ax.axhline(y, color="C3", ls=style, lw=0.8, label=name if k == 0 else None)
    ax.set_ylabel(f"{param} ({unit})")
    ax.set_title(f"{rows[0].serial}: {param}, control limits from the unit's history (σ̂ = MR̄/1.128)")
    ax.margins(y=0.22)  # room above the points for the legend row
    ax.legend(fontsize=7, loc="upper left", ncols=4)  # a fixed place: "best" searches every point
    en = [
        normalised_error(rows[k - 1].values[i], rows[k - 1].expanded[i], rows[k].values[i], rows[k].expanded[i])
        if ok[k] and ok[k - 1] else math.nan
        for k in range(1, len(rows))
    ]  # fmt: skip
    if en:
        ax2.bar(t[1:], en, width=max((t[-1] - t[0]).days / (4 * len(t)), 0.5), color="C0")
    ax2.axhline(1.0, color="C3", ls="--", lw=0.8)
    ax2.set_ylabel("E_n vs previous")
    fig.autofmt_xdate()
    fig.subplots_adjust(left=0.11, right=0.98, top=0.94, bottom=0.12, hspace=0.08)  # fixed margins: no layout pass
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out


def due_report(rows: Sequence[CalibrationRow], s: IntervalSettings, now: _dt.datetime) -> dict[str, Any]:
    """ILAC-G24 methods 1 and 2 for one unit (oldest-first history of one configuration)."""
    last = rows[-1]
    t_last = parse_time(last.run_utc)
    findings = [
        in_tolerance(rows[k - 1].values, rows[k - 1].expanded, rows[k].values, rows[k].expanded,
                     rows[k - 1].identified & rows[k].identified, rows[k].decision)
        for k in range(1, len(rows))
    ]  # fmt: skip
    m1 = staircase(findings, s)
    t0 = parse_time(rows[0].run_utc)
    days = [(parse_time(r.run_utc) - t0).total_seconds() / 86400.0 for r in rows]
    drifts = []
    for i, n in enumerate(last.names):
        if not last.identified[i]:
            continue
        sel = [k for k, r in enumerate(rows) if r.identified[i]]
        d = control_chart_interval(n, [days[k] for k in sel], [rows[k].values[i] for k in sel], last.expanded[i], s)
        if d is not None:
            drifts.append(d)
    m2 = min(drifts, key=lambda d: d.interval_days) if drifts else None
    interval = m1 if m2 is None else min(m1, m2.interval_days)
    due = t_last + _dt.timedelta(days=interval)
    return {
        "serial": last.serial,
        "configuration": last.configuration,
        "last_calibration": last.run_utc,
        "calibrations": len(rows),
        "findings_in_tolerance": findings,
        "method1_staircase_days": m1,
        "method2_control_chart_days": None if m2 is None else m2.interval_days,
        "method2_limiting_parameter": None if m2 is None else m2.name,
        "interval_days": interval,
        "due_utc": due.strftime("%Y-%m-%d"),
        "overdue": due < now,
        "settings": s.source,
    }


def export_document(rows: Sequence[CalibrationRow]) -> dict[str, Any]:
    """The unit's history as one JSON document (SI; identical from SQLite and PostgreSQL)."""
    cals = []
    for k, r in enumerate(rows):
        en = en_between(rows[k - 1], r) if k > 0 else None
        cals.append(
            {
                "run_utc": r.run_utc,
                "configuration": r.configuration,
                "bench": r.bench,
                "procedure": {"name": r.procedure_name, "sha256": r.procedure_sha256},
                "recording_sha256": r.recording_sha256,
                "calibration_digest": r.digest,
                "run_folder": r.run_folder,
                "method": r.method,
                "status": r.status,
                "operator": r.operator,
                "decision": r.decision,
                "certificate_number": r.certificate_number,
                "supersedes": r.supersedes,
                "compensation": {"x_si": r.values.tolist(), "use": r.identified.tolist()},
                "parameters": {
                    n: {"value": float(r.values[i]), "u": float(r.u[i]), "U": float(r.expanded[i]),
                        "identified": bool(r.identified[i]), "budget_u": loads(r.budgets[i])}  # fmt: skip
                    for i, n in enumerate(r.names)
                },
                "covariance": loads(r.covariance),
                "certificate_covariance": loads(r.certificate_covariance),
                "as_found": loads(r.as_found),
                "as_left": loads(r.as_left),
                "en_vs_previous": en,
            }
        )
    r0 = rows[0]
    return {
        "format": EXPORT_FORMAT,
        "format_version": EXPORT_VERSION,
        "unit": {"serial": r0.serial, "model": r0.model},
        "model": MODEL_TEXT,
        "equation": EQUATION,
        "parameter_names": list(r0.names),
        "parameter_kinds": list(r0.kinds),
        "units": UNITS_TEXT,
        "calibrations": cals,
    }


def export_text(rows: Sequence[CalibrationRow], fmt: str) -> str:
    """``json`` or ``csv`` text of a unit's history."""
    if fmt == "json":
        return dumps(export_document(rows), nonfinite="null", indent=1)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["serial", "model", "configuration", "run_utc", "bench", "certificate", "decision", "parameter",
                "kind", "value_si", "u_si", "U_si", "identified", "En_vs_previous"])  # fmt: skip
    for k, r in enumerate(rows):
        en = en_between(rows[k - 1], r) if k > 0 else {}
        for i, n in enumerate(r.names):
            e = en.get(n)
            w.writerow([r.serial, r.model, r.configuration, r.run_utc, r.bench, r.certificate_number or "",
                        r.decision or "", n, r.kinds[i], repr(float(r.values[i])), repr(float(r.u[i])),
                        repr(float(r.expanded[i])), str(bool(r.identified[i])).lower(),
                        "" if e is None else repr(float(e))])  # fmt: skip
    return buf.getvalue()


def load_export(path: str | Path) -> dict[str, Any]:
    """Read an export JSON back (for tests and users' scripts)."""
    return json.loads(Path(path).read_text(encoding="utf-8"))


__all__ = [
    "EQUATION",
    "EXPORT_FORMAT",
    "compare_table",
    "due_report",
    "en_between",
    "export_document",
    "export_text",
    "history_table",
    "load_export",
    "plot_trend",
]
