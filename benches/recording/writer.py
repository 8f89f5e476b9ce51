"""Writing a run (:class:`Hdf5Recorder`): incremental, checkpointed, checksummed (``benches/RECORDING.md``).

Part of the package :mod:`benches.recording`, the one place that knows the HDF5 layout.
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np
from numpy.typing import NDArray

from drivers.protocols import ImuBlock, Reading, TableState

from .encoding import (
    _COUNT_DTYPE,
    EXC_DTYPE,
    _append_read_back,
    _append_rows,
    _ChunkWriter,
    _quantise,
    _StepHasher,
    _stored_rows,
    _written_fault,
    ns_delta_encode,
    ns_delta_last,
)
from .layout import (
    _GROUP_LEN,
    _H5_ERRORS,
    _IMU_DTYPES,
    _KIND_LEN,
    _MSG_LEN,
    _NAME_LEN,
    _STATUS_LEN,
    _TABLE_DTYPES,
    _WIDTH,
    AUX_NAME,
    EVENT_DTYPE,
    FORMAT,
    FORMAT_VERSION,
    IMU_CHUNK,
    IMU_FIELDS,
    NS_DELTA,
    QUANTISED_FIELDS,
    STATUS_VALUES,
    STEP_DTYPE,
    TABLE_CHUNK,
    TABLE_FIELDS,
    TIMING_BLOCK,
    TIMING_CLOCKS,
    TIMING_TABLE,
    RecordingError,
    StepRecord,
    _clip_utf8,
    _encoding_of,
    _fixed,
    _utc_now,
)
from .reader import open_recording
from .written import KeptRows, WrittenRecording, WrittenStep, file_identity, register_written


class Recorder(Protocol):
    """What the runner writes a run through."""

    @property
    def n_samples(self) -> int:
        """Samples recorded so far (including buffered ones)."""
        ...

    def add_samples(self, block: ImuBlock) -> None:
        """Append unit samples (body frame, SI)."""
        ...

    def add_table(self, state: TableState) -> None:
        """Append one table reading."""
        ...

    def event(self, time: float, level: str, message: str) -> None:
        """Append an event-log line (bench time, s)."""
        ...

    def end_step(self, record: StepRecord) -> None:
        """Append a step row and flush everything to disk."""
        ...

    def set_status(self, status: str) -> None:
        """Set the run status ("running", "complete", "interrupted", "failed") and flush."""
        ...

    def close(self) -> None:
        """Flush and close (always safe to call twice)."""
        ...


_FILTERS: dict[str, Any] = {"fletcher32": True, "shuffle": True, "compression": "gzip", "compression_opts": 1}


def storage_filters(compression: str | None = "gzip") -> dict[str, Any]:
    """HDF5 filter options of every dataset: Fletcher-32 always; shuffle + ``compression`` unless None."""
    if compression is None:
        return {"fletcher32": True}
    if compression == "lzf":
        return {"fletcher32": True, "shuffle": True, "compression": "lzf"}
    return dict(_FILTERS)


class Hdf5Recorder:
    """Write a run to ``path`` (see ``benches/RECORDING.md``).

    Parameters
    ----------
    path : Path
        The ``recording.h5`` file. Created (must not exist) unless ``resume`` is True.
    attrs : dict
        Root attributes for a new file (bench_name, procedure_name, procedure_sha256, procedure_overrides
        (a dict), seed, sample_rate_hz, simulated, software_version, …).
    bench_text, procedure_text : str
        The bench and procedure files, verbatim.
    truth : dict or None
        Simulated benches: the 18 accelerometer parameters by name (SI) and extra truth arrays.
    resume : bool
        Open an existing recording to continue it: it is verified first (a damaged file is refused), then
        everything after the last complete step (samples and table readings) is truncated.
    checkpoint_samples : int
        Write buffered samples to disk at least every this many samples.
    quanta : dict or None
        ``{"accel": lsb, "gyro": lsb}`` (m/s², rad/s per count): store these as int32 counts + exact residual.
    compression : {"gzip", "lzf", None}
        Lossless compression after the shuffle filter (Fletcher-32 is always on).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        attrs: dict[str, Any] | None = None,
        bench_text: str = "",
        procedure_text: str = "",
        truth: dict[str, Any] | None = None,
        resume: bool = False,
        checkpoint_samples: int = 60_000,
        quanta: dict[str, float] | None = None,
        compression: str | None = "gzip",
    ) -> None:
        self.path = Path(path)
        self.checkpoint_samples = int(checkpoint_samples)
        self._buf_imu: list[ImuBlock] = []
        self._buf_table: list[TableState] = []
        self._buf_timing: list[tuple[int, float, float, float]] = []  # per reading: sample index, controller, host
        self._buf_blocks: list[tuple[int, float]] = []  # per block: end sample, host receive time
        self._buf_events: list[tuple[float, str, str, str]] = []
        self._buf_aux: dict[str, list[tuple[float, Reading]]] = {}
        self._buffered = 0
        self._closed = False
        self._filters = storage_filters(compression)
        self._hasher = _StepHasher()
        self._quanta: dict[str, float] = {}
        self._deferred: dict[str, float] = {}
        self._ns_last: dict[str, int] = {}  # /timing clock columns stored as ns deltas: ns of their last value
        self._handles: dict[str, h5py.Dataset] = {}  # datasets appended to at every step, opened once
        self._ended: list[tuple[int, int, int, str]] = []  # steps ended: start, end sample, index, name
        self._steps_written: list[WrittenStep] = []  # step rows written and read back, with their /imu digests
        self._status = "running"
        # the recorded values a verifying pass keeps (identification in this process; new compressed recordings)
        self._keeper = KeptRows() if not resume and self._filters.get("compression") == "gzip" else None
        try:
            if resume:
                self._file = self._open_resume()
            else:
                if self.path.exists():
                    raise RecordingError(f"{self.path}: already exists; choose a new --out folder or use --resume")
                try:
                    self.path.parent.mkdir(parents=True, exist_ok=True)
                except OSError as exc:
                    raise RecordingError(f"{self.path.parent}: cannot create the run folder ({exc.strerror})") from None
                self._file = self._create(attrs or {}, bench_text, procedure_text, truth, quanta or {})
        except _H5_ERRORS as exc:
            if isinstance(exc, RecordingError):
                raise
            raise RecordingError(f"{self.path}: cannot write the recording ({exc})") from None
        self._written = int(self._file["imu/counter"].shape[0])
        self._table_written = int(self._file["table/time"].shape[0])
        self._table_step_start = self._table_written
        self._chunks: _ChunkWriter | None = None
        if not self._deferred:
            self._start_chunk_writer()

    def _start_chunk_writer(self) -> None:
        if self._filters.get("compression") == "gzip":
            self._chunks = _ChunkWriter(self._file, IMU_FIELDS, IMU_CHUNK, self._quanta)
            self._chunks.describe = self._steps_text

    def _steps_text(self, a: int, b: int) -> str:
        """`` (step …)``: the steps rows [a, b) of /imu belong to (for messages)."""
        hit = [f"step {i} {n!r}" for s, e, i, n in self._ended if s < b and e > a]
        if b > (self._ended[-1][1] if self._ended else 0):
            hit.append("the step being recorded")
        return f" ({', '.join(hit)})"

    def _counts_dataset(self, imu: h5py.Group, name: str, lsb: float) -> None:
        self._dataset(imu, name, _COUNT_DTYPE[name], _WIDTH.get(name), IMU_CHUNK)
        imu[name].attrs["lsb"] = lsb
        exg = imu["exceptions"] if "exceptions" in imu else _group(imu, "exceptions")
        exg.create_dataset(name, shape=(0,), maxshape=(None,), dtype=EXC_DTYPE, chunks=(1024,), **self._filters)
        self._quanta[name] = lsb

    def _materialise(self, cols: dict[str, NDArray[Any]] | None) -> None:
        """Decide the storage of the quantisable sample datasets on the first samples (before any row is
        written): counts if they sit on the unit's count grid (≤ 0.1 % exceptions), else float64 (a unit
        sending floats). The (empty) counts datasets exist from the start, so an early kill leaves a readable
        file."""
        imu = self._file["imu"]
        for name, lsb in self._deferred.items():
            if cols is None or not len(cols[name]):
                continue
            _c, exc = _quantise(cols[name], lsb, _COUNT_DTYPE[name])
            if exc.size > 1e-3 * cols[name].size:
                del imu[name]
                del imu["exceptions"][name]
                self._quanta.pop(name, None)
                self._dataset(imu, name, _IMU_DTYPES[name], _WIDTH.get(name), IMU_CHUNK)
        self._deferred = {}
        self._start_chunk_writer()

    # ---- creation / resume -------------------------------------------------------------------------------
    def _dataset(self, g: h5py.Group, name: str, dtype: Any, width: int | None, chunk: int) -> None:
        shape = (0,) if width is None else (0, width)
        maxshape = (None,) if width is None else (None, width)
        chunks = (chunk,) if width is None else (chunk, width)
        g.create_dataset(name, shape=shape, maxshape=maxshape, dtype=dtype, chunks=chunks, **self._filters)

    def _create(
        self,
        attrs: dict[str, Any],
        bench_text: str,
        procedure_text: str,
        truth: dict[str, Any] | None,
        quanta: dict[str, float],
    ) -> h5py.File:
        f = _new_file(self.path)
        root = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "created_utc": _utc_now(),
            "status": "running",
            "integrity": "fletcher32+sha256-per-step",
        }
        for k, v in {**attrs, **root}.items():
            if k == "procedure_overrides" and not isinstance(v, str):
                v = json.dumps(dict(v or {}), sort_keys=True)
            _set_attr(f, k, "" if v is None else v)
        _write_text(f, "bench_yaml", bench_text, self._filters)
        _write_text(f, "procedure_yaml", procedure_text, self._filters)
        imu = _group(f, "imu")
        for name in IMU_FIELDS:
            lsb = quanta.get(name) if name in QUANTISED_FIELDS else None
            if lsb is not None and math.isfinite(lsb) and lsb > 0:
                self._counts_dataset(imu, name, float(lsb))
                self._deferred[name] = float(lsb)  # kept as counts, or float64: decided on the first samples
            else:
                self._dataset(imu, name, _IMU_DTYPES[name], _WIDTH.get(name), IMU_CHUNK)
        tab = _group(f, "table")
        for name in TABLE_FIELDS:
            self._dataset(tab, name, _TABLE_DTYPES[name], _WIDTH.get(name), TABLE_CHUNK)
        self._timing_datasets(f)
        f.create_dataset("steps", shape=(0,), maxshape=(None,), dtype=STEP_DTYPE, chunks=(64,), fletcher32=True)
        f.create_dataset("events", shape=(0,), maxshape=(None,), dtype=EVENT_DTYPE, chunks=(64,), fletcher32=True)
        if truth is not None:
            g = _group(f, "truth")
            for k, v in truth.items():
                arr = np.asarray(v, dtype=np.float64)
                g.attrs[k] = float(arr) if arr.ndim == 0 else arr  # attributes: in the checksummed header
        f.flush()
        return f

    def _timing_datasets(self, f: h5py.File) -> None:
        """The raw time sources (``/timing``), created if missing (a recording made before they existed). The clock
        columns are int64 nanosecond deltas (``encoding = "ns-delta"``); a recording that has them as float64 (made
        before that) keeps float64 when resumed."""
        g = f["timing"] if "timing" in f else _group(f, "timing")
        for name, dt in {**TIMING_TABLE, **TIMING_BLOCK}.items():
            if name in g:
                continue
            if name in TIMING_CLOCKS:
                self._dataset(g, name, np.int64, None, TABLE_CHUNK)
                _set_attr(g[name], "encoding", NS_DELTA)
                _set_attr(g[name], "unit", "s")
                self._ns_last[name] = 0
            else:
                self._dataset(g, name, dt, None, TABLE_CHUNK)

    def _dataset_at(self, path: str) -> h5py.Dataset:
        """The open file's dataset at ``path``, looked up once (an h5py lookup costs more than the append)."""
        d = self._handles.get(path)
        if d is None:
            d = self._handles[path] = self._file[path]
        return d

    def _append_timing(self, d: h5py.Dataset, name: str, values: NDArray[np.float64]) -> None:
        """Append rows to a ``/timing`` column in its stored encoding."""
        if name in self._ns_last:
            data, self._ns_last[name] = ns_delta_encode(values, self._ns_last[name])
            _append_rows(d, data)
        else:
            _append_rows(d, values.astype({**TIMING_TABLE, **TIMING_BLOCK}[name]))

    def _open_resume(self) -> h5py.File:
        if not self.path.exists():
            raise RecordingError(f"{self.path}: no recording to resume")
        with open_recording(self.path) as rec:  # verifies every checksum first
            if rec.header.format_version != FORMAT_VERSION:
                raise RecordingError(
                    f"{self.path}: format version {rec.header.format_version} cannot be continued by this "
                    f"version (writes {FORMAT_VERSION}); start a new run"
                )
            steps = rec.steps
        complete = [s for s in steps if s.status == "complete"]
        # the step table is append-only and complete rows precede the (single) interrupted one
        cut = complete[-1].end_sample if complete else 0
        keep_t = complete[-1].table_end if complete else 0
        try:
            f = h5py.File(self.path, "r+")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot open the recording to resume it ({exc})") from None
        try:
            for name, d in f["imu"].items():
                if not isinstance(d, h5py.Dataset):
                    continue
                d.resize(min(cut, d.shape[0]), axis=0)
                if name in QUANTISED_FIELDS and "lsb" in d.attrs:
                    self._quanta[name] = float(d.attrs["lsb"])
            for name in list(self._quanta):
                d = f["imu/exceptions"][name]
                rows = d["row"] if d.shape[0] else np.zeros(0, np.int64)
                d.resize(int(np.searchsorted(rows, cut)), axis=0)
            for d in f["table"].values():
                d.resize(min(keep_t, d.shape[0]), axis=0)
            self._timing_datasets(f)
            tg = f["timing"]
            for name in TIMING_TABLE:
                tg[name].resize(min(keep_t, tg[name].shape[0]), axis=0)
            ends = tg["block_end_sample"][()]
            n_keep = int(np.searchsorted(ends, cut, side="right"))
            for name in TIMING_BLOCK:
                tg[name].resize(min(n_keep, tg[name].shape[0]), axis=0)
            for name in TIMING_CLOCKS:
                if _encoding_of(tg[name]) == NS_DELTA:
                    self._ns_last[name] = ns_delta_last(tg[name][()])
            f["steps"].resize(len(complete), axis=0)
            _set_attr(f, "status", "running")
            f.flush()
        except _H5_ERRORS as exc:
            f.close()
            raise RecordingError(f"{self.path}: cannot truncate the interrupted step to resume ({exc})") from None
        return f

    # ---- appending ---------------------------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        """Samples recorded so far, including buffered ones."""
        return self._written + self._buffered

    def add_samples(self, block: ImuBlock) -> None:
        """Buffer unit samples (hashed and written at the next checkpoint)."""
        if len(block) == 0:
            return
        self._buf_imu.append(block)
        self._buffered += len(block)
        self._buf_blocks.append((self.n_samples, float(getattr(block, "host_time", math.nan))))
        if self._buffered >= self.checkpoint_samples:
            self.checkpoint(full=False)
        elif self._chunks is not None and self._chunks.pending:
            with self._writing():
                self._chunks.drain(wait=False)  # chunks (and step rows) the encoder has finished

    def add_table(self, state: TableState) -> None:
        """Buffer one table reading (hashed and written at the next step-boundary checkpoint), with its raw time
        sources (the samples recorded before it, the controller's and the host's clocks)."""
        self._buf_table.append(state)
        self._buf_timing.append(
            (
                self.n_samples,
                float(getattr(state, "controller_time", math.nan)),
                float(getattr(state, "host_request", math.nan)),
                float(getattr(state, "host_answer", math.nan)),
            )
        )

    def event(self, time: float, level: str, message: str) -> None:
        """Buffer an event-log line."""
        self._buf_events.append((float(time), _utc_now(), level, message))

    def add_aux(self, name: str, time: float, reading: Reading) -> None:
        """Buffer one reading of the auxiliary device ``name`` at bench time ``time`` (s); written at the next
        full checkpoint under ``/aux/<name>`` (``benches/RECORDING.md``)."""
        if not AUX_NAME.fullmatch(name):
            raise RecordingError(f"auxiliary device name {name!r}: use letters, digits, '_' and '-' only")
        self._buf_aux.setdefault(name, []).append((float(time), reading))

    def checkpoint(self, full: bool = True, wait: bool = True) -> None:
        """Write buffered samples, table readings and events, then flush the file (RecordingError if it fails).

        With the compressed storage, samples are encoded by a worker thread; ``wait`` False does not wait
        for it (the chunks are written by a later checkpoint, :meth:`add_samples` or :meth:`close`).
        """
        with self._writing():
            self._checkpoint(full, wait)

    @contextlib.contextmanager
    def _writing(self) -> Iterator[None]:
        try:
            yield
        except RecordingError:
            raise
        except _H5_ERRORS as exc:
            msg = str(exc).split("\n")[0]
            raise RecordingError(
                f"{self.path}: cannot write the recording ({exc.__class__.__name__}: {msg}); is the disk full? "
                "The completed steps are kept; free space and resume the run"
            ) from None

    def _checkpoint(self, full: bool = True, wait: bool = True) -> None:
        """Write buffered samples, table readings and events, then flush the file.

        ``full=False`` (the periodic checkpoint inside a long step) writes only whole chunks of samples, so a
        compressed chunk is not rewritten (and its old copy left as dead space) at every checkpoint.
        """
        f = self._file
        if self._buf_imu:
            n = sum(len(b) for b in self._buf_imu)
            cols = {name: np.concatenate([getattr(b, name) for b in self._buf_imu]) for name in IMU_FIELDS}
            k = n if full else ((self._written + n) // IMU_CHUNK) * IMU_CHUNK - self._written
            if self._deferred:
                self._materialise(cols)
            if k > 0 and self._keeper is not None:
                self._keeper.add(self._written, {name: cols[name][:k] for name in KeptRows.FIELDS})
            if k > 0 and self._chunks is not None:
                self._chunks.submit({name: cols[name][:k] for name in IMU_FIELDS}, self._written, self._hasher)
            elif k > 0:
                for name in IMU_FIELDS:
                    data, exc = _stored_rows(name, cols[name][:k], self._hasher, self._quanta, self._written)
                    if exc is not None and exc.size:
                        _append_rows(f["imu/exceptions"][name], exc)
                    _append_rows(f["imu"][name], data)
            if k > 0:
                self._written += k
                self._buf_imu.clear()
                self._buffered = n - k
                if k < n:
                    self._buf_imu.append(ImuBlock(**{name: cols[name][k:] for name in IMU_FIELDS}))
        if self._chunks is not None:
            self._chunks.drain(wait=full and wait)
        if not full:
            f.flush()
            return
        if self._buf_table:
            b = self._buf_table
            tcols = {
                "time": np.array([s.time for s in b], dtype=np.float64),
                "angles": np.array([s.angles for s in b], dtype=np.float64).reshape(-1, 3),
                "rates": np.array([s.rates for s in b], dtype=np.float64).reshape(-1, 3),
                "status": np.array([int(s.status) for s in b], dtype=np.uint16),
            }
            for name, data in tcols.items():
                self._hasher.update("table", name, data)
                self._append_checked(f"table/{name}", data, "the step being recorded")
            self._table_written += len(b)
            self._buf_table.clear()
            tim = np.array(self._buf_timing, dtype=np.float64).reshape(-1, 4)
            for j, name in enumerate(TIMING_TABLE):
                self._append_timing(self._dataset_at(f"timing/{name}"), name, tim[:, j])
            self._buf_timing.clear()
        if self._buf_blocks:
            blk = np.array(self._buf_blocks, dtype=np.float64).reshape(-1, 2)
            for j, name in enumerate(TIMING_BLOCK):
                self._append_timing(self._dataset_at(f"timing/{name}"), name, blk[:, j])
            self._buf_blocks.clear()
        if self._buf_events:
            rows = np.array(
                [(t, w.encode(), _clip_utf8(lv, 16), _clip_utf8(m, _MSG_LEN)) for t, w, lv, m in self._buf_events],
                dtype=EVENT_DTYPE,
            )
            _append_rows(self._dataset_at("events"), rows)
            self._buf_events.clear()
        if self._buf_aux:
            _write_aux(f, self._buf_aux)
            self._buf_aux.clear()
        f.flush()

    def _append_checked(self, path: str, data: NDArray[Any], where: str) -> None:
        """Append rows to dataset ``path`` and read them back: RecordingDamaged naming the rows and ``where`` (the
        step) if they differ, and nothing queued is written any more (no step row after rows that failed)."""
        d = self._dataset_at(path)
        n0, same = _append_read_back(d, data)
        if not same:
            err = _written_fault(str(self.path), path, n0, d.shape[0], f" ({where})",
                                 "the rows read back after writing are not the ones written")  # fmt: skip
            if self._chunks is not None:
                self._chunks.stop(err)
            raise err

    def end_step(self, record: StepRecord) -> None:
        """Append a step row with the SHA-256 of the step's rows (the step boundary checkpoint).

        The row is written (and the file flushed) only once every row of the step is on disk: at once with
        the uncompressed storages; with the compressed one, as soon as the encoder has finished the step's
        chunks (the runner does not wait for it; :meth:`set_status` and :meth:`close` do).
        """
        self.checkpoint(wait=False)
        hasher, table_start, table_end = self._hasher, self._table_step_start, self._table_written
        if self._keeper is not None:
            self._keeper.end_step(record)
        self._ended.append((record.start_sample, record.end_sample, record.index, record.name))

        def write_row() -> None:
            row = np.array(
                [
                    (
                        record.index,
                        _clip_utf8(record.name, _NAME_LEN),
                        _clip_utf8(record.kind, _KIND_LEN),
                        _clip_utf8(record.group, _GROUP_LEN),
                        record.start_sample,
                        record.acq_start,
                        record.acq_end,
                        record.end_sample,
                        _clip_utf8(record.status, _STATUS_LEN),
                        record.axis,
                        record.rate,
                        record.angles,
                        table_start,
                        table_end,
                        hasher.hexdigest().encode(),
                    )
                ],
                dtype=STEP_DTYPE,
            )
            self._append_checked("steps", row, f"the row of step {record.index} {record.name!r}")
            self._file.flush()
            self._steps_written.append(
                WrittenStep(
                    record.index,
                    record.start_sample,
                    record.end_sample,
                    table_start,
                    table_end,
                    record.status,
                    hasher.hexdigest(),
                    hasher.imu_digests(),
                )
            )

        with self._writing():
            if self._chunks is not None:
                self._chunks.after(write_row)
                self._chunks.drain(wait=False)
            else:
                write_row()
        self._hasher = _StepHasher()
        self._table_step_start = self._table_written

    def set_status(self, status: str) -> None:
        """Set the run status and flush."""
        if status not in STATUS_VALUES:
            raise ValueError(f"status must be one of {STATUS_VALUES}")
        self.checkpoint()
        with self._writing():
            _set_attr(self._file, "status", status)
            _set_attr(self._file, "updated_utc", _utc_now())
            self._file.flush()
        self._status = status

    def close(self) -> None:
        """Flush and close; safe to call more than once."""
        if self._closed:
            return
        try:
            self.checkpoint()
        finally:
            try:
                if self._chunks is not None:
                    with self._writing():
                        self._chunks.close()
            finally:
                self._handles.clear()
                self._file.close()
                self._closed = True
        evidence = self._evidence()
        if evidence is not None:
            register_written(evidence)

    def _evidence(self) -> WrittenRecording | None:
        """What this recorder verified while writing (:mod:`benches.recording.written`), for the identification
        of the same process: only for a new recording closed complete, every chunk written by the verifying chunk
        writer, every step row written, every check passed; None otherwise (a full verifying pass then runs)."""
        chunks, keeper = self._chunks, self._keeper
        if chunks is None or keeper is None or chunks.broken is not None or self._status != "complete":
            return None
        if len(self._steps_written) != len(self._ended) or self._buffered:
            return None
        kept = keeper.finish(self._written, IMU_FIELDS)
        if kept is None:
            return None
        return WrittenRecording(
            path=self.path,
            identity=file_identity(self.path),
            n_samples=self._written,
            n_table=self._table_written,
            steps=tuple(self._steps_written),
            exceptions={n: h.digest() for n, h in chunks.exc_sha.items()},
            kept=kept,
        )


_COMPACT = (4096, 4000)  # attributes kept in the (checksummed) object header, never in a fractal heap


def _new_file(path: Path) -> h5py.File:
    """A new file in HDF5 1.8 format (metadata checksums, no consistency flags that a killed writer would leave)
    whose root group keeps its attributes and links compact (inside its checksummed object header)."""
    fcpl = h5py.h5p.create(h5py.h5p.FILE_CREATE)
    fcpl.set_attr_phase_change(*_COMPACT)  # (the root's 7 links stay compact by HDF5's default of ≤ 8)
    fapl = h5py.h5p.create(h5py.h5p.FILE_ACCESS)
    fapl.set_libver_bounds(h5py.h5f.LIBVER_V18, h5py.h5f.LIBVER_V18)
    fid = h5py.h5f.create(str(path).encode(), h5py.h5f.ACC_EXCL, fcpl=fcpl, fapl=fapl)
    return h5py.File(fid)


def _group(parent: h5py.Group, name: str) -> h5py.Group:
    """A group whose attributes stay compact (checksummed object header); callers keep ≤ 8 links per group."""
    gcpl = h5py.h5p.create(h5py.h5p.GROUP_CREATE)
    gcpl.set_attr_phase_change(*_COMPACT)  # links: every group holds ≤ 8, compact by HDF5's default
    h5py.h5g.create(parent.id, name.encode(), gcpl=gcpl)
    return parent[name]


def _set_attr(f: h5py.File, key: str, value: Any) -> None:
    """Strings as fixed-length UTF-8 (stored inside the checksummed object header, not the global heap)."""
    if isinstance(value, str):
        b = value.encode("utf-8")
        f.attrs.create(key, np.array(b, dtype=_fixed(max(1, len(b)))))
    elif isinstance(value, bool | np.bool_):
        f.attrs[key] = bool(value)
    else:
        f.attrs[key] = value


def _write_text(f: h5py.File, name: str, text: str, filters: dict[str, Any]) -> None:
    b = text.encode("utf-8")
    n = max(1, len(b))
    f.create_dataset(name, data=np.array([b], dtype=_fixed(n)), chunks=(1,), fletcher32=True)


def _aux_dataset(g: h5py.Group, name: str, rows: int, unit: str) -> h5py.Dataset:
    """``g[name]`` (float64, Fletcher-32), created NaN-filled to ``rows`` rows if new."""
    if name in g:
        return g[name]
    d = g.create_dataset(name, shape=(rows,), maxshape=(None,), dtype=np.float64, chunks=(256,), fletcher32=True)
    if rows:
        d[:] = np.nan
    d.attrs["unit"] = unit
    return d


def _write_aux(f: h5py.File, buffered: dict[str, list[tuple[float, Reading]]]) -> None:
    """Append buffered auxiliary readings: ``/aux/<device>/time`` (bench s) and one dataset per channel (SI,
    ``unit`` attribute); a channel missing from a reading is NaN there."""
    root = f["aux"] if "aux" in f else _group(f, "aux")
    for device, rows in buffered.items():
        g = root[device] if device in root else _group(root, device)
        n0 = int(g["time"].shape[0]) if "time" in g else 0
        t = _aux_dataset(g, "time", n0, "s")
        _append_rows(t, np.array([r[0] for r in rows], dtype=np.float64))
        channels = dict.fromkeys(k for _, r in rows for k in r.values)
        for ch in channels:
            unit = next(r.units.get(ch, "") for _, r in rows if ch in r.values)
            d = _aux_dataset(g, ch, n0, unit)
            _append_rows(d, np.array([float(r.values.get(ch, np.nan)) for _, r in rows], dtype=np.float64))
        for ch in g:
            if ch != "time" and ch not in channels:
                _append_rows(g[ch], np.full(len(rows), np.nan))
