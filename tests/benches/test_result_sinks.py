"""The ResultSink protocol: the run folder is the first sink and the record; a copy that fails never loses a result."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benches.calibration_result import CalibrationResult
from benches.certificate import issue_certificate
from benches.results import (
    CalibrationDocument,
    CertificateDocument,
    ResultSink,
    ResultSinks,
    SinkError,
    register_copy_sink,
    sinks_for_run,
    unregister_copy_sink,
)
from benches.results.run_folder import RunFolderSink
from tests.certificate_fixtures import make_run_folder


class Collect:
    """A copy sink keeping what it is given (test code only)."""

    name = "collector"

    def __init__(self) -> None:
        self.seen: list[tuple[str, object]] = []

    def calibration(self, doc):
        self.seen.append(("calibration", doc))
        return doc

    def certificate(self, doc):
        self.seen.append(("certificate", doc))
        return doc

    def analysis(self, doc):
        self.seen.append(("analysis", doc))
        return doc


class Unreachable(Collect):
    name = "registry"

    def certificate(self, doc):
        raise SinkError("registry sqlite:///x: cannot be reached (disk I/O error)")

    def calibration(self, doc):
        raise OSError("no space left")


def test_both_sinks_satisfy_the_protocol():
    assert isinstance(RunFolderSink(), ResultSink)
    assert isinstance(Collect(), ResultSink)


def test_the_certificate_goes_to_the_run_folder_then_to_the_copies_with_its_number(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    copy = Collect()
    pdf, js, verdict = issue_certificate(run, issue_date="2026-11-27", sinks=ResultSinks(RunFolderSink(), [copy]))
    assert pdf == run / "certificate.pdf" and js == run / "certificate.json" and pdf.exists() and js.exists()
    [(kind, doc)] = copy.seen
    assert kind == "certificate" and isinstance(doc, CertificateDocument)
    # the copy sees the finished document: the number allocated by the register, the files written
    number = json.loads(js.read_text())["certificate_number"]
    assert doc.number == number and number.startswith("TB-") and doc.pdf == pdf and doc.verdict == verdict
    assert (run.parent / "certificate-register.jsonl").exists()


def test_an_unreachable_copy_says_so_in_one_line_and_the_run_folder_keeps_the_result(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    said: list[str] = []
    sinks = ResultSinks(RunFolderSink(), [Unreachable()], say=said.append)
    pdf, js, _ = issue_certificate(run, issue_date="2026-11-27", sinks=sinks)
    assert pdf.exists() and js.exists()
    assert len(said) == 1 and "\n" not in said[0]
    assert "cannot be reached" in said[0] and "run folder keeps the result" in said[0]

    result = CalibrationResult.load(run / "calibration.json")
    out = sinks.calibration(CalibrationDocument(run=run, result=result, path=tmp_path / "again.json"))
    assert out.path == tmp_path / "again.json" and out.path.exists()
    assert len(said) == 2 and "OSError" in said[1] and "no space left" in said[1]


def test_a_failing_record_sink_fails_the_command(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    copy = Collect()
    (run / "certificate.pdf").write_bytes(b"")  # the run folder sink then writes certificate-<n>.pdf
    out = tmp_path / "taken.pdf"
    out.write_bytes(b"x")
    from benches.certificate import CertificateError

    with pytest.raises(CertificateError, match="never overwritten"):
        issue_certificate(run, out_pdf=out, sinks=ResultSinks(RunFolderSink(), [copy]))
    assert copy.seen == []  # nothing reached the copies


def test_registered_copy_sinks_join_every_chain(tmp_path):
    copy = Collect()
    register_copy_sink("collector", lambda runs, options: copy)
    try:
        sinks = sinks_for_run(tmp_path / "runs" / "r1", {"registry": "off"})
        assert copy in sinks.copies and isinstance(sinks.record, RunFolderSink)
    finally:
        unregister_copy_sink("collector")
    assert copy not in sinks_for_run(tmp_path / "runs" / "r1", {"registry": "off"}).copies


def test_the_run_folder_sink_writes_analyses(tmp_path):
    from benches.results import AnalysisDocument

    doc = RunFolderSink().analysis(
        AnalysisDocument(run=None, name="noise", out=tmp_path / "noise", result={"a": 1.0}, figures={"n.png": b"P"})
    )
    assert json.loads((tmp_path / "noise" / "noise.json").read_text()) == {"a": 1.0}
    assert (tmp_path / "noise" / "n.png").read_bytes() == b"P"
    assert [Path(p).name for p in doc.written] == ["noise.json", "n.png"]


class Reporting(Collect):
    """A copy that says where it put each document (its optional ``report``)."""

    name = "archive"

    def report(self, kind, doc):
        return f"archive: {kind} of {Path(doc.run).name} kept"


def test_each_copy_tells_where_it_put_a_document_as_soon_as_it_has_taken_it(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    result = CalibrationResult.load(run / "calibration.json")
    events: list[str] = []

    class Slow(Reporting):
        def calibration(self, doc):
            events.append("slow took it")
            return super().calibration(doc)

    said: list[str] = []
    sinks = ResultSinks(RunFolderSink(), [Slow(), Unreachable(), Collect(), Reporting()], say=said.append,
                        tell=events.append)  # fmt: skip
    kept = sinks.keep("calibration", CalibrationDocument(run=run, result=result))
    assert kept.path == run / "calibration.json" and events == []  # the record alone; no copy has it yet
    assert sinks.report("calibration", kept) == f"calibration: {run / 'calibration.json'}"
    sinks.copy("calibration", kept)
    # each copy's line right after that copy took it; a failing copy costs one line (say) and no tell; a copy
    # without ``report`` says nothing
    assert events == ["slow took it", "archive: calibration of r1 kept", "archive: calibration of r1 kept"]
    assert len(said) == 1 and "no space left" in said[0]
    # publishing in one call does the same (without tell: nothing is told)
    events.clear()
    ResultSinks(RunFolderSink(), [Reporting()]).calibration(CalibrationDocument(run=run, result=result))
    assert events == []


def test_the_run_folder_reports_where_the_record_is(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    result = CalibrationResult.load(run / "calibration.json")
    sink = RunFolderSink()
    assert sink.report("calibration", CalibrationDocument(run=run, result=result)) is None  # not yet written
    doc = sink.calibration(CalibrationDocument(run=run, result=result, path=tmp_path / "c.json"))
    assert sink.report("calibration", doc) == f"calibration: {tmp_path / 'c.json'}"
