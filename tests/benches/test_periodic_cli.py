"""``tablebench periodic`` end to end: .npy and HDF5-recording input, JSON/PNG output, user errors."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
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


def test_json_has_explicit_units_and_settled_status(
    npy: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["periodic", str(npy), "--rate", "1000", "--channels", "ch0", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert sum(ln.startswith(("all settled", "not settled")) for ln in text.splitlines()) == 1  # one line
    assert "all settled" in text
    doc = json.loads((tmp_path / "periodic.json").read_text())
    ch = doc["channels"]["ch0"]
    assert ch["unit"] == "SI" and ch["psd_unit"] == "(SI)^2/Hz"  # .npy input: SI of unknown kind
    # every number in the channel is either unit-suffixed (_hz, _rad, _db, _samples/_seconds) or listed in units
    for key, value in ch.items():
        if isinstance(value, float) and not key.endswith(("_hz", "_rad", "_db")):
            assert key in ch["units"], key
    for term in ch["terms"]:
        assert term["amplitude_unit"] == "SI"
        for key, value in term.items():
            if isinstance(value, float) and not key.endswith(("_hz", "_rad", "_db")):
                assert f"terms[].{key}" in ch["units"], key
    for key in ("residual_rms", "periodic_rms", "bandwidth_hz", "bandwidth_lost"):
        assert f"comparison[].{key}" in ch["units"]
    assert ch["unsettled"] == [] and doc["unsettled"] == []
    assert ch["identification"]["method"] == "lm" and ch["identification"]["converged"] is True
    lo, hi = ch["identification"]["search_band_hz"]
    assert 0 < lo < 80.13 and 127.43 < hi < 500


def test_recording_channels_carry_their_si_unit(tmp_path: Path) -> None:
    doc = analyse_periodic({"gyro_x": gyro_record(12_000)}, FS, units={"gyro_x": "rad/s"})
    ch = doc["channels"]["gyro_x"]
    assert ch["unit"] == "rad/s" and ch["terms"][0]["amplitude_unit"] == "rad/s"
    assert ch["units"]["offset"] == "rad/s" and ch["units"]["psd_median_after"] == "(rad/s)^2/Hz"


def test_grid_method_reproduces_the_paper_and_agrees(npy: Path, tmp_path: Path) -> None:
    out_lm, out_grid = tmp_path / "lm", tmp_path / "grid"
    assert main(["periodic", str(npy), "--rate", "1000", "--channels", "ch0", "--out", str(out_lm)]) == 0
    args = ["periodic", str(npy), "--rate", "1000", "--channels", "ch0", "--method", "grid", "--out", str(out_grid)]
    assert main(args) == 0
    lm = json.loads((out_lm / "periodic.json").read_text())["channels"]["ch0"]
    grid = json.loads((out_grid / "periodic.json").read_text())["channels"]["ch0"]
    assert grid["identification"]["method"] == "grid"
    for a, b in zip(lm["terms"], grid["terms"], strict=True):
        assert abs(a["frequency_hz"] - b["frequency_hz"]) < 0.5 * a["frequency_sigma_hz"]


def test_unsettled_items_are_one_line_and_in_the_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A fit that did not converge (LM and grid both capped: simulated) is listed in periodic.json and in one
    line of text."""
    from analysis.periodic import identify
    from analysis.periodic.model import FitReport

    def capped(x, rate_hz, f0, half, **kw):  # noqa: ANN001, ANN003, ANN202
        return np.array(f0), FitReport(method="grid", converged=False, message="frequencies still moving")

    monkeypatch.setattr(identify, "refine_frequencies", capped)
    monkeypatch.setattr(
        identify, "refine_lm", lambda x, r, f0, h: (np.array(f0), FitReport(converged=False, message="cap"))
    )
    p = tmp_path / "g.npy"
    np.save(p, gyro_record(12_000))
    assert main(["periodic", str(p), "--rate", "1000", "--out", str(tmp_path / "o")]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith(("not settled", "all settled"))]
    assert len(lines) == 1 and lines[0].startswith("not settled: ch0: grid refinement did not converge")
    doc = json.loads((tmp_path / "o" / "periodic.json").read_text())
    assert doc["channels"]["ch0"]["identification"]["converged"] is False
    assert doc["channels"]["ch0"]["identification"]["fallback"] is True
    assert any("did not converge" in s for s in doc["unsettled"])


def test_plot_returns_a_figure_and_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from matplotlib.figure import Figure

    from analysis.periodic.plot import plot_channel
    from analysis.periodic.report import analyse_channel

    monkeypatch.chdir(tmp_path)
    res = analyse_channel(gyro_record(12_000), FS, 8.0)
    fig = plot_channel(res, FS, "gyro_x", "deg/s", DEG)
    assert isinstance(fig, Figure) and list(tmp_path.iterdir()) == []
