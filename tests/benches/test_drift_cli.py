"""``tablebench drift``: report, drift.json layout, PNGs, ``--channel`` alias, clear errors on bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from analysis.drift.arma import simulate_arma
from analysis.drift.report import analyse_drift
from benches.cli import main


@pytest.fixture()
def record(tmp_path: Path) -> Path:
    rng = np.random.default_rng(70)
    n = 6000
    drift = simulate_arma([0.9], [0.4], (1e-5) ** 2, n, rng) + 7e-5  # rad/s: bias + ARMA drift
    white = 1e-3 * rng.standard_normal(n)
    path = tmp_path / "rec.csv"
    np.savetxt(path, np.stack([drift, white], axis=1), delimiter=",", header="gyro_a,accel_b", comments="")
    return path


def test_drift_command_writes_json_and_plots(record: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "out"
    assert main(["drift", str(record), "--rate", "100", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "ARMA(1,1)" in text and "daniel_mean" in text and "ljung_box" in text and "threshold" in text
    doc = json.loads((out / "drift.json").read_text())
    ch = doc["channels"]["gyro_a"]
    model = ch["model"]
    for key in ("p", "q", "phi", "theta", "sigma2", "criterion"):
        assert key in model
    assert (model["p"], model["q"]) == (1, 1) and model["criterion"] == "bic" and model["method"] == "ml"
    assert abs(model["phi"][0] - 0.9) < 3 * model["se_phi"][0] + 1e-9
    for name in ("daniel_mean", "reverse_arrangement_mean", "daniel_mean_square", "reverse_arrangement_mean_square",
                 "jarque_bera", "welch_periodicity", "ljung_box"):  # fmt: skip
        t = ch["tests"][name]
        assert set(("statistic", "threshold", "verdict")) <= set(t) and t["verdict"] in ("pass", "reject")
    assert doc["channels"]["accel_b"]["model"]["p"] == 0
    for kind in ("acf", "psd", "hist", "compensation"):
        png = out / f"drift_gyro_a_{kind}.png"
        assert png.exists() and png.read_bytes()[:4] == b"\x89PNG"


def test_channel_alias_and_options(record: Path, tmp_path: Path) -> None:
    out = tmp_path / "o2"
    rc = main(["drift", str(record), "--rate", "100", "--channel", "gyro_a", "--criterion", "aic", "--no-online",
               "--outliers", "mad", "--detrend", "1", "--out", str(out)])  # fmt: skip
    assert rc == 0
    doc = json.loads((out / "drift.json").read_text())
    assert list(doc["channels"]) == ["gyro_a"]
    ch = doc["channels"]["gyro_a"]
    assert ch["model"]["criterion"] == "aic" and ch["outliers"]["method"] == "mad" and ch["detrend"]["order"] == 1
    assert ch["online"]["run"] is False


def test_fit_method_and_progress(record: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "o3"
    assert main(["drift", str(record), "--rate", "100", "--channel", "gyro_a", "--fit", "css", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "gyro_a: ARMA(3, 3) fitted (10/10)" in err and "gyro_a: pre-processing" in err
    assert json.loads((out / "drift.json").read_text())["channels"]["gyro_a"]["model"]["method"] == "css"
    assert main(["drift", str(record), "--rate", "100", "--channel", "gyro_a", "--quiet", "--no-online"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    "data,args,message",
    [
        (np.full(1000, 2.0), [], "constant"),
        (np.r_[np.random.default_rng(0).standard_normal(500), np.nan], [], "NaN"),
        (np.random.default_rng(0).standard_normal(60), [], "at least 200"),
        (np.random.default_rng(0).standard_normal(1000), ["--forgetting", "1.5"], "--forgetting"),
        (np.random.default_rng(0).standard_normal(1000), ["--channel", "nope"], "unknown channel"),
    ],
)
def test_bad_input_is_one_clear_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, data: np.ndarray, args: list[str], message: str
) -> None:
    path = tmp_path / "bad.npy"
    np.save(path, data)
    assert main(["drift", str(path), "--rate", "50", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_analyse_drift_api() -> None:
    rng = np.random.default_rng(71)
    res = analyse_drift({"g": simulate_arma([0.8], [], 1.0, 3000, rng)}, 10.0, criterion="aic", online=False)
    assert res["channels"]["g"]["model"]["criterion"] == "aic"
    with pytest.raises(ValueError, match="unknown drift option"):
        analyse_drift({"g": np.arange(300.0)}, 10.0, bogus=1)
