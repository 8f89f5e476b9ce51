"""``thermal_calibration.json``: a thermal calibration as a file (docs/methods/thermal.md, "The thermal
calibration file").

Written by ``tablebench thermal`` (and ``tablebench run`` of a thermal procedure) into the run folder; read by
the thermal certificate and by ``tablebench correct``. SI throughout (K, m/s², rad/s, rad). Content::

    "format": "tablebench-thermal-calibration", "format_version": 1,
    "run", "recording_sha256", "bench", "unit": {"model", "serial_number"},
    "names": [30 parameter names], "reference_K", "temperature_range_K": [lo, hi] (validity range),
    "orders": [per parameter], "rate_term", "coefficients": [...], "covariance": [[...]],
    "chi2", "dof", "bic",
    "plateaus": [{"name", "setpoint_K", "temperature_K", "rate_K_per_s", "direction", "windows", "samples",
                  "x": [30], "covariance": [[30 × 30]]}],
    "skipped": [...], "incomplete_steps": [...],
    "integrity": {...}   (core.integrity: the digest of the values, bound to the recording's SHA-256)

:func:`load_thermal` refuses (one line, exit 2) a file that is not one, whose digest does not match its
values, or whose arrays have the wrong shapes.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.thermal.model import PlateauEstimate, ThermalModel
from core.errors import UserError
from core.integrity import values_digest, with_integrity
from core.jsonio import write_json

FORMAT = "tablebench-thermal-calibration"
FORMAT_VERSION = 1
FILE_NAME = "thermal_calibration.json"
COVERS = "every value of this file; the recording it was identified from (recording_sha256)"


class ThermalFileError(UserError, ValueError):
    """A thermal calibration file that cannot be used (one line naming the file and the fix)."""


@dataclass(frozen=True)
class ThermalFile:
    """A verified thermal calibration: the model, the plateaus it was fitted to, and who it is for."""

    path: str
    model: ThermalModel
    plateaus: list[dict[str, Any]]
    content: dict[str, Any]

    def estimates(self) -> list[PlateauEstimate]:
        """The plateau estimates (SI)."""
        return [
            PlateauEstimate(float(p["temperature_K"]), np.asarray(p["x"], float), np.asarray(p["covariance"], float),
                            float(p["rate_K_per_s"]), str(p["direction"]))  # fmt: skip
            for p in self.plateaus
        ]


def thermal_content(cal: Any, rr: Any) -> dict[str, Any]:
    """The file's content (without integrity) of a :class:`benches.thermal.identify.ThermalCalibration` of the
    open recorded run ``rr``."""
    m: ThermalModel = cal.model
    cfg = rr.config
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "run": str(rr.folder),
        "recording_sha256": rr.sha256,
        "bench": cfg.name,
        "unit": {"model": cfg.unit.model, "serial_number": cfg.unit.serial_number},
        "names": list(m.names),
        "reference_K": m.reference,
        "temperature_range_K": [float(v) for v in m.temperature_range],
        "orders": [int(o) for o in m.orders],
        "rate_term": bool(m.rate_term),
        "coefficients": m.coefficients.tolist(),
        "covariance": m.covariance.tolist(),
        "chi2": float(m.chi2),
        "n_data": int(m.n_data),
        "dof": int(m.dof),
        "bic": float(m.bic),
        "plateaus": [
            {
                "name": p.name,
                "setpoint_K": p.setpoint if math.isfinite(p.setpoint) else None,
                "temperature_K": p.estimate.temperature,
                "rate_K_per_s": p.estimate.rate,
                "direction": p.estimate.direction,
                "windows": p.windows,
                "samples": p.samples,
                "x": np.asarray(p.estimate.x).tolist(),
                "covariance": np.asarray(p.estimate.covariance).tolist(),
            }
            for p in cal.plateaus
        ],
        "skipped": list(cal.skipped),
        "incomplete_steps": list(cal.incomplete_steps),
    }


def save_thermal(content: dict[str, Any], path: str | Path) -> Path:
    """Write the file atomically, strict JSON, with its integrity block."""
    return write_json(path, with_integrity(content, str(content["recording_sha256"]), COVERS))


def _array(raw: dict[str, Any], key: str, shape: tuple[int, ...], where: str) -> np.ndarray:
    try:
        a = np.asarray(raw[key], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise ThermalFileError(f"{where}: {key} is missing or not numeric; identify the run again") from None
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ThermalFileError(f"{where}: {key} must be finite with shape {shape}, got {a.shape}")
    return a


def load_thermal(path: str | Path) -> ThermalFile:
    """Read and verify a thermal calibration file."""
    where = str(path)
    try:
        raw = json.loads(Path(path).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ThermalFileError(f"{where}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ThermalFileError(f"{where}: not a readable JSON file ({exc})") from None
    if not isinstance(raw, dict) or raw.get("format") != FORMAT:
        raise ThermalFileError(f"{where}: not a thermal calibration (format {FORMAT!r}); give thermal_calibration.json")
    if raw.get("format_version") != FORMAT_VERSION:
        raise ThermalFileError(f"{where}: format_version {raw.get('format_version')!r} is not {FORMAT_VERSION}")
    integ = raw.get("integrity")
    try:
        ok = isinstance(integ, dict) and integ.get("values_sha256") == values_digest(raw)
    except ValueError:
        ok = False
    if not ok:
        raise ThermalFileError(
            f"{where}: its values do not match its integrity digest (edited or damaged); identify the run again "
            "(tablebench thermal RUN)"
        )
    try:
        names = tuple(str(n) for n in raw["names"])
        orders = tuple(int(o) for o in raw["orders"])
        rate_term = bool(raw["rate_term"])
        lo, hi = (float(v) for v in raw["temperature_range_K"])
        plateaus = list(raw["plateaus"])
    except (KeyError, TypeError, ValueError):
        raise ThermalFileError(f"{where}: names/orders/rate_term/temperature_range_K/plateaus malformed") from None
    if len(orders) != len(names) or min(orders, default=0) < 0 or not lo <= hi:
        raise ThermalFileError(f"{where}: orders must give one order >= 0 per name and the range lo <= hi")
    k = sum(o + 1 + int(rate_term) for o in orders)
    coef = _array(raw, "coefficients", (k,), where)
    cov = _array(raw, "covariance", (k, k), where)
    model = ThermalModel(
        names, float(raw["reference_K"]), orders, rate_term, coef, cov, (lo, hi),
        float(raw.get("chi2", math.nan)), int(raw.get("n_data", 0)), float(raw.get("bic", math.nan)),
    )  # fmt: skip
    return ThermalFile(where, model, plateaus, raw)


def is_thermal_file(path: str | Path) -> bool:
    """True when ``path`` is a JSON file whose ``format`` says it is a thermal calibration."""
    try:
        with open(path, encoding="utf-8") as fh:
            head = fh.read(4096)
    except (OSError, UnicodeDecodeError):
        return False
    return f'"format": "{FORMAT}"' in head or f'"format":"{FORMAT}"' in head
