"""Where results go: the :class:`ResultSink` protocol, its three documents, and the chain that feeds the sinks.

After bluesky's ``callbacks/json_writer.py`` (a callback receives named documents and writes them): a
result is a small frozen *document* — a calibration, a certificate, an analysis — and a sink is anything with
one method per document kind. Each method returns the document, completed with what the sink decided (the
run folder sink fills in the file it wrote and the certificate number it allocated), so the next sink sees
the finished document.

The **first** sink of a chain is the *record*: the run folder (:class:`benches.results.run_folder.RunFolderSink`).
If it fails, the command fails. Every further sink (a calibration registry) is a *copy*: when it cannot
take a result (a database that cannot be reached, a disk that is full), the chain says so in one line and
the command goes on — the run folder stays the record and the copy can be made later
(``tablebench registry add RUN``). See ``docs/extending.md`` (a results store) and ``docs/registry.md``.

**Where a result went.** A sink may also have ``report(kind, doc) -> str | None``: one line naming where it put
the document it has just taken (the run folder: ``calibration: RUN/calibration.json``; the registry: the unit,
the calibration's number in its history and the database). The chain hands each copy's line to ``tell`` as
soon as that copy has taken the document, so a command says where a result went stage by stage: ``run``
publishes in two steps, :meth:`ResultSinks.keep` (the record; the command then says the record's line) and
:meth:`ResultSinks.copy` (every copy, each telling its own line).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, runtime_checkable

from core.errors import UserError

if TYPE_CHECKING:
    from benches.calibration_result import CalibrationResult
    from benches.certificate.content import Certificate

KINDS = ("calibration", "certificate", "analysis")
"""The document kinds, and the name of the sink method that receives each."""


class SinkError(UserError, RuntimeError):
    """A sink cannot take a result (unreachable, refused); the message names the sink and the fix."""


@dataclass(frozen=True)
class CalibrationDocument:
    """An identification's result for a run.

    Attributes
    ----------
    run : Path
        The run folder.
    result : CalibrationResult
        The typed calibration.json content (SI).
    path : Path or None
        Where calibration.json is (or is to be) written; the run folder sink fills it in.
    """

    run: Path
    result: CalibrationResult
    path: Path | None = None


@dataclass(frozen=True)
class CertificateDocument:
    """A certificate being issued for a run.

    Attributes
    ----------
    run : Path
        The run folder.
    certificate : Certificate
        Its content; ``number`` and ``supersedes`` are set by the run folder sink (document control).
    out_pdf, out_json : Path or None
        Requested output files (None: the run folder's free ``certificate*.pdf``/``.json``).
    pdf, json : Path or None
        The files written (set by the run folder sink).
    """

    run: Path
    certificate: Certificate
    out_pdf: Path | None = None
    out_json: Path | None = None
    pdf: Path | None = None
    json: Path | None = None

    @property
    def number(self) -> str:
        """The certificate number (``TB-000042``; provisional until the run folder sink issues it)."""
        return self.certificate.number

    @property
    def verdict(self) -> str:
        """PASS, FAIL, INCONCLUSIVE, INCOMPLETE or NO LIMITS."""
        return self.certificate.verdict


@dataclass(frozen=True)
class AnalysisDocument:
    """An analysis result (noise, periodic, drift, …) as its JSON mapping (SI) and its figures.

    Attributes
    ----------
    run : Path or None
        The run folder it belongs to (None for an analysis of a loose ``.npy``/``.csv``).
    name : str
        The analysis (the command's name): the file is ``<name>.json``.
    out : Path
        The output folder.
    result : Mapping
        The JSON content (SI numbers).
    figures : Mapping of str to bytes
        PNG file name → bytes.
    nonfinite : str
        How non-finite numbers are written (:func:`core.jsonio.write_json`).
    written : tuple of Path
        The files written (set by the run folder sink).
    """

    run: Path | None
    name: str
    out: Path
    result: Mapping[str, Any]
    figures: Mapping[str, bytes] = field(default_factory=dict)
    nonfinite: str = "null"
    written: tuple[Path, ...] = ()


Document = TypeVar("Document", CalibrationDocument, CertificateDocument, AnalysisDocument)


@runtime_checkable
class ResultSink(Protocol):
    """A destination for results: one method per document kind, each returning the (completed) document.

    ``name`` is how messages name the sink. A sink that cannot take a document raises :class:`SinkError`
    (one line: what is wrong and what to do); a sink that does not keep a kind returns the document unchanged.
    """

    name: str

    def calibration(self, doc: CalibrationDocument) -> CalibrationDocument:
        """Take an identification's result."""
        ...

    def certificate(self, doc: CertificateDocument) -> CertificateDocument:
        """Take an issued certificate."""
        ...

    def analysis(self, doc: AnalysisDocument) -> AnalysisDocument:
        """Take an analysis result."""
        ...


def report_of(sink: ResultSink, kind: str, doc: Document) -> str | None:
    """The line in which ``sink`` says where it put ``doc`` of ``kind`` (its optional ``report`` method; None when
    it has none or has nothing to say, e.g. a kind it does not keep)."""
    report = getattr(sink, "report", None)
    if report is None:
        return None
    line = report(kind, doc)
    return str(line) if line else None


def _say_stderr(text: str) -> None:
    try:
        print(text, file=sys.stderr, flush=True)
    except OSError:
        pass


class ResultSinks:
    """The chain: the record sink first (its failure is the command's failure), then the copies.

    Parameters
    ----------
    record : ResultSink
        The sink that keeps the record (the run folder).
    copies : sequence of ResultSink
        Further sinks; a failure of one is reported in one line by ``say`` and does not stop the chain.
    say : callable
        ``say(text)`` for those lines (stderr by default).
    tell : callable, optional
        ``tell(line)`` for each copy's line saying where it put a document (:func:`report_of`), told as soon as
        that copy has taken it; None (default): not told.
    """

    def __init__(
        self,
        record: ResultSink,
        copies: Sequence[ResultSink] = (),
        say: Callable[[str], None] = _say_stderr,
        tell: Callable[[str], None] | None = None,
    ) -> None:
        self.record = record
        self.copies = list(copies)
        self.say = say
        self.tell = tell
        self.failures: list[str] = []
        """One line per copy that could not take a document (for tests and closing summaries)."""

    def __call__(self, kind: str, doc: Document) -> Document:
        """Publish ``doc`` of ``kind`` (one of :data:`KINDS`) to every sink; returns the completed document."""
        doc = self.keep(kind, doc)
        self.copy(kind, doc)
        return doc

    def keep(self, kind: str, doc: Document) -> Document:
        """The first half of publishing: the record sink alone takes ``doc`` (its failure is the caller's);
        returns the completed document, which :meth:`copy` then hands to the copies."""
        if kind not in KINDS:
            raise ValueError(f"unknown document kind {kind!r} (one of {KINDS})")
        return getattr(self.record, kind)(doc)

    def copy(self, kind: str, doc: Document) -> None:
        """The second half: every copy takes the completed ``doc``, in order; each one's line goes to ``tell``
        when it has taken it, and a copy that cannot take it costs one line (``say``) and stops nothing."""
        if kind not in KINDS:
            raise ValueError(f"unknown document kind {kind!r} (one of {KINDS})")
        for sink in self.copies:
            try:
                getattr(sink, kind)(doc)
                line = report_of(sink, kind, doc) if self.tell is not None else None
            except SinkError as exc:
                self._fail(f"{exc}")
                continue
            except Exception as exc:  # noqa: BLE001 — a copy never takes the record down with it
                self._fail(f"{sink.name}: could not take the {kind} ({exc.__class__.__name__}: {exc})")
                continue
            if line is not None and self.tell is not None:
                self.tell(line)

    def report(self, kind: str, doc: Document) -> str | None:
        """The record sink's line for ``doc`` (where the record is: ``calibration: RUN/calibration.json``)."""
        return report_of(self.record, kind, doc)

    def _fail(self, text: str) -> None:
        run_hint = "the run folder keeps the result"
        line = text if run_hint in text else f"{text}; {run_hint}"
        self.failures.append(line)
        self.say(line)

    # convenience, so call sites read as what they do
    def calibration(self, doc: CalibrationDocument) -> CalibrationDocument:
        """Publish a calibration."""
        return self("calibration", doc)

    def certificate(self, doc: CertificateDocument) -> CertificateDocument:
        """Publish a certificate."""
        return self("certificate", doc)

    def analysis(self, doc: AnalysisDocument) -> AnalysisDocument:
        """Publish an analysis result."""
        return self("analysis", doc)


def completed(doc: Document, **changes: Any) -> Document:
    """``doc`` with ``changes`` (documents are frozen)."""
    return replace(doc, **changes)


__all__ = [
    "KINDS",
    "AnalysisDocument",
    "CalibrationDocument",
    "CertificateDocument",
    "ResultSink",
    "ResultSinks",
    "SinkError",
    "completed",
    "report_of",
]
