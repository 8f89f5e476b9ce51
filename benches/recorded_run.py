"""One recorded run, typed and opened once: the recording, its header, the parsed bench, the compiled procedure.

Identification (:mod:`benches.identify`), the certificate (:mod:`benches.certificate`) and the analyses
(:mod:`benches.cli.analysis_input`) take a :class:`RecordedRun` instead of each opening the recording and parsing
its copies of the bench and procedure files again. ``tablebench run`` builds it once at the end of the run and
hands it the bench and procedure it already parsed and compiled (:func:`open_run` reuses them when they are
exactly the recorded texts), so one run parses the bench once and compiles the procedure once.

The recording is verified when it is opened (every checksum, :func:`benches.recording.open_recording`; the run
that has just written it uses the verification done while writing, ``open_run(..., written=True)``); the
bench copy is parsed and the procedure copy compiled on first use, so a tool that needs neither never pays
for them (or fails on them).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from core.errors import UserError
from core.provenance import file_sha256
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure_text
from procedures.steps import CompiledProcedure

from .bench_config import BenchConfig, chamber_limits, load_bench_text
from .recording import Recording, RunHeader, StepRecord, open_recording


@dataclass(eq=False)
class RecordedRun:
    """A recording opened read-only and verified, with what every consumer of a run needs (a context manager).

    Attributes
    ----------
    recording : benches.recording.Recording
        The open recording (samples, table readings, events, truth).
    header : RunHeader
        Its root attributes, typed.
    steps : tuple of StepRecord
        The step table.
    """

    recording: Recording
    header: RunHeader
    steps: tuple[StepRecord, ...]
    _given_config: BenchConfig | None = field(default=None, repr=False)
    _given_compiled: CompiledProcedure | None = field(default=None, repr=False)
    _given_overrides: dict[str, float] | None = field(default=None, repr=False)

    # ---- identity ----------------------------------------------------------------------------------------
    @property
    def path(self) -> Path:
        """The recording file."""
        return self.recording.path

    @property
    def folder(self) -> Path:
        """The run folder (the recording's parent)."""
        return self.recording.path.parent

    @property
    def integrity_verified(self) -> bool:
        """True when every checksum was verified on opening (False: a recording without checksums)."""
        return bool(self.recording.integrity_verified)

    @property
    def integrity_note(self) -> str:
        """One line saying whether the recording's integrity was verified."""
        return str(self.recording.integrity_note)

    @property
    def n_samples(self) -> int:
        """Rows of /imu."""
        return int(self.recording.n_samples)

    @cached_property
    def sha256(self) -> str:
        """SHA-256 of the recording file (computed once)."""
        return file_sha256(self.path)

    def attrs(self) -> dict[str, Any]:
        """The header as plain values plus ``integrity_verified`` / ``integrity_note``."""
        d = self.header.as_dict()
        d["integrity_verified"] = self.integrity_verified
        d["integrity_note"] = self.integrity_note
        return d

    # ---- the recorded inputs -----------------------------------------------------------------------------
    @cached_property
    def bench_text(self) -> str:
        """The bench file as recorded ('' when absent; RecordingDamaged if it fails its SHA-256)."""
        return self.recording.bench_text

    @cached_property
    def procedure_text(self) -> str:
        """The procedure file as recorded ('' when absent; RecordingDamaged if it fails its SHA-256)."""
        return self.recording.procedure_text

    @cached_property
    def config(self) -> BenchConfig:
        """The recorded bench file, parsed (ConfigError naming ``<recording>:/bench_yaml`` if it does not)."""
        if self._given_config is not None and self._given_config.text == self.bench_text:
            return self._given_config
        return load_bench_text(self.bench_text, f"{self.path}:/bench_yaml")

    @cached_property
    def compiled(self) -> CompiledProcedure | None:
        """The recorded procedure with its recorded overrides, compiled for the recorded bench; None when the
        recording carries no procedure or bench text that compiles (another tool's recording)."""
        given = self._given_compiled
        overrides = dict(self.header.procedure_overrides)
        try:
            if (
                given is not None
                and given.text == self.procedure_text
                and self._given_overrides == overrides
                and self._given_config is not None
                and self._given_config.text == self.bench_text
            ):
                return given
            if not self.procedure_text.strip() or not self.bench_text.strip():
                return None
            cfg = self.config
            proc = load_procedure_text(self.procedure_text, f"{self.path}:/procedure_yaml", overrides or None)
            return compile_procedure(
                proc, limits=cfg.turntable.limits, mounting=cfg.unit.mounting, chamber=chamber_limits(cfg)
            )
        except (UserError, ValueError):
            return None

    # ---- steps ---------------------------------------------------------------------------------------------
    def incomplete_steps(self) -> list[StepRecord]:
        """Steps whose status is not "complete"."""
        return [s for s in self.steps if s.status != "complete"]

    # ---- context -------------------------------------------------------------------------------------------
    def __enter__(self) -> RecordedRun:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Close the recording (safe to call twice)."""
        self.recording.close()


def open_run(
    path: str | Path,
    *,
    config: BenchConfig | None = None,
    compiled: CompiledProcedure | None = None,
    overrides: dict[str, float] | None = None,
    written: bool = False,
) -> RecordedRun:
    """Open and verify a recording (a run folder or its ``recording.h5``) as a :class:`RecordedRun`.

    Parameters
    ----------
    path : path
        Run folder or recording file.
    config, compiled, overrides : optional
        The bench, the compiled procedure and the parameter overrides it was compiled with, as the caller
        already has them (``tablebench run``); used instead of parsing the recorded copies again when they are
        exactly the recorded texts and overrides.
    written : bool
        The caller is the process that has just written the recording (``tablebench run``): the verification the
        recorder did while writing is used instead of a second full pass, if it describes this file unchanged
        (``open_recording(..., written=True)``); otherwise the full verification runs.

    Raises
    ------
    benches.recording.RecordingError
        Missing, unreadable or damaged recording.
    """
    rec = open_recording(path, written=written)
    try:
        return RecordedRun(
            recording=rec,
            header=rec.header,
            steps=tuple(rec.steps),
            _given_config=config,
            _given_compiled=compiled,
            _given_overrides=None if overrides is None else dict(overrides),
        )
    except BaseException:
        rec.close()
        raise


@contextlib.contextmanager
def run_of(source: str | Path | RecordedRun) -> Iterator[RecordedRun]:
    """The :class:`RecordedRun` of ``source``: opened (and closed at the end) from a path, or the given one
    (left open for its owner)."""
    if isinstance(source, RecordedRun):
        yield source
        return
    rr = open_run(source)
    try:
        yield rr
    finally:
        rr.close()


__all__ = ["RecordedRun", "open_run", "run_of"]
