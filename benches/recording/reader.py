"""Reading a run (:func:`open_recording` → :class:`Recording`): typed, every checksum verified on opening.

Part of the package :mod:`benches.recording`, the one place that knows the HDF5 layout.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from core.provenance import text_sha256

from .encoding import EXC_DTYPE, _dequantise, _StepHasher, ns_delta_decode
from .layout import (
    _H5_ERRORS,
    _IMU_DTYPES,
    FORMAT,
    FORMAT_VERSION,
    IMU_CHUNK,
    IMU_FIELDS,
    NS_DELTA,
    QUANTISED_FIELDS,
    READ_CHUNK,
    READABLE_VERSIONS,
    TABLE_FIELDS,
    TIMING_BLOCK,
    TIMING_CLOCKS,
    TIMING_TABLE,
    AuxReadings,
    Event,
    RecordingDamaged,
    RecordingError,
    RunHeader,
    Samples,
    StepRecord,
    TableReadings,
    TimeSources,
    Truth,
    _encoding_of,
    _plain,
    _text,
    recording_file,
)
from .written import (
    WrittenRecording,
    file_identity,
    kept_plan,
    take_written,
)

# ---- reading -------------------------------------------------------------------------------------------------------


class Recording:
    """A recording opened read-only (use :func:`open_recording`; a context manager).

    Attributes
    ----------
    path : Path
    header : RunHeader
    steps : list of StepRecord
    n_samples, n_table : int
        Rows of /imu and /table.
    integrity_verified : bool
        True: every checksum (Fletcher-32 of every chunk, SHA-256 of every complete step) was verified.
        False: the recording carries no checksums (format version 1, e.g. written by another tool).
    integrity_note : str
        One line saying whether the recording's integrity was verified.
    """

    def __init__(self, path: Path, f: h5py.File) -> None:
        self.path = path
        self._f = f
        self._step_context: str = ""
        with self._guard("/ (root attributes)"):
            self.header = self._read_header()
        version = self.header.format_version
        if version not in READABLE_VERSIONS:
            raise RecordingError(
                f"{path}: recording format version {version} is not readable by this version of tablebench "
                f"(reads {', '.join(map(str, READABLE_VERSIONS))}); use the version that wrote it"
            )
        self._step_rows: int | None = None
        self._kept: list[tuple[int, int, dict[str, NDArray[Any]]]] = []  # rows decoded by verify(), kept
        self.unfinished_tail = ""
        """Non-empty when rows after the last step row were left unfinished by a failed write (disk full) of a
        run that did not complete: they are ignored (``--resume`` and ``runs --salvage`` drop them)."""
        try:
            with self._guard("/imu, /table (layout)"):
                self._check_layout()
        except RecordingDamaged:
            if not self._unfinished_tail():
                raise
        with self._guard("/steps"):
            self.steps = self._read_steps()
        self._check_steps()
        self.integrity_verified = version >= 2
        self.integrity_note = (
            "integrity verified (Fletcher-32 per chunk, SHA-256 per step)"
            if self.integrity_verified
            else f"integrity cannot be verified: {path.name} carries no checksums (format version {version})"
        )

    # ---- context -----------------------------------------------------------------------------------------
    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Close the file (safe to call twice); the rows kept by :meth:`verify` are released."""
        self._kept = []
        with contextlib.suppress(Exception):
            self._f.close()

    @contextlib.contextmanager
    def _guard(self, where: str, step: StepRecord | None = None, rows: tuple[int, int] | None = None) -> Iterator[None]:
        try:
            yield
        except RecordingError:
            raise
        except _H5_ERRORS as exc:
            at = f", step {step.index} {step.name!r}" if step is not None else ""
            if rows is not None:
                at = f" rows {rows[0]}–{rows[1]}{self._steps_text(*rows)}"
            msg = str(exc).split("\n")[0]
            raise RecordingDamaged(
                f"{self.path}: dataset {where}{at} is damaged or unreadable ({exc.__class__.__name__}: {msg}); "
                f"{self._fix()}"
            ) from None

    def _steps_text(self, a: int, b: int) -> str:
        hit = [s for s in self.steps if s.start_sample < b and s.end_sample > a]
        if not hit:
            return " (after the last recorded step)"
        if len(hit) == 1:
            return f" (step {hit[0].index} {hit[0].name!r})"
        return f" (steps {hit[0].index} {hit[0].name!r} to {hit[-1].index} {hit[-1].name!r})"

    def _fix(self) -> str:
        return (
            f"recover the intact steps with 'tablebench runs --salvage {self.path.parent}' "
            "or re-record from a backup copy"
        )

    # ---- header and layout ------------------------------------------------------------------------------
    def _read_header(self) -> RunHeader:
        a = {k: _plain(self._f.attrs[k]) for k in self._f.attrs}
        if a.get("format") != FORMAT:
            raise RecordingError(f"{self.path}: not a tablebench recording (root attribute format != {FORMAT!r})")
        try:
            version = int(a.get("format_version", 1))
        except (TypeError, ValueError):
            raise RecordingError(f"{self.path}: root attribute format_version is not an integer") from None
        try:
            ov = json.loads(str(a.get("procedure_overrides") or "{}"))
            overrides = {str(k): float(v) for k, v in dict(ov).items()}
        except (ValueError, TypeError, AttributeError):
            raise RecordingDamaged(f"{self.path}: root attribute procedure_overrides is not a JSON object") from None
        seed_raw = a.get("seed", -1)
        try:
            seed_i = int(seed_raw)
        except (TypeError, ValueError):
            raise RecordingDamaged(f"{self.path}: root attribute seed is not an integer ({seed_raw!r})") from None
        try:
            rate = float(a.get("sample_rate_hz", 0.0))
        except (TypeError, ValueError):
            rate = math.nan
        if not (math.isfinite(rate) and rate > 0):
            raise RecordingDamaged(f"{self.path}: root attribute sample_rate_hz is not a positive number ({rate})")
        g = a.get("site_g")
        known = set(RunHeader.__dataclass_fields__) | {"integrity"}
        return RunHeader(
            format=FORMAT,
            format_version=version,
            software_version=str(a.get("software_version", "")),
            created_utc=str(a.get("created_utc", "")),
            updated_utc=str(a.get("updated_utc", "")),
            status=str(a.get("status", "?")),
            seed=None if seed_i < 0 else seed_i,
            bench_name=str(a.get("bench_name", "")),
            bench_file=str(a.get("bench_file", "")),
            bench_sha256=str(a.get("bench_sha256", "")),
            procedure_name=str(a.get("procedure_name", "")),
            procedure_file=str(a.get("procedure_file", "")),
            procedure_sha256=str(a.get("procedure_sha256", "")),
            procedure_overrides=overrides,
            sample_rate_hz=rate,
            simulated=bool(a.get("simulated", False)),
            transport=str(a.get("transport", "")),
            site_g=float(g) if isinstance(g, int | float) and g else None,
            site_g_source=str(a.get("site_g_source", "")),
            extra={k: v for k, v in a.items() if k not in known},
        )

    def _unfinished_tail(self) -> bool:
        """A run stopped by a failed write (ENOSPC) leaves its datasets ragged or a chunk unwritten AFTER its last
        step row (step rows are written only once their rows are on disk). If the recording did not complete and
        the layout is sound up to the last step row's end, read it as ending there (True); else False."""
        if self.header.status == "complete" or self.header.format_version < 2:
            return False
        try:
            rows = self._f["steps"][()]
            ends = [(k + 1, int(r["end_sample"]), int(r["table_end"])) for k, r in enumerate(rows)]
            ends = [e for e, r in zip(ends, rows, strict=True) if _text(r["status"]) == "complete"]
        except (RecordingError, *_H5_ERRORS):
            return False
        for n_rows, end, t_end in [*ends[::-1], (0, 0, 0)]:  # the last complete step whose rows are all there
            try:
                with self._guard("/imu, /table (layout)"):
                    self._check_layout(end, t_end)
            except (RecordingError, *_H5_ERRORS):
                continue
            self._step_rows = n_rows
            self.unfinished_tail = (
                f"the rows after sample {end} (the end of the last complete step) were left unfinished by a failed "
                "write (disk full?) and are ignored"
            )
            return True
        return False

    def _check_layout(self, limit: int | None = None, table_limit: int | None = None) -> None:
        """The datasets' extents, chunk indexes and exception rows; ``limit``/``table_limit``: check only the
        rows before these (every dataset must hold at least as many), the rest being an unfinished tail."""
        f = self._f
        if "imu" not in f or "accel" not in f["imu"]:
            raise RecordingError(f"{self.path}: the recording holds no unit samples (/imu/accel missing)")
        self.n_samples = int(f["imu/accel"].shape[0]) if limit is None else limit
        self.sample_fields: tuple[str, ...] = tuple(n for n in IMU_FIELDS if n in f["imu"])
        self._quanta: dict[str, float] = {}
        self._exc: dict[str, NDArray[Any]] = {}
        for name, d in f["imu"].items():
            if not isinstance(d, h5py.Dataset):
                continue
            if d.shape[0] != self.n_samples if limit is None else d.shape[0] < limit:
                raise RecordingDamaged(
                    f"{self.path}: dataset /imu/{name} has {d.shape[0]} rows but /imu/accel {self.n_samples}; "
                    f"the file is damaged or truncated; {self._fix()}"
                )
            if name in QUANTISED_FIELDS and np.issubdtype(d.dtype, np.integer):
                lsb = float(d.attrs["lsb"])
                has_exc = "exceptions" in f["imu"] and name in f["imu/exceptions"]
                if not (math.isfinite(lsb) and lsb > 0) or not has_exc:
                    raise RecordingDamaged(f"{self.path}: dataset /imu/{name}: counts without a valid lsb/exceptions")
                self._quanta[name] = lsb
                with self._guard(f"/imu/exceptions/{name}"):
                    exc = np.asarray(f["imu/exceptions"][name][()], dtype=EXC_DTYPE)
                if limit is not None and exc.size:
                    exc = exc[: int(np.searchsorted(exc["row"], limit))]
                width = 1 if d.ndim == 1 else d.shape[1]
                if exc.size and (
                    np.any(np.diff(exc["row"]) < 0)
                    or exc["row"][0] < 0
                    or exc["row"][-1] >= self.n_samples
                    or np.any((exc["col"] < 0) | (exc["col"] >= width))
                ):
                    raise RecordingDamaged(f"{self.path}: dataset /imu/exceptions/{name}: rows out of order or range")
                self._exc[name] = exc
        if "table" in f and "time" in f["table"]:
            self.n_table = int(f["table/time"].shape[0]) if table_limit is None else table_limit
            for name, d in f["table"].items():
                if d.shape[0] != self.n_table if table_limit is None else d.shape[0] < table_limit:
                    raise RecordingDamaged(
                        f"{self.path}: dataset /table/{name} has {d.shape[0]} rows but /table/time {self.n_table}; "
                        f"{self._fix()}"
                    )
        else:
            self.n_table = 0
        if self.header.format_version >= 2:
            missing = [n for n in ("bench_yaml", "procedure_yaml", "steps", "events", "table") if n not in f]
            missing += [f"imu/{n}" for n in IMU_FIELDS if n not in f["imu"]]
            if missing:
                raise RecordingDamaged(
                    f"{self.path}: dataset(s) /{', /'.join(missing)} missing from a format-2 recording; {self._fix()}"
                )
            for name, obj in _walk(f):
                if not obj.fletcher32:
                    raise RecordingDamaged(
                        f"{self.path}: dataset /{name} has no Fletcher-32 checksum in a format-2 recording; "
                        f"{self._fix()}"
                    )
                self._check_chunks(name, obj, self._tail_rows(name, limit, table_limit))

    def _tail_rows(self, name: str, limit: int | None, table_limit: int | None) -> int | None:
        """Rows of dataset ``name`` that must be intact when the recording ends at ``limit`` (None: all)."""
        if limit is None:
            return None
        if name.startswith("imu/exceptions/"):
            exc = self._exc.get(name.rsplit("/", 1)[-1])
            return None if exc is None else int(exc.size)
        if name.startswith("imu/"):
            return limit
        return table_limit if name.startswith("table/") else None

    def _check_chunks(self, name: str, d: h5py.Dataset, limit: int | None = None) -> None:
        """Every chunk of the dataset's extent is indexed exactly once, at its place, with every filter applied.

        The chunk index (a B-tree) carries no checksum of its own: a damaged key would silently turn a chunk
        into fill values, a damaged filter mask would skip the Fletcher-32 check.
        """
        rows = int(d.shape[0]) if d.shape else 1
        if limit is not None and d.shape:
            rows = min(rows, limit)  # an unfinished tail: its chunks may be missing
        step = int(d.chunks[0]) if d.chunks else rows
        want = list(range(0, rows, step)) if d.shape else [0]
        got: list[int] | None = []
        for info in _chunk_infos(d):
            if info.filter_mask != 0 or any(info.chunk_offset[1:]) or info.size <= 0:
                got = None
                break
            off = int(info.chunk_offset[0]) if d.shape else 0
            if limit is None or off < rows:
                got.append(off)
        if got is None or sorted(got) != want:
            raise RecordingDamaged(
                f"{self.path}: dataset /{name}: its chunk index is damaged (chunks missing, misplaced or unfiltered); "
                f"{self._fix()}"
            )

    def _read_steps(self) -> list[StepRecord]:
        if "steps" not in self._f:
            return []
        rows = self._f["steps"][()]
        if self._step_rows is not None:  # an unfinished tail: the step rows after the last intact step
            rows = rows[: self._step_rows]
        names = rows.dtype.names or ()
        need = {"index", "name", "kind", "start_sample", "acq_start", "acq_end", "end_sample", "status"}
        if not need <= set(names):
            raise RecordingError(f"{self.path}: /steps lacks column(s) {', '.join(sorted(need - set(names)))}")
        v2 = "sha256" in names
        out = []
        for r in rows:
            out.append(
                StepRecord(
                    index=int(r["index"]),
                    name=_text(r["name"]),
                    kind=_text(r["kind"]),
                    group=_text(r["group"]) if "group" in names else "",
                    start_sample=int(r["start_sample"]),
                    acq_start=int(r["acq_start"]),
                    acq_end=int(r["acq_end"]),
                    end_sample=int(r["end_sample"]),
                    status=_text(r["status"]),
                    axis=int(r["axis"]) if "axis" in names else -1,
                    rate=float(r["rate"]) if "rate" in names else 0.0,
                    angles=tuple(float(x) for x in r["angles"]) if "angles" in names else (math.nan,) * 3,  # type: ignore[arg-type]
                    table_start=int(r["table_start"]) if v2 else -1,
                    table_end=int(r["table_end"]) if v2 else -1,
                    sha256=_text(r["sha256"]) if v2 else "",
                )
            )
        return out

    def _check_steps(self) -> None:
        prev_end, prev_t = 0, 0
        for s in self.steps:
            where = f"{self.path}: /steps row {s.index} {s.name!r}"
            if s.status not in ("complete", "interrupted", "failed"):
                raise RecordingDamaged(f"{where}: unknown status {s.status!r}; {self._fix()}")
            if not (0 <= s.start_sample <= s.acq_start <= s.acq_end <= s.end_sample):
                raise RecordingDamaged(f"{where}: inconsistent sample indices; {self._fix()}")
            if s.status == "complete" and s.end_sample > self.n_samples:
                raise RecordingDamaged(
                    f"{where}: ends at sample {s.end_sample} but /imu holds {self.n_samples}; the file is truncated; "
                    f"{self._fix()}"
                )
            if self.header.format_version >= 2:
                if s.start_sample != prev_end or s.table_start != prev_t or s.table_end < s.table_start:
                    raise RecordingDamaged(f"{where}: rows not contiguous with the previous step; {self._fix()}")
                if s.status == "complete" and s.table_end > self.n_table:
                    raise RecordingDamaged(f"{where}: table rows beyond /table; {self._fix()}")
                if s.status == "complete" and len(s.sha256) != 64:
                    raise RecordingDamaged(f"{where}: no SHA-256; {self._fix()}")
                prev_end, prev_t = s.end_sample, s.table_end

    # ---- verification ------------------------------------------------------------------------------------
    def verify(self, keep: bool = True) -> None:
        """Read every dataset (Fletcher-32 of every chunk) and check every complete step's SHA-256.

        The samples are read once, in large chunk-aligned blocks, each step's rows hashed as they pass. With
        ``keep``, the decoded rows of every complete step's acquisition window (the fields in
        :data:`~benches.recording.written.KEPT_FIELDS`: what identification reads) are kept as they pass, and
        :meth:`samples` serves them from memory once every checksum has passed: the identification reads the
        verified pass's rows instead of decoding the file a second time; the rows between the windows are kept too
        for the fields in :data:`~benches.recording.written.KEPT_BETWEEN` (the time base's motion windows), and the
        whole record for :data:`~benches.recording.written.KEPT_WHOLE` (the selection:
        :func:`~benches.recording.written.kept_plan`). :meth:`close` releases them.

        Raises
        ------
        RecordingDamaged
            Naming the file, the dataset and the step. Format-1 recordings: only the readability is checked.
        """
        v2 = self.header.format_version >= 2
        done = [s for s in self.steps if s.status == "complete"] if v2 else []
        hashers = [_StepHasher() for _ in done]
        plan = (
            kept_plan([(s.acq_start, s.acq_end) for s in self.complete_steps()], self.n_samples, self.sample_fields)
            if keep
            else []
        )
        kept: list[tuple[int, int, dict[str, NDArray[Any]]]] = [(a, b, {}) for a, b, _, _ in plan]
        names = [list(fields) for _, _, fields, _ in plan]  # the fields each kept range keeps
        first = 0
        for chunk in self.iter_samples(fields=self.sample_fields):
            a, b = chunk.start, chunk.start + len(chunk)
            while first < len(done) and done[first].end_sample <= a:
                first += 1
            k = first
            while k < len(done) and done[k].start_sample < b:
                s = done[k]
                lo, hi = max(a, s.start_sample) - a, min(b, s.end_sample) - a
                for name in IMU_FIELDS:
                    hashers[k].update("imu", name, getattr(chunk, name)[lo:hi])
                k += 1
            for (ka, kb, arrays), keeps in zip(kept, names, strict=True):
                lo, hi = max(a, ka), min(b, kb)
                if lo < hi:
                    for name in keeps:
                        v = getattr(chunk, name)
                        if name not in arrays:
                            arrays[name] = np.empty((kb - ka, *v.shape[1:]), dtype=v.dtype)
                        arrays[name][lo - ka : hi - ka] = v[lo - a : hi - a]
        self._check_step_sha(done, hashers)
        self._check_small()
        for _, _, arrays in kept:
            for v in arrays.values():
                v.flags.writeable = False  # served as views: nobody changes the verified rows
        self._kept = kept  # every checksum passed

    def _check_step_sha(self, done: list[StepRecord], hashers: list[_StepHasher]) -> None:
        """Add each complete step's /table rows to its hasher (holding its /imu rows) and compare the SHA-256 with
        the one its row stores (RecordingDamaged naming the step)."""
        table = self.table()
        for s, h in zip(done, hashers, strict=True):
            for name in TABLE_FIELDS:
                h.update("table", name, getattr(table, name)[s.table_start : s.table_end])
            if h.hexdigest() != s.sha256:
                raise RecordingDamaged(
                    f"{self.path}: step {s.index} {s.name!r}: the SHA-256 of its rows (/imu "
                    f"{s.start_sample}–{s.end_sample}, /table {s.table_start}–{s.table_end}) does not match the "
                    f"one stored when the step closed; the data are damaged; {self._fix()}"
                )

    def _check_small(self) -> None:
        """Read the small datasets for their checksums: events, bench and procedure texts, truth, aux."""
        self.events()
        self.bench_text  # noqa: B018 - read for its checksums
        self.procedure_text  # noqa: B018
        self.truth()
        for name in self.aux_names():
            self.aux(name)

    def _verify_written(self, ev: WrittenRecording) -> bool:
        """Verify a recording this process has just written, using what the recorder verified while writing
        (:mod:`benches.recording.written`) instead of a second pass over the samples.

        The recorder checked every /imu chunk as written (read back equal, decoding to the rows hashed into the
        step's SHA-256); here the file must be the one it closed (same identity, extents, step rows, exception
        rows), every complete step's SHA-256 is recomputed from the recorder's /imu digests and the /table rows
        read now, and the small datasets are read for their checksums (as :meth:`verify`). The rows the recorder
        kept are served as :meth:`verify` keeps them.

        Returns False (nothing kept; run :meth:`verify`) when the evidence does not describe this file.
        Raises RecordingDamaged when a checksum fails.
        """
        done = self.complete_steps()
        mine = [w for w in ev.steps if w.status == "complete"]
        if (
            self.header.format_version != FORMAT_VERSION
            or self.unfinished_tail
            or file_identity(self.path) != ev.identity
            or (self.n_samples, self.n_table) != (ev.n_samples, ev.n_table)
            or len(self.steps) != len(ev.steps)
            or [(s.index, s.start_sample, s.end_sample, s.table_start, s.table_end, s.sha256) for s in done]
            != [(w.index, w.start_sample, w.end_sample, w.table_start, w.table_end, w.sha256) for w in mine]
            or set(self._exc) != set(ev.exceptions)
        ):
            return False
        for name, exc in self._exc.items():
            if hashlib.sha256(np.ascontiguousarray(exc, dtype=EXC_DTYPE).data).digest() != ev.exceptions[name]:
                raise RecordingDamaged(
                    f"{self.path}: dataset /imu/exceptions/{name} differs from the rows written; {self._fix()}"
                )
        self._check_step_sha(done, [_StepHasher.from_imu_digests(w.imu_digests) for w in mine])
        self._check_small()
        self._kept = ev.kept
        return True

    def _kept_rows(self, name: str, a: int, b: int) -> NDArray[Any] | None:
        """Rows [a, b) of field ``name`` from the rows :meth:`verify` kept (a read-only view), or None."""
        for ka, kb, arrays in self._kept:
            if ka <= a and b <= kb and name in arrays:
                return arrays[name][a - ka : b - ka]
        # rows spanning several kept ranges (a motion window reaching into an acquisition window): put together
        # from them (a copy) when they cover [a, b) without a hole
        spans = [(ka, kb, arrays[name]) for ka, kb, arrays in self._kept if name in arrays and ka < b and kb > a]
        spans.sort(key=lambda r: (r[0], -r[1]))
        parts, pos = [], a
        for ka, kb, v in spans:
            if ka > pos:
                return None
            if kb > pos:
                parts.append(v[pos - ka : min(kb, b) - ka])
                pos = min(kb, b)
            if pos >= b:
                return np.concatenate(parts)
        return None

    def _kept_index(self, name: str, idx: NDArray[Any]) -> NDArray[Any] | None:
        """Rows ``idx`` of field ``name`` from the rows :meth:`verify` kept (a copy), or None unless every index
        falls in one kept window (a fancy-index read of the file decodes every chunk it touches)."""
        if not self._kept or idx.ndim != 1 or idx.size == 0 or idx.dtype.kind not in "iu":
            return None
        lo, hi = int(idx.min()), int(idx.max()) + 1
        rows = self._kept_rows(name, lo, hi)
        return None if rows is None else rows[idx - lo]

    # ---- typed access ------------------------------------------------------------------------------------
    def _read_text(self, name: str) -> str:
        if name not in self._f:
            return ""
        d = self._f[name]
        v = d[()] if d.shape == () else d[0]
        return _text(v)

    @property
    def bench_text(self) -> str:
        """The bench file's text as recorded ('' if absent); checked against ``bench_sha256`` when given."""
        with self._guard("/bench_yaml"):
            text = self._read_text("bench_yaml")
        self._check_text("bench_yaml", text, self.header.bench_sha256)
        return text

    @property
    def procedure_text(self) -> str:
        """The procedure file's text as recorded ('' if absent)."""
        with self._guard("/procedure_yaml"):
            text = self._read_text("procedure_yaml")
        self._check_text("procedure_yaml", text, self.header.procedure_sha256)
        return text

    def _check_text(self, name: str, text: str, sha: str) -> None:
        if self.header.format_version >= 2 and len(sha) == 64:
            if text_sha256(text) != sha:
                raise RecordingDamaged(
                    f"{self.path}: dataset /{name}: the text does not match its SHA-256 in the header; {self._fix()}"
                )

    def complete_steps(self) -> list[StepRecord]:
        """The steps with status "complete", in order."""
        return [s for s in self.steps if s.status == "complete"]

    def step(self, name: str) -> StepRecord:
        """The step named ``name`` (RecordingError listing the names if there is none)."""
        for s in self.steps:
            if s.name == name:
                return s
        raise RecordingError(f"{self.path}: no step named {name!r}; steps: {', '.join(s.name for s in self.steps)}")

    def _imu_dataset(self, name: str) -> h5py.Dataset:
        if name not in self._f["imu"]:
            raise RecordingError(
                f"{self.path}: dataset /imu/{name} is missing; this use of the recording needs it (RECORDING.md)"
            )
        return self._f["imu"][name]

    def _imu_rows(self, name: str, a: int, b: int) -> NDArray[Any]:
        d = self._imu_dataset(name)
        if name in self._quanta:
            return _dequantise(d[a:b], self._quanta[name], self._exc.get(name), np.arange(a, max(a, b)))
        return np.asarray(d[a:b], dtype=_IMU_DTYPES[name])

    def samples(
        self, start: int = 0, stop: int | None = None, fields: Sequence[str] = IMU_FIELDS, *, index: Any = None
    ) -> Samples:
        """Unit samples, rows ``[start, stop)`` (or the row indices ``index``), of the named ``fields``.

        Body frame, SI: accel m/s², gyro rad/s, time s (the unit's sample clock), temperature K.
        """
        bad = [x for x in fields if x not in IMU_FIELDS]
        if bad:
            raise ValueError(f"unknown sample field(s) {bad}; known: {IMU_FIELDS}")
        stop = self.n_samples if stop is None else min(int(stop), self.n_samples)
        start = max(0, int(start))
        out = Samples(start=start)
        for name in fields:
            with self._guard(f"/imu/{name}", rows=(start, stop)):
                if index is not None:
                    idx = np.asarray(index)
                    v = self._kept_index(name, idx)
                    if v is None and name in self._quanta:
                        c = self._imu_dataset(name)[idx]
                        v = _dequantise(c, self._quanta[name], self._exc.get(name), idx.astype(np.int64))
                    elif v is None:
                        v = np.asarray(self._imu_dataset(name)[idx], dtype=_IMU_DTYPES[name])
                else:
                    v = self._kept_rows(name, start, stop) if stop > start else None
                    if v is None:
                        v = self._imu_rows(name, start, max(start, stop))
                setattr(out, name, v)
        return out

    def iter_samples(
        self,
        start: int = 0,
        stop: int | None = None,
        fields: Sequence[str] = IMU_FIELDS,
        chunk: int = READ_CHUNK,
        *,
        step: StepRecord | None = None,
    ) -> Iterator[Samples]:
        """Unit samples of rows ``[start, stop)`` in chunks of at most ``chunk`` rows (long records)."""
        stop = self.n_samples if stop is None else min(int(stop), self.n_samples)
        a = max(0, int(start))
        while a < stop:
            b = min(stop, a + int(chunk))
            out = Samples(start=a)
            for name in fields:
                try:
                    with self._guard(f"/imu/{name}", step, rows=None if step else (a, b)):
                        setattr(out, name, self._imu_rows(name, a, b))
                except RecordingDamaged:
                    self._locate(name, a, b, step)
                    raise
            yield out
            a = b

    def _locate(self, name: str, a: int, b: int, step: StepRecord | None) -> None:
        """Re-read rows [a, b) chunk by chunk; raise naming the first damaged chunk's rows and steps."""
        c0 = a - a % IMU_CHUNK
        for lo in range(c0, b, IMU_CHUNK):
            lo, hi = max(lo, a), min(lo + IMU_CHUNK, b)
            with self._guard(f"/imu/{name}", step, rows=None if step else (lo, hi)):
                self._imu_rows(name, lo, hi)

    def _table_rows(self, a: int, b: int) -> TableReadings:
        if self.n_table == 0:
            z = np.zeros(0)
            return TableReadings(z, np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.uint16))
        g = self._f["table"]
        return TableReadings(
            np.asarray(g["time"][a:b], dtype=np.float64),
            np.asarray(g["angles"][a:b], dtype=np.float64).reshape(-1, 3),
            np.asarray(g["rates"][a:b], dtype=np.float64).reshape(-1, 3),
            np.asarray(g["status"][a:b], dtype=np.uint16),
        )

    def table(self, start: int = 0, stop: int | None = None) -> TableReadings:
        """The table's readings, rows ``[start, stop)`` (all by default)."""
        stop = self.n_table if stop is None else min(int(stop), self.n_table)
        with self._guard("/table"):
            return self._table_rows(max(0, int(start)), stop)

    def storage_bytes(self, name: str = "/") -> int:
        """Bytes stored for a dataset or (recursively) a group, e.g. ``"timing"`` (benchmarks: size shares)."""
        obj = self._f[name]
        if isinstance(obj, h5py.Dataset):
            return int(obj.id.get_storage_size())
        total = 0

        def add(_n: str, o: Any) -> None:
            nonlocal total
            if isinstance(o, h5py.Dataset):
                total += int(o.id.get_storage_size())

        obj.visititems(add)
        return total

    def timing(self) -> TimeSources | None:
        """The raw time sources (``/timing``; RECORDING.md), or None for a recording made before they existed."""
        if "timing" not in self._f:
            return None
        with self._guard("/timing"):
            g = self._f["timing"]
            cols = {name: self._timing_column(g[name], name) for name in (*TIMING_TABLE, *TIMING_BLOCK)}
        n = min(self.n_table, cols["table_sample_index"].shape[0])
        return TimeSources(
            **{k: v[:n] for k, v in cols.items() if k in TIMING_TABLE},
            block_end_sample=cols["block_end_sample"],
            block_host_time=cols["block_host_time"],
        )

    def _timing_column(self, d: Any, name: str) -> NDArray[Any]:
        """One ``/timing`` column as its values (the clock columns: s, decoded from ns deltas when so stored)."""
        enc = _encoding_of(d)
        if enc == NS_DELTA and name in TIMING_CLOCKS:
            return ns_delta_decode(d[()])
        if enc:
            raise RecordingError(
                f"{self.path}: /timing/{name} has encoding {enc!r}, which this version cannot read; read it with "
                "the tablebench version that wrote it"
            )
        return d[()]

    def events(self) -> list[Event]:
        """The event log."""
        if "events" not in self._f:
            return []
        with self._guard("/events"):
            rows = self._f["events"][()]
            return [Event(float(r["time"]), _text(r["wall_utc"]), _text(r["level"]), _text(r["message"])) for r in rows]

    def aux_names(self) -> list[str]:
        """The auxiliary devices recorded (``/aux/<name>``), in name order."""
        if "aux" not in self._f:
            return []
        with self._guard("/aux"):
            return sorted(str(k) for k in self._f["aux"])

    def aux(self, name: str) -> AuxReadings:
        """The readings of auxiliary device ``name`` (RecordingError listing the recorded ones if absent)."""
        if name not in self.aux_names():
            raise RecordingError(
                f"{self.path}: no auxiliary device {name!r} recorded; recorded: {', '.join(self.aux_names()) or 'none'}"
            )
        with self._guard(f"/aux/{name}"):
            g = self._f["aux"][name]
            time = np.asarray(g["time"][()], dtype=np.float64)
            channels = {str(k): np.asarray(d[()], dtype=np.float64) for k, d in g.items() if k != "time"}
            units = {str(k): _text(d.attrs.get("unit", "")) for k, d in g.items() if k != "time"}
        for ch, v in channels.items():
            if v.shape != time.shape:
                raise RecordingDamaged(
                    f"{self.path}: dataset /aux/{name}/{ch} has {v.shape[0]} rows, /aux/{name}/time {time.shape[0]}"
                )
        return AuxReadings(name, time, channels, units)

    def truth(self) -> Truth | None:
        """The simulator's truth (simulated benches), or None."""
        if "truth" not in self._f:
            return None
        with self._guard("/truth"):
            g = self._f["truth"]
            params, arrays = {}, {}
            for k, v in g.attrs.items():
                a = np.asarray(v, dtype=np.float64)
                if a.ndim == 0:
                    params[str(k)] = float(a)
                else:
                    arrays[str(k)] = a
            arrays.update({str(k): np.asarray(d[()], dtype=np.float64) for k, d in g.items()})
        return Truth(params, arrays)

    def temperature_stats(self) -> dict[str, float]:
        """Mean, min and max of the unit's temperature over the record (K), read in chunks; {} if empty."""
        tot, lo, hi, n = 0.0, math.inf, -math.inf, 0
        whole = self._kept_rows("temperature", 0, self.n_samples) if self.n_samples else None
        chunks = (
            (whole[a : a + READ_CHUNK] for a in range(0, self.n_samples, READ_CHUNK))  # as verified: same chunks
            if whole is not None
            else (c.temperature for c in self.iter_samples(fields=("temperature",)))
        )
        for x in chunks:
            assert x is not None
            if x.size:
                tot, lo, hi, n = tot + float(x.sum()), min(lo, float(x.min())), max(hi, float(x.max())), n + x.size
        return {"mean": tot / n, "min": lo, "max": hi} if n else {}


def _chunk_infos(d: h5py.Dataset) -> list[Any]:
    """The chunk index entries of a chunked dataset (offset, filter mask, size …), in index order: one pass over the
    index (``chunk_iter``, HDF5 ≥ 1.12.3: 3.2 ms for a run's 1 240 chunks) instead of one lookup per entry
    (``get_chunk_info(i)``, which walks the index to its i-th entry: 12.5 ms), which remains the fallback."""
    out: list[Any] = []
    try:
        d.id.chunk_iter(out.append)
    except (AttributeError, NotImplementedError):  # an h5py/HDF5 without it
        out = [d.id.get_chunk_info(i) for i in range(d.id.get_num_chunks())]
    return out


def _walk(f: h5py.File) -> list[tuple[str, h5py.Dataset]]:
    out: list[tuple[str, h5py.Dataset]] = []
    f.visititems(lambda n, o: out.append((n, o)) if isinstance(o, h5py.Dataset) else None)
    return out


_VERIFIED: dict[Path, tuple[int, ...]] = {}
"""Recordings verified in full by this process → their file identity then (device, inode, size, modification and
change times in ns). Opening an unchanged file again skips the second full pass (``tablebench run`` opens its
recording for the identification, the certificate and the registry): any write to the file, or a change of
its times, changes the identity and it is verified again; every chunk read is still checked (Fletcher-32)."""


_KEPT: dict[str, Any] = {}
"""The rows the last full verification kept (:meth:`Recording.verify`), with the file's key and identity: a
recording opened again unchanged (no second pass) serves them too (``certificate`` opens the run for its
budget, the registry for its as found / as left). One recording only, replaced by the next verification."""


def open_recording(path: str | Path, *, verify: bool = True, written: bool = False) -> Recording:
    """Open a recording (a run folder or its ``recording.h5``) read-only, checked and by default verified.

    A file this process has already verified and which has not changed since (:data:`_VERIFIED`) is not read
    through a second time. With ``written`` (``tablebench run`` identifying the recording it has just made), a
    file this process has just written, checked while writing and closed complete
    (:mod:`benches.recording.written`), is verified from that evidence (:meth:`Recording._verify_written`: the
    steps' SHA-256 from the recorder's digests and the table read now, the small datasets read) instead of a second
    pass over its samples; any other file, or one changed since, is verified in full.

    Raises
    ------
    RecordingError
        Missing, not HDF5, not a recording, another format version; :class:`RecordingDamaged` when a
        checksum fails or the structure is damaged (the message names the file, the dataset and the step).
    """
    p = recording_file(path)
    if not p.exists():
        raise RecordingError(f"{p}: no such recording (give a run folder or its recording.h5)")
    try:
        f = h5py.File(p, "r")
    except _H5_ERRORS as exc:
        msg = str(exc).split("\n")[0]
        if "unable to lock file" in msg:
            raise RecordingError(
                f"{p}: in use by another process (a run still writing it?); try again when that process ends"
            ) from None
        raise RecordingError(
            f"{p}: not a readable HDF5 recording ({msg}); it may be truncated, damaged or not a recording"
        ) from None
    try:
        rec = Recording(p, f)
        if verify:
            key, ident = p.resolve(), file_identity(p)
            ev = take_written(p)  # released whether used or not
            if _VERIFIED.get(key) != ident:
                _VERIFIED.pop(key, None)
                if not (written and ev is not None and rec._verify_written(ev)):
                    rec.verify()
                if rec.integrity_verified:
                    _VERIFIED[key] = ident
                    _KEPT.clear()
                    _KEPT.update(key=(key, ident), kept=rec._kept)
            elif _KEPT.get("key") == (key, ident):
                rec._kept = _KEPT["kept"]
    except BaseException:
        f.close()
        raise
    return rec
