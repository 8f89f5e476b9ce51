"""What the recorder verified while writing, handed to the reader of the same process (``benches/RECORDING.md``,
"Where the integrity is verified").

The recorder checks every /imu chunk as it writes it (:class:`benches.recording.encoding._ChunkWriter`: the bytes
read back equal the bytes written, and they decode to exactly the rows hashed into the step's SHA-256) and keeps
the recorded values of the rows a full :meth:`benches.recording.Recording.verify` keeps (:class:`KeptRows`, the
selection of :func:`kept_plan`, shared by both). When a new recording closes complete with every check passed, it
leaves a :class:`WrittenRecording` here; ``tablebench run``'s own identification opens the file with
``open_recording(path, written=True)``, which uses it instead of a second full pass over the samples when the file
is unchanged since (its identity: device, inode, size, modification and change times).

Part of the package :mod:`benches.recording`, the one place that knows the HDF5 layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .layout import _IMU_DTYPES, StepRecord

KEPT_FIELDS = ("time", "accel", "gyro", "status")
"""The sample fields :meth:`Recording.verify` keeps for the acquisition windows (what identification reads)."""
KEPT_WHOLE = ("temperature",)
"""The sample fields :meth:`Recording.verify` keeps for every row (the temperature summaries of identification and
certificate; 8 bytes a row, and it compresses to almost nothing, so decoding it again costs more than keeping it),
in recordings of at most :data:`KEPT_WHOLE_MAX_ROWS` rows (64 MiB; a longer one is decoded again when read)."""
KEPT_WHOLE_MAX_ROWS = 1 << 23
KEPT_BETWEEN = ("time", "gyro")
"""The sample fields :meth:`Recording.verify` also keeps for the rows between the acquisition windows (the moves:
the time base's motion windows, benches.timebase, read them with the windows' edges; 32 bytes a row), in
recordings with at most :data:`KEPT_BETWEEN_MAX_ROWS` such rows (64 MiB; more are decoded again when read)."""
KEPT_BETWEEN_MAX_ROWS = 1 << 21

Kept = list[tuple[int, int, dict[str, NDArray[Any]]]]
"""Kept rows: (first row, end row, {field: values of rows [first, end)}), read-only arrays."""


def _gaps(ranges: list[tuple[int, int]], n: int) -> list[tuple[int, int]]:
    """The row ranges of [0, n) outside ``ranges`` (in order)."""
    out, pos = [], 0
    for a, b in sorted(ranges):
        if a > pos:
            out.append((pos, min(a, n)))
        pos = max(pos, b)
    if pos < n:
        out.append((pos, n))
    return [(a, b) for a, b in out if b > a]


def kept_plan(
    windows: Sequence[tuple[int, int]], n_samples: int, fields: Sequence[str]
) -> list[tuple[int, int, tuple[str, ...], str]]:
    """The rows kept by a verifying pass, in the order kept: (first row, end row, fields, role).

    ``windows``: the acquisition windows [acq_start, acq_end) of the complete steps, in step order; ``fields``: the
    sample fields the recording holds. Role "window" (:data:`KEPT_FIELDS` of each non-empty window), "between"
    (:data:`KEPT_BETWEEN` of each range outside the windows, when they total at most
    :data:`KEPT_BETWEEN_MAX_ROWS` rows) and "whole" (:data:`KEPT_WHOLE` of every row, up to
    :data:`KEPT_WHOLE_MAX_ROWS`).
    """
    out: list[tuple[int, int, tuple[str, ...], str]] = []
    keep = tuple(n for n in KEPT_FIELDS if n in fields)
    if keep:
        out += [(a, min(b, n_samples), keep, "window") for a, b in windows if min(b, n_samples) > a]
    between = tuple(n for n in KEPT_BETWEEN if n in fields)
    gaps = _gaps([(a, b) for a, b, _, _ in out], n_samples)
    if between and 0 < sum(b - a for a, b in gaps) <= KEPT_BETWEEN_MAX_ROWS:
        out += [(a, b, between, "between") for a, b in gaps]
    whole = tuple(n for n in KEPT_WHOLE if n in fields)
    if whole and 0 < n_samples <= KEPT_WHOLE_MAX_ROWS:
        out.append((0, n_samples, whole, "whole"))
    return out


def file_identity(p: str | Path) -> tuple[int, ...]:
    """The file's identity: device, inode, size, modification and change times (ns). Equal identities mean the
    file is unchanged (what every "this process already read/verified it" shortcut keys on: the recorder's
    evidence, the verified-recording memo, identification's and the budget's memos)."""
    st = Path(p).stat()
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


@dataclass(frozen=True)
class WrittenStep:
    """One step row as the recorder wrote it, with the SHA-256 digests of its /imu rows it verified."""

    index: int
    start_sample: int
    end_sample: int
    table_start: int
    table_end: int
    status: str
    sha256: str
    imu_digests: tuple[bytes, ...]
    """SHA-256 of the step's rows of /imu/{counter,time,accel,gyro,temperature,status} (the values hashed, which
    the written chunks were checked to decode to)."""


@dataclass(frozen=True)
class WrittenRecording:
    """The verification evidence of a recording written (and closed complete) by this process."""

    path: Path
    identity: tuple[int, ...]
    n_samples: int
    n_table: int
    steps: tuple[WrittenStep, ...]
    exceptions: dict[str, bytes]
    """SHA-256 of all the rows written to /imu/exceptions/<name>, per quantised dataset."""
    kept: Kept


_WRITTEN: dict[str, Any] = {}
"""The last recording this process wrote and verified ({"key": resolved path, "evidence": WrittenRecording}):
one only, replaced by the next, released when the file is opened for verification."""


def register_written(evidence: WrittenRecording) -> None:
    """Leave ``evidence`` for :func:`take_written` (replacing any earlier one)."""
    _WRITTEN.clear()
    _WRITTEN.update(key=evidence.path.resolve(), evidence=evidence)


def take_written(path: Path) -> WrittenRecording | None:
    """The evidence left for ``path`` (released: a second call gives None), or None."""
    if _WRITTEN.get("key") != path.resolve():
        return None
    ev = _WRITTEN.get("evidence")
    _WRITTEN.clear()
    return ev


def _take(parts: list[tuple[int, dict[str, NDArray[Any]]]], name: str, a: int, b: int) -> NDArray[Any] | None:
    """Rows [a, b) of field ``name`` from ``parts`` ((first row, {field: rows}) in row order), as a new array of
    the field's recorded dtype; None unless the parts cover [a, b) without a hole."""
    pieces, pos = [], a
    for r0, cols in parts:
        v = cols[name]
        r1 = r0 + len(v)
        if r1 <= pos or r0 >= b:
            continue
        if r0 > pos:
            return None
        pieces.append(v[pos - r0 : min(r1, b) - r0])
        pos = min(r1, b)
        if pos >= b:
            break
    if pos < b:
        return None
    dt = _IMU_DTYPES[name]
    out = np.concatenate(pieces).astype(dt, copy=False) if len(pieces) > 1 else np.array(pieces[0], dtype=dt)
    if out.base is not None or not out.flags.c_contiguous:
        out = out.copy()
    return out


class KeptRows:
    """The recorder's copy of the recorded values a full verifying pass would keep (:func:`kept_plan`).

    Fed on the recorder's thread: :meth:`add` the rows as they are written (views of the recorded arrays),
    :meth:`end_step` when a step closes (its window, the rows between windows and the whole-record fields are
    copied out, the rest let go), :meth:`finish` at the end (the kept rows, in a verifying pass's order and
    dtypes). Memory as :meth:`Recording.verify`: the parts beyond its limits are dropped as soon as they are
    exceeded.
    """

    FIELDS = tuple(dict.fromkeys(KEPT_FIELDS + KEPT_BETWEEN + KEPT_WHOLE))

    def __init__(self) -> None:
        self.parts: list[tuple[int, dict[str, NDArray[Any]]]] = []  # rows of the step in progress (views)
        self.windows: list[tuple[int, int, dict[str, NDArray[Any]]]] = []
        self.between: list[tuple[int, dict[str, NDArray[Any]]]] | None = []  # None: beyond the limit
        self.n_between = 0
        self.whole: list[tuple[int, dict[str, NDArray[Any]]]] | None = []
        self.end = 0  # rows assigned to ended steps
        self.valid = True

    def add(self, row0: int, cols: dict[str, NDArray[Any]]) -> None:
        """Rows ``row0 …`` as recorded (only :attr:`FIELDS` are kept, as views)."""
        if self.valid:
            self.parts.append((row0, {n: cols[n] for n in self.FIELDS}))

    def end_step(self, step: StepRecord) -> None:
        """Step ``step`` closed: its rows are [start_sample, end_sample), its window [acq_start, acq_end)."""
        if not self.valid:
            return
        a, b = step.start_sample, step.end_sample
        if a != self.end or b < a:
            self.invalidate()
            return
        wa, wb = (step.acq_start, step.acq_end) if step.status == "complete" else (b, b)
        ranges = [(a, wa), (wb, b)] if wb > wa else [(a, b)]
        if wb > wa:
            win = {n: _take(self.parts, n, wa, wb) for n in KEPT_FIELDS}
            if any(v is None for v in win.values()):
                self.invalidate()
                return
            self.windows.append((wa, wb, win))  # type: ignore[arg-type]
        ok = self._keep_rest(ranges, a, b)
        self.parts = [p for p in self.parts if p[0] + len(p[1]["time"]) > b]
        self.end = b
        if not ok:
            self.invalidate()

    def _keep_rest(self, ranges: list[tuple[int, int]], a: int, b: int) -> bool:
        """Copy out the rows between the windows and the whole-record fields of a step's rows [a, b)."""
        ranges = [(x, y) for x, y in ranges if y > x]
        self.n_between += sum(y - x for x, y in ranges)
        if self.between is not None and self.n_between > KEPT_BETWEEN_MAX_ROWS:
            self.between = None  # a verifying pass would not keep them either
        if self.between is not None:
            for x, y in ranges:
                got = {n: _take(self.parts, n, x, y) for n in KEPT_BETWEEN}
                if any(v is None for v in got.values()):
                    return False
                self.between.append((x, got))  # type: ignore[arg-type]
        if self.whole is not None and b > KEPT_WHOLE_MAX_ROWS:
            self.whole = None
        if self.whole is not None and b > a:
            got = {n: _take(self.parts, n, a, b) for n in KEPT_WHOLE}
            if any(v is None for v in got.values()):
                return False
            self.whole.append((a, got))  # type: ignore[arg-type]
        return True

    def invalidate(self) -> None:
        """Give up (the evidence will not be offered: a full verifying pass runs instead)."""
        self.valid = False
        self.parts, self.windows, self.between, self.whole = [], [], None, None

    def finish(self, n_samples: int, fields: Sequence[str]) -> Kept | None:
        """The kept rows of a recording of ``n_samples`` rows (those after the last ended step, recorded while the
        table came to rest, belong to no window), in the order and form :meth:`Recording.verify` keeps them; None
        if they cannot be given."""
        if self.valid and n_samples > self.end and not self._keep_rest([(self.end, n_samples)], self.end, n_samples):
            self.invalidate()
        if not self.valid or self.end > n_samples:
            return None
        windows = {(a, b): arrays for a, b, arrays in self.windows}
        kept: Kept = []
        for a, b, names, role in kept_plan([(a, b) for a, b, _ in self.windows], n_samples, fields):
            if role == "window":
                arrays = {n: windows[(a, b)][n] for n in names}
            else:
                src = self.between if role == "between" else self.whole
                if src is None:
                    return None
                got = {n: _take(src, n, a, b) for n in names}
                if any(v is None for v in got.values()):
                    return None
                arrays = got  # type: ignore[assignment]
            for v in arrays.values():
                v.flags.writeable = False
            kept.append((a, b, arrays))
        self.invalidate()  # handed over: nothing more is kept here
        return kept
