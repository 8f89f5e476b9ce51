"""The run recording: one HDF5 file per run, written incrementally, flushed at every step boundary.

Layout: ``benches/RECORDING.md``. Samples are buffered in memory and written to the file in short bursts
at checkpoints (every step boundary and every ``checkpoint_samples`` samples), each burst followed by a
flush, so that between bursts the file on disk is complete and consistent: a process killed at any
moment (even by SIGKILL) leaves a readable file holding every completed step.

The :class:`Recorder` protocol is the seam the runner writes through; :class:`Hdf5Recorder` implements it.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import h5py
import numpy as np

from core.errors import UserError
from drivers.protocols import ImuBlock, TableState

FORMAT = "tablebench-recording"
FORMAT_VERSION = 1
STATUS_VALUES = ("running", "complete", "interrupted", "failed")

_STR = h5py.string_dtype("utf-8")
STEP_DTYPE = np.dtype(
    [
        ("index", np.int32),
        ("name", _STR),
        ("kind", _STR),
        ("group", _STR),
        ("start_sample", np.int64),
        ("acq_start", np.int64),
        ("acq_end", np.int64),
        ("end_sample", np.int64),
        ("status", _STR),
        ("axis", np.int8),
        ("rate", np.float64),
        ("angles", np.float64, (3,)),
    ]
)
EVENT_DTYPE = np.dtype([("time", np.float64), ("wall_utc", _STR), ("level", _STR), ("message", _STR)])


class RecordingError(UserError, RuntimeError):
    """A recording cannot be created, opened or resumed; the message names the file and the fix."""


@dataclass(frozen=True)
class StepRecord:
    """One row of the step table (sample indices into /imu, end exclusive)."""

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


def _utc_now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _decode(v: Any) -> Any:
    return v.decode("utf-8") if isinstance(v, bytes) else v


class Hdf5Recorder:
    """Write a run to ``path`` (see ``benches/RECORDING.md``).

    Parameters
    ----------
    path : Path
        The ``recording.h5`` file. Created (must not exist) unless ``resume`` is True.
    attrs : dict
        Root attributes for a new file (bench_name, procedure_name, procedure_sha256, seed,
        sample_rate_hz, simulated, software_version, …).
    bench_text, procedure_text : str
        The bench and procedure files, verbatim.
    truth : dict or None
        Simulated benches: the 18 accelerometer parameters by name (SI) and extra truth arrays.
    resume : bool
        Open an existing recording to continue it: everything after the last complete step is truncated.
    checkpoint_samples : int
        Write buffered samples to disk at least every this many samples.
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
    ) -> None:
        self.path = Path(path)
        self.checkpoint_samples = int(checkpoint_samples)
        self._buf_imu: list[ImuBlock] = []
        self._buf_table: list[TableState] = []
        self._buf_events: list[tuple[float, str, str, str]] = []
        self._buffered = 0
        self._closed = False
        if resume:
            self._file = self._open_resume()
        else:
            if self.path.exists():
                raise RecordingError(f"{self.path}: already exists; choose a new --out folder or use --resume")
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self._create(attrs or {}, bench_text, procedure_text, truth)
        self._written = int(self._file["imu/time"].shape[0])

    # ---- creation / resume -------------------------------------------------------------------------------
    def _create(
        self, attrs: dict[str, Any], bench_text: str, procedure_text: str, truth: dict[str, Any] | None
    ) -> h5py.File:
        f = h5py.File(self.path, "w")
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["created_utc"] = _utc_now()
        f.attrs["status"] = "running"
        for k, v in attrs.items():
            f.attrs[k] = v if v is not None else ""
        f.create_dataset("bench_yaml", data=bench_text, dtype=_STR)
        f.create_dataset("procedure_yaml", data=procedure_text, dtype=_STR)
        imu = f.create_group("imu")
        ch = 8192
        imu.create_dataset("counter", shape=(0,), maxshape=(None,), dtype=np.uint32, chunks=(ch,))
        imu.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(ch,))
        imu.create_dataset("accel", shape=(0, 3), maxshape=(None, 3), dtype=np.float64, chunks=(ch, 3))
        imu.create_dataset("gyro", shape=(0, 3), maxshape=(None, 3), dtype=np.float64, chunks=(ch, 3))
        imu.create_dataset("temperature", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(ch,))
        imu.create_dataset("status", shape=(0,), maxshape=(None,), dtype=np.uint16, chunks=(ch,))
        tab = f.create_group("table")
        tab.create_dataset("time", shape=(0,), maxshape=(None,), dtype=np.float64, chunks=(1024,))
        tab.create_dataset("angles", shape=(0, 3), maxshape=(None, 3), dtype=np.float64, chunks=(1024, 3))
        tab.create_dataset("rates", shape=(0, 3), maxshape=(None, 3), dtype=np.float64, chunks=(1024, 3))
        tab.create_dataset("status", shape=(0,), maxshape=(None,), dtype=np.uint16, chunks=(1024,))
        f.create_dataset("steps", shape=(0,), maxshape=(None,), dtype=STEP_DTYPE, chunks=(64,))
        f.create_dataset("events", shape=(0,), maxshape=(None,), dtype=EVENT_DTYPE, chunks=(256,))
        if truth is not None:
            g = f.create_group("truth")
            for k, v in truth.items():
                arr = np.asarray(v)
                if arr.ndim == 0 and np.issubdtype(arr.dtype, np.number):
                    g.attrs[k] = float(arr)
                else:
                    g.create_dataset(k, data=arr)
        f.flush()
        return f

    def _open_resume(self) -> h5py.File:
        if not self.path.exists():
            raise RecordingError(f"{self.path}: no recording to resume")
        try:
            f = h5py.File(self.path, "r+")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot open the recording to resume it ({exc})") from None
        if f.attrs.get("format") != FORMAT:
            f.close()
            raise RecordingError(f"{self.path}: not a tablebench recording")
        steps = f["steps"][()]
        complete = [row for row in steps if _decode(row["status"]) == "complete"]
        keep_steps = len(complete)
        # the step table is append-only and complete rows precede the (single) interrupted one
        cut = int(complete[-1]["end_sample"]) if complete else 0
        for name in ("counter", "time", "accel", "gyro", "temperature", "status"):
            d = f["imu"][name]
            d.resize(min(cut, d.shape[0]), axis=0)
        if cut > 0:
            t_cut = float(f["imu/time"][cut - 1])
        else:
            t_cut = -np.inf
        tt = f["table/time"][()]
        keep_t = int(np.searchsorted(tt, t_cut, side="right"))
        for name in ("time", "angles", "rates", "status"):
            f["table"][name].resize(keep_t, axis=0)
        f["steps"].resize(keep_steps, axis=0)
        f.attrs["status"] = "running"
        f.flush()
        return f

    # ---- appending ---------------------------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        """Samples recorded so far, including buffered ones."""
        return self._written + self._buffered

    def add_samples(self, block: ImuBlock) -> None:
        """Buffer unit samples; written at the next checkpoint."""
        if len(block) == 0:
            return
        self._buf_imu.append(block)
        self._buffered += len(block)
        if self._buffered >= self.checkpoint_samples:
            self.checkpoint()

    def add_table(self, state: TableState) -> None:
        """Buffer one table reading."""
        self._buf_table.append(state)

    def event(self, time: float, level: str, message: str) -> None:
        """Buffer an event-log line."""
        self._buf_events.append((float(time), _utc_now(), level, message))

    def checkpoint(self) -> None:
        """Write every buffered sample, table reading and event, then flush the file."""
        f = self._file
        if self._buf_imu:
            n0 = f["imu/time"].shape[0]
            n = sum(len(b) for b in self._buf_imu)
            cols = {
                "counter": np.concatenate([b.counter for b in self._buf_imu]),
                "time": np.concatenate([b.time for b in self._buf_imu]),
                "accel": np.concatenate([b.accel for b in self._buf_imu]),
                "gyro": np.concatenate([b.gyro for b in self._buf_imu]),
                "temperature": np.concatenate([b.temperature for b in self._buf_imu]),
                "status": np.concatenate([b.status for b in self._buf_imu]),
            }
            for name, data in cols.items():
                d = f["imu"][name]
                d.resize(n0 + n, axis=0)
                d[n0:] = data
            self._written = n0 + n
            self._buf_imu.clear()
            self._buffered = 0
        if self._buf_table:
            m0 = f["table/time"].shape[0]
            m = len(self._buf_table)
            for name, data in (
                ("time", np.array([s.time for s in self._buf_table])),
                ("angles", np.array([s.angles for s in self._buf_table])),
                ("rates", np.array([s.rates for s in self._buf_table])),
                ("status", np.array([int(s.status) for s in self._buf_table], dtype=np.uint16)),
            ):
                d = f["table"][name]
                d.resize(m0 + m, axis=0)
                d[m0:] = data
            self._buf_table.clear()
        if self._buf_events:
            e0 = f["events"].shape[0]
            rows = np.array(self._buf_events, dtype=EVENT_DTYPE)
            f["events"].resize(e0 + len(rows), axis=0)
            f["events"][e0:] = rows
            self._buf_events.clear()
        f.flush()

    def end_step(self, record: StepRecord) -> None:
        """Append a step row, then checkpoint (the step boundary flush)."""
        self.checkpoint()
        row = np.array(
            [
                (
                    record.index,
                    record.name,
                    record.kind,
                    record.group,
                    record.start_sample,
                    record.acq_start,
                    record.acq_end,
                    record.end_sample,
                    record.status,
                    record.axis,
                    record.rate,
                    record.angles,
                )
            ],
            dtype=STEP_DTYPE,
        )
        d = self._file["steps"]
        k = d.shape[0]
        d.resize(k + 1, axis=0)
        d[k:] = row
        self._file.flush()

    def set_status(self, status: str) -> None:
        """Set the run status and flush."""
        if status not in STATUS_VALUES:
            raise ValueError(f"status must be one of {STATUS_VALUES}")
        self.checkpoint()
        self._file.attrs["status"] = status
        self._file.attrs["updated_utc"] = _utc_now()
        self._file.flush()

    def close(self) -> None:
        """Flush and close; safe to call more than once."""
        if self._closed:
            return
        try:
            self.checkpoint()
        finally:
            self._file.close()
            self._closed = True


# ---- reading -------------------------------------------------------------------------------------------------


def read_steps(f: h5py.File) -> list[StepRecord]:
    """The step table of an open recording as :class:`StepRecord` rows."""
    rows = f["steps"][()] if "steps" in f else np.zeros(0, dtype=STEP_DTYPE)
    out = []
    for r in rows:
        out.append(
            StepRecord(
                index=int(r["index"]),
                name=_decode(r["name"]),
                kind=_decode(r["kind"]),
                group=_decode(r["group"]),
                start_sample=int(r["start_sample"]),
                acq_start=int(r["acq_start"]),
                acq_end=int(r["acq_end"]),
                end_sample=int(r["end_sample"]),
                status=_decode(r["status"]),
                axis=int(r["axis"]),
                rate=float(r["rate"]),
                angles=tuple(float(a) for a in r["angles"]),
            )
        )
    return out


def open_recording(path: str | Path) -> h5py.File:
    """Open a recording read-only, with a clear error if it is not one."""
    p = Path(path)
    if p.is_dir():
        p = p / "recording.h5"
    if not p.exists():
        raise RecordingError(f"{p}: no such recording (give a run folder or its recording.h5)")
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise RecordingError(f"{p}: not a readable HDF5 file ({exc}); it may be truncated or not a recording") from None
    if f.attrs.get("format") != FORMAT:
        f.close()
        raise RecordingError(f"{p}: not a tablebench recording (no format attribute)")
    return f
