"""Thermal calibration of a run folder: identify, write ``thermal_calibration.json``, issue the thermal
certificate (used by ``tablebench thermal`` and by ``tablebench run`` of a thermal procedure;
docs/methods/thermal.md)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

from benches.identify import IdentificationError
from benches.recorded_run import RecordedRun, run_of
from benches.recording import RecordingError
from benches.thermal.certificate import issue_thermal_certificate
from benches.thermal.document import FILE_NAME, load_thermal, save_thermal, thermal_content
from benches.thermal.identify import identify_thermal


def thermal_calibrate(
    run: Path | RecordedRun, *, reference: float | None = None, max_order: int = 3, rate_term: bool = False,
    issue_date: str | None = None, certificate: bool = True, say: Callable[[str], None] | None = None,
) -> tuple[Path, Path | None]:  # fmt: skip
    """Identify the run (a folder, or an open recorded run, left open), write thermal_calibration.json into its
    folder, issue the certificate; returns (calibration, PDF or None)."""
    say = say or (lambda m: print(m, file=sys.stderr))

    try:
        with run_of(run) as rr:
            run_dir = rr.folder
            cal = identify_thermal(rr, reference=reference, max_order=max_order, rate_term=rate_term,
                                   progress=lambda m: say(f"  {m}"))  # fmt: skip
            content = thermal_content(cal, rr)
    except RecordingError as exc:
        raise IdentificationError(str(exc)) from None
    path = save_thermal(content, run_dir / FILE_NAME)
    m = cal.model
    say(f"thermal model: T_ref {m.reference - 273.15:g} °C, valid {m.temperature_range[0] - 273.15:.2f} to "
        f"{m.temperature_range[1] - 273.15:.2f} °C, orders {list(m.orders)}, χ²/dof {m.chi2:.1f}/{m.dof}")  # fmt: skip
    if not certificate:
        return path, None
    pdf = run_dir / "thermal-certificate.pdf"
    issue_thermal_certificate(load_thermal(path), pdf, pdf.with_suffix(".json"), issue_date)
    return path, pdf
