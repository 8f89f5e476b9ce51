"""Tamper evidence of calibration.json: a digest of its own values bound to the recording's digest, and a
plausibility check of the values (``docs/registry.md``, tamper evidence).

:meth:`benches.calibration_result.CalibrationResult.save` writes ``"integrity"``::

    "integrity": {"algorithm": "sha256", "values_sha256": "<hex>", "recording_sha256": "<hex>",
                  "covers": "…"}

``values_sha256`` is the SHA-256 of the file's content without the ``integrity`` key, as canonical JSON
(sorted keys, no spaces, ASCII, Python's shortest round-trip floats: the same text for the same values,
whatever the indentation or key order of the file). The content includes ``recording_sha256``, so the
digest binds the values to the recording they were identified from; the certificate checks in turn that
the recording in the run folder has that SHA-256.

:func:`load_verified` is what ``certificate``, ``correct`` and ``registry add`` read calibration.json with. It
refuses, in one line saying what to do (identify the run again from its recording — the recording is the
record, identification is repeatable):

* a file whose values do not match its digest (edited by hand, damaged);
* a file without a digest (written before the digest existed, or with it removed): a lab cannot tell it from
  an edited one, and re-identifying costs one command — refused, not accepted with a warning;
* implausible values even under a valid digest: a scale factor |S| ≥ 0.5 (S = −1 would be no output at all),
  |τ| ≥ 0.5 rad, |b| ≥ g/2, |d| ≥ 1 s²/m, |r| ≥ 1 m, or any identified parameter beyond
  :data:`PRIOR_SIGMAS` times its prior (the bench file's datasheet bound, 1σ).

A digest is not a signature: whoever can read this module can recompute it. It makes a hand edit evident,
not a forgery impossible; the registry keeps each calibration's digest, so a later copy that differs from
the one recorded is evident too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from benches.calibration_result import COVERS, CalibrationFormatError, CalibrationResult, read_raw
from core.integrity import ALGORITHM, canonical, values_digest
from core.integrity import with_integrity as _with_integrity

PRIOR_SIGMAS = 5.0
"""An identified value farther than this many prior σ (the bench's datasheet bound) from 0 is refused."""
HARD_BOUNDS = {"scale": 0.5, "misalignment": 0.5, "bias": 9.80665 / 2, "quadratic": 1.0, "size_effect": 1.0}
"""Physical bounds by parameter kind, SI: beyond them a value cannot describe a working accelerometer."""
REIDENTIFY = "re-identify the run from its recording (tablebench identify RUN), then issue the certificate again"


class CalibrationTamperedError(CalibrationFormatError):
    """calibration.json's values do not match its digest, it has none, or its values are implausible."""


def with_integrity(content: Mapping[str, Any]) -> dict[str, Any]:
    """calibration.json content with its ``integrity`` block bound to its ``recording_sha256``."""
    return _with_integrity(content, str(content.get("recording_sha256", "")), COVERS)


def check_integrity(raw: Mapping[str, Any], where: str) -> str:
    """The file's digest if its values match it; :class:`CalibrationTamperedError` (one line) otherwise."""
    integ = raw.get("integrity")
    if not isinstance(integ, Mapping) or not isinstance(integ.get("values_sha256"), str):
        raise CalibrationTamperedError(
            f"{where}: has no integrity digest (written before format version 3, or the digest was removed), so "
            f"its values cannot be trusted; {REIDENTIFY}"
        )
    if integ.get("algorithm", ALGORITHM) != ALGORITHM:
        algo = integ.get("algorithm")
        raise CalibrationTamperedError(f"{where}: integrity.algorithm {algo!r} is unknown; {REIDENTIFY}")
    if str(integ.get("recording_sha256", "")) != str(raw.get("recording_sha256", "")):
        raise CalibrationTamperedError(
            f"{where}: its recording_sha256 differs from the one its digest was bound to (edited); {REIDENTIFY}"
        )
    try:
        digest = values_digest(raw)
    except ValueError:  # NaN/Infinity: never written by tablebench's strict writer
        raise CalibrationTamperedError(
            f"{where}: holds a non-finite number (NaN/Infinity), which tablebench never writes; {REIDENTIFY}"
        ) from None
    if digest != integ["values_sha256"]:
        raise CalibrationTamperedError(
            f"{where}: its values do not match its integrity digest (edited after identification, or damaged); "
            f"{REIDENTIFY}"
        )
    return str(integ["values_sha256"])


def check_plausible(result: CalibrationResult, where: str) -> None:
    """Refuse values no working unit can have (see the module docstring); one line naming the parameter."""
    for p in result.parameters.values():
        bound = HARD_BOUNDS.get(p.kind)
        if bound is not None and not abs(p.value) < bound:
            raise CalibrationTamperedError(
                f"{where}: parameters.{p.name}.value = {p.value:g} is physically implausible (|{p.name}| must be "
                f"< {bound:g} SI for a working unit); {REIDENTIFY}"
            )
        if p.identified and math.isfinite(p.prior_sigma) and abs(p.value) > PRIOR_SIGMAS * p.prior_sigma:
            raise CalibrationTamperedError(
                f"{where}: parameters.{p.name}.value = {p.value:g} is {abs(p.value) / p.prior_sigma:.3g} prior σ "
                f"from 0 (the bench's datasheet bound is {p.prior_sigma:g}); implausible — {REIDENTIFY} (if the "
                "unit really is this far outside its datasheet, widen unit.prior in the bench file first)"
            )


def load_verified(path: str | Path) -> tuple[CalibrationResult, str]:
    """Read calibration.json for use (certificate, correct, registry add): format, digest, plausibility.

    Returns the typed result and its digest.
    """
    raw = read_raw(path)
    where = str(path)
    result = CalibrationResult.from_dict(raw, where)  # the format's checks first (names the key)
    digest = check_integrity(raw, where)
    check_plausible(result, where)
    return result, digest


__all__ = [
    "PRIOR_SIGMAS",
    "CalibrationTamperedError",
    "canonical",
    "check_integrity",
    "check_plausible",
    "load_verified",
    "read_raw",
    "values_digest",
    "with_integrity",
]
