"""The calibration certificate, one package (no import loop):

* :mod:`.content` — what a certificate says (:class:`Certificate`, :class:`BenchInfo`, GUM rounding);
* :mod:`.budget` — the budget's inputs from a run (step geometry through THE reference function, bench
  uncertainties), the maths being :mod:`analysis.identification.budget`;
* :mod:`.build` — run folder → :class:`Certificate` (decision rule, traceability), and issuing it;
* :mod:`.noise_report` — the noise report a static record gets instead of a calibration certificate;
* :mod:`.analyses` — the analyses' rows (noise, periodic, drift) in display units;
* :mod:`.plots` — figures, drawn as vector graphics with :mod:`.drawing`; :mod:`.pdf` — the PDF rendering.

Imports flow content ← budget ← build → plots → drawing, pdf → content; build → noise_report → analyses → content.
"""

from __future__ import annotations

from .build import bench_info, build_certificate, combined_covariance, issue_certificate, publish_certificate
from .content import (
    FORMAT,
    FORMAT_VERSION,
    MODEL_TEXT,
    NOISE_REPORT,
    SIGN_CONVENTIONS,
    BenchInfo,
    Certificate,
    CertificateError,
    ParameterResult,
    format_with_uncertainty,
)

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "MODEL_TEXT",
    "NOISE_REPORT",
    "SIGN_CONVENTIONS",
    "BenchInfo",
    "Certificate",
    "CertificateError",
    "ParameterResult",
    "bench_info",
    "build_certificate",
    "combined_covariance",
    "format_with_uncertainty",
    "issue_certificate",
    "publish_certificate",
]
