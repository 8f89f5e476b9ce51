"""Issue 8: killing a run (SIGINT, SIGKILL) keeps every completed step; --resume equals an uninterrupted run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from benches.recording import open_recording
from tests.simbench import bench_variant

CLI = [sys.executable, "-m", "benches.cli"]


def _start(args: list[str], cwd) -> subprocess.Popen:
    return subprocess.Popen(
        CLI + args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )


def _wait_for_step(proc: subprocess.Popen, marker: str, timeout: float = 120.0) -> None:
    t0 = time.monotonic()
    assert proc.stderr is not None
    for line in proc.stderr:
        if line.startswith(f"step {marker}"):
            return
        if time.monotonic() - t0 > timeout:
            break
    raise AssertionError(f"step {marker} never started")


def _steps_and_data(path):
    with open_recording(path) as rec:
        steps = rec.steps
        end = steps[-1].end_sample if steps else 0
        smp = rec.samples(0, end, ("accel", "counter"))
        return rec.header.status, steps, smp.accel, smp.counter


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("interrupt")
    bench = bench_variant(tmp, rate=200.0)
    common = ["--bench", str(bench), "--procedure", "ten-step", "--seed", "5", "--plain", "--no-identify"]
    ref = subprocess.run(CLI + ["run", *common, "--out", str(tmp / "ref")], cwd=tmp, capture_output=True, text=True)
    assert ref.returncode == 0, ref.stderr[-2000:]
    return tmp, common, _steps_and_data(tmp / "ref" / "recording.h5")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
def test_killed_run_keeps_completed_steps_and_resumes_to_the_same_data(setup, sig):
    tmp, common, (ref_status, ref_steps, ref_accel, ref_counter) = setup
    out = tmp / f"killed-{sig.name}"
    proc = _start(["run", *common, "--out", str(out)], tmp)
    _wait_for_step(proc, "B/hold-2")
    os.kill(proc.pid, sig)
    proc.wait(timeout=60)
    if sig == signal.SIGINT:
        assert proc.returncode == 130
    status, steps, accel, _ = _steps_and_data(out / "recording.h5")  # readable after the kill
    done = [s for s in steps if s.status == "complete"]
    assert len(done) >= 10 and status in ("interrupted", "running")
    for s in done:  # every completed step equals the uninterrupted run's
        r = next(x for x in ref_steps if x.name == s.name)
        assert (s.start_sample, s.acq_start, s.acq_end, s.end_sample) == (
            r.start_sample,
            r.acq_start,
            r.acq_end,
            r.end_sample,
        )
    np.testing.assert_array_equal(accel[: done[-1].end_sample], ref_accel[: done[-1].end_sample])
    res = subprocess.run(CLI + ["run", "--resume", str(out), "--plain"], cwd=tmp, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    status, steps, accel, counter = _steps_and_data(out / "recording.h5")
    assert status == "complete" and ref_status == "complete"
    assert [(s.name, s.start_sample, s.acq_end, s.end_sample, s.status) for s in steps] == [
        (s.name, s.start_sample, s.acq_end, s.end_sample, s.status) for s in ref_steps
    ]
    np.testing.assert_array_equal(accel, ref_accel)
    np.testing.assert_array_equal(counter, ref_counter)


def test_bad_procedure_exits_2_and_nothing_moves(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nsteps:\n  - spin: {axis: y, rate_dps: 5000, revolutions: 1}\n", encoding="utf-8")
    res = subprocess.run(
        CLI + ["run", "--procedure", str(bad), "--out", str(tmp_path / "r")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2
    assert "bad.yaml:3" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "r" / "recording.h5").exists()


def test_resume_of_a_damaged_recording_is_a_clear_error(tmp_path):
    run = tmp_path / "bad"
    run.mkdir()
    (run / "recording.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    res = subprocess.run(CLI + ["run", "--resume", str(run)], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 2
    assert "recording.h5" in res.stderr and "Traceback" not in res.stderr
