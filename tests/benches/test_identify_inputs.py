"""Issue 3: recordings that cannot be identified get a clear message (CLI exit 2, no traceback)."""

from __future__ import annotations

import shutil

import h5py
import pytest

from benches.cli import main
from benches.identify import IdentificationError, identify_run
from tests.simbench import bench_variant, run_procedure


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("idin")
    bench = bench_variant(tmp, rate=50.0)
    proc = tmp / "short.yaml"
    proc.write_text(
        "name: short\nsteps:\n  - orient: {x: East, y: North, z: Up}\n  - hold: {duration_s: 20}\n"
        "  - orient: {x: Up, y: East, z: North}\n  - hold: {duration_s: 20}\n",
        encoding="utf-8",
    )
    warm = tmp / "warm.yaml"
    warm.write_text("name: warm-only\nsteps:\n  - warmup: {duration_s: 5, at: {x: East, y: North, z: Up}}\n")
    return tmp, run_procedure(tmp, bench, str(proc), seed=1), run_procedure(tmp, bench, str(warm), seed=1, out="w")


def test_truncated_recording_is_refused_clearly(short_run, tmp_path, capsys):
    _tmp, run, _w = short_run
    data = (run / "recording.h5").read_bytes()
    bad = tmp_path / "cut.h5"
    bad.write_bytes(data[: len(data) // 3])
    assert main(["identify", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "cut.h5" in err and "truncated" in err and "Traceback" not in err


def test_recording_without_truth_identifies_and_says_so(short_run, tmp_path, capsys):
    _tmp, run, _w = short_run
    copy = tmp_path / "real"
    shutil.copytree(run, copy)
    with h5py.File(copy / "recording.h5", "r+") as f:
        del f["truth"]
    result = identify_run(copy).to_dict()
    assert result["truth"] is None
    assert result["information"]["rank"] < 18 and result["information"]["unidentifiable"]
    assert main(["identify", str(copy), "--out", str(tmp_path / "c.json")]) == 0
    assert "no simulator truth" in capsys.readouterr().out


def test_recording_without_hold_or_spin_is_refused_clearly(short_run, capsys):
    _tmp, _run, warm = short_run
    with pytest.raises(IdentificationError, match="no complete hold or spin"):
        identify_run(warm)
    assert main(["identify", str(warm)]) == 2
    assert "run a calibration procedure" in capsys.readouterr().err
