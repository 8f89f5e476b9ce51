"""The calibration registry as a results sink, and ``registry add``: one run folder into the database.

The sink records a run whenever ``identify``, ``run`` or ``certificate`` publish a calibration or a
certificate (:mod:`benches.results.sink`); it reads everything from the run folder the first sink has just
written, so ``registry add RUN`` later records exactly the same rows (and adding twice changes nothing).
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.identification.model import PARAM_NAMES
from benches.results.sink import AnalysisDocument, CalibrationDocument, CertificateDocument
from core.errors import UserError

from .record import as_found_as_left, canonical, run_record
from .url import resolve_url

if TYPE_CHECKING:
    from .store import AddOutcome, Registry


def _utc_now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def _compensation(x: Any, identified: Any) -> Any:
    x = np.array(x, dtype=float)
    x[~np.asarray(identified, dtype=bool)] = 0.0  # never applied when not identified (as `correct`)
    return x


def add_run(
    reg: Registry, run: str | Path, *, operator: str | None = None, configuration: str | None = None
) -> AddOutcome:
    """Record the run folder ``run`` (calibration, certificates, as found / as left); idempotent."""
    from .queries import previous_of  # lazy: sqlalchemy, needed only when recording (--help time)

    rec = run_record(run, operator=operator, configuration=configuration, recorded_utc=_utc_now())
    cal = rec["calibration"]
    if reg.has_calibration(cal["digest"]):
        # recorded before (``run``/``identify``, then ``certificate``): the insert keeps the stored row and its
        # as found / as left, so they are not computed again (a read of every acquisition window, issue 32)
        return reg.add(rec)
    prev = previous_of(reg, rec["unit"], cal["run_utc"], cal["digest"])
    x_found = None
    if prev is not None:  # the previous calibration's accelerometer block, by name
        acc = prev.block(PARAM_NAMES)
        x_found = _compensation(prev.values[acc], prev.identified[acc])
    res = as_found_as_left(run, _compensation(rec["x"], rec["x_identified"]), x_found, cal["recording_sha256"])
    if res is not None:
        found, left = res
        cal["as_left"] = canonical(left)
        if found is not None and prev is not None:
            cal["as_found"] = canonical(dict(found, certificate=prev.certificate_number, run_utc=prev.run_utc))
            cal["as_found_of"] = prev.id
    return reg.add(rec)


class RegistrySink:
    """Records every calibration and certificate published into the registry at ``url``."""

    name = "registry"

    def __init__(self, url: str, operator: str | None = None) -> None:
        self.url = url
        self.operator = operator
        self._reg: Registry | None = None
        self._last: tuple[Path, AddOutcome] | None = None
        self._down = False  # could not record once: not tried again by this command (one line, not one per result)

    def _registry(self) -> Registry:
        from .store import Registry  # lazy: sqlalchemy, needed only when recording (--help time)

        if self._reg is None:
            self._reg = Registry(self.url)
        return self._reg

    def _add(self, run: Path) -> None:
        from .store import RegistryError, display_url  # lazy: sqlalchemy, needed only when recording (--help time)

        self._last = None
        if self._down:  # its line said so, and ``registry add RUN`` records everything of the run later
            return
        try:
            self._last = (run, add_run(self._registry(), run, operator=self.operator))
        except UserError as exc:
            self._down = True
            text = str(exc).removeprefix(f"registry {display_url(self.url)}: ")
            raise RegistryError(
                f"registry {display_url(self.url)}: not recorded ({text}); the run folder keeps the result — "
                f"record it later with: tablebench registry add {run}"
            ) from None

    def calibration(self, doc: CalibrationDocument) -> CalibrationDocument:
        """Record the run once its calibration.json is written (in the run folder)."""
        self._last = None
        if doc.path is not None and Path(doc.path).resolve() == (Path(doc.run) / "calibration.json").resolve():
            self._add(Path(doc.run))
        return doc

    def certificate(self, doc: CertificateDocument) -> CertificateDocument:
        """Record the issued certificate (and the calibration, if not yet there)."""
        self._add(Path(doc.run))
        return doc

    def analysis(self, doc: AnalysisDocument) -> AnalysisDocument:
        """Analyses are not kept by the registry (they stay in the run folder)."""
        return doc

    def report(self, kind: str, doc: CalibrationDocument | CertificateDocument | AnalysisDocument) -> str | None:
        """Where the registry put the run it has just recorded (:func:`benches.results.sink.report_of`): the unit,
        the calibration's place in its history and the database, e.g. ``registry: SIM-U-0001 (QA-3000)
        calibration 3 of 3 (id 17) in /lab/runs/registry.sqlite`` (a certificate: ``registry: certificate
        TB-000042 with …``); None when it recorded nothing new for ``doc``."""
        if self._last is None or kind == "analysis" or self._last[0] != Path(doc.run):
            return None
        out = self._last[1]
        what = f"calibration {out.place} of {out.of} (id {out.calibration_id})"
        if kind == "certificate":
            if not out.certificates_added:
                return None  # recorded before (nothing new to say)
            what = f"certificate {', '.join(out.certificates_added)} with {out.serial} {what}"
        else:
            what = f"{out.serial} ({out.model}) {what}" if out.model else f"{out.serial} {what}"
            if not out.added:
                what += ", already recorded"
        return f"registry: {what} in {_where(self.url)}"


def _where(url: str) -> str:
    """The database as a technician finds it: an SQLite file's path, else the URL without its password."""
    if url.startswith("sqlite:///") and url != "sqlite:///:memory:":
        return url.removeprefix("sqlite:///")
    from .store import display_url  # lazy: sqlalchemy, imported by now when recording (--help time)

    return display_url(url)


def sink_factory(runs_folder: Path, options: Mapping[str, Any]) -> RegistrySink | None:
    """The registry sink of a command (``options["registry"]``: URL, path or "off"; see :func:`resolve_url`)."""
    url = resolve_url(options.get("registry"), runs_folder)
    return None if url is None else RegistrySink(url, operator=options.get("operator"))


__all__ = ["RegistrySink", "add_run", "sink_factory"]
