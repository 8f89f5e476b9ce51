"""Input for analysis commands (noise, periodic, drift): a recording, or a ``.npy`` / ``.csv`` file.

Every analysis command accepts:

- a recording (``RUN_DIR`` or ``RUN_DIR/recording.h5``; layout in ``benches/RECORDING.md``), whose channels
  are ``accel_x accel_y accel_z`` (m/s²) and ``gyro_x gyro_y gyro_z`` (rad/s), body frame, at the recording's
  sample rate; optionally restricted to one step (``--step NAME``);
- a ``.npy`` file (1-D, or 2-D with one column per channel, SI units) with ``--rate HZ``;
- a ``.csv`` file (one column per channel, optional header row of channel names) with ``--rate HZ``.

Problems (missing file, NaNs, non-numeric CSV, too-short records, bad rate) raise :class:`InputError`
with a message that names the file and the fix.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from benches.recorded_run import RecordedRun, run_of
from benches.recording import Recording, RecordingError, recording_file
from core.errors import UserError

READ_CHUNK_ROWS = 1 << 18
"""Rows per chunk when a recording step is read into the analysis arrays."""
RECORDING_CHANNELS: tuple[str, ...] = ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z")
CHANNEL_UNITS: dict[str, str] = {
    "accel_x": "m/s^2",
    "accel_y": "m/s^2",
    "accel_z": "m/s^2",
    "gyro_x": "rad/s",
    "gyro_y": "rad/s",
    "gyro_z": "rad/s",
}


MAX_RATE_HZ = 1e6
"""Highest sample rate accepted for .npy/.csv input (inertial units sample at ≤ tens of kHz)."""


class InputError(UserError, ValueError):
    """An analysis input cannot be used; the message names the file and the fix."""


@dataclass
class AnalysisInput:
    """Channels of a record at one sample rate.

    Attributes
    ----------
    source : str
        Path the data came from.
    rate : float
        Sample rate, Hz.
    channels : dict[str, ndarray]
        Channel name → 1-D float64 array (SI units, see ``units``).
    units : dict[str, str]
        Channel name → SI unit label ("m/s^2", "rad/s", or "SI" for foreign data).
    """

    source: str
    rate: float
    channels: dict[str, NDArray[np.float64]]
    units: dict[str, str]
    integrity_note: str = ""


def add_input_arguments(parser: argparse.ArgumentParser, default_channels: str | None = None) -> None:
    """Add the common input/output options: INPUT, --rate, --channels, --step, --out."""
    parser.add_argument("input", metavar="RUN|FILE", help="a recording (run folder or .h5), or a .npy/.csv file")
    parser.add_argument("--rate", type=float, default=None, help="sample rate in Hz (required for .npy/.csv)")
    parser.add_argument(
        "--channels",
        default=default_channels,
        help="comma-separated channel names (recording: accel_x,...,gyro_z; .npy/.csv: ch0,ch1,... or header "
        "names); default: all",
    )
    parser.add_argument("--step", default=None, help="recording only: analyse only the samples of this step")
    parser.add_argument("--out", default=None, metavar="DIR", help="write <command>.json and PNG plots here")


def _check_rate(rate: float | None, source: str) -> float:
    if rate is None:
        raise InputError(f"{source}: --rate HZ is required for .npy and .csv input (e.g. --rate 1000)")
    if not math.isfinite(rate) or rate <= 0 or rate > MAX_RATE_HZ:
        raise InputError(f"{source}: --rate must be a positive number of Hz, at most {MAX_RATE_HZ:g}; got {rate:g}")
    return float(rate)


def _finite_columns(data: NDArray[np.float64], names: list[str], source: str, allow_gaps: bool = False) -> None:
    bad = np.isinf(data) if allow_gaps else ~np.isfinite(data)
    if bad.any():
        rows, cols = np.nonzero(bad)
        raise InputError(
            f"{source}: {int(bad.sum())} non-finite value(s) (NaN/inf), first in channel {names[cols[0]]!r} "
            f"at sample {int(rows[0])}; remove or interpolate them before analysis"
        )


def _select(channels: dict[str, NDArray[np.float64]], wanted: str | None, source: str) -> list[str]:
    if wanted is None:
        return list(channels)
    names = [c.strip() for c in wanted.split(",") if c.strip()]
    if not names:
        raise InputError(f"--channels {wanted!r}: names no channel; available: {', '.join(channels)} (omit for all)")
    unknown = [n for n in names if n not in channels]
    if unknown:
        raise InputError(f"{source}: unknown channel(s) {', '.join(unknown)}; available: {', '.join(channels)}")
    return names


MAX_ARRAY_BYTES = 1 << 36
"""Largest data file an analysis loads into memory (64 GiB): a header claiming more is refused unread."""


def _npy_header(path: Path, fh) -> tuple[tuple[int, ...], np.dtype, bool]:
    """(shape, dtype, fortran_order) of an open ``.npy`` file, read from its header alone."""
    source = str(path)
    try:
        major, _minor = np.lib.format.read_magic(fh)
        if major == 1:
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
        elif major in (2, 3):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
        else:
            raise ValueError(f"unknown .npy format version {major}")
    except Exception as exc:  # a damaged header raises ValueError, EOFError, SyntaxError...
        raise InputError(f"{source}: not a readable .npy array ({exc}); save it with numpy.save") from None
    return tuple(int(n) for n in shape), dtype, bool(fortran)


def read_npy(path: str | Path) -> NDArray[np.float64]:
    """THE loader of ``.npy`` data files (analyses and ``correct``): the header's shape and dtype are checked
    against the file's size before anything is allocated, so a lying or truncated header is one clear line
    (not a MemoryError or a half-read array); only real numeric arrays are accepted; returns float64."""
    p = Path(path)
    source = str(p)
    try:
        size = p.stat().st_size
        with p.open("rb") as fh:
            shape, dtype, fortran = _npy_header(p, fh)
            offset = fh.tell()
            if dtype.hasobject or not (np.issubdtype(dtype, np.integer) or np.issubdtype(dtype, np.floating)):
                what = "complex" if np.issubdtype(dtype, np.complexfloating) else str(dtype)
                raise InputError(f"{source}: expected a real numeric array, got dtype {what}; save real numbers")
            claimed = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if claimed != size - offset:
                raise InputError(
                    f"{source}: the .npy header claims shape {shape} of {dtype} ({claimed:,} bytes) but the file "
                    f"holds {size - offset:,} bytes of data; the file is damaged or truncated, save it again"
                )
            if claimed > MAX_ARRAY_BYTES:
                raise InputError(f"{source}: {claimed:,} bytes is more than this command loads ({MAX_ARRAY_BYTES:,})")
            count = int(np.prod(shape))
            data = np.fromfile(fh, dtype=dtype, count=count)
    except OSError as exc:
        raise InputError(f"{source}: cannot be read ({exc.strerror or exc})") from None
    data = data.reshape(shape, order="F" if fortran else "C")
    return np.asarray(data, dtype=np.float64)


def _all_numbers(fields: list[str]) -> bool:
    try:
        [float(f) for f in fields]
    except ValueError:
        return False
    return True


def read_csv(path: str | Path) -> tuple[NDArray[np.float64], list[str] | None]:
    """THE loader of ``.csv`` data files: (samples × columns float64, header names or None). An empty file, a
    header with repeated or empty names, ragged rows and non-numeric cells are each one clear line."""
    p = Path(path)
    source = str(p)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{source}: cannot read as text CSV ({exc})") from None
    lines = [(k + 1, ln) for k, ln in enumerate(text.splitlines()) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise InputError(f"{source}: empty CSV; expected one numeric column per channel")
    header: list[str] | None = None
    fields = [f.strip() for f in lines[0][1].split(",")]
    if not _all_numbers(fields):
        header = fields
        lines = lines[1:]
        dup = sorted({n for n in header if header.count(n) > 1})
        if dup or "" in header:
            what = f"repeated column name(s) {', '.join(map(repr, dup))}" if dup else "an empty column name"
            raise InputError(f"{source}:1: the header has {what}; give every column its own name")
        if not lines:
            raise InputError(f"{source}: a header but no data rows; expected one numeric column per channel")
    width = len(header) if header else len(fields)
    try:  # the fast path; on any failure the rows are checked one by one to name the line
        data = np.loadtxt([ln for _k, ln in lines], delimiter=",", ndmin=2, dtype=np.float64)
        if data.shape[1] == width:
            return data, header
    except ValueError:
        pass
    for lineno, ln in lines:
        cells = ln.split(",")
        if len(cells) != width:
            raise InputError(f"{source}:{lineno}: {len(cells)} value(s), expected {width} (one per column)")
        try:
            [float(c) for c in cells]
        except ValueError:
            raise InputError(
                f"{source}:{lineno}: non-numeric value in {ln.strip()[:60]!r}; expected one number per column"
            ) from None
    raise InputError(f"{source}: not a CSV of numbers; expected one numeric column per channel")


def _load_array(path: Path, rate: float | None, wanted: str | None, allow_gaps: bool = False) -> AnalysisInput:
    source = str(path)
    rate_v = _check_rate(rate, source)
    header: list[str] | None = None
    if path.suffix.lower() == ".npy":
        data = read_npy(path)
    else:
        data, header = read_csv(path)
    data = np.asarray(data, dtype=np.float64)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2:
        raise InputError(f"{source}: expected a 1-D or 2-D array (samples × channels), got shape {data.shape}")
    if data.shape[0] < data.shape[1] and data.shape[0] <= 16 and data.shape[1] > 16:
        raise InputError(
            f"{source}: shape {data.shape} looks like channels × samples; save one column per channel (transpose it)"
        )
    names = header if header and len(header) == data.shape[1] else [f"ch{i}" for i in range(data.shape[1])]
    _finite_columns(data, names, source, allow_gaps)
    channels = {n: np.ascontiguousarray(data[:, i]) for i, n in enumerate(names)}
    sel = _select(channels, wanted, source)
    return AnalysisInput(source, rate_v, {n: channels[n] for n in sel}, {n: "SI" for n in sel})


def _load_recording(
    path: Path | RecordedRun, rate: float | None, wanted: str | None, step: str | None, allow_gaps: bool = False
) -> AnalysisInput:
    source = str(path.path if isinstance(path, RecordedRun) else path)
    with contextlib.ExitStack() as stack:
        try:
            rec = stack.enter_context(run_of(path)).recording
        except RecordingError as exc:
            raise InputError(str(exc)) from None
        file_rate = rec.header.sample_rate_hz
        if rate is not None and abs(rate - file_rate) > 1e-9 * file_rate:
            raise InputError(f"{source}: --rate {rate} disagrees with the recording's {file_rate} Hz; omit --rate")
        start, stop = 0, rec.n_samples
        if step is not None:
            try:
                s = rec.step(step)
            except RecordingError as exc:
                raise InputError(str(exc)) from None
            start, stop = s.start_sample, s.end_sample
        sel = _select(dict.fromkeys(RECORDING_CHANNELS[:6]), wanted, source)
        data = _read_channels(rec, start, stop, sel, source, allow_gaps)
    channels = dict(zip(sel, data, strict=True))  # rows of one (C, N) float64 array
    result = AnalysisInput(source, file_rate, {s: channels[s] for s in sel}, {s: CHANNEL_UNITS[s] for s in sel})
    result.integrity_note = rec.integrity_note
    if not rec.integrity_verified:
        print(f"warning: {rec.integrity_note}", file=sys.stderr)
    return result


def _read_channels(rec: Recording, start: int, stop: int, sel: list[str], source: str, allow_gaps: bool) -> NDArray:
    """The selected channels of rows [start, stop) read chunk by chunk (``Recording.iter_samples``) straight
    into one (C, N) float64 array: no whole-step temporaries, no per-channel copies, no stacking. The unit's
    status flags are checked per chunk, the values as every input is (:func:`_finite_columns`)."""
    fields = tuple(f for f in ("accel", "gyro") if any(s.startswith(f) for s in sel))
    if "status" in rec.sample_fields:
        fields += ("status",)
    mask = sum(1 << RECORDING_CHANNELS.index(s) for s in sel)  # status bit i = channel i invalid
    data = np.empty((len(sel), max(0, stop - start)))
    n_flag, first_flag = 0, None
    try:
        for chunk in rec.iter_samples(start, stop, fields, chunk=READ_CHUNK_ROWS):
            a = chunk.start - start
            status = getattr(chunk, "status", None)
            if status is not None and status.size:
                flagged = np.flatnonzero(status & mask)
                if flagged.size:
                    if first_flag is None:
                        first_flag = chunk.start + int(flagged[0])
                    n_flag += int(flagged.size)
            nrow = getattr(chunk, fields[0]).shape[0]
            for i, name in enumerate(sel):
                data[i, a : a + nrow] = getattr(chunk, name[:-2])[:, "xyz".index(name[-1])]
    except RecordingError as exc:
        raise InputError(str(exc)) from None
    if first_flag is not None:
        raise InputError(
            f"{source}: {n_flag} sample(s) of {', '.join(sel)} flagged invalid by the unit's status, first at "
            f"sample {first_flag}; analyse a clean step with --step NAME"
        )
    _finite_columns(data.T, sel, source, allow_gaps)
    return data


def recording_path(path: str | Path) -> Path:
    """The ``recording.h5`` of a run folder, or the path itself if it is a file."""
    return recording_file(path)


def load_input(
    path: str | Path | RecordedRun,
    rate: float | None = None,
    channels: str | None = None,
    step: str | None = None,
    min_samples: int = 16,
    allow_gaps: bool = False,
) -> AnalysisInput:
    """Load a recording, ``.npy`` or ``.csv`` into named SI channels; see the module docstring.

    ``allow_gaps``: NaN samples are kept (the analysis treats them as gaps); ±inf is still refused. ``path`` may
    also be an open :class:`benches.recorded_run.RecordedRun` (read, left open)."""
    if isinstance(path, RecordedRun):
        return _checked(_load_recording(path, rate, channels, step, allow_gaps), path.path, min_samples)
    p = recording_path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or run folder")
    suffix = p.suffix.lower()
    if suffix in (".npy", ".csv", ".txt"):
        if step is not None:
            raise InputError(f"{p}: --step applies only to recordings")
        result = _load_array(p, rate, channels, allow_gaps)
    elif suffix in (".h5", ".hdf5"):
        result = _load_recording(p, rate, channels, step, allow_gaps)
    else:
        raise InputError(f"{p}: unknown input type {suffix or '(no extension)'}; give a run folder, .h5, .npy or .csv")
    return _checked(result, p, min_samples)


def _checked(result: AnalysisInput, p: Path, min_samples: int) -> AnalysisInput:
    if not result.channels:
        raise InputError(f"{p}: no channels selected")
    n = len(next(iter(result.channels.values())))
    if n < min_samples:
        raise InputError(f"{p}: only {n} samples; this analysis needs at least {min_samples}")
    for name, x in result.channels.items():  # nothing to analyse (and every estimate would be 0/0)
        finite = x[np.isfinite(x)]
        if finite.size and np.all(finite == finite[0]):
            raise InputError(
                f"{p}: channel {name!r} is constant ({finite[0]:g} in all {n} samples); the analysis needs a "
                "varying signal (check the channel selection, --channels, or the sensor's quantisation)"
            )
    return result


def output_dir(out: str | None, default_name: str) -> Path | None:
    """Create and return the ``--out`` directory, or None when no output was asked for."""
    if out is None:
        return None
    d = Path(out)
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    return d
