"""The recording's HDF5 layout: format constants, dataset dtypes and chunking, the typed records and
errors (``benches/RECORDING.md``).

Part of the package :mod:`benches.recording`, the one place that knows the HDF5 layout.
"""

from __future__ import annotations

import datetime as _dt
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from core.errors import UserError

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
TIMING_CLOCKS: tuple[str, ...] = ("table_controller_time", "table_host_request", "table_host_answer", "block_host_time")
"""``/timing`` clock columns: read as float64 s; written as int64 nanosecond deltas (:data:`NS_DELTA`)."""
NS_DELTA = "ns-delta"
"""Value of a dataset's ``encoding`` attribute: row i holds round(t_i·10⁹) − round(t_j·10⁹), j the previous row
that is not NaN (0 before the first); a NaN row holds :data:`NS_NAN` (RECORDING.md, "/timing")."""
NS_NAN = int(np.iinfo(np.int64).min)
"""The ``ns-delta`` encoding's NaN row (−2⁶³)."""

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
class AuxReadings:
    """The readings of one auxiliary device (``/aux/<name>``): bench time (N,) s and channels (N,) SI, with units."""

    name: str
    time: NDArray[np.float64]
    channels: dict[str, NDArray[np.float64]]
    units: dict[str, str]

    def __len__(self) -> int:
        return int(self.time.shape[0])


AUX_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")
"""An auxiliary device's name (its group under ``/aux``)."""


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


def _encoding_of(d: h5py.Dataset) -> str:
    """A dataset's ``encoding`` attribute ("" when it has none: stored as its values)."""
    return _text(d.attrs["encoding"]) if "encoding" in d.attrs else ""


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
