"""A run folder as registry rows: unit, bench, calibration, parameters, certificates, as found / as left.

Sources, all in the run folder: ``calibration.json`` (values, covariance, the run's identity), every
certificate the run's register lists (``certificate*.json``: decision, number, what it supersedes, U and the
budget of each parameter), and for as found / as left the recording itself (:func:`as_found_as_left`).

**As found** (ISO/IEC 17025 7.8.4.1 c; the lab's usual practice): the unit's *previous* calibration (same
serial number, model and configuration, latest run before this one) applied to *this* run's data: per
acquisition step, the mean residual f_out − h(x_prev; f_ref, ω) of the model f_out = h(x; f, ω)
(:func:`analysis.identification.model.predict`) against this run's reference f_ref, ω (body frame b, m/s²).
**As left** is the same with this run's own calibration. A unit that has drifted shows an as-found residual
well above its as-left one.
"""

from __future__ import annotations

import getpass
import hashlib
import json
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from analysis.identification.model import PARAM_NAMES, mean_model_error
from benches.calibration_integrity import load_verified, read_raw
from benches.calibration_result import CalibrationResult
from benches.certificate_register import CertificateRegister, RegisterError
from benches.recording import RecordingError, open_recording
from benches.results.recalibration import DEFAULT_CONFIGURATION, IntervalSettings, from_bench_text
from core.errors import UserError

OPERATOR_ENV = "TABLEBENCH_OPERATOR"


class RunRecordError(UserError, ValueError):
    """A run folder cannot be recorded (no calibration, unreadable certificate); the message says what to do."""


def canonical(obj: Any) -> str:
    """Canonical JSON text (sorted keys, no spaces, shortest round-trip floats): equal on both engines."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def default_operator() -> str:
    """``TABLEBENCH_OPERATOR``, else the login name."""
    env = os.environ.get(OPERATOR_ENV, "").strip()
    if env:
        return env
    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no login name (a container without passwd entry)
        return "unknown"


def _load_calibration(run: Path) -> tuple[dict[str, Any], CalibrationResult]:
    path = run / "calibration.json"
    if not path.exists():
        raise RunRecordError(
            f"{path}: no calibration in this run folder; identify it first (tablebench identify {run})"
        )
    result, _digest = load_verified(path)  # format, integrity digest, plausible values (one line each)
    return read_raw(path), result


def calibration_digest(raw: Mapping[str, Any]) -> str:
    """The digest the registry keys a calibration by: the file's own integrity digest when it carries one
    (``docs/registry.md``, tamper evidence), else SHA-256 of its canonical values and the recording's digest."""
    integ = raw.get("integrity")
    if isinstance(integ, Mapping) and isinstance(integ.get("values_sha256"), str):
        return str(integ["values_sha256"])
    body = {k: v for k, v in raw.items() if k != "integrity"}
    return hashlib.sha256(canonical(body).encode("utf-8")).hexdigest()


def _certificates(run: Path) -> list[dict[str, Any]]:
    """Every certificate issued for ``run`` (register order), as read from its JSON."""
    try:
        key = str(run.resolve())
        entries = [e for e in CertificateRegister.for_run(run).entries() if e.run == key]
    except RegisterError as exc:
        raise RunRecordError(str(exc)) from None
    out = []
    for e in entries:
        p = Path(e.json)
        try:
            data = p.read_bytes()
            d = json.loads(data.decode("utf-8"))
        except FileNotFoundError:
            continue  # the number was consumed but the file never written (a failed issue)
        except (OSError, ValueError) as exc:
            raise RunRecordError(
                f"{p}: certificate JSON not readable ({exc}); restore it from the run's backup"
            ) from None
        out.append({"entry": e, "json": d, "sha256": hashlib.sha256(data).hexdigest()})
    return out


def bench_settings(run: str | Path) -> tuple[str, IntervalSettings]:
    """(unit configuration, recalibration settings) from the bench text recorded with the run (the run
    folder's bench.yaml copy when the recording cannot be read); defaults when neither is there."""
    run = Path(run)
    # the run this process has just identified: its recording's bench text is in memory (a process that has
    # identified nothing, e.g. ``registry due``, does not import the identification to find that out)
    identify = sys.modules.get("benches.identify")
    data = identify.recent_data(run) if identify is not None else None
    try:
        if data is not None:
            return from_bench_text(data.run.bench_text, f"{data.path}:/bench_yaml")
        with open_recording(run / "recording.h5") as f:
            return from_bench_text(f.bench_text, f"{run / 'recording.h5'}:/bench_yaml")
    except (RecordingError, OSError):
        pass
    try:
        return from_bench_text((run / "bench.yaml").read_text(encoding="utf-8"), run / "bench.yaml")
    except (OSError, UnicodeDecodeError):
        return DEFAULT_CONFIGURATION, IntervalSettings()


def _run_time(raw: Mapping[str, Any], run: Path) -> str:
    created = str((raw.get("run") or {}).get("created_utc") or "")
    if created:
        return created

    try:
        with open_recording(run / "recording.h5") as f:
            return str(f.header.created_utc or "")
    except (RecordingError, OSError):
        return ""


def run_record(
    run: str | Path, *, operator: str | None = None, configuration: str | None = None, recorded_utc: str = ""
) -> dict[str, Any]:
    """The rows of one run folder (without as found / as left: :func:`as_found_as_left`)."""
    run = Path(run).resolve()
    raw, result = _load_calibration(run)
    info = dict(raw.get("run") or {})
    unit = dict(info.get("unit") or {})
    table = dict(info.get("table") or {})
    certs = _certificates(run)
    cert_last = certs[-1]["json"] if certs else None
    serial = str(unit.get("serial_number") or (cert_last or {}).get("unit", {}).get("serial_number") or "")
    if not serial:
        raise RunRecordError(
            f"{run}/calibration.json: the unit has no serial number (run.unit.serial_number); set unit.serial_number "
            "in the bench file — a registry keeps a unit's history by its serial number"
        )
    run_utc = _run_time(raw, run) or recorded_utc
    # every parameter of the calibration's model (the accelerometer triad's 18, and the gyro triad's when the
    # run calibrated the whole unit), in the model's order; as found / as left use the accelerometer block
    names = list(result.parameters)
    idx = [names.index(n) for n in PARAM_NAMES]
    params = []
    cert_params = (cert_last or {}).get("parameters", {})
    for n in names:
        p = result.parameters[n]
        cp = cert_params.get(n) or {}
        expanded = cp.get("expanded_uncertainty")
        params.append(
            {
                "name": n,
                "kind": p.kind,
                "value": p.value,
                "u": p.u,
                "expanded": float(expanded) if isinstance(expanded, int | float) else 2.0 * p.u,
                "identified": bool(p.identified),
                "budget": canonical(cp["budget"]) if isinstance(cp.get("budget"), dict) else None,
            }
        )
    certificates = [
        {
            "number": c["entry"].number,
            "supersedes": c["entry"].supersedes,
            "verdict": str(c["json"].get("verdict", "")),
            "issue_date": str(c["json"].get("issue_date", "")),
            "json_sha256": c["sha256"],
        }
        for c in certs
    ]
    cert_cov = {
        c["entry"].number: canonical(c["json"]["covariance"]) for c in certs if c["json"].get("covariance") is not None
    }
    calibration = {
        "digest": calibration_digest(raw),
        "recording_sha256": result.recording_sha256,
        "run_folder": str(run),
        "run_utc": run_utc,
        "recorded_utc": recorded_utc,
        "procedure_name": str(info.get("procedure_name", "")),
        "procedure_sha256": str(info.get("procedure_sha256", "")),
        "method": result.method,
        "status": str(info.get("status", "")),
        "operator": operator if operator else default_operator(),
        "software_version": str(raw.get("software_version", "")),
        "parameter_names": canonical(names),
        "covariance": canonical(np.asarray(result.covariance).tolist()),
    }
    return {
        "unit": {
            "serial": serial,
            "model": str(unit.get("model", "")),
            "configuration": configuration or bench_settings(run)[0],
        },
        "bench": {
            "name": str(info.get("bench_name", "")),
            "table_model": str(table.get("model", "")),
            "table_serial": str(table.get("serial_number", "")),
        },
        "calibration": calibration,
        "parameters": params,
        "certificates": certificates,
        "certificate_covariance": cert_cov,
        "x": np.asarray(result.x)[idx],  # the accelerometer block (as found / as left)
        "x_identified": [bool(result.parameters[n].identified) for n in PARAM_NAMES],
    }


_MOMENTS: dict[str, Any] = {}
"""Recording SHA-256 → the sample means of its acquisition windows (:func:`_window_moments`; one read per
recording and process: ``registry add`` of many runs of one recording, and the as found and as left of one run,
read it once)."""


def window_moments(f_out: np.ndarray, f_ref: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The (4, 3) sample means of f_out − f_ref, f_ref, f_ref∘f_ref and c(ω) over one window (body frame;
    :func:`analysis.identification.model.centripetal`), equal to the last bit to ``np.mean(…, axis=0)`` of each.

    ``np.mean`` over the samples of an (n, 3) array adds the rows one after another (a three-wide inner loop per
    row, four such passes with their temporaries); here the twelve per-sample quantities are formed column-wise
    (fast, contiguous) and laid out as one (n, 12) array whose rows are added one after another once — the same
    additions in the same order, so the same sums, in about half the time (issue 32). A test checks the equality
    against ``np.mean`` of the per-sample values.
    """
    n = int(f_ref.shape[0])
    if n == 0:
        return np.full((4, 3), np.nan)
    cols = np.empty((12, n))
    np.subtract(f_out.T, f_ref.T, out=cols[0:3])
    cols[3:6] = f_ref.T
    np.multiply(cols[3:6], cols[3:6], out=cols[6:9])
    w2 = np.square(np.asarray(omega, dtype=float).T)
    np.subtract((w2[0] + w2[1]) + w2[2], w2, out=cols[9:12])  # c(ω): the row sum of ω², less each ω_i²
    rows = np.ascontiguousarray(cols.T)  # (n, 12), C order: the reduction below runs along the rows in order
    return (np.add.reduce(rows, axis=0) / n).reshape(4, 3)


def _window_moments(run: Path, recording_sha256: str) -> list[tuple[str, np.ndarray]] | None:
    """Per acquisition window, its name and the (4, 3) sample means of f_out − f_ref, f_ref, f_ref∘f_ref and
    c(ω) (body frame; :func:`analysis.identification.model.centripetal`); None when the recording cannot be
    read. (The first is the mean of the small differences, not of f_out: no rounding of g-sized sums in it.)"""
    from benches.identify import IdentificationError, load_run  # lazy: filterpy, scipy (--help time)

    if recording_sha256 and recording_sha256 in _MOMENTS:
        return _MOMENTS[recording_sha256]
    try:
        windows = load_run(run).windows
    except (IdentificationError, UserError, OSError):
        return None
    moments = [(w.name, window_moments(w.f_out, w.f_ref, w.omega)) for w in windows]
    if recording_sha256:
        if len(_MOMENTS) >= 64:
            _MOMENTS.pop(next(iter(_MOMENTS)))
        _MOMENTS[recording_sha256] = moments
    return moments


def as_found_as_left(
    run: str | Path, x_left: np.ndarray, x_found: np.ndarray | None, recording_sha256: str = ""
) -> tuple[dict | None, dict] | None:
    """Residuals of this run's data against its reference under the previous (as found) and this (as left)
    calibration; None when the recording cannot be read (the registry then stores no as found).

    Each step's mean residual is mean(f_out − h(x; f_ref, ω)) = mean(f_out − f_ref) − [(S+T) mean(f_ref) + b +
    D mean(f_ref∘f_ref) + diag(r) mean(c(ω))]: the model (:func:`analysis.identification.model.predict`) is
    affine in f_ref, f_ref∘f_ref and c(ω), so the window means are formed once per recording and the model is
    applied to them (:func:`analysis.identification.model.mean_model_error`).

    Returns two mappings ``{"rms": [3], "max_abs_step_mean": [3], "steps": {name: [3]}}`` in m/s², body frame
    (``as_found`` is None when there is no previous calibration).
    """
    moments = _window_moments(Path(run), recording_sha256)
    if moments is None:
        return None

    def residuals(x: np.ndarray) -> dict[str, Any]:
        steps = {name: mo[0] - mean_model_error(x, mo[1], mo[2], mo[3]) for name, mo in moments}
        m = np.array(list(steps.values())) if steps else np.zeros((0, 3))
        return {
            "rms": np.sqrt(np.mean(m**2, axis=0)).tolist() if len(m) else [0.0] * 3,
            "max_abs_step_mean": np.max(np.abs(m), axis=0).tolist() if len(m) else [0.0] * 3,
            "steps": {k: v.tolist() for k, v in steps.items()},
            "unit": "m/s^2 (body frame)",
        }

    left = residuals(np.asarray(x_left, dtype=float))
    found = residuals(np.asarray(x_found, dtype=float)) if x_found is not None else None
    return found, left


__all__ = [
    "DEFAULT_CONFIGURATION",
    "OPERATOR_ENV",
    "RunRecordError",
    "as_found_as_left",
    "bench_settings",
    "calibration_digest",
    "canonical",
    "default_operator",
    "run_record",
]
