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
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray

from analysis.identification.specification import ModelSpec, get_model, model_for_names
from analysis.timebase import TimeBase
from analysis.units import DISPLAY_UNITS
from core.errors import UserError
from core.integrity import with_integrity
from core.jsonio import to_jsonable, write_json

FORMAT = "tablebench-calibration"
FORMAT_VERSION = 3
"""Version 2: ``u``/``u_white`` per parameter (version 1 called them sigma/sigma_white), ``identified``,
``covariance_white``, and "not identified" instead of null for an infinite predicted σ."""
READABLE_VERSIONS = (1, 2, 3)
"""Version 3: the ``integrity`` block (a digest of the file's values bound to ``recording_sha256``,
:mod:`benches.calibration_integrity`); ``certificate``, ``correct`` and ``registry add`` require it."""
COVERS = (
    "SHA-256 of every key of this file except 'integrity', as canonical JSON (sorted keys, no spaces, ASCII); "
    "recording_sha256 is among them, binding the values to the recording"
)
NOT_IDENTIFIED = "not identified"
SI_UNITS = {k: v for m in ("accelerometer", "gyro") for k, v in get_model(m).si_units.items()}
"""The SI unit written for each parameter kind."""


class CalibrationFormatError(UserError, ValueError):
    """calibration.json is missing, of another format/version, or malformed; the message names the key."""


# ---- the typed blocks of calibration.json --------------------------------------------------------------------------

_B = TypeVar("_B", bound="_Block")



def read_raw(path: str | Path) -> dict[str, Any]:
    """calibration.json as a mapping (one :class:`CalibrationFormatError` line for any read problem)."""
    p = Path(path)
    try:
        d = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CalibrationFormatError(f"{p}: no such calibration file; identify the run first") from None
    except IsADirectoryError:
        raise CalibrationFormatError(f"{p}: is a folder; give its calibration.json") from None
    except OSError as exc:
        raise CalibrationFormatError(f"{p}: cannot be read ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CalibrationFormatError(f"{p}: not readable JSON ({exc.__class__.__name__}: {exc})") from None
    if not isinstance(d, dict):
        raise CalibrationFormatError(f"{p}: not a tablebench calibration file (a JSON object is expected)")
    return d

@dataclass(frozen=True, kw_only=True)
class _Block:
    """A calibration.json block read as typed members; absent keys are None and stay absent when written,
    keys this version does not know are kept in ``other`` (files written by other versions round-trip)."""

    other: dict[str, Any] = field(default_factory=dict)
    KEY: ClassVar[str] = ""

    @classmethod
    def _names(cls) -> list[str]:
        return [f.name for f in fields(cls) if f.name != "other"]

    @classmethod
    def from_mapping(cls: type[_B], d: Any, where: str = "calibration.json") -> _B:
        """The block from its JSON mapping (values as read; the consumers check what they use)."""
        if not isinstance(d, Mapping):
            raise CalibrationFormatError(
                f"{where}: {cls.KEY} is missing or malformed (expected a mapping, got {type(d).__name__}); see "
                "benches/CALIBRATION_FORMAT.md, or identify the run again"
            )
        names = cls._names()
        kw = {n: cls._read(n, d[n], where) for n in names if n in d}
        return cls(**kw, other={k: v for k, v in d.items() if k not in names})

    @classmethod
    def _read(cls, name: str, value: Any, where: str) -> Any:
        return value

    def to_mapping(self) -> dict[str, Any]:
        """The block as written to calibration.json (present members in declaration order, then ``other``)."""
        out = {n: _plain(getattr(self, n)) for n in self._names() if getattr(self, n) is not None}
        return {**out, **self.other}


def _plain(v: Any) -> Any:
    if isinstance(v, _Block):
        return v.to_mapping()
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


@dataclass(frozen=True, kw_only=True)
class InformationSummary(_Block):
    """``information``: numerical rank and condition of the data information, the parameters it cannot
    identify, and how the rank was decided (``condition`` is ``inf`` or the string written for it when
    rank-deficient)."""

    KEY: ClassVar[str] = "information"
    rank: int | None = None
    condition: float | str | None = None
    unidentifiable: list[str] | None = None
    tolerance: str | None = None


@dataclass(frozen=True, kw_only=True)
class StepResiduals(_Block):
    """One row of ``residuals.per_step``: the fit residual of one acquisition window (body frame, m/s²)."""

    KEY: ClassVar[str] = "residuals.per_step"
    name: str | None = None
    samples: int | None = None
    mean: list[float] | None = None
    rms: list[float] | None = None
    kind: str | None = None

    def as_row(self) -> dict[str, Any]:
        """The row as the certificate's budget and plots take it (a plain mapping)."""
        return self.to_mapping()


@dataclass(frozen=True, kw_only=True)
class Residuals(_Block):
    """``residuals``: overall RMS per axis (m/s²) and the rows per step."""

    KEY: ClassVar[str] = "residuals"
    rms: list[float] | None = None
    per_step: tuple[StepResiduals, ...] | None = None

    @classmethod
    def _read(cls, name: str, value: Any, where: str) -> Any:
        if name != "per_step" or value is None:
            return value
        if not isinstance(value, list | tuple):
            raise CalibrationFormatError(
                f"{where}: residuals.per_step is missing or malformed (expected a list of rows); see "
                "benches/CALIBRATION_FORMAT.md, or identify the run again"
            )
        return tuple(StepResiduals.from_mapping(r, where) for r in value)

    def rows(self) -> list[dict[str, Any]]:
        """``per_step`` as plain mappings ([] when absent)."""
        return [r.as_row() for r in self.per_step or ()]


@dataclass(frozen=True, kw_only=True)
class PlanSummary(_Block):
    """``plan``: the plan on the actual data geometry (predicted total 1σ per parameter, rank, warnings)."""

    KEY: ClassVar[str] = "plan"
    predicted_sigma: dict[str, float | str] | None = None
    rank: int | None = None
    warnings: list[str] | None = None


@dataclass(frozen=True, kw_only=True)
class TruthCheck(_Block):
    """``truth``: a simulated bench's true parameters and the estimate's errors against them (SI)."""

    KEY: ClassVar[str] = "truth"
    values: dict[str, float] | None = None
    error_over_u: dict[str, float] | None = None
    nees: float | None = None
    dof: int | None = None
    nees_states: list[str] | None = None


@dataclass(frozen=True, kw_only=True)
class FilterHistory(_Block):
    """``history``: the streaming filter's estimate and white-noise 1σ after each update."""

    KEY: ClassVar[str] = "history"
    time: list[float] | None = None
    step: list[str] | None = None
    estimate: list[list[float]] | None = None
    sigma: list[list[float]] | None = None


@dataclass(frozen=True, kw_only=True)
class RunInfo(_Block):
    """``run``: the recording's provenance (status, bench, procedure, seed, site, unit, table, temperature K)."""

    KEY: ClassVar[str] = "run"
    status: str | None = None
    bench_name: str | None = None
    procedure_name: str | None = None
    procedure_sha256: str | None = None
    procedure_overrides: dict[str, float] | None = None
    integrity_verified: bool | None = None
    integrity_note: str | None = None
    seed: int | None = None
    created_utc: str | None = None
    transport: str | None = None
    site: dict[str, Any] | None = None
    unit: dict[str, Any] | None = None
    table: dict[str, Any] | None = None
    temperature_k: dict[str, float | None] | None = None


@dataclass(frozen=True, kw_only=True)
class TimeBaseBlock(_Block):
    """``time_base``: the run's t_table = t₀ + (1 + ε) t_unit (docs/methods/time-base.md) with its u and method
    (the members of :meth:`analysis.timebase.TimeBase.as_dict`, non-finite numbers as null), its effect on the
    18 parameters (``effect_u``: u contributed, SI, included in the covariance; ``sensitivity``: ∂x/∂(t₀, ε) per
    parameter) and on a gyro scale factor (``gyro_scale_factor_u`` = u(ε), 1 : 1)."""

    KEY: ClassVar[str] = "time_base"
    offset_s: float | None = None
    rate: float | None = None
    u_offset_s: float | None = None
    u_rate: float | None = None
    covariance: list[list[float | None]] | None = None
    method: str | None = None
    model: str | None = None
    misfit: float | None = None
    events: list[dict[str, Any]] | None = None
    check: dict[str, Any] | None = None
    notes: list[str] | None = None
    effect_u: dict[str, float] | None = None
    sensitivity: dict[str, list[float]] | None = None
    gyro_scale_factor_u: float | None = None

    @property
    def estimate(self) -> TimeBase:
        """The typed estimate (:class:`analysis.timebase.TimeBase`; null numbers read as NaN)."""
        d = {k: (math.nan if v is None else v) for k, v in self.to_mapping().items()}
        cov = self.covariance or [[0.0, 0.0], [0.0, 0.0]]
        d["covariance"] = [[math.nan if x is None else x for x in row] for row in cov]
        return TimeBase.from_dict(d)


_BLOCKS: dict[str, type[_Block]] = {
    "information": InformationSummary,
    "residuals": Residuals,
    "plan": PlanSummary,
    "truth": TruthCheck,
    "history": FilterHistory,
    "run": RunInfo,
    "time_base": TimeBaseBlock,
}


@dataclass(frozen=True)
class ParameterEstimate:
    """One identified parameter, SI.

    Attributes
    ----------
    name, kind : str
        Name (the model's ``names``) and quantity kind.
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
    """What an identification produces (calibration.json), typed. Arrays SI in the identified model's name order
    (:attr:`error_model`: the accelerometer's 18, or the whole unit's with the gyro).

    The blocks of the file are typed members (``information``, ``residuals``, ``plan``, ``truth``,
    ``history``, ``run``, ``warnings``, …; None when a file lacks them); ``extra`` keeps only keys this version
    does not know. For compatibility a known key given in ``extra`` is moved to its typed member.
    """

    parameters: dict[str, ParameterEstimate]
    covariance: NDArray[np.float64]
    covariance_white: NDArray[np.float64]
    noise_variance: NDArray[np.float64]
    method: str
    recording: str
    recording_sha256: str
    extra: dict[str, Any] = field(default_factory=dict)
    """Keys of the file this version does not know (kept, written back)."""
    noise_source: str | None = None
    software_version: str | None = None
    model: str | None = None
    information: InformationSummary | None = None
    residuals: Residuals | None = None
    plan: PlanSummary | None = None
    truth: TruthCheck | None = None
    history: FilterHistory | None = None
    run: RunInfo | None = None
    warnings: list[str] = field(default_factory=list)
    live_vs_offline_max_u: float | None = None
    time_base: TimeBaseBlock | None = None
    """The run's time base (t_table = t₀ + (1 + ε) t_unit) and its effect; ``time_base.estimate`` is typed."""
    """Largest |live filter − offline| / u_white of ``tablebench run`` (None: no live filter)."""

    def __post_init__(self) -> None:
        extra = dict(self.extra)
        ns = extra.pop("noise_source", None)
        if isinstance(ns, Mapping):
            if self.noise_source is None and "source" in ns:
                self.noise_source = ns["source"]
            rest = {k: v for k, v in ns.items() if k != "source"}
            if rest:
                extra["noise_source"] = rest
        for key, cls in _BLOCKS.items():
            if key in extra and getattr(self, key) is None:
                v = extra.pop(key)
                if v is not None:
                    setattr(self, key, cls.from_mapping(v, self.recording or "calibration.json"))
        for key in ("software_version", "model", "live_vs_offline_max_u"):
            if key in extra and getattr(self, key) is None:
                setattr(self, key, extra.pop(key))
        if "warnings" in extra and not self.warnings:
            self.warnings = list(extra.pop("warnings") or [])
        self.extra = extra

    @property
    def per_step(self) -> list[dict[str, Any]]:
        """``residuals.per_step`` as plain rows ([] when absent)."""
        return self.residuals.rows() if self.residuals is not None else []

    # ---- access ------------------------------------------------------------------------------------------
    @property
    def error_model(self) -> ModelSpec:
        """The identified error model (:mod:`analysis.identification.specification`), from the parameter names."""
        return model_for_names(tuple(self.parameters))

    @property
    def names(self) -> tuple[str, ...]:
        """State names, in order."""
        return tuple(self.parameters)

    @property
    def x(self) -> NDArray[np.float64]:
        """Estimates (n,), SI."""
        return np.array([p.value for p in self.parameters.values()])

    @property
    def u(self) -> NDArray[np.float64]:
        """Combined standard uncertainties of the identification (n,), SI."""
        return np.array([p.u for p in self.parameters.values()])

    @property
    def identified(self) -> NDArray[np.bool_]:
        """Identification state per parameter (n,)."""
        return np.array([p.identified for p in self.parameters.values()])

    def compensation_vector(self) -> tuple[NDArray[np.float64], list[str]]:
        """The vector to apply (not-identified parameters set to 0) and the names left out."""
        x = self.x
        names = self.names
        skipped = [n for n in names if not self.parameters[n].identified]
        for n in skipped:
            x[names.index(n)] = 0.0
        return x, skipped

    def truth_nees(self, covariance: NDArray[np.float64]) -> float | None:
        """NEES of the estimate against the simulator truth over the identified states, judged with
        ``covariance`` (n, n; SI; this result's names order), e.g. the certificate's type A + B covariance
        (:func:`benches.certificate.combined_covariance`); None without truth."""
        t = self.truth
        if t is None or not t.nees_states or not t.values:
            return None
        names = list(self.names)
        idx = [names.index(n) for n in t.nees_states]
        e = self.x[idx] - np.array([t.values[n] for n in t.nees_states])
        sub = np.asarray(covariance, dtype=float)[np.ix_(idx, idx)]
        try:
            return float(e @ np.linalg.solve(sub, e))
        except np.linalg.LinAlgError:
            return None

    def summary(self, combined_covariance: NDArray[np.float64] | None = None) -> str:
        """A readable table (display units; u = the identification's combined standard uncertainty, k = 1).

        ``combined_covariance``: the certificate's covariance (type A + B, :func:`benches.certificate.
        combined_covariance`); given, the NEES against a simulator's truth is judged with it, as the certificate
        states the uncertainty, and the identification's own (type A) NEES is shown beside it.
        """
        result = self
        w = max(8, *(len(n) for n in result.parameters))
        lines = [f"{'param':{w}s} {'value':>12s} {'u (k=1)':>10s} {'unit':7s} {'err/u':>7s}  note"]
        truth = result.truth
        err_u = (truth.error_over_u or {}) if truth is not None else {}
        for name, p in result.parameters.items():
            unit, one = DISPLAY_UNITS[p.kind]
            e = err_u.get(name)
            note = "" if p.identified else "NOT IDENTIFIED (prior-dominated; not applied)"
            e_txt = "" if e is None else f"{e:7.2f}"
            lines.append(f"{name:{w}s} {p.value / one:12.4f} {p.u / one:10.4f} {unit:7s} {e_txt:>7s}  {note}")
        info = result.information or InformationSummary()
        cond = info.condition
        cond_txt = f"{cond:.3g}" if isinstance(cond, float) else str(cond)
        lines.append(
            f"information rank {info.rank}/{len(result.parameters)}, condition {cond_txt}; method {result.method}"
        )
        lines.append(
            "u = the identification's combined standard uncertainty (white noise ⊕ correlated bias instability, "
            "k = 1); the certificate adds table, gravity and model components and states U = 2u"
        )
        if self.time_base is not None:
            lines.append(self.time_base.estimate.summary())
        nees_ab = None if combined_covariance is None or truth is None else self.truth_nees(combined_covariance)
        if truth is not None and truth.to_mapping() and nees_ab is not None:
            band = 2.0 * math.sqrt(2.0 * truth.dof)  # ≈ 95 % of a χ²(dof)
            lines.append(
                f"NEES {nees_ab:.2f} over {truth.dof} identified states against the simulator truth with the "
                f"certificate's u (type A + B: the identification's own ⊕ table attitude and rate accuracy, g, model "
                f"mismatch; expected {truth.dof} ± {band:.0f} if u is right); with the identification's own u "
                f"(type A) alone: {truth.nees:.2f}"
            )
        elif truth is not None and (truth.to_mapping()):
            band = 2.0 * math.sqrt(2.0 * truth.dof)  # ≈ 95 % of a χ²(dof)
            lines.append(
                f"NEES {truth.nees:.2f} over {truth.dof} identified states against the simulator truth (expected "
                f"{truth.dof} ± {band:.0f} if u is right); u here is the identification's own (type A: white noise ⊕ "
                "bias instability): the certificate's type-B components (table attitude and rate accuracy, g) are "
                "not in it, so a NEES above the band can be covered there"
            )
        else:
            lines.append("no simulator truth in the recording (a real bench): errors against truth not computed")
        lines += [f"warning: {w}" for w in result.warnings]
        return "\n".join(lines)

    # ---- (de)serialisation -------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """calibration.json content (format version :data:`FORMAT_VERSION`)."""
        params = {}
        for n in self.names:
            p = self.parameters[n]
            unit, one = DISPLAY_UNITS[p.kind]
            params[n] = {
                "value": p.value,
                "u": p.u,
                "u_white": p.u_white,
                "unit": SI_UNITS[p.kind],
                "kind": p.kind,
                "display_unit": unit,
                "display_value": p.value / one,
                "display_u": p.u / one,
                "identified": p.identified,
                "prior_sigma": p.prior_sigma,
            }
        blocks: dict[str, Any] = {}
        if self.software_version is not None:
            blocks["software_version"] = self.software_version
        if self.model is not None:
            blocks["model"] = self.model
        if self.information is not None:
            info = self.information.to_mapping()
            cond = info.get("condition")
            if "condition" in info and not (isinstance(cond, int | float) and math.isfinite(cond)):
                info["condition"] = "infinite (rank-deficient)"
            blocks["information"] = info
        if self.residuals is not None:
            blocks["residuals"] = self.residuals.to_mapping()
        if self.plan is not None:
            plan = self.plan.to_mapping()
            if "predicted_sigma" in plan:
                plan["predicted_sigma"] = {
                    k: (v if isinstance(v, int | float) and math.isfinite(v) else NOT_IDENTIFIED)
                    for k, v in dict(plan["predicted_sigma"]).items()
                }
            blocks["plan"] = plan
        blocks["truth"] = None if self.truth is None else self.truth.to_mapping()
        blocks["history"] = None if self.history is None else self.history.to_mapping()
        if self.run is not None:
            blocks["run"] = self.run.to_mapping()
        blocks["warnings"] = list(self.warnings)
        if self.live_vs_offline_max_u is not None:
            blocks["live_vs_offline_max_u"] = self.live_vs_offline_max_u
        if self.time_base is not None:
            blocks["time_base"] = self.time_base.to_mapping()
        extra = dict(self.extra)
        noise = {"variance": self.noise_variance.tolist()}
        if self.noise_source is not None:
            noise["source"] = self.noise_source
        noise.update(dict(extra.pop("noise_source", {})))
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "recording": self.recording,
            "recording_sha256": self.recording_sha256,
            "method": self.method,
            "uncertainty": "u = the identification's combined standard uncertainty (white noise ⊕ correlated bias "
            "instability), k = 1; the certificate's u adds the type-B components and states U = 2u",
            "parameter_names": list(self.names),
            "parameters": params,
            "covariance": self.covariance.tolist(),
            "covariance_white": self.covariance_white.tolist(),
            "measurement_noise": noise,
            **blocks,
            **extra,
        }

    def save(self, path: str | Path) -> Path:
        """Write calibration.json atomically; any non-finite number raises ``ValueError`` naming its key."""
        content = with_integrity(to_jsonable(self.to_dict()), self.recording_sha256, COVERS)  # tamper evidence
        return write_json(path, content, nonfinite="error")

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
            names = tuple(d.get("parameter_names") or get_model("accelerometer").names)
            try:
                model = model_for_names(names)
            except ValueError:
                raise ValueError(
                    "must be the names of a registered model in order (the accelerometer's 18, optionally followed "
                    "by the gyro's), see CALIBRATION_FORMAT.md"
                ) from None
            params = {}
            for n, kind in zip(model.names, model.kinds, strict=True):
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
            cov = _matrix(d["covariance"], key, model.n_params)
            key = "covariance_white"
            cov_w = None
            if d.get("covariance_white") is not None:
                cov_w = _matrix(d["covariance_white"], key, model.n_params)
            key = "measurement_noise.variance"
            nv = np.asarray(d["measurement_noise"]["variance"], dtype=float)
            if nv.shape != (model.n_axes,) or not np.all(np.isfinite(nv)) or np.any(nv <= 0):
                raise ValueError(f"must be {model.n_axes} finite positive variances, SI² (one per axis)")
        except CalibrationFormatError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationFormatError(
                f"{where}: {key} is missing or malformed ({exc.__class__.__name__}: {exc}); see "
                "benches/CALIBRATION_FORMAT.md, or identify the run again"
            ) from None
        if cov_w is None:  # version 1 without the white part: diag of sigma_white, correlations of the total
            s_w = np.array([params[n].u_white for n in model.names])
            s_t = np.sqrt(np.diag(cov))
            cov_w = cov * np.outer(s_w / s_t, s_w / s_t)
        known = {"format", "format_version", "recording", "recording_sha256", "method", "uncertainty",
                 "parameter_names", "parameters", "covariance", "covariance_white", "measurement_noise",
                 "integrity"}  # fmt: skip (integrity: benches/calibration_integrity.py)
        extra = {k: v for k, v in d.items() if k not in known}
        noise = dict(d["measurement_noise"])
        typed: dict[str, Any] = {}
        for key, block in _BLOCKS.items():
            v = extra.pop(key, None)
            if v is not None:
                typed[key] = block.from_mapping(v, where)
        for key in ("software_version", "model", "live_vs_offline_max_u"):
            if key in extra:
                typed[key] = extra.pop(key)
        warnings = extra.pop("warnings", None)
        if not isinstance(warnings, list | type(None)):
            raise CalibrationFormatError(
                f"{where}: warnings is missing or malformed (expected a list of strings); see "
                "benches/CALIBRATION_FORMAT.md, or identify the run again"
            )
        rest = {k: v for k, v in noise.items() if k not in ("variance", "source")}
        if rest:
            extra["noise_source"] = rest
        return cls(
            **typed,
            warnings=list(warnings or []),
            noise_source=noise.get("source"),
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
        return cls.from_dict(read_raw(path), str(path))


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


def _matrix(v: Any, key: str, n: int = 18) -> NDArray[np.float64]:
    m = np.asarray(v, dtype=float)
    if m.shape != (n, n) or not np.all(np.isfinite(m)):
        raise ValueError(f"{key} must be a finite {n} × {n} matrix")
    if not np.allclose(m, m.T, rtol=1e-9, atol=0.0) or np.any(np.diag(m) <= 0):
        raise ValueError(f"{key} must be symmetric with positive variances")
    return m


__all__ = [
    "SI_UNITS",
    "FilterHistory",
    "InformationSummary",
    "PlanSummary",
    "Residuals",
    "RunInfo",
    "StepResiduals",
    "TruthCheck",
    "FORMAT",
    "FORMAT_VERSION",
    "NOT_IDENTIFIED",
    "CalibrationFormatError",
    "CalibrationResult",
    "ParameterEstimate",
]
