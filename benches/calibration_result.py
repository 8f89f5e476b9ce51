"""The calibration result: one typed object, one schema, versioned load/save (``benches/CALIBRATION_FORMAT.md``).

``tablebench identify`` and ``run`` build it, ``save`` writes ``calibration.json`` through the one strict JSON
writer (:func:`core.jsonio.write_json`: a NaN or ∞ anywhere raises, it is never written silently), and
``correct``, the certificate and the run read it back with :meth:`CalibrationResult.load`, which checks the
format, the version and every number it hands out. A parameter the procedure cannot identify is in the
explicit state ``identified = False`` (its value is the prior-dominated estimate and is never applied), and a
predicted σ that is infinite (unobservable) is written as the string ``"not identified"``, not as NaN/∞/null.

Uncertainty names (one per figure, everywhere): ``u`` = the identification's combined standard uncertainty
(white noise ⊕ correlated bias instability), ``u_white`` = its white-noise part; the certificate adds the
type-B components to give its own u and U = k·u, k = 2.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from analysis.identification.model import PARAM_KINDS, PARAM_NAMES
from analysis.timebase import TimeBase
from analysis.units import DISPLAY_UNITS
from core.errors import UserError
from core.jsonio import write_json

FORMAT = "tablebench-calibration"
FORMAT_VERSION = 2
"""Version 2: ``u``/``u_white`` per parameter (version 1 called them sigma/sigma_white), ``identified``,
``covariance_white``, and "not identified" instead of null for an infinite predicted σ."""
READABLE_VERSIONS = (1, 2)
NOT_IDENTIFIED = "not identified"


class CalibrationFormatError(UserError, ValueError):
    """calibration.json is missing, of another format/version, or malformed; the message names the key."""


@dataclass(frozen=True)
class ParameterEstimate:
    """One identified parameter, SI.

    Attributes
    ----------
    name, kind : str
        Name (``PARAM_NAMES``) and quantity kind.
    value : float
        Estimate (for a not-identified parameter: the prior-dominated value, never applied).
    u, u_white : float
        The identification's combined standard uncertainty and its white-noise part.
    prior_sigma : float
        The prior 1σ (bench datasheet bound).
    identified : bool
        False when the procedure cannot identify it (information rank or plan).
    """

    name: str
    kind: str
    value: float
    u: float
    u_white: float
    prior_sigma: float
    identified: bool


@dataclass
class CalibrationResult:
    """What an identification produces (calibration.json), typed. Arrays SI in ``PARAM_NAMES`` order."""

    parameters: dict[str, ParameterEstimate]
    covariance: NDArray[np.float64]
    covariance_white: NDArray[np.float64]
    noise_variance: NDArray[np.float64]
    method: str
    recording: str
    recording_sha256: str
    extra: dict[str, Any] = field(default_factory=dict)
    """Everything else of the file (information, residuals, plan, truth, history, run, warnings, …)."""

    # ---- access ------------------------------------------------------------------------------------------
    @property
    def x(self) -> NDArray[np.float64]:
        """Estimates (18,), SI."""
        return np.array([self.parameters[n].value for n in PARAM_NAMES])

    @property
    def u(self) -> NDArray[np.float64]:
        """Combined standard uncertainties of the identification (18,), SI."""
        return np.array([self.parameters[n].u for n in PARAM_NAMES])

    @property
    def identified(self) -> NDArray[np.bool_]:
        """Identification state per parameter (18,)."""
        return np.array([self.parameters[n].identified for n in PARAM_NAMES])

    @property
    def time_base(self) -> TimeBase | None:
        """The run's time base (t_table = t₀ + (1 + ε) t_unit with u), or None (a file from before it existed)."""
        d = self.extra.get("time_base")
        if not isinstance(d, Mapping):
            return None
        clean = {k: (math.nan if v is None else v) for k, v in d.items()}
        cov = d.get("covariance") or [[0.0, 0.0], [0.0, 0.0]]
        clean["covariance"] = [[math.nan if x is None else x for x in row] for row in cov]
        return TimeBase.from_dict(clean)

    def compensation_vector(self) -> tuple[NDArray[np.float64], list[str]]:
        """The vector to apply (not-identified parameters set to 0) and the names left out."""
        x = self.x
        skipped = [n for n in PARAM_NAMES if not self.parameters[n].identified]
        for n in skipped:
            x[PARAM_NAMES.index(n)] = 0.0
        return x, skipped

    def summary(self) -> str:
        """A readable table (display units; u = the identification's combined standard uncertainty, k = 1)."""
        result = self
        lines = [f"{'param':8s} {'value':>12s} {'u (k=1)':>10s} {'unit':7s} {'err/u':>7s}  note"]
        truth = result.extra.get("truth") or {}
        for name, p in result.parameters.items():
            unit, one = DISPLAY_UNITS[p.kind]
            e = truth.get("error_over_u", {}).get(name)
            note = "" if p.identified else "NOT IDENTIFIED (prior-dominated; not applied)"
            e_txt = "" if e is None else f"{e:7.2f}"
            lines.append(f"{name:8s} {p.value / one:12.4f} {p.u / one:10.4f} {unit:7s} {e_txt:>7s}  {note}")
        info = result.extra.get("information") or {}
        cond = info.get("condition")
        cond_txt = f"{cond:.3g}" if isinstance(cond, float) else str(cond)
        lines.append(f"information rank {info.get('rank')}/18, condition {cond_txt}; method {result.method}")
        lines.append(
            "u = the identification's combined standard uncertainty (white noise ⊕ correlated bias instability, "
            "k = 1); the certificate adds table, gravity and model components and states U = 2u"
        )
        tb = self.time_base
        if tb is not None:
            lines.append(tb.summary())
        if truth:
            lines.append(f"NEES {truth['nees']:.2f} over {truth['dof']} identified states (simulator truth)")
        else:
            lines.append("no simulator truth in the recording (a real bench): errors against truth not computed")
        lines += [f"warning: {w}" for w in result.extra.get("warnings", [])]
        return "\n".join(lines)

    # ---- (de)serialisation -------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """calibration.json content (format version :data:`FORMAT_VERSION`)."""
        si_units = {"bias": "m/s^2", "scale": "1", "misalignment": "rad", "quadratic": "s^2/m", "size_effect": "m"}
        params = {}
        for n in PARAM_NAMES:
            p = self.parameters[n]
            unit, one = DISPLAY_UNITS[p.kind]
            params[n] = {
                "value": p.value,
                "u": p.u,
                "u_white": p.u_white,
                "unit": si_units[p.kind],
                "kind": p.kind,
                "display_unit": unit,
                "display_value": p.value / one,
                "display_u": p.u / one,
                "identified": p.identified,
                "prior_sigma": p.prior_sigma,
            }
        extra = dict(self.extra)
        plan = dict(extra.get("plan") or {})
        if "predicted_sigma" in plan:
            plan["predicted_sigma"] = {
                k: (v if isinstance(v, int | float) and math.isfinite(v) else NOT_IDENTIFIED)
                for k, v in dict(plan["predicted_sigma"]).items()
            }
            extra["plan"] = plan
        info = dict(extra.get("information") or {})
        cond = info.get("condition")
        if "condition" in info and not (isinstance(cond, int | float) and math.isfinite(cond)):
            info["condition"] = "infinite (rank-deficient)"
            extra["information"] = info
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "recording": self.recording,
            "recording_sha256": self.recording_sha256,
            "method": self.method,
            "uncertainty": "u = the identification's combined standard uncertainty (white noise ⊕ correlated bias "
            "instability), k = 1; the certificate's u adds the type-B components and states U = 2u",
            "parameter_names": list(PARAM_NAMES),
            "parameters": params,
            "covariance": self.covariance.tolist(),
            "covariance_white": self.covariance_white.tolist(),
            "measurement_noise": {"variance": self.noise_variance.tolist(), **dict(extra.pop("noise_source", {}))},
            **extra,
        }

    def save(self, path: str | Path) -> Path:
        """Write calibration.json atomically; any non-finite number raises ``ValueError`` naming its key."""
        return write_json(path, self.to_dict(), nonfinite="error")

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str = "calibration.json") -> CalibrationResult:
        """Validate and type a calibration.json mapping (versions :data:`READABLE_VERSIONS`)."""
        if not isinstance(d, Mapping) or d.get("format") != FORMAT:
            raise CalibrationFormatError(f"{where}: not a tablebench calibration file (format key)")
        ver = d.get("format_version")
        if ver not in READABLE_VERSIONS:
            raise CalibrationFormatError(
                f"{where}: format_version {ver!r} is not readable by this version (reads {READABLE_VERSIONS}); "
                "identify the run again"
            )
        key = "parameter_names"
        try:
            if tuple(d.get("parameter_names") or PARAM_NAMES) != PARAM_NAMES:
                raise ValueError("must be the 18 names of CALIBRATION_FORMAT.md in order")
            params = {}
            for n, kind in zip(PARAM_NAMES, PARAM_KINDS, strict=True):
                key = f"parameters.{n}"
                p = d["parameters"][n]
                u_key, uw_key, id_key = ("u", "u_white", "identified") if ver >= 2 else (
                    "sigma", "sigma_white", "identifiable")  # fmt: skip
                for req in ("value", u_key):
                    if req not in p:
                        key = f"{key}.{req}"
                        raise KeyError(req)
                params[n] = ParameterEstimate(
                    name=n,
                    kind=kind,
                    value=_finite(p["value"], f"{key}.value"),
                    u=_finite(p[u_key], f"{key}.{u_key}", positive=True),
                    u_white=_finite(p.get(uw_key, p[u_key]), f"{key}.{uw_key}", positive=True),
                    prior_sigma=_finite(p.get("prior_sigma", math.inf) if "prior_sigma" in p else 1.0,
                                        f"{key}.prior_sigma", positive=True),
                    identified=_bool(p.get(id_key, True), f"{key}.{id_key}"),
                )  # fmt: skip
            key = "covariance"
            cov = _matrix(d["covariance"], key)
            key = "covariance_white"
            cov_w = _matrix(d["covariance_white"], key) if d.get("covariance_white") is not None else None
            key = "measurement_noise.variance"
            nv = np.asarray(d["measurement_noise"]["variance"], dtype=float)
            if nv.shape != (3,) or not np.all(np.isfinite(nv)) or np.any(nv <= 0):
                raise ValueError("must be 3 finite positive variances, (m/s²)²")
        except CalibrationFormatError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationFormatError(
                f"{where}: {key} is missing or malformed ({exc.__class__.__name__}: {exc}); see "
                "benches/CALIBRATION_FORMAT.md, or identify the run again"
            ) from None
        if cov_w is None:  # version 1 without the white part: diag of sigma_white, correlations of the total
            s_w = np.array([params[n].u_white for n in PARAM_NAMES])
            s_t = np.sqrt(np.diag(cov))
            cov_w = cov * np.outer(s_w / s_t, s_w / s_t)
        known = {"format", "format_version", "recording", "recording_sha256", "method", "uncertainty",
                 "parameter_names", "parameters", "covariance", "covariance_white", "measurement_noise"}  # fmt: skip
        extra = {k: v for k, v in d.items() if k not in known}
        extra["noise_source"] = {k: v for k, v in dict(d["measurement_noise"]).items() if k != "variance"}
        return cls(
            parameters=params,
            covariance=cov,
            covariance_white=cov_w,
            noise_variance=nv,
            method=str(d.get("method", "")),
            recording=str(d.get("recording", "")),
            recording_sha256=str(d.get("recording_sha256", "")),
            extra=extra,
        )

    @classmethod
    def load(cls, path: str | Path) -> CalibrationResult:
        """Read and validate calibration.json; one clear :class:`CalibrationFormatError` for any problem."""
        p = Path(path)
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise CalibrationFormatError(f"{p}: no such calibration file; identify the run first") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise CalibrationFormatError(f"{p}: not readable JSON ({exc.__class__.__name__}: {exc})") from None
        return cls.from_dict(d, str(p))


def _finite(v: Any, key: str, positive: bool = False) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"{key} must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise ValueError(f"{key} must be > 0, got {v!r}")
    return float(v)


def _bool(v: Any, key: str) -> bool:
    if not isinstance(v, bool):
        raise ValueError(f"{key} must be true or false, got {v!r}")
    return v


def _matrix(v: Any, key: str) -> NDArray[np.float64]:
    m = np.asarray(v, dtype=float)
    if m.shape != (18, 18) or not np.all(np.isfinite(m)):
        raise ValueError(f"{key} must be a finite 18 × 18 matrix")
    if not np.allclose(m, m.T, rtol=1e-9, atol=0.0) or np.any(np.diag(m) <= 0):
        raise ValueError(f"{key} must be symmetric with positive variances")
    return m


__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "NOT_IDENTIFIED",
    "CalibrationFormatError",
    "CalibrationResult",
    "ParameterEstimate",
]
