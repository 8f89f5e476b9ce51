"""Runner and recorder on a fake bench: step table, flushing, interruption, resume, limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benches.recording import Hdf5Recorder, open_recording
from benches.runner import Runner
from drivers.protocols import TableError
from tests.fakes import FakeClock, FakeStep, FakeTable, FakeUnit, fake_steps


def _run(tmp_path, steps, *, fail_after=None, replay=(), resume=False, start_sample=0, name="recording.h5"):
    clock = FakeClock(100.0)
    table = FakeTable(clock, fail_after=fail_after)
    unit = FakeUnit(clock)
    rec = Hdf5Recorder(tmp_path / name, attrs={"sample_rate_hz": 100.0}, resume=resume, checkpoint_samples=150)
    runner = Runner(table, unit, steps, rec, position_tolerance=1e-6, block_seconds=0.1)
    try:
        result = runner.run(replay=replay, start_sample=start_sample)
    finally:
        rec.close()
    return result, table


def test_complete_run_records_every_step_with_consistent_ranges(tmp_path):
    result, table = _run(tmp_path, fake_steps())
    assert result.status == "complete"
    with open_recording(tmp_path / "recording.h5") as f:
        steps = f.steps
        n = f.n_samples
        assert f.header.status == "complete"
        assert [s.name for s in steps] == [s.name for s in fake_steps()]
        assert all(s.status == "complete" for s in steps)
        for a, b in zip(steps, steps[1:], strict=False):
            assert a.end_sample == b.start_sample
        hold = steps[2]
        assert hold.acq_end - hold.acq_start == 300  # 3 s at 100 Hz, after 0.5 s settle
        assert hold.acq_start - hold.start_sample == 50
        spin = steps[3]
        assert spin.acq_end - spin.acq_start == 1200
        # samples are contiguous and counted from 0; table read and heartbeat sent once per block (0.1 s)
        assert np.array_equal(f.samples(fields=("counter",)).counter, np.arange(n, dtype=np.uint32))
        assert f.n_table >= n // 10
        messages = [e.message for e in f.events()]
        assert any("note: done" in m for m in messages)
    assert table.heartbeats >= n // 10
    # the table was left at rest
    assert table.commands[-1] == ("stop",)
    assert np.all(table.rates == 0)


def test_out_of_limit_command_refused_before_any_motion(tmp_path):
    steps = [FakeStep(0, "fast", "spin", axis=0, rate=math.radians(500), duration=1.0)]
    clock = FakeClock(100.0)
    table = FakeTable(clock)
    rec = Hdf5Recorder(tmp_path / "r.h5", attrs={"sample_rate_hz": 100.0})
    with pytest.raises(TableError, match="nothing moved"):
        Runner(table, FakeUnit(clock), steps, rec, position_tolerance=1e-6).run()
    rec.close()
    assert table.commands == []


def test_fault_stops_the_table_and_marks_the_step(tmp_path):
    result, table = _run(tmp_path, fake_steps(), fail_after=4.0)
    assert result.status == "failed" and "STALL" in result.reason
    with open_recording(tmp_path / "recording.h5") as f:
        steps = f.steps
        assert f.header.status == "failed"
        assert steps[-1].status == "failed"
        assert all(s.status == "complete" for s in steps[:-1])
    assert ("stop",) in table.commands


def test_resume_by_replay_equals_uninterrupted_run(tmp_path):
    full, _ = _run(tmp_path, fake_steps(), name="full.h5")
    part, _ = _run(tmp_path, fake_steps(), fail_after=7.0, name="part.h5")
    assert part.status == "failed"
    with open_recording(tmp_path / "part.h5") as f:
        done = f.complete_steps()
    start = done[-1].end_sample
    resumed, _ = _run(
        tmp_path, fake_steps(), replay=[s.index for s in done], resume=True, start_sample=start, name="part.h5"
    )
    assert resumed.status == "complete"
    with open_recording(tmp_path / "full.h5") as a, open_recording(tmp_path / "part.h5") as b:
        sa, sb = a.steps, b.steps
        assert [(s.name, s.start_sample, s.acq_start, s.acq_end, s.end_sample) for s in sa] == [
            (s.name, s.start_sample, s.acq_start, s.acq_end, s.end_sample) for s in sb
        ]
        last = sa[-1].end_sample
        assert np.array_equal(a.samples(0, last).accel, b.samples(0, last).accel)
        assert np.array_equal(a.table().time, b.table().time)  # the table stream too
        assert [s.sha256 for s in sa] == [s.sha256 for s in sb]
        assert b.header.status == "complete"


def test_lost_link_stops_cleanly_and_records_the_failed_step(tmp_path):
    from drivers.protocols import LinkError

    class FlakyTable(FakeTable):
        def read_state(self):
            if self.clock.time > 5.0:
                raise LinkError("controller stopped answering (timeout 0.5 s)")
            return super().read_state()

    clock = FakeClock(100.0)
    table = FlakyTable(clock)
    rec = Hdf5Recorder(tmp_path / "r.h5", attrs={"sample_rate_hz": 100.0})
    result = Runner(table, FakeUnit(clock), fake_steps(), rec, position_tolerance=1e-6).run()
    rec.close()
    assert result.status == "failed" and "link lost" in result.reason
    assert ("stop",) in table.commands  # the stop was still sent on the command channel
    with open_recording(tmp_path / "r.h5") as f:
        steps = f.steps
        assert f.header.status == "failed" and steps[-1].status == "failed"
        assert all(s.status == "complete" for s in steps[:-1])
