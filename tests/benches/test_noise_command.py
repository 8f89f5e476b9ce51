"""``tablebench noise``: inputs (recording, .npy, .csv), outputs (noise.json, noise.png), clear errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from analysis.noise.plot import plot_noise
from analysis.noise.terms import analyse_noise
from benches.cli import main


def _write_recording(path: Path, accel: np.ndarray, gyro: np.ndarray, rate: float) -> None:
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w") as fh:
        fh.attrs["format"] = "tablebench-recording"
        fh.attrs["sample_rate_hz"] = rate
        fh.create_dataset("imu/accel", data=accel)
        fh.create_dataset("imu/gyro", data=gyro)


def test_npy_input_writes_json_and_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(1)
    rate, sw = 100.0, 2e-3
    np.save(tmp_path / "d.npy", rng.normal(0.0, sw, (40_000, 2)))
    rc = main(
        ["noise", str(tmp_path / "d.npy"), "--rate", "100", "--out", str(tmp_path / "out"), "--published-itotvar"]
    )
    assert rc == 0
    text = capsys.readouterr().out
    assert "ch0" in text and "N" in text
    data = json.loads((tmp_path / "out" / "noise.json").read_text())
    ch = data["channels"]["ch1"]
    assert {"tau", "adev", "oadev", "totdev", "mdev", "terms", "itotdev_published"} <= set(ch)
    assert set(ch["terms"]["N"]) >= {"value", "sigma", "unit"}
    assert ch["terms"]["N"]["value"] == pytest.approx(sw / math.sqrt(rate), rel=0.05)
    assert (tmp_path / "out" / "noise.png").stat().st_size > 10_000


def test_recording_input_uses_si_channels_and_display_units(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(2)
    n, rate = 20_000, 200.0
    accel = rng.normal(0.0, 1e-3, (n, 3)) + [0.0, 0.0, 9.81]
    gyro = rng.normal(0.0, 1e-4, (n, 3))
    run = tmp_path / "run1"
    run.mkdir()
    _write_recording(run / "recording.h5", accel, gyro, rate)
    rc = main(["noise", str(run), "--channels", "gyro_z,accel_z", "--out", str(tmp_path / "o")])
    assert rc == 0
    out = capsys.readouterr().out
    assert "deg/√h" in out and "µg/√Hz" in out
    data = json.loads((tmp_path / "o" / "noise.json").read_text())
    assert set(data["channels"]) == {"gyro_z", "accel_z"}
    assert data["channels"]["gyro_z"]["terms"]["N"]["unit"] == "rad/s^0.5"
    assert data["channels"]["accel_z"]["terms"]["N"]["value"] == pytest.approx(1e-3 / math.sqrt(rate), rel=0.05)


@pytest.mark.parametrize(
    ("content", "args", "message"),
    [
        ("nan", ["--rate", "10"], "non-finite"),
        ("text", ["--rate", "10"], "non-numeric"),
        ("ok", [], "--rate HZ is required"),
        ("ok", ["--rate", "-5"], "positive"),
        ("short", ["--rate", "10"], "at least 64"),
        ("ok", ["--rate", "10", "--confidence", "1.5"], "--confidence"),
        ("constant", ["--rate", "10"], "channel 'gy'"),
    ],
)
def test_bad_input_is_one_clear_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, args: list[str], message: str
) -> None:
    f = tmp_path / "d.csv"
    rows = np.random.default_rng(3).normal(size=(500, 2))
    if content == "nan":
        rows[17, 1] = np.nan
    if content == "short":
        rows = rows[:20]
    if content == "constant":
        rows[:, 1] = 0.25
    text = "\n".join(",".join(f"{v}" for v in r) for r in rows)
    if content == "text":
        text += "\n1.0,abc"
    f.write_text("gx,gy\n" + text + "\n")
    rc = main(["noise", str(f), *args])
    err = capsys.readouterr().err
    assert rc == 2
    assert message in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_all_taus_refused_on_long_records(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    np.save(tmp_path / "d.npy", np.zeros(300_000))
    assert main(["noise", str(tmp_path / "d.npy"), "--rate", "10", "--taus", "all"]) == 2
    assert "O(N²)" in capsys.readouterr().err


def test_plot_noise_is_usable_from_the_result_dict(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    res = analyse_noise({"gyro_x": rng.normal(0, 1e-4, 8192)}, 100.0, {"gyro_x": "rad/s"})
    p = plot_noise(res, tmp_path / "n.png", title="t")
    assert p.exists() and p.stat().st_size > 5_000
