"""The certificate's content model: what a certificate says (rendered by :mod:`.pdf` and :meth:`Certificate.to_json`).

Constants of the format, the bench information it needs, one row per parameter, and the GUM rounding of a
value with its expanded uncertainty. Built by :mod:`benches.certificate.build`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import asdict, dataclass, field
from typing import Any

from analysis.units import kelvin_to_celsius
from core.errors import UserError
from core.jsonio import dumps

FORMAT = "tablebench-certificate"
FORMAT_VERSION = 1
ANALYSES = ("noise", "periodic", "drift")
CALIBRATION_CERTIFICATE = "CALIBRATION CERTIFICATE"
NOISE_REPORT = "NOISE REPORT"
"""The document a static record gets instead of a calibration certificate (:mod:`benches.certificate.noise_report`);
also its verdict (no conformity statement)."""

MODEL_TEXT = "f_out = f + (S + T) f + b + D (f∘f) + diag(r) c(ω) + v"
GYRO_MODEL_TEXT = "ω_out = (I + S_g + T_g) ω_ib + b_g + G f + S2 (ω_ib∘ω_ib) + A |ω_ib| + v_g"
GYRO_CONVENTIONS: tuple[str, ...] = (
    "ω_ib: true angular rate of the unit relative to inertial space, body frame: the table's rate from its "
    "encoder angles over time plus the Earth rate at the site (Ω = 7.292115e-5 rad/s); ω_out the gyro output, rad/s.",
    "b_g: gyro bias (°/h); S_g = diag: scale-factor errors (ppm); T_g: misalignment, δω_i += τ_ij ω_j, the "
    "accelerometer's convention (arcsec); G: g-sensitivity, δω_i += G_ij f_j (°/h/g; diagonal unless stated); "
    "S2 (ppm/(°/s)) and A (ppm, +A for positive, −A for negative rates) only when listed.",
    "Gyro compensation (exact inverse): ω_ib = (I + S_g + T_g)⁻¹ (ω_out − b_g − G f) when S2 = A = 0, otherwise "
    "solved per sample by Newton's iteration; f is the compensated specific force.",
)
SIGN_CONVENTIONS: tuple[str, ...] = (
    "Body frame b: the unit's case axes x, y, z as marked on the unit; navigation frame n: East-North-Up.",
    "f: true specific force at the triad's reference point, body frame; at rest f = C_n^b [0, 0, g]ᵀ, i.e. an "
    "axis pointing up reads +g.",
    "f_out: the unit's output (after its own count scaling), body frame, m/s².",
    "b: bias, added to the output (f_out − f at zero input); shown in µg (1 µg = 9.80665e-6 m/s²).",
    "S = diag(S_x, S_y, S_z): scale-factor errors, output axis i reads (1 + S_i) f_i plus the other terms; "
    "shown in ppm.",
    "T: misalignment, off-diagonal; convention δf_i += τ_ij f_j (output axis i senses τ_ij of the input along j); "
    "shown in arcsec (small angles, rad).",
    "D = diag(d): quadratic (second-order) coefficients, δf_i += d_i f_i²; shown in µg/g².",
    "r: size effect, δf_i += r_i c_i(ω) with c(ω) = [ω_y²+ω_z², ω_z²+ω_x², ω_x²+ω_y²]; shown in mm. Physically, "
    "r_i is minus the offset of accelerometer i along its own sensing axis from the table's rotation centre, as the "
    "accelerometer senses it: r_i = −(1 + S_i) ρ_i,i − ½ Σ_k≠i τ_ik ρ_i,k (ρ_i its position, body frame; the "
    "correction to −ρ_i,i is ppm-level). It moves with the mounting: r is only valid for the unit mounted as "
    "calibrated.",
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
    gyro_bias_instability: list[float] | None = None
    azimuth_uncertainty: float | None = None
    rate_accuracy: float = 0.0
    latency: float = 0.0
    reference_standards: list[dict[str, str]] = field(default_factory=list)
    ambient: dict[str, float | None] = field(default_factory=dict)
    """The laboratory's ambient conditions (bench ``site.ambient``, SI: temperature K, tolerance K, relative
    humidity fraction, pressure Pa); empty or None values: not stated."""


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
    """Everything a certificate says; rendered by :mod:`benches.certificate.pdf` and :meth:`to_json`."""

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
    plots: dict[str, Any] = field(default_factory=dict)
    """Figures by name, vector drawings (:class:`benches.certificate.drawing.Drawing`: the certificate's and the
    noise report's; content imports no other module of the package); ``bytes(figure)`` is each
    one's identity (its SHA-256 in the JSON). The analyses' own figures stay PNG files (``analysis_plots``)."""
    analysis_plots: list[tuple[str, bytes]] = field(default_factory=list)
    supersedes: str = ""
    document: str = CALIBRATION_CERTIFICATE
    """:data:`CALIBRATION_CERTIFICATE`, or :data:`NOISE_REPORT` for a static record."""
    noise: dict[str, Any] = field(default_factory=dict)
    """A noise report's analysis (record step, method, the noise.json-format result, channel statistics)."""

    @property
    def is_noise_report(self) -> bool:
        """True for the noise report of a static record (no parameters, no conformity statement)."""
        return self.document == NOISE_REPORT

    @property
    def has_gyro(self) -> bool:
        """True when the certificate covers the gyro triad too (the whole unit)."""
        return any(p.name.startswith("gyro_") for p in self.parameters)

    @property
    def item_title(self) -> str:
        """What the certificate calibrates, in its heading."""
        return "Inertial unit (accelerometer and gyro triads)" if self.has_gyro else "Accelerometer triad"

    @property
    def model_text(self) -> str:
        """The error model(s) the parameters belong to."""
        return MODEL_TEXT + ("; " + GYRO_MODEL_TEXT if self.has_gyro else "")

    @property
    def conventions(self) -> tuple[str, ...]:
        """Sign conventions of the certified parameters."""
        return SIGN_CONVENTIONS + (GYRO_CONVENTIONS if self.has_gyro else ())

    def to_dict(self) -> dict[str, Any]:
        """The machine-readable certificate (SI values; plots by name and SHA-256)."""
        if self.is_noise_report:
            return self._noise_report_dict()
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
            "model": self.model_text,
            "sign_conventions": list(self.conventions),
            "parameter_names": [p.name for p in self.parameters],
            "compensation": {
                "model": self.model_text,
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
            "plots": {k: hashlib.sha256(bytes(v)).hexdigest() for k, v in sorted(self.plots.items())},
            "analysis_plots": {k: hashlib.sha256(v).hexdigest() for k, v in self.analysis_plots},
        }
        return d

    def _noise_report_dict(self) -> dict[str, Any]:
        """The machine-readable noise report (SI values in ``noise.analysis``, the noise.json format)."""
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "document": self.document,
            "certificate_number": self.number,
            "supersedes": self.supersedes,
            "issue_date": self.issue_date,
            "verdict": self.verdict,
            "complete": self.complete,
            "incomplete_reason": self.incomplete_reason,
            "unit": self.unit,
            "bench": self.bench,
            "procedure": self.procedure,
            "recording": self.recording,
            "environment": self.environment,
            "noise": self.noise,
            "warnings": self.warnings,
            "analyses": self.analyses,
            "software_version": self.software_version,
            "plots": {k: hashlib.sha256(bytes(v)).hexdigest() for k, v in sorted(self.plots.items())},
            "analysis_plots": {k: hashlib.sha256(v).hexdigest() for k, v in self.analysis_plots},
        }

    def to_json(self) -> str:
        """Deterministic JSON text of :meth:`to_dict` (non-finite numbers as null: "not available")."""
        return dumps(self.to_dict(), nonfinite="null", indent=2)


# ---- helpers -------------------------------------------------------------------------------------------------

AMBIENT_NOT_STATED = "not stated in the bench file (site.ambient)"


def ambient_text(ambient: dict[str, Any] | None) -> str:
    """The laboratory's ambient conditions as the certificate states them (°C, % RH, hPa), or "not stated".

    ``ambient``: the certificate's ``environment.laboratory_ambient`` (SI: K, fraction, Pa).
    """
    a = ambient or {}
    t = a.get("temperature_k")
    if t is None:
        return AMBIENT_NOT_STATED
    tol = a.get("temperature_tolerance_k")
    parts = [f"{kelvin_to_celsius(t):.1f}" + (f" ± {tol:.1f}" if tol is not None else "") + " °C air temperature"]
    if a.get("relative_humidity") is not None:
        parts.append(f"{100 * a['relative_humidity']:.0f} % relative humidity")
    if a.get("pressure_pa") is not None:
        parts.append(f"{a['pressure_pa'] / 100:.0f} hPa")
    return ", ".join(parts) + " (laboratory, as stated in the bench file)"



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


