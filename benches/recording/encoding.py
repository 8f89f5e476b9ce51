"""Encoding of the stored values: quantised counts with exact residuals, per-step SHA-256, Fletcher-32 and
the background chunk encoder of the writer.

Part of the package :mod:`benches.recording`, the one place that knows the HDF5 layout.
"""

from __future__ import annotations

import hashlib
import zlib
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from .layout import _IMU_DTYPES, _TABLE_DTYPES, IMU_FIELDS, NS_NAN, TABLE_FIELDS, RecordingDamaged, RecordingError

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
    v = np.multiply(c, lsb, dtype=np.float64)  # one pass; the same as c.astype(float64) * lsb, bit for bit
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
        # the array's own buffer (C order, little-endian), not a bytes copy of it: the same bytes hashed
        self.parts[(group, name)].update(np.ascontiguousarray(data, dtype=np.dtype(dt).newbyteorder("<")).data)

    def hexdigest(self) -> str:
        h = hashlib.sha256()
        for key in [("imu", n) for n in IMU_FIELDS] + [("table", n) for n in TABLE_FIELDS]:
            h.update(self.parts[key].digest())
        return h.hexdigest()

    def imu_digests(self) -> tuple[bytes, ...]:
        """The SHA-256 digests of the step's /imu datasets (in :data:`IMU_FIELDS` order)."""
        return tuple(self.parts[("imu", n)].digest() for n in IMU_FIELDS)

    @classmethod
    def from_imu_digests(cls, digests: Sequence[bytes]) -> _StepHasher:
        """A hasher whose /imu parts are finished, with these digests (:meth:`imu_digests`); the /table parts are
        still to be updated."""
        h = cls()
        for n, d in zip(IMU_FIELDS, digests, strict=True):
            h.parts[("imu", n)] = _Finished(d)  # type: ignore[assignment]
        return h


class _Finished:
    """A finished hash: only its digest."""

    def __init__(self, digest: bytes) -> None:
        self._digest = bytes(digest)

    def digest(self) -> bytes:
        return self._digest


# ---- writing -------------------------------------------------------------------------------------------------------


_F32_BLOCK = 1 << 16
"""Words per pass of :func:`_fletcher32`: its float64 sums stay exact integers (below 2⁴⁸)."""
_F32_WEIGHTS = np.arange(_F32_BLOCK, 0, -1, dtype=np.float64)
"""k, k − 1, …, 1 for a block of k words: the last k entries (each word's weight in the second sum)."""


def _fletcher32(data: bytes) -> int:
    """HDF5's Fletcher-32 (``H5_checksum_fletcher32``): 16-bit big-endian words, sums in one's-complement
    arithmetic modulo 65535 (the library folds every 360 words; folding keeps the sums congruent and a
    non-zero sum never folds to 0, so the result is the residue in 1 … 65535, or 0 for an all-zero input).

    Vectorised in a few numpy passes (each releasing the GIL): it runs in the recorder's encoder thread. The words
    are summed as float64 in blocks of :data:`_F32_BLOCK`, where every partial sum is an integer below 2⁴⁸ and so
    exact (float64 holds integers exactly up to 2⁵³; the weighted sum is a BLAS dot product); the blocks are
    combined in Python integers.
    """
    b = np.frombuffer(data, np.uint8)
    n = b.size // 2
    words = np.frombuffer(data, ">u2", count=n)
    sum1 = sum2 = 0
    for start in range(0, n, _F32_BLOCK):
        w = words[start : start + _F32_BLOCK].astype(np.float64)
        k = w.size
        s1 = int(w.sum())  # < 2¹⁶ · 2¹⁶
        s2 = int(np.dot(w, _F32_WEIGHTS[_F32_BLOCK - k :]))  # Σ (k − i) w_i < 2¹⁶ · 2¹⁶ · 2¹⁶
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


def _decodes_to(encoded: bytes, chunk: NDArray[Any]) -> bool:
    """Whether an encoded chunk (:func:`_encode_chunk`: deflate stream + Fletcher-32) decodes, through the
    pipeline's inverse (inflate, unshuffle), to exactly ``chunk``'s bytes. zlib and numpy release the GIL."""
    it = chunk.dtype.itemsize
    want = np.ascontiguousarray(chunk).view(np.uint8).reshape(-1, it)
    try:
        raw = zlib.decompress(encoded[:-4])
    except zlib.error:
        return False
    if len(raw) != want.size:
        return False
    return bool(np.array_equal(np.frombuffer(raw, np.uint8).reshape(it, -1).T, want))


def _dequantises_to(
    counts: NDArray[Any], lsb: float, exc: NDArray[Any], row0: int, values: NDArray[Any], name: str
) -> bool:
    """Whether stored counts with their exceptions (rows ``row0 …``) read back (:func:`_dequantise`, as the reader
    does) as exactly the recorded ``values`` (bit for bit, in the dataset's recorded dtype)."""
    back = _dequantise(counts, lsb, exc, np.arange(row0, row0 + len(counts), dtype=np.int64))
    want = np.ascontiguousarray(values, dtype=_IMU_DTYPES[name])
    return back.shape == want.shape and bool(np.array_equal(back.view(np.uint8), want.view(np.uint8)))


def _read_chunk(d: h5py.Dataset, offset: tuple[int, ...]) -> tuple[int, bytes]:
    """A chunk's stored bytes and filter mask, as the file holds them (HDF5's direct chunk read)."""
    mask, data = d.id.read_direct_chunk(offset)
    return int(mask), bytes(data)


class _ChunkMismatch(Exception):
    """An encoded chunk or batch of rows failed its check (raised on the encoder thread)."""

    def __init__(self, name: str, r0: int, r1: int, what: str) -> None:
        super().__init__(what)
        self.name, self.r0, self.r1, self.what = name, r0, r1, what


def _append_rows(d: h5py.Dataset, data: NDArray[Any]) -> None:
    """Append rows to an extendable dataset."""
    n0 = d.shape[0]
    d.resize(n0 + data.shape[0], axis=0)
    d[n0:] = data


def _append_read_back(d: h5py.Dataset, data: NDArray[Any]) -> tuple[int, bool]:
    """Append rows to an extendable dataset and read them back: (the first row appended, whether the rows read
    back are, byte for byte in the dataset's dtype, the ones written) — the writer's check of what it appends."""
    n0 = d.shape[0]
    _append_rows(d, data)
    same = np.asarray(d[n0:], dtype=d.dtype).tobytes() == np.ascontiguousarray(data, dtype=d.dtype).tobytes()
    return n0, same


def _written_fault(path: str, dataset: str, r0: int, r1: int, where: str, what: str) -> RecordingDamaged:
    """The error of a check made while writing: rows [r0, r1) of ``dataset`` (``where``: `` (step …)``)."""
    return RecordingDamaged(
        f"{path}: dataset /{dataset} rows {r0}–{r1}{where}: {what} (checked while writing; a storage, file-system or "
        "memory fault?); the run is stopped and the steps completed before are kept: check the disk, then "
        "'tablebench runs' says how to resume or salvage the run"
    )


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

    Verified while written (RECORDING.md, "Where the integrity is verified"): on the worker, the counts with
    their exceptions must read back (:func:`_dequantise`, as the reader does) as exactly the rows hashed, and
    every encoded chunk must decode (inflate, unshuffle) to exactly the stored rows; on the draining thread, every
    chunk read back from the file (:func:`_read_chunk`) must be the bytes written, with every filter applied, and
    every exception row appended must read back. A failure raises :class:`RecordingDamaged` naming the file, the
    dataset, the rows and the step (:attr:`describe`), and nothing queued after it is written (:attr:`broken`):
    no step row names rows that failed.
    """

    def __init__(self, f: h5py.File, names: Sequence[str], chunk: int, quanta: dict[str, float]) -> None:
        self.chunk = chunk
        self.names = tuple(names)
        self.quanta = dict(quanta)
        self.path = str(f.filename)
        self.ds = {n: f["imu"][n] for n in names}
        self.exc_ds = {n: f["imu/exceptions"][n] for n in self.quanta}
        self.dtypes = {n: d.dtype for n, d in self.ds.items()}
        self.shapes = {n: d.shape[1:] for n, d in self.ds.items()}
        self.rows = {n: int(d.shape[0]) for n, d in self.ds.items()}
        self.tail = {n: d[self.rows[n] - self.rows[n] % chunk : self.rows[n]] for n, d in self.ds.items()}
        self.pending: Any = deque()
        self.pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="recording-encoder")
        self.exc_sha = {n: hashlib.sha256() for n in self.quanta}
        """SHA-256 of the exception rows this writer appended (and read back), per dataset."""
        self.describe: Callable[[int, int], str] = lambda a, b: ""
        """`` (step …)`` naming the steps of rows [a, b), for messages (set by the recorder)."""
        self.broken: RecordingError | None = None
        """The failed check that stopped the writing (nothing queued after it is written)."""

    def submit(self, cols: dict[str, NDArray[Any]], row0: int, hasher: _StepHasher) -> None:
        """Queue rows ``row0 …`` of every dataset (recorded values) for hashing, quantising and encoding."""
        self.pending.append((self.pool.submit(self._encode, cols, row0, hasher), None))

    def after(self, action: Callable[[], None]) -> None:
        """Run ``action`` (on the draining thread) once everything submitted so far is written."""
        self.pending.append((None, action))

    def _encode(
        self, cols: dict[str, NDArray[Any]], row0: int, hasher: _StepHasher
    ) -> tuple[list[tuple[str, int, int, bytes]], dict[str, NDArray[Any]]]:
        """Worker thread: the encoded chunks (dataset, first row, end row, bytes) and the count exceptions, each
        checked to decode to the rows hashed (:class:`_ChunkMismatch` if not)."""
        out: list[tuple[str, int, int, bytes]] = []
        excs: dict[str, NDArray[Any]] = {}
        for name in self.names:
            data, exc = _stored_rows(name, cols[name], hasher, self.quanta, row0)
            if exc is not None and exc.size:
                excs[name] = exc
            new = np.asarray(data, dtype=self.dtypes[name])
            if exc is not None and not _dequantises_to(new, self.quanta[name], exc, row0, cols[name], name):
                raise _ChunkMismatch(
                    name, row0, row0 + len(new), "the stored counts do not read back as the rows hashed"
                )
            tail = self.tail[name]
            rows = np.concatenate([tail, new]) if len(tail) else new
            r0 = self.rows[name] - len(tail)
            for off in range(0, len(rows), self.chunk):
                part = rows[off : off + self.chunk]
                if len(part) < self.chunk:
                    buf = np.zeros((self.chunk, *self.shapes[name]), dtype=self.dtypes[name])
                    buf[: len(part)] = part
                    part = buf
                part_bytes = _encode_chunk(part, name in _RLE_FIELDS)
                r1 = r0 + off + min(self.chunk, len(rows) - off)
                if not _decodes_to(part_bytes, part):
                    raise _ChunkMismatch(name, r0 + off, r1, "an encoded chunk does not decode to the rows hashed")
                out.append((name, r0 + off, r1, part_bytes))
            left = len(rows) % self.chunk
            self.tail[name] = rows[len(rows) - left :] if left else rows[:0]
            self.rows[name] += len(new)
        return out, excs

    def stop(self, error: RecordingError) -> None:
        """A check failed (here or in the recorder): nothing queued is written any more (:attr:`broken`)."""
        self.pending.clear()
        self.broken = error

    def _break(self, name: str, r0: int, r1: int, what: str) -> None:
        """Stop writing and raise RecordingDamaged for rows [r0, r1) of /imu/``name``."""
        self.stop(_written_fault(self.path, f"imu/{name}", r0, r1, self.describe(r0, r1), what))
        raise self.broken  # type: ignore[misc]

    def drain(self, wait: bool) -> None:
        """Write the encoded chunks and run the queued actions (in order): those ready, or all with ``wait``;
        each chunk read back and compared with the bytes written. After a failed check nothing more is written."""
        if self.broken is not None:
            self.pending.clear()
            return
        while self.pending and (wait or self.pending[0][0] is None or self.pending[0][0].done()):
            fut, action = self.pending.popleft()
            if fut is None:
                action()
                continue
            try:
                chunks, excs = fut.result()
            except _ChunkMismatch as m:
                self._break(m.name, m.r0, m.r1, m.what)
            for name, r0, r1, data in chunks:
                d = self.ds[name]
                if d.shape[0] < r1:
                    d.resize(r1, axis=0)
                offset = (r0,) + (0,) * (d.ndim - 1)
                d.id.write_direct_chunk(offset, data, 0)
                mask, back = _read_chunk(d, offset)
                if mask != 0 or back != data:
                    self._break(name, r0, r1, "the chunk read back from the file is not the one written")
            for name, exc in excs.items():
                _, same = _append_read_back(self.exc_ds[name], exc)
                if not same:
                    self._break(f"exceptions/{name}", int(exc["row"][0]), int(exc["row"][-1]) + 1,
                                "the exception rows read back are not the ones written")  # fmt: skip
                self.exc_sha[name].update(np.ascontiguousarray(exc, dtype=EXC_DTYPE).data)

    def close(self) -> None:
        """Write everything pending and stop the worker."""
        try:
            self.drain(True)
        finally:
            self.pool.shutdown(wait=True)


def ns_delta_encode(values: NDArray[Any], last: int) -> tuple[NDArray[np.int64], int]:
    """Clock readings (s, float; NaN: none) → int64 nanosecond deltas (RECORDING.md, "/timing"), and the new
    ``last`` (ns of the last non-NaN value; the first row's delta is from ``last``, 0 for a new dataset)."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    ok = np.isfinite(v)
    ns = np.rint(v[ok] * 1e9).astype(np.int64)
    out = np.full(v.shape, NS_NAN, dtype=np.int64)
    out[ok] = np.diff(ns, prepend=np.int64(last))
    return out, int(ns[-1]) if ns.size else int(last)


def ns_delta_decode(deltas: NDArray[Any]) -> NDArray[np.float64]:
    """int64 nanosecond deltas (from the dataset's first row) → clock readings, s (NaN where :data:`NS_NAN`)."""
    d = np.asarray(deltas, dtype=np.int64).reshape(-1)
    ok = d != NS_NAN
    out = np.full(d.shape, np.nan)
    out[ok] = np.cumsum(d[ok]) / 1e9
    return out


def ns_delta_last(deltas: NDArray[Any]) -> int:
    """ns of the last non-NaN value of a stored ``ns-delta`` column (where appending continues)."""
    d = np.asarray(deltas, dtype=np.int64).reshape(-1)
    return int(np.sum(d[d != NS_NAN], dtype=np.int64))
