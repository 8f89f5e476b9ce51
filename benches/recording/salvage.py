"""Salvage of a damaged recording's intact steps, and the decoded-samples file of ``tablebench decode``.

Part of the package :mod:`benches.recording`, the one place that knows the HDF5 layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from numpy.typing import NDArray

from drivers.protocols import ImuBlock, TableState

from .encoding import _StepHasher
from .layout import _H5_ERRORS, IMU_FIELDS, TABLE_FIELDS, RecordingError, StepRecord, _plain, recording_file
from .reader import Recording
from .writer import Hdf5Recorder, storage_filters


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
