"""``tablebench periodic`` end to end: .npy and HDF5-recording input, JSON/PNG output, user errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.periodic.report import analyse_periodic
from analysis.units import DEG
from benches.cli import main

FS = 1000.0
FREQS = [80.13, 83.08, 127.43]
AMPS = [0.6 * DEG, 0.4 * DEG, 0.3 * DEG]
SIGMA = 0.108 * DEG


def gyro_record(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    j = np.arange(n)
    x = 0.01 + sum(
        a * np.cos(2 * np.pi * f * j / FS + 0.3 * i) for i, (f, a) in enumerate(zip(FREQS, AMPS, strict=True))
    )
    return x + SIGMA * rng.standard_normal(n)


@pytest.fixture(scope="module")
def npy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("periodic") / "gyro.npy"
    rng = np.random.default_rng(9)
    np.save(p, np.column_stack([gyro_record(16_000), SIGMA * rng.standard_normal(16_000)]))
    return p


def test_npy_input_writes_json_and_png(npy: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["periodic", str(npy), "--rate", "1000", "--out", str(tmp_path)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "80.13" in text and "average 10" in text and "low-pass" in text
    doc = json.loads((tmp_path / "periodic.json").read_text())
    ch0, ch1 = doc["channels"]["ch0"], doc["channels"]["ch1"]
    for key in ("terms", "offset", "residual_rms_before", "residual_rms_after"):
        assert key in ch0
    assert {"frequency_hz", "frequency_sigma_hz", "amplitude", "phase_rad"} <= set(ch0["terms"][0])
    found = sorted(t["frequency_hz"] for t in ch0["terms"])
    assert np.allclose(found, FREQS, atol=2e-3)
    assert ch0["residual_rms_after"] == pytest.approx(SIGMA, rel=0.03)
    assert ch0["residual_rms_before"] > 4 * SIGMA
    assert ch1["terms"] == [] and ch1["residual_rms_after"] == ch1["residual_rms_before"]
    assert (tmp_path / "periodic_ch0.png").stat().st_size > 10_000


def test_terms_override_and_calibration_length(npy: Path, tmp_path: Path) -> None:
    rc = main(["periodic", str(npy), "--rate", "1000", "--channels", "ch0", "--terms", "2",
               "--calibrate-seconds", "5", "--out", str(tmp_path)])  # fmt: skip
    assert rc == 0
    doc = json.loads((tmp_path / "periodic.json").read_text())
    assert len(doc["channels"]["ch0"]["terms"]) == 2
    assert doc["channels"]["ch0"]["identification"]["calibration_samples"] == 5000


def test_recording_input(tmp_path: Path) -> None:
    h5py = pytest.importorskip("h5py")
    n = 12_000
    gyro = np.zeros((n, 3))
    gyro[:, 2] = gyro_record(n, seed=4)
    with h5py.File(tmp_path / "recording.h5", "w") as fh:
        fh.attrs["format"] = "tablebench-recording"
        fh.attrs["sample_rate_hz"] = FS
        fh.create_dataset("imu/accel", data=np.zeros((n, 3)))
        fh.create_dataset("imu/gyro", data=gyro)
    out = tmp_path / "out"
    assert main(["periodic", str(tmp_path), "--channels", "gyro_z", "--out", str(out)]) == 0
    doc = json.loads((out / "periodic.json").read_text())
    assert len(doc["channels"]["gyro_z"]["terms"]) == 3


@pytest.mark.parametrize(
    "args, message",
    [
        # the analysis names its parameter, the command maps it to the option
        (["--calibrate-seconds", "30"], "--calibrate-seconds 30.0: the record has 16000 samples"),
        (["--calibrate-seconds", "30"], "shorten the calibration"),
        (["--calibrate-seconds", "0.01"], "--calibrate-seconds 0.01: a calibration of 0.01 s"),
        (["--calibrate-seconds", "0.01"], "at least"),
        (["--false-alarm", "1.5"], "--false-alarm must be a probability"),
        (["--calibrate-seconds", "nan"], "positive"),
        (["--terms", "-1"], "between 0 and 30"),
        (["--channels", "nope"], "unknown channel"),
    ],
)
def test_user_errors_are_one_line_exit_2(
    npy: Path, args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = main(["periodic", str(npy), "--rate", "1000", *args])
    err = capsys.readouterr().err
    assert rc == 2
    assert message in err and "Traceback" not in err and err.count("\n") == 1


def test_missing_rate_is_reported(npy: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["periodic", str(npy)]) == 2
    assert "--rate" in capsys.readouterr().err


def test_analyse_periodic_structure_for_the_certificate() -> None:
    doc = analyse_periodic({"gyro_x": gyro_record(12_000)}, FS, calibrate_seconds=8.0)
    ch = doc["channels"]["gyro_x"]
    assert len(ch["terms"]) == 3
    assert ch["residual_rms_after"] < ch["residual_rms_before"]
    json.dumps(doc, allow_nan=False)
