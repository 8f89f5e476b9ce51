"""The run recording: the ONE module that knows the HDF5 layout (``benches/RECORDING.md``).

Writing (:class:`Hdf5Recorder`): one file per run, written incrementally. Samples are buffered in memory and
written in short bursts at checkpoints (every step boundary and every ``checkpoint_samples`` samples), each
burst followed by a flush, so a process killed at any moment (even by SIGKILL) leaves a readable file holding
every completed step. Every dataset is chunked with HDF5's Fletcher-32 checksum filter (and shuffle + gzip
level 1 compression); every file-format structure carries HDF5's own metadata checksum (1.8 object headers,
superblock v2); when a step closes, a SHA-256 over that step's sample rows and table readings is stored in its
step row. Accelerometer and gyro samples that are quantised counts (``quanta``) are stored as int32 counts and
an exact float64 residual, so the stored values equal the recorded ones bit for bit.

Reading (:func:`open_recording` → :class:`Recording`): a typed run header (:class:`RunHeader`), typed steps
(:class:`StepRecord`), samples (:class:`Samples`, whole or as an iterator of chunks), table readings
(:class:`TableReadings`), events (:class:`Event`) and the simulator's truth (:class:`Truth`). On opening,
every checksum is verified; any failure, and any HDF5 error (also while reading data lazily), raises
:class:`RecordingError` naming the file, the dataset and the step. A recording written by another tool to
the layout without checksums (format version 1) stays usable: :attr:`Recording.integrity_verified` is False
and :attr:`Recording.integrity_note` says so in one line.

No other module imports h5py or names a dataset path.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import json
import math
import zlib
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np
from numpy.typing import NDArray

from core.errors import UserError
from core.provenance import text_sha256
from drivers.protocols import ImuBlock, TableState

FORMAT = "tablebench-recording"
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)
STATUS_VALUES = ("running", "complete", "interrupted", "failed")
RECORDING_NAME = "recording.h5"

IMU_FIELDS: tuple[str, ...] = ("counter", "time", "accel", "gyro", "temperature", "status")
TABLE_FIELDS: tuple[str, ...] = ("time", "angles", "rates", "status")
_IMU_DTYPES = {
    "counter": np.uint32,
    "time": np.float64,
    "accel": np.float64,
    "gyro": np.float64,
    "temperature": np.float64,
    "status": np.uint16,
}
_TABLE_DTYPES = {"time": np.float64, "angles": np.float64, "rates": np.float64, "status": np.uint16}
_WIDTH = {"accel": 3, "gyro": 3, "angles": 3, "rates": 3}
QUANTISED_FIELDS = ("time", "accel", "gyro")

TIMING_TABLE = {"table_sample_index": np.int64, "table_controller_time": np.float64,
                "table_host_request": np.float64, "table_host_answer": np.float64}  # fmt: skip
"""``/timing`` datasets with one row per table reading (RECORDING.md, time sources)."""
TIMING_BLOCK = {"block_end_sample": np.int64, "block_host_time": np.float64}
"""``/timing`` datasets with one row per block of unit samples received."""

IMU_CHUNK = 16384
TABLE_CHUNK = 1024
READ_CHUNK = 1 << 18

_NAME_LEN, _KIND_LEN, _GROUP_LEN, _STATUS_LEN, _MSG_LEN = 128, 16, 64, 16, 256


def _fixed(n: int) -> np.dtype:
    return h5py.string_dtype("utf-8", n)


# format version 1 (vlen strings, no checksums) — what other tools may still write
STEP_DTYPE_V1 = np.dtype(
    [
        ("index", np.int32),
        ("name", h5py.string_dtype("utf-8")),
        ("kind", h5py.string_dtype("utf-8")),
        ("group", h5py.string_dtype("utf-8")),
        ("start_sample", np.int64),
        ("acq_start", np.int64),
        ("acq_end", np.int64),
        ("end_sample", np.int64),
        ("status", h5py.string_dtype("utf-8")),
        ("axis", np.int8),
        ("rate", np.float64),
        ("angles", np.float64, (3,)),
    ]
)
STEP_DTYPE = np.dtype(
    [
        ("index", np.int32),
        ("name", _fixed(_NAME_LEN)),
        ("kind", _fixed(_KIND_LEN)),
        ("group", _fixed(_GROUP_LEN)),
        ("start_sample", np.int64),
        ("acq_start", np.int64),
        ("acq_end", np.int64),
        ("end_sample", np.int64),
        ("status", _fixed(_STATUS_LEN)),
        ("axis", np.int8),
        ("rate", np.float64),
        ("angles", np.float64, (3,)),
        ("table_start", np.int64),
        ("table_end", np.int64),
        ("sha256", _fixed(64)),
    ]
)
EVENT_DTYPE = np.dtype(
    [("time", np.float64), ("wall_utc", _fixed(32)), ("level", _fixed(16)), ("message", _fixed(_MSG_LEN))]
)
_H5_ERRORS = (OSError, KeyError, ValueError, RuntimeError, TypeError, IndexError, UnicodeDecodeError, AttributeError)


class RecordingError(UserError, RuntimeError):
    """A recording cannot be created, opened, verified or resumed; the message names the file and the fix."""


class RecordingDamaged(RecordingError):
    """A checksum failed or the HDF5 structure is damaged; the message names file, dataset and step."""


# ---- typed records ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class StepRecord:
    """One row of the step table (sample indices into /imu, table indices into /table, ends exclusive)."""

    index: int
    name: str
    kind: str
    group: str
    start_sample: int
    acq_start: int
    acq_end: int
    end_sample: int
    status: str
    axis: int = -1
    rate: float = 0.0
    angles: tuple[float, float, float] = (float("nan"), float("nan"), float("nan"))
    table_start: int = -1
    table_end: int = -1
    sha256: str = ""


@dataclass(frozen=True)
class RunHeader:
    """The recording's root attributes, typed (``benches/RECORDING.md``).

    Attributes
    ----------
    procedure_overrides : dict
        The procedure parameters overridden with ``--set NAME=VALUE`` (SI/YAML units as given), {} if none.
    seed : int or None
        Simulator seed (None: none recorded).
    extra : dict
        Any other root attribute (another tool's), as plain Python values.
    """

    format: str
    format_version: int
    software_version: str
    created_utc: str
    updated_utc: str
    status: str
    seed: int | None
    bench_name: str
    bench_file: str
    bench_sha256: str
    procedure_name: str
    procedure_file: str
    procedure_sha256: str
    procedure_overrides: dict[str, float]
    sample_rate_hz: float
    simulated: bool
    transport: str
    site_g: float | None
    site_g_source: str
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """Every header field as plain JSON-able values (``extra`` merged in)."""
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "extra"}
        d["procedure_overrides"] = dict(self.procedure_overrides)
        return {**self.extra, **d}


@dataclass
class Samples:
    """Unit samples, rows ``[start, start + n)`` of the recording (body frame, SI); unread fields are None."""

    start: int
    counter: NDArray[np.uint32] | None = None
    time: NDArray[np.float64] | None = None
    accel: NDArray[np.float64] | None = None
    gyro: NDArray[np.float64] | None = None
    temperature: NDArray[np.float64] | None = None
    status: NDArray[np.uint16] | None = None

    def __len__(self) -> int:
        for name in IMU_FIELDS:
            v = getattr(self, name)
            if v is not None:
                return int(v.shape[0])
        return 0


@dataclass
class TableReadings:
    """The table's readings (controller clock = bench time): time (M,) s, angles (M, 3) rad, rates (M, 3)
    rad/s (outer, middle, inner gimbal), status (M,) ``TableStatus`` bits."""

    time: NDArray[np.float64]
    angles: NDArray[np.float64]
    rates: NDArray[np.float64]
    status: NDArray[np.uint16]

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass(frozen=True)
class TimeSources:
    """Every time source of a run, raw (RECORDING.md): per table reading (rows as ``/table``) the number of unit
    samples recorded before it, the controller's clock (NaN: not reported) and the host's request and answer
    times; per block of unit samples its end (samples recorded after it) and the host's receive time. Seconds."""

    table_sample_index: NDArray[np.int64]
    table_controller_time: NDArray[np.float64]
    table_host_request: NDArray[np.float64]
    table_host_answer: NDArray[np.float64]
    block_end_sample: NDArray[np.int64]
    block_host_time: NDArray[np.float64]


@dataclass(frozen=True)
class Event:
    """One line of the event log (bench time, s)."""

    time: float
    wall_utc: str
    level: str
    message: str


@dataclass(frozen=True)
class Truth:
    """A simulated bench's truth: the 18 accelerometer parameters by name (SI) and further arrays."""

    parameters: dict[str, float]
    arrays: dict[str, NDArray[np.float64]]


# ---- helpers ------------------------------------------------------------------------------------------------------


def _utc_now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _text(v: Any) -> str:
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray) and v.shape == ():
        return _text(v[()])
    return str(v)


def _plain(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return v


def _clip_utf8(s: str, n: int) -> bytes:
    b = s.encode("utf-8")
    if len(b) <= n:
        return b
    return b[: n - 3].decode("utf-8", "ignore").encode("utf-8") + "…".encode()


def recording_file(path: str | Path) -> Path:
    """The ``recording.h5`` of a run folder, or the path itself if it is not a folder."""
    p = Path(path)
    return p / RECORDING_NAME if p.is_dir() else p


EXC_DTYPE = np.dtype([("row", np.int64), ("col", np.int8), ("value", np.float64)])


def _quantise(v: NDArray[np.float64], lsb: float, dtype: Any = np.int32) -> tuple[NDArray[Any], NDArray[Any]]:
    """Counts ``c`` with ``c * lsb == v`` bit for bit, and the exceptions (row, col, value) where it is not."""
    v = np.ascontiguousarray(v, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        c = np.rint(v / lsb).astype(dtype)  # NaN, inf, out of range: garbage counts, caught just below
        back = c * lsb
    bad = back.view(np.uint64) != v.view(np.uint64)
    if not bad.any():
        return c, np.zeros(0, EXC_DTYPE)
    c[bad] = 0
    pos = np.nonzero(bad.reshape(v.shape[0], -1))
    exc = np.zeros(pos[0].size, EXC_DTYPE)
    exc["row"], exc["col"] = pos[0], pos[1]
    exc["value"] = v.reshape(v.shape[0], -1)[pos]
    return c, exc


def _dequantise(c: NDArray[Any], lsb: float, exc: NDArray[Any] | None, rows: NDArray[np.int64]) -> NDArray[np.float64]:
    """Values of counts ``c`` at recording rows ``rows`` (sorted), exceptions applied."""
    v = c.astype(np.float64) * lsb
    if exc is not None and exc.size:
        lo, hi = np.searchsorted(exc["row"], [rows[0], rows[-1] + 1]) if rows.size else (0, 0)
        if hi > lo:
            e = exc[lo:hi]
            where = np.searchsorted(rows, e["row"])
            hit = (where < rows.size) & (rows[np.minimum(where, rows.size - 1)] == e["row"])
            v2 = v.reshape(v.shape[0], -1)
            v2[where[hit], e["col"][hit]] = e["value"][hit]
    return v


_COUNT_DTYPE = {"time": np.int64, "accel": np.int32, "gyro": np.int32}


class _StepHasher:
    """SHA-256 of one step: sha256 over the per-dataset SHA-256 digests of its rows, in the fixed order
    /imu/{counter,time,accel,gyro,temperature,status}, /table/{time,angles,rates,status} (little-endian,
    C order, the values as read back: counts already scaled)."""

    def __init__(self) -> None:
        self.parts = {("imu", n): hashlib.sha256() for n in IMU_FIELDS}
        self.parts.update({("table", n): hashlib.sha256() for n in TABLE_FIELDS})

    def update(self, group: str, name: str, data: NDArray[Any]) -> None:
        dt = (_IMU_DTYPES if group == "imu" else _TABLE_DTYPES)[name]
        self.parts[(group, name)].update(np.ascontiguousarray(data, dtype=np.dtype(dt).newbyteorder("<")).tobytes())

    def hexdigest(self) -> str:
        h = hashlib.sha256()
        for key in [("imu", n) for n in IMU_FIELDS] + [("table", n) for n in TABLE_FIELDS]:
            h.update(self.parts[key].digest())
        return h.hexdigest()


# ---- writing -------------------------------------------------------------------------------------------------------


def _fletcher32(data: bytes) -> int:
    """HDF5's Fletcher-32 (``H5_checksum_fletcher32``): 16-bit big-endian words, sums in one's-complement
    arithmetic modulo 65535 (the library folds every 360 words; folding keeps the sums congruent and a
    non-zero sum never folds to 0, so the result is the residue in 1 … 65535, or 0 for an all-zero input).

    Vectorised in a few numpy passes (each releasing the GIL): it runs in the recorder's encoder thread.
    """
    b = np.frombuffer(data, np.uint8)
    n = b.size // 2
    sum1 = sum2 = 0
    block = 1 << 20  # words per pass: the weighted sum stays below 2⁶⁴ (65535 · 2²⁰ · 2²⁰ / 2)
    for start in range(0, n, block):
        stop = min(n, start + block)
        w = (b[2 * start : 2 * stop : 2].astype(np.uint64) << np.uint64(8)) | b[2 * start + 1 : 2 * stop : 2]
        k = stop - start
        s1 = int(w.sum())
        s2 = int(np.dot(w, np.arange(k, 0, -1, dtype=np.uint64)))
        sum2 += k * sum1 + s2  # each word adds the running sum1 to sum2
        sum1 += s1
    if b.size % 2:
        sum1 += int(b[-1]) << 8
        sum2 += sum1
    r1 = (sum1 - 1) % 65535 + 1 if sum1 else 0
    r2 = (sum2 - 1) % 65535 + 1 if sum2 else 0
    return (r2 << 16) | r1


_RLE_FIELDS = frozenset({"accel", "gyro", "temperature"})
"""Datasets deflated with zlib's run-length strategy: their low byte planes are noise (no long matches to
find), their high planes runs; Z_RLE is about twice as fast as the default match search there and no larger.
Counters and time stamps (long arithmetic runs) keep the default strategy."""


def _encode_chunk(chunk: NDArray[Any], rle: bool = False) -> bytes:
    """One chunk through HDF5's pipeline shuffle → deflate (level 1) → Fletcher-32, as the library would.

    ``rle``: deflate with zlib's Z_RLE strategy (still a standard deflate stream: HDF5's filter inflates it).
    """
    it = chunk.dtype.itemsize
    raw = np.ascontiguousarray(chunk).view(np.uint8).reshape(-1, it).T.tobytes()
    if rle:
        enc = zlib.compressobj(1, zlib.DEFLATED, zlib.MAX_WBITS, 8, zlib.Z_RLE)
        z = enc.compress(raw) + enc.flush()
    else:
        z = zlib.compress(raw, 1)
    return z + _fletcher32(z).to_bytes(4, "little")


def _append_rows(d: h5py.Dataset, data: NDArray[Any]) -> None:
    """Append rows to an extendable dataset."""
    n0 = d.shape[0]
    d.resize(n0 + data.shape[0], axis=0)
    d[n0:] = data


def _stored_rows(
    name: str, data: NDArray[Any], hasher: _StepHasher, quanta: dict[str, float], row0: int
) -> tuple[NDArray[Any], NDArray[Any] | None]:
    """Hash recording rows ``row0 …`` of /imu dataset ``name`` (recorded values) into the step's SHA-256 and
    return what is stored: counts and their exceptions (recording rows) for a quantised dataset, else the
    values and None."""
    hasher.update("imu", name, data)
    if name not in quanta:
        return data, None
    counts, exc = _quantise(data, quanta[name], _COUNT_DTYPE[name])
    exc["row"] += row0
    return counts, exc


class _ChunkWriter:
    """The /imu writing pipeline of the compressed storage: everything but the HDF5 calls runs in one worker
    thread, in submission order, so the runner's thread never waits for it (zlib and numpy release the GIL;
    h5py does not, so chunk writes stay on the calling thread).

    Per batch of rows (:meth:`submit`) the worker hashes the rows into the step's SHA-256, quantises the
    count datasets (exceptions kept), and encodes whole chunks through the pipeline the file declares
    (shuffle → deflate → Fletcher-32, so any HDF5 reader decodes them). Rows of the last, partly filled chunk
    are kept (``tail``) and that chunk is re-encoded when rows follow. :meth:`after` queues an action (a
    step row) that runs once everything submitted before it is on disk; :meth:`drain` writes results in
    order: those ready, or all of them with ``wait``.
    """

    def __init__(self, f: h5py.File, names: Sequence[str], chunk: int, quanta: dict[str, float]) -> None:
        self.chunk = chunk
        self.names = tuple(names)
        self.quanta = dict(quanta)
        self.ds = {n: f["imu"][n] for n in names}
        self.exc_ds = {n: f["imu/exceptions"][n] for n in self.quanta}
        self.dtypes = {n: d.dtype for n, d in self.ds.items()}
        self.shapes = {n: d.shape[1:] for n, d in self.ds.items()}
        self.rows = {n: int(d.shape[0]) for n, d in self.ds.items()}
        self.tail = {n: d[self.rows[n] - self.rows[n] % chunk : self.rows[n]] for n, d in self.ds.items()}
        self.pending: Any = deque()
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="recording-encoder")

    def submit(self, cols: dict[str, NDArray[Any]], row0: int, hasher: _StepHasher) -> None:
        """Queue rows ``row0 …`` of every dataset (recorded values) for hashing, quantising and encoding."""
        self.pending.append((self.pool.submit(self._encode, cols, row0, hasher), None))

    def after(self, action: Callable[[], None]) -> None:
        """Run ``action`` (on the draining thread) once everything submitted so far is written."""
        self.pending.append((None, action))

    def _encode(
        self, cols: dict[str, NDArray[Any]], row0: int, hasher: _StepHasher
    ) -> tuple[list[tuple[str, int, int, bytes]], dict[str, NDArray[Any]]]:
        """Worker thread: the encoded chunks (dataset, first row, end row, bytes) and the count exceptions."""
        out: list[tuple[str, int, int, bytes]] = []
        excs: dict[str, NDArray[Any]] = {}
        for name in self.names:
            data, exc = _stored_rows(name, cols[name], hasher, self.quanta, row0)
            if exc is not None and exc.size:
                excs[name] = exc
            new = np.asarray(data, dtype=self.dtypes[name])
            tail = self.tail[name]
            rows = np.concatenate([tail, new]) if len(tail) else new
            r0 = self.rows[name] - len(tail)
            for off in range(0, len(rows), self.chunk):
                part = rows[off : off + self.chunk]
                if len(part) < self.chunk:
                    buf = np.zeros((self.chunk, *self.shapes[name]), dtype=self.dtypes[name])
                    buf[: len(part)] = part
                    part_bytes = _encode_chunk(buf, name in _RLE_FIELDS)
                else:
                    part_bytes = _encode_chunk(part, name in _RLE_FIELDS)
                out.append((name, r0 + off, r0 + off + min(self.chunk, len(rows) - off), part_bytes))
            left = len(rows) % self.chunk
            self.tail[name] = rows[len(rows) - left :] if left else rows[:0]
            self.rows[name] += len(new)
        return out, excs

    def drain(self, wait: bool) -> None:
        """Write the encoded chunks and run the queued actions (in order): those ready, or all with ``wait``."""
        while self.pending and (wait or self.pending[0][0] is None or self.pending[0][0].done()):
            fut, action = self.pending.popleft()
            if fut is None:
                action()
                continue
            chunks, excs = fut.result()
            for name, r0, r1, data in chunks:
                d = self.ds[name]
                if d.shape[0] < r1:
                    d.resize(r1, axis=0)
                d.id.write_direct_chunk((r0,) + (0,) * (d.ndim - 1), data, 0)
            for name, exc in excs.items():
                _append_rows(self.exc_ds[name], exc)

    def close(self) -> None:
        """Write everything pending and stop the worker."""
        try:
            self.drain(True)
        finally:
            self.pool.shutdown(wait=True)


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
        self._buffered = 0
        self._closed = False
        self._filters = storage_filters(compression)
        self._hasher = _StepHasher()
        self._quanta: dict[str, float] = {}
        self._deferred: dict[str, float] = {}
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
        """The raw time sources (``/timing``), created if missing (a recording made before they existed)."""
        g = f["timing"] if "timing" in f else _group(f, "timing")
        for name, dt in {**TIMING_TABLE, **TIMING_BLOCK}.items():
            if name not in g:
                self._dataset(g, name, dt, None, TABLE_CHUNK)

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
                _append_rows(f["table"][name], data)
            self._table_written += len(b)
            self._buf_table.clear()
            tim = np.array(self._buf_timing, dtype=np.float64).reshape(-1, 4)
            for j, name in enumerate(TIMING_TABLE):
                _append_rows(f["timing"][name], tim[:, j].astype(TIMING_TABLE[name]))
            self._buf_timing.clear()
        if self._buf_blocks:
            blk = np.array(self._buf_blocks, dtype=np.float64).reshape(-1, 2)
            for j, name in enumerate(TIMING_BLOCK):
                _append_rows(f["timing"][name], blk[:, j].astype(TIMING_BLOCK[name]))
            self._buf_blocks.clear()
        if self._buf_events:
            rows = np.array(
                [
                    (t, w.encode(), _clip_utf8(lv, 16), _clip_utf8(m, _MSG_LEN))
                    for t, w, lv, m in self._buf_events
                ],
                dtype=EVENT_DTYPE,
            )
            _append_rows(f["events"], rows)
            self._buf_events.clear()
        f.flush()

    def end_step(self, record: StepRecord) -> None:
        """Append a step row with the SHA-256 of the step's rows (the step boundary checkpoint).

        The row is written (and the file flushed) only once every row of the step is on disk: at once with
        the uncompressed storages; with the compressed one, as soon as the encoder has finished the step's
        chunks (the runner does not wait for it; :meth:`set_status` and :meth:`close` do).
        """
        self.checkpoint(wait=False)
        hasher, table_start, table_end = self._hasher, self._table_step_start, self._table_written

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
            _append_rows(self._file["steps"], row)
            self._file.flush()

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
                self._file.close()
                self._closed = True


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
        with self._guard("/imu, /table (layout)"):
            self._check_layout()
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
        """Close the file (safe to call twice)."""
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

    def _check_layout(self) -> None:
        f = self._f
        if "imu" not in f or "accel" not in f["imu"]:
            raise RecordingError(f"{self.path}: the recording holds no unit samples (/imu/accel missing)")
        self.n_samples = int(f["imu/accel"].shape[0])
        self.sample_fields: tuple[str, ...] = tuple(n for n in IMU_FIELDS if n in f["imu"])
        self._quanta: dict[str, float] = {}
        self._exc: dict[str, NDArray[Any]] = {}
        for name, d in f["imu"].items():
            if not isinstance(d, h5py.Dataset):
                continue
            if d.shape[0] != self.n_samples:
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
            self.n_table = int(f["table/time"].shape[0])
            for name, d in f["table"].items():
                if d.shape[0] != self.n_table:
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
                self._check_chunks(name, obj)

    def _check_chunks(self, name: str, d: h5py.Dataset) -> None:
        """Every chunk of the dataset's extent is indexed exactly once, at its place, with every filter applied.

        The chunk index (a B-tree) carries no checksum of its own: a damaged key would silently turn a chunk
        into fill values, a damaged filter mask would skip the Fletcher-32 check.
        """
        rows = int(d.shape[0]) if d.shape else 1
        step = int(d.chunks[0]) if d.chunks else rows
        want = list(range(0, rows, step)) if d.shape else [0]
        n = d.id.get_num_chunks()
        got = []
        for i in range(n):
            info = d.id.get_chunk_info(i)
            if info.filter_mask != 0 or any(info.chunk_offset[1:]) or info.size <= 0:
                got = None
                break
            got.append(int(info.chunk_offset[0]) if d.shape else 0)
        if got is None or sorted(got) != want:
            raise RecordingDamaged(
                f"{self.path}: dataset /{name}: its chunk index is damaged (chunks missing, misplaced or unfiltered); "
                f"{self._fix()}"
            )

    def _read_steps(self) -> list[StepRecord]:
        if "steps" not in self._f:
            return []
        rows = self._f["steps"][()]
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
    def verify(self) -> None:
        """Read every dataset (Fletcher-32 of every chunk) and check every complete step's SHA-256.

        The samples are read once, in large chunk-aligned blocks, each step's rows hashed as they pass.

        Raises
        ------
        RecordingDamaged
            Naming the file, the dataset and the step. Format-1 recordings: only the readability is checked.
        """
        v2 = self.header.format_version >= 2
        done = [s for s in self.steps if s.status == "complete"] if v2 else []
        hashers = [_StepHasher() for _ in done]
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
        self.events()
        self.bench_text  # noqa: B018 - read for its checksums
        self.procedure_text  # noqa: B018
        self.truth()

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
                    if name in self._quanta:
                        c = self._imu_dataset(name)[idx]
                        v = _dequantise(c, self._quanta[name], self._exc.get(name), idx.astype(np.int64))
                    else:
                        v = np.asarray(self._imu_dataset(name)[idx], dtype=_IMU_DTYPES[name])
                else:
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
            cols = {name: g[name][()] for name in (*TIMING_TABLE, *TIMING_BLOCK)}
        n = min(self.n_table, cols["table_sample_index"].shape[0])
        return TimeSources(
            **{k: v[:n] for k, v in cols.items() if k in TIMING_TABLE},
            block_end_sample=cols["block_end_sample"],
            block_host_time=cols["block_host_time"],
        )

    def events(self) -> list[Event]:
        """The event log."""
        if "events" not in self._f:
            return []
        with self._guard("/events"):
            rows = self._f["events"][()]
            return [
                Event(float(r["time"]), _text(r["wall_utc"]), _text(r["level"]), _text(r["message"])) for r in rows
            ]

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
        for c in self.iter_samples(fields=("temperature",)):
            x = c.temperature
            assert x is not None
            if x.size:
                tot, lo, hi, n = tot + float(x.sum()), min(lo, float(x.min())), max(hi, float(x.max())), n + x.size
        return {"mean": tot / n, "min": lo, "max": hi} if n else {}


def _walk(f: h5py.File) -> list[tuple[str, h5py.Dataset]]:
    out: list[tuple[str, h5py.Dataset]] = []
    f.visititems(lambda n, o: out.append((n, o)) if isinstance(o, h5py.Dataset) else None)
    return out


def open_recording(path: str | Path, *, verify: bool = True) -> Recording:
    """Open a recording (a run folder or its ``recording.h5``) read-only, checked and by default verified.

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
            rec.verify()
    except BaseException:
        f.close()
        raise
    return rec


def salvage(src: str | Path, dst: str | Path) -> int:
    """Copy the intact complete steps of a damaged recording into a new recording ``dst`` (status interrupted).

    Returns the number of steps kept; resume the copy with ``tablebench run --resume``.
    """
    src_p = recording_file(src)
    dst_p = Path(dst)
    if dst_p.exists():
        raise RecordingError(f"{dst_p}: already exists; choose a new folder for the salvaged recording")
    try:
        f = h5py.File(src_p, "r")
    except _H5_ERRORS as exc:
        raise RecordingError(f"{src_p}: cannot be opened at all ({exc}); nothing can be salvaged") from None
    try:
        rec = Recording(src_p, f)
    except RecordingError:
        f.close()
        raise
    with rec:
        good: list[StepRecord] = []
        for s in rec.complete_steps():
            try:
                h = _StepHasher()
                for c in rec.iter_samples(start=s.start_sample, stop=s.end_sample, step=s):
                    for name in IMU_FIELDS:
                        h.update("imu", name, getattr(c, name))
                t = rec.table(s.table_start, s.table_end)
                for name in TABLE_FIELDS:
                    h.update("table", name, getattr(t, name))
            except RecordingError:
                break
            if rec.header.format_version >= 2 and h.hexdigest() != s.sha256:
                break
            good.append(s)
        hd = rec.header
        attrs = hd.as_dict()
        for k in ("format", "format_version", "status", "created_utc", "updated_utc"):
            attrs.pop(k, None)
        attrs["seed"] = -1 if hd.seed is None else hd.seed
        attrs["salvaged_from"] = str(src_p)
        try:
            truth = rec.truth()
        except RecordingError:
            truth = None
        truth_d: dict[str, Any] | None = None
        if truth is not None:
            truth_d = {**truth.parameters, **truth.arrays}
        out = Hdf5Recorder(
            dst_p,
            attrs=attrs,
            bench_text=rec.bench_text,
            procedure_text=rec.procedure_text,
            truth=truth_d,
            quanta=dict(rec._quanta),
        )
        try:
            for s in good:
                for c in rec.iter_samples(start=s.start_sample, stop=s.end_sample):
                    out.add_samples(
                        ImuBlock(c.counter, c.time, c.accel, c.gyro, c.temperature, c.status)  # type: ignore[arg-type]
                    )
                t = rec.table(s.table_start, s.table_end)
                for i in range(len(t)):
                    out.add_table(TableState(float(t.time[i]), t.angles[i], t.rates[i], int(t.status[i])))  # type: ignore[arg-type]
                out.end_step(s)
            out.event(0.0, "warning", f"salvaged {len(good)} intact step(s) from {src_p}")
            out.set_status("interrupted")
        finally:
            out.close()
    return len(good)


__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "Event",
    "Hdf5Recorder",
    "Recorder",
    "Recording",
    "RecordingDamaged",
    "RecordingError",
    "RunHeader",
    "Samples",
    "StepRecord",
    "TableReadings",
    "Truth",
    "open_recording",
    "recording_file",
    "salvage",
]


def write_decoded_samples(
    path: str | Path, names: Sequence[str], table: NDArray[np.float64], attrs: dict[str, Any]
) -> Path:
    """Write decoded unit samples (``tablebench decode --out OUT.h5``): one dataset per column under
    ``/samples`` (float64, Fletcher-32, shuffle + gzip) and the decode summary as root attributes. This is not
    a recording (no steps, no table stream); the recording reader refuses it with a clear message."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with h5py.File(p, "w") as f:
            f.attrs["format"] = "tablebench-decoded-samples"
            for k, v in attrs.items():
                f.attrs[k] = _plain(v) if not isinstance(v, str) else v
            g = f.create_group("samples")
            for j, name in enumerate(names):
                g.create_dataset(name, data=np.ascontiguousarray(table[:, j]), **storage_filters("gzip"))
    except OSError as exc:
        raise RecordingError(f"{p}: cannot write the decoded samples ({exc})") from None
    return p
