"""Issues 8/18: a run stopped by SIGINT, SIGTERM, SIGHUP or SIGKILL keeps every completed step, the recording
stays readable, and --resume gives a recording equal bit for bit to the uninterrupted run on both streams
(unit samples and table readings); resume refuses another seed; a complete recording whose identification or
certificate was not done is finished by --resume."""

from __future__ import annotations

import os
import signal
import subprocess

import numpy as np
import pytest

from benches.recording import open_recording
from tests.simbench import CLI, bench_variant, short_ten_step, start_cli, wait_for_step

SHORT = short_ten_step(hold_s=3, warmup_s=5)


def _contents(path):
    """Status, steps, and both streams of the completed steps (the reader verifies every checksum)."""
    with open_recording(path) as rec:
        steps = rec.steps
        done = rec.complete_steps()
        end = done[-1].end_sample if done else 0
        t_end = done[-1].table_end if done else 0
        smp = rec.samples(0, end)
        return rec.header.status, steps, smp, rec.table(0, t_end)


def _assert_same_streams(a, b, n: int, m: int) -> None:
    for name in ("counter", "time", "accel", "gyro", "temperature", "status"):
        np.testing.assert_array_equal(getattr(a[2], name)[:n], getattr(b[2], name)[:n], err_msg=name)
    for name in ("time", "angles", "rates", "status"):
        np.testing.assert_array_equal(getattr(a[3], name)[:m], getattr(b[3], name)[:m], err_msg=f"table {name}")


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("interrupt")
    bench = bench_variant(tmp, rate=200.0)
    proc = tmp / "short-ten-step.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    common = ["--bench", str(bench), "--procedure", str(proc), "--seed", "5", "--plain", "--no-identify"]
    ref = subprocess.run(CLI + ["run", *common, "--out", str(tmp / "ref")], cwd=tmp, capture_output=True, text=True)
    assert ref.returncode == 0, ref.stderr[-2000:]
    return tmp, common, _contents(tmp / "ref" / "recording.h5")


CASES = [
    pytest.param(signal.SIGINT, "A/hold-3", id="SIGINT-A"),
    pytest.param(signal.SIGTERM, "B/hold-2", id="SIGTERM-B"),
    pytest.param(signal.SIGHUP, "B/spin", id="SIGHUP-Bspin"),
    pytest.param(signal.SIGKILL, "C/hold-1", id="SIGKILL-C"),
    pytest.param(signal.SIGHUP, "A/hold", marks=pytest.mark.slow, id="SIGHUP-A"),
    pytest.param(signal.SIGKILL, "A/spin", marks=pytest.mark.slow, id="SIGKILL-Aspin"),
    pytest.param(signal.SIGINT, "C/spin", marks=pytest.mark.slow, id="SIGINT-Cspin"),
    pytest.param(signal.SIGTERM, "C/hold-6", marks=pytest.mark.slow, id="SIGTERM-C"),
]


@pytest.mark.parametrize(("sig", "where"), CASES)
def test_stopped_run_keeps_completed_steps_and_resumes_bit_for_bit(setup, sig, where):
    tmp, common, ref = setup
    ref_status, ref_steps, _ref_smp, _ref_tab = ref
    out = tmp / f"stopped-{sig.name}-{where.replace('/', '_')}"
    proc = start_cli(["run", *common, "--out", str(out)], tmp)
    wait_for_step(proc, where)
    os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=120)
    if sig != signal.SIGKILL:  # the safe stop: table at rest, recording closed, how to resume
        assert proc.returncode == 130, err[-2000:]
        assert f"{sig.name} received" in err and f"tablebench run --resume {out}" in err
    part = _contents(out / "recording.h5")  # readable (and verified) after the stop
    status, steps, _, _ = part
    done = [s for s in steps if s.status == "complete"]
    assert len(done) >= 2 and status in ("interrupted", "running")
    if sig != signal.SIGKILL:
        assert status == "interrupted" and steps[-1].status == "interrupted"
    for s in done:  # every completed step equals the uninterrupted run's, both streams (its SHA-256)
        r = next(x for x in ref_steps if x.name == s.name)
        assert repr(s) == repr(r)  # repr: NaN angles of spins compare equal
    _assert_same_streams(part, ref, done[-1].end_sample, done[-1].table_end)
    res = subprocess.run(CLI + ["run", "--resume", str(out), "--plain"], cwd=tmp, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    final = _contents(out / "recording.h5")
    assert final[0] == "complete" == ref_status
    # indices, table ranges and per-step SHA-256 (samples + table readings)
    assert list(map(repr, final[1])) == list(map(repr, ref_steps))
    assert len(final[2]) == len(ref[2]) and len(final[3]) == len(ref[3])
    _assert_same_streams(final, ref, len(ref[2]), len(ref[3]))


def test_resume_refuses_another_seed_and_finishes_a_complete_run(setup):
    tmp, common, _ = setup
    out = tmp / "seeded"
    proc = start_cli(["run", *common, "--out", str(out)], tmp)
    wait_for_step(proc, "A/hold-1")
    os.kill(proc.pid, signal.SIGINT)
    proc.communicate(timeout=120)
    res = subprocess.run(CLI + ["run", "--resume", str(out), "--seed", "6"], cwd=tmp, capture_output=True, text=True)
    assert res.returncode == 2 and "--seed 6 differs from the run's recorded seed 5" in res.stderr
    assert "Traceback" not in res.stderr
    # the run recorded without identification: --resume finishes what was not done
    ref = tmp / "ref"
    res = subprocess.run(CLI + ["run", "--resume", str(ref), "--plain"], cwd=tmp, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "finishing what was not done: identification, certificate" in res.stderr
    assert (ref / "calibration.json").exists() and (ref / "certificate.pdf").exists()
    res = subprocess.run(CLI + ["run", "--resume", str(ref)], cwd=tmp, capture_output=True, text=True)
    assert res.returncode == 2 and "nothing to resume" in res.stderr


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


@pytest.mark.parametrize("seed", ["-1", str(2**64), str(2**70)])
def test_bad_seed_is_one_line_before_any_run_folder(tmp_path, seed):
    res = subprocess.run(
        CLI + ["run", "--seed", seed, "--out", str(tmp_path / "r")], cwd=tmp_path, capture_output=True, text=True
    )
    assert res.returncode == 2 and "--seed" in res.stderr and "Traceback" not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists() and not (tmp_path / "runs").exists()


def test_out_that_cannot_be_created_is_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    res = subprocess.run(
        CLI + ["run", "--no-identify", "--out", str(blocker / "sub" / "run")],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert res.returncode == 2 and "--out" in res.stderr and "Traceback" not in res.stderr
    assert res.stderr.strip().splitlines()[-1].startswith("tablebench run: error:")


def test_resume_of_a_damaged_recording_is_a_clear_error(tmp_path):
    run = tmp_path / "bad"
    run.mkdir()
    (run / "recording.h5").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    res = subprocess.run(CLI + ["run", "--resume", str(run)], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 2
    assert "recording.h5" in res.stderr and "Traceback" not in res.stderr


def test_interruption_after_the_recording_completed_says_what_is_left(setup, monkeypatch, capsys):
    """Ctrl-C (or SIGTERM/SIGHUP) during identification: the recording is complete; say what was not done."""
    import benches.identify
    from benches.cli import main

    tmp, common, _ = setup
    out = tmp / "late"
    assert main(["run", *common, "--out", str(out)]) == 0  # recorded only (--no-identify)

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(benches.identify, "identify_run", interrupted)
    capsys.readouterr()
    assert main(["run", "--resume", str(out), "--plain"]) == 130
    err = capsys.readouterr().err
    assert "not done: identification, certificate" in err and f"tablebench run --resume {out}" in err
    assert not (out / "calibration.json").exists()
