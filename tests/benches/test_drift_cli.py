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
    assert model["include_mean"] and model["converged"] and model["status"] == "converged" and model["k"] == 4
    assert ch["order_selection"]["criterion"] == "bic" and len(ch["order_selection"]["table"]) == 16
    assert isinstance(ch["unsettled"], list)
    verdicts = [ln.strip() for ln in text.splitlines() if ln.strip().startswith(("settled:", "NOT settled:"))]
    assert len(verdicts) == 2, text  # one line per channel: settled or NOT settled
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
    assert "gyro_a: ARMA(3, 3) fitted (16/16)" in err and "gyro_a: pre-processing" in err
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


def test_no_mean_and_p_ge_q(record: Path, tmp_path: Path) -> None:
    out = tmp_path / "o4"
    rc = main(["drift", str(record), "--rate", "100", "--channel", "gyro_a", "--no-mean", "--p-ge-q", "--no-online",
               "--quiet", "--out", str(out)])  # fmt: skip
    assert rc == 0
    ch = json.loads((out / "drift.json").read_text())["channels"]["gyro_a"]
    assert ch["model"]["include_mean"] is False and ch["model"]["mean"] == 0.0 and ch["model"]["se_mean"] is None
    assert ch["order_selection"]["p_ge_q"] and all(r["p"] >= r["q"] for r in ch["order_selection"]["table"])


def test_unsettled_fit_reported_in_json_and_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A fit that does not converge is listed in drift.json ("unsettled") and in one line of the text report."""
    from analysis.drift import arma_optimiser

    monkeypatch.setattr(arma_optimiser, "GAIN_TOL", 0.0)  # no point can meet the criteria
    path = tmp_path / "short.npy"
    np.save(path, simulate_arma([0.9], [0.4], 1.0, 400, np.random.default_rng(72)))
    out = tmp_path / "o5"
    rc = main(["drift", str(path), "--rate", "100", "--segments", "20", "--no-online", "--quiet", "--p-ge-q",
               "--out", str(out)])  # fmt: skip
    assert rc == 0
    text = capsys.readouterr().out
    lines = [ln for ln in text.splitlines() if "NOT settled" in ln]
    assert len(lines) == 1 and "not converged" in lines[0] and "gradient norm" in lines[0]
    ch = json.loads((out / "drift.json").read_text())["channels"]["ch0"]
    issues = {u["item"]: u for u in ch["unsettled"]}
    assert len(issues) >= 9  # every candidate with p + q > 0
    assert all(u["issue"] in ("not converged", "boundary", "parameter redundancy") for u in issues.values())
    assert ch["model"]["converged"] is False and "did not converge" in ch["model"]["note"]


def test_white_channel_plot_title_has_no_nan(tmp_path: Path) -> None:
    """A white residual has no Kalman compensation: the title says so instead of 'after filter nan'."""
    from analysis.drift.plot import plot_channel
    from analysis.drift.report import analyse_channel

    res = analyse_channel(np.random.default_rng(3).standard_normal(1000), 50.0, "w")
    assert res.summary["model"]["p"] == 0
    figures = plot_channel(res, "w", "m/s^2")
    assert set(figures) == {"acf", "psd", "hist", "compensation"}
    titles = [ax.get_title() for fig in figures.values() for ax in fig.axes]
    assert all("nan" not in t.lower() for t in titles), titles
    assert "nothing predictable" in figures["compensation"].axes[0].get_title()
    assert list(tmp_path.iterdir()) == []  # the analysis layer writes no files


def test_overflowing_values_are_one_clear_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = tmp_path / "huge.npy"
    np.save(path, np.random.default_rng(0).standard_normal(1000) * 1e296)
    assert main(["drift", str(path), "--rate", "50", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "too large" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
