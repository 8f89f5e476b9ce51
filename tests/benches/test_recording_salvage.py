"""A damaged recording: resume refuses it and says how to recover; --salvage keeps the intact steps, which
resume can continue; the reader names the damaged dataset and step."""

from __future__ import annotations

import h5py  # only to locate a chunk to damage
import numpy as np
import pytest

from benches.cli import main
from benches.recording import Hdf5Recorder, RecordingDamaged, StepRecord, open_recording, salvage
from drivers.protocols import ImuBlock, TableState, TableStatus

ROWS = 20_000  # per step; chunks hold 16384 rows, so the steps straddle chunk boundaries


def _write(path, steps: int = 5) -> None:
    rng = np.random.default_rng(1)
    rec = Hdf5Recorder(path, attrs={"sample_rate_hz": 100.0, "seed": 3}, quanta={"accel": 1e-6, "time": 1e-9})
    n = 0
    for k in range(steps):
        for a in range(0, ROWS, 5000):
            m = 5000
            idx = np.arange(n + a, n + a + m)
            rec.add_samples(
                ImuBlock(
                    counter=idx.astype(np.uint32),
                    time=np.rint(idx * 1e7) * 1e-9,
                    accel=np.rint(rng.normal(0, 50, (m, 3)) + [0, 0, 9.8e6]) * 1e-6,
                    gyro=rng.normal(0, 1e-5, (m, 3)),
                    temperature=np.full(m, 300.0),
                    status=np.zeros(m, np.uint16),
                )
            )
            rec.add_table(TableState((n + a + m) / 100.0, np.zeros(3), np.zeros(3), TableStatus.IN_POSITION))
        rec.end_step(StepRecord(k, f"hold-{k}", "hold", "A", n, n, n + ROWS, n + ROWS, "complete"))
        n += ROWS
    rec.set_status("interrupted")
    rec.close()


def _damage_chunk(path, dataset: str, row: int) -> None:
    with h5py.File(path, "r") as f:
        d = f[dataset]
        info = d.id.get_chunk_info_by_coord((row // d.chunks[0] * d.chunks[0],) + (0,) * (d.ndim - 1))
        off = info.byte_offset + info.size // 3
    data = bytearray(path.read_bytes())
    data[off] ^= 0x5A
    path.write_bytes(bytes(data))


def test_damage_is_named_and_salvage_keeps_the_intact_steps(tmp_path, capsys):
    run = tmp_path / "runs" / "r"
    run.mkdir(parents=True)
    rec = run / "recording.h5"
    _write(rec)
    with open_recording(rec) as r:
        ref = r.samples()
        assert r.integrity_verified and len(r.steps) == 5
    _damage_chunk(rec, "imu/accel", 3 * ROWS + 10)  # inside step 3
    with pytest.raises(RecordingDamaged, match=r"/imu/accel rows .*step.* 'hold-3'"):
        open_recording(rec)
    capsys.readouterr()
    assert main(["run", "--resume", str(run)]) == 2
    err = capsys.readouterr().err
    assert "damaged" in err and "--salvage" in err and len(err.strip().splitlines()) == 1
    kept = salvage(rec, tmp_path / "salvaged.h5")
    with open_recording(tmp_path / "salvaged.h5") as s:
        assert kept == len(s.steps) == 2  # the chunk holding rows 49152–65535 also holds step 2's end
        assert s.header.status == "interrupted" and s.header.seed == 3
        got = s.samples()
        for name in ("counter", "time", "accel", "gyro"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name)[: 2 * ROWS])
    assert main(["runs", "--salvage", str(run)]) == 0
    assert (tmp_path / "runs" / "r-salvaged" / "recording.h5").exists()
    # a salvaged recording can be continued (the recorder accepts it for resume)
    Hdf5Recorder(tmp_path / "salvaged.h5", resume=True).close()
