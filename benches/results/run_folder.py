"""The first results sink, and the record: the run folder with its certificate register.

* a calibration → ``RUN/calibration.json`` (or the path the document names), through the strict JSON writer
  (:meth:`benches.calibration_result.CalibrationResult.save`);
* a certificate → its number from the register of the runs folder (:mod:`benches.certificate_register`:
  monotonic, never reused, a re-issue names what it supersedes), then the PDF and the JSON, each written once
  and never overwritten (``certificate.pdf``, ``certificate-<number>.pdf`` after the first);
* an analysis → ``OUT/<name>.json`` and its PNG figures.

Behaviour is exactly that of the commands before the sinks existed (``docs/extending.md``, a results store).
"""

from __future__ import annotations

from pathlib import Path

from benches.certificate_register import CertificateRegister, RegisterError, free_paths, write_new
from core.jsonio import write_json, write_text_atomic

from .sink import AnalysisDocument, CalibrationDocument, CertificateDocument, completed


class RunFolderSink:
    """Writes results into the run folder (see the module docstring); the first sink of every chain."""

    name = "run folder"

    def calibration(self, doc: CalibrationDocument) -> CalibrationDocument:
        """Write calibration.json (atomic; a non-finite number raises ``ValueError`` naming its key)."""
        path = doc.path if doc.path is not None else Path(doc.run) / "calibration.json"
        return completed(doc, path=doc.result.save(path))

    def certificate(self, doc: CertificateDocument) -> CertificateDocument:
        """Allocate the number (register), then write the PDF and the JSON (never overwriting a file)."""
        from benches.certificate.content import CertificateError  # lazy: scipy, filterpy via the package (--help time)
        from benches.certificate.pdf import render_pdf  # lazy: fpdf, matplotlib (--help time)

        run = Path(doc.run)
        out_pdf, out_json = doc.out_pdf, doc.out_json

        def paths(number: str) -> tuple[Path, Path]:
            if out_pdf is None:
                return free_paths(run, number, "noise-report" if doc.certificate.is_noise_report else "certificate")
            pdf = Path(out_pdf)
            return pdf, Path(out_json) if out_json is not None else pdf.with_suffix(".json")

        if out_pdf is not None:
            for p in paths(""):
                if p.exists():
                    raise CertificateError(
                        f"{p}: already exists; a certificate is never overwritten (choose another name)"
                    )
        cert = doc.certificate
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
        return completed(doc, pdf=pdf_path, json=json_path)

    def analysis(self, doc: AnalysisDocument) -> AnalysisDocument:
        """Write ``OUT/<name>.json`` and the figures."""
        out = Path(doc.out)
        out.mkdir(parents=True, exist_ok=True)
        written = [write_json(out / f"{doc.name}.json", dict(doc.result), nonfinite=doc.nonfinite)]  # type: ignore[arg-type]
        for fname, png in doc.figures.items():
            written.append(write_text_atomic(out / fname, png))
        return completed(doc, written=tuple(written))

    def report(self, kind: str, doc: CalibrationDocument | CertificateDocument | AnalysisDocument) -> str | None:
        """Where the record is (:func:`benches.results.sink.report_of`): ``calibration: PATH``, ``certificate: PDF``,
        ``NAME: OUT/NAME.json``; None before the document is written."""
        if isinstance(doc, CalibrationDocument):
            return None if doc.path is None else f"calibration: {doc.path}"
        if isinstance(doc, CertificateDocument):
            return None if doc.pdf is None else f"certificate: {doc.pdf}"
        return f"{doc.name}: {doc.written[0]}" if doc.written else None


__all__ = ["RunFolderSink"]
