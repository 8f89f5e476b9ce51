"""``tablebench noise``: inputs (recording, .npy, .csv), outputs (noise.json, noise.png), clear errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.noise.plot import plot_noise
from analysis.noise.terms import analyse_noise
from benches.cli import main


def _write_recording(path: Path, accel: np.ndarray, gyro: np.ndarray, rate: float) -> None:
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
        ("inf", ["--rate", "10"], "non-finite"),
        ("ok", ["--rate", "10", "--channels", ""], "--channels is empty"),
        ("ok", ["--rate", "10", "--estimators", "adev,avar"], "unknown avar"),
        ("ok", ["--rate", "10", "--taus", "weekly"], "--taus"),
        ("ok", ["--rate", "10", "--taus", "1,-2"], "positive"),
        ("text", ["--rate", "10"], "non-numeric"),
        ("ok", [], "--rate HZ is required"),
        ("ok", ["--rate", "-5"], "positive"),
        ("short", ["--rate", "10"], "at least 64"),
        ("ok", ["--rate", "10", "--confidence", "1.5"], "--confidence"),
        ("constant", ["--rate", "10"], "channel 'gy'"),
        ("ok", ["--rate", "10", "--fit-estimator", "mdev"], "--fit-estimator mdev: its noise terms have no fixed"),
        ("ok", ["--rate", "10", "--fit-estimator", "theo1"], "--fit-estimator theo1: it is biased"),
        ("ok", ["--rate", "10", "--fit-estimator", "avar"], "--fit-estimator avar: unknown estimator"),
    ],
)
def test_bad_input_is_one_clear_line_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, args: list[str], message: str
) -> None:
    f = tmp_path / "d.csv"
    rows = np.random.default_rng(3).normal(size=(500, 2))
    if content == "inf":
        rows[17, 1] = np.inf
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
    np.save(tmp_path / "d.npy", np.random.default_rng(0).standard_normal(300_000))  # not constant: that is refused
    assert main(["noise", str(tmp_path / "d.npy"), "--rate", "10", "--taus", "all"]) == 2
    assert "O(N²)" in capsys.readouterr().err


def test_plot_noise_returns_a_figure_of_every_estimator(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    res = analyse_noise(
        {"gyro_x": rng.normal(0, 1e-4, 8192)}, 100.0, {"gyro_x": "rad/s"}, estimators=("oadev", "hdev", "tdev", "mtie")
    )
    fig = plot_noise(res, title="t")
    labels = {t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()}
    assert {"OADEV", "HDEV", "TDEV", "MTIE"} <= labels
    assert "deviation (deg/h)" in fig.axes[0].get_ylabel()
    fig.savefig(tmp_path / "n.png")
    assert (tmp_path / "n.png").stat().st_size > 5_000


def test_estimators_taus_and_per_tau_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--estimators/--taus LIST/--data-type phase; noise.json has value, terms, EDF, interval, α per τ."""
    rng = np.random.default_rng(5)
    rate = 50.0
    rate_rec = rng.normal(0.0, 1e-3, 6000)
    np.save(tmp_path / "angle.npy", np.cumsum(rate_rec) / rate)
    rc = main(
        [
            "noise", str(tmp_path / "angle.npy"), "--rate", "50", "--data-type", "phase",
            "--estimators", "oadev,htotdev,theo1,mtie", "--taus", "0.02,0.1,1,4", "--out", str(tmp_path / "o"),
        ]
    )
    assert rc == 0
    data = json.loads((tmp_path / "o" / "noise.json").read_text())
    assert data["data_type"] == "phase"
    dev = data["channels"]["ch0"]["deviations"]
    assert set(dev) == {"oadev", "htotdev", "theo1", "mtie"}
    o = dev["oadev"]
    assert o["tau"] == [0.02, 0.1, 1.0, 4.0]
    for key in ("value", "n_terms", "edf", "lo", "hi", "alpha"):
        assert len(o[key]) == 4
    assert o["n_terms"][0] == 6000 - 2
    assert all(lo < v < hi for lo, v, hi in zip(o["lo"], o["value"], o["hi"], strict=True))
    assert o["value"][0] == pytest.approx(1e-3, rel=0.05)  # phase input: the rate's white noise at τ₀
    assert "lo" not in dev["mtie"]
    assert "gaps: none" in capsys.readouterr().out


def test_gaps_are_reported_and_skipped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(6)
    y = rng.normal(0.0, 1e-3, 5000)
    y[[100, 101, 2500]] = np.nan
    np.save(tmp_path / "g.npy", y)
    assert main(["noise", str(tmp_path / "g.npy"), "--rate", "10", "--out", str(tmp_path / "o")]) == 0
    assert "ch0: 2 gap(s), 3 NaN sample(s)" in capsys.readouterr().out
    data = json.loads((tmp_path / "o" / "noise.json").read_text())
    ch = data["channels"]["ch0"]
    assert ch["gaps"] == {"samples": 3, "runs": 2}
    assert ch["deviations"]["oadev"]["n_terms"][0] == 5001 - 2 - 5  # the five second differences over a gap
    assert ch["terms"]["N"]["value"] == pytest.approx(1e-3 / math.sqrt(10), rel=0.05)


def test_recording_is_read_in_chunks_into_one_array(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The recording loader fills one (C, N) float64 array chunk by chunk (chunk boundaries inside the step):
    values equal the file's, the channels are rows of that one array, gaps and ±inf are located exactly."""
    import benches.cli.analysis_input as ai
    from benches.cli.analysis_input import InputError, load_input

    monkeypatch.setattr(ai, "READ_CHUNK_ROWS", 1000)
    rng = np.random.default_rng(4)
    n, rate = 4321, 100.0
    accel = rng.normal(0.0, 1e-3, (n, 3))
    gyro = rng.normal(0.0, 1e-4, (n, 3))
    gyro[2500, 1] = np.nan
    run = tmp_path / "run"
    run.mkdir()
    _write_recording(run / "recording.h5", accel, gyro, rate)
    data = load_input(run, channels="gyro_y,accel_x,gyro_z", allow_gaps=True)
    assert list(data.channels) == ["gyro_y", "accel_x", "gyro_z"]
    np.testing.assert_array_equal(data.channels["gyro_y"], gyro[:, 1])
    np.testing.assert_array_equal(data.channels["accel_x"], accel[:, 0])
    np.testing.assert_array_equal(data.channels["gyro_z"], gyro[:, 2])
    base = data.channels["gyro_y"]
    assert all(np.shares_memory(base.base, v) for v in data.channels.values())  # one array, no per-channel copies
    with pytest.raises(InputError, match=r"first in channel 'gyro_y' at sample 2500"):
        load_input(run, channels="gyro_x,gyro_y")
    gyro[3999, 0] = np.inf
    _write_recording(run / "recording.h5", accel, gyro, rate)
    with pytest.raises(InputError, match=r"first in channel 'gyro_x' at sample 3999"):
        load_input(run, channels="gyro_x,gyro_z", allow_gaps=True)
    # the command on the recording equals the same data as .npy
    res_rec = analyse_noise(load_input(run, channels="accel_y,accel_z").channels, rate, "SI")
    np.save(tmp_path / "a.npy", accel[:, 1:])
    res_npy = analyse_noise(load_input(tmp_path / "a.npy", rate=rate).channels, rate, "SI")
    for k_rec, k_npy in (("accel_y", "ch0"), ("accel_z", "ch1")):
        np.testing.assert_array_equal(res_rec["channels"][k_rec]["oadev"], res_npy["channels"][k_npy]["oadev"])


def test_noise_type_and_drift_removal_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(9)
    y = rng.normal(0.0, 1e-3, 20_000) + 1e-7 * np.arange(20_000)
    np.save(tmp_path / "d.npy", y)
    out = tmp_path / "o"
    args = ["noise", str(tmp_path / "d.npy"), "--rate", "10", "--out", str(out)]
    assert main([*args, "--noise-type", "wfm@0:50,rwfm@50:1e6", "--remove-drift", "linear"]) == 0
    data = json.loads((out / "noise.json").read_text())
    ch = data["channels"]["ch0"]
    alpha = np.array(ch["deviations"]["oadev"]["alpha"])
    tau = np.array(ch["deviations"]["oadev"]["tau"])
    assert np.all(alpha[tau <= 50] == 0) and np.all(alpha[tau > 50] == -2)
    assert ch["drift_removed"]["model"] == "linear"
    assert ch["drift_removed"]["coefficients"][1] == pytest.approx(1e-7 * 10, rel=0.05)  # per second
    assert "slope-line" in capsys.readouterr().out
    assert main([*args, "--noise-type", "ffm"]) == 0
    assert set(json.loads((out / "noise.json").read_text())["channels"]["ch0"]["deviations"]["oadev"]["alpha"]) == {-1}


@pytest.mark.parametrize("bad", ["pink", "3", "wfm@5", "wfm@9:1", ""])
def test_bad_noise_type_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str], bad: str) -> None:
    np.save(tmp_path / "d.npy", np.random.default_rng(1).normal(size=1000))
    assert main(["noise", str(tmp_path / "d.npy"), "--rate", "10", "--noise-type", bad]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--noise-type" in err[0]


def test_psd_and_dynamic_outputs(tmp_path: Path) -> None:
    np.save(tmp_path / "d.npy", np.random.default_rng(2).normal(0.0, 1e-3, (20_000, 2)))
    out = tmp_path / "o"
    assert main(["noise", str(tmp_path / "d.npy"), "--rate", "10", "--out", str(out), "--psd", "--dynamic", "200"]) == 0
    data = json.loads((out / "noise.json").read_text())
    assert set(data["channels"]["ch0"]["psd"]["terms"]) == {"N", "B", "K"}
    assert data["dynamic"]["step_s"] == 50.0 and len(data["dynamic"]["channels"]["ch1"]["adev"]) == 37
    assert (out / "noise_psd.png").stat().st_size > 1000 and (out / "noise_dynamic.png").stat().st_size > 1000
    assert main(["noise", str(tmp_path / "d.npy"), "--rate", "10", "--dynamic", "0:5"]) == 2


def test_noise_type_option_reproduces_stable32_bounds_from_the_command_line(tmp_path: Path) -> None:
    """``tablebench noise PHASE.DAT --data-type phase --noise-type α@τ:τ,… --edf stable32`` with the α Stable32
    printed: the intervals in noise.json equal Stable32's printed bounds within 1 % on every row (allantools'
    PHASE.DAT runs, tests/data/noise/allantools/README.md, HTOTDEV's flicker-PM rows included; all 530 rows of
    every file: tests/analysis/noise/test_stability_allantools_stable32.py)."""
    ref_dir = Path(__file__).resolve().parents[1] / "data" / "noise" / "allantools" / "phasedat"
    np.save(tmp_path / "p.npy", np.loadtxt(ref_dir / "PHASE.DAT", comments="#"))
    for est, run in (("oadev", "phase_dat_oadev_octave.txt"), ("mdev", "phase_dat_mdev_octave.txt"),
                     ("totdev", "phase_dat_totdev_octave.txt"), ("htotdev", "phase_dat_htotdev_octave.txt")):
        rows = np.array([[float(v) for v in line.lstrip("#").split()[:7]]
                         for line in (ref_dir / run).read_text(encoding="latin-1").splitlines()
                         if line.lstrip("#").split()[:1] and line.lstrip("#").split()[0].isdigit()])
        spec = ",".join(f"{int(a)}@{t:g}:{t:g}" for t, a in zip(rows[:, 1], rows[:, 3], strict=True))
        out = tmp_path / est
        assert main(["noise", str(tmp_path / "p.npy"), "--rate", "1", "--data-type", "phase", "--estimators", est,
                     "--out", str(out), "--noise-type", spec, "--edf", "stable32"]) == 0
        data = json.loads((out / "noise.json").read_text())
        assert data["edf_rules"] == "stable32"
        d = data["channels"]["ch0"]["deviations"][est]
        j = np.searchsorted(np.array(d["tau"]), rows[:, 1])
        np.testing.assert_array_equal(np.array(d["alpha"])[j], rows[:, 3])
        np.testing.assert_allclose(np.array(d["lo"])[j], rows[:, 4], rtol=0.01)
        np.testing.assert_allclose(np.array(d["hi"])[j], rows[:, 6], rtol=0.01)
