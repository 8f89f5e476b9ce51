"""The thermal calibration of a simulated thermal record, through the runner: ``tablebench run`` of a short
3-plateau procedure on the simulated thermal bench (the session issues the thermal calibration and certificate),
``tablebench thermal`` again with a pinned date, the certificate's text and numbers, and ``tablebench correct``
with the thermal model (the unit's temperature channel; outside the calibrated range refused or warned)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from pypdf import PdfReader

from analysis.identification.model import correct as correct_accel
from analysis.units import CELSIUS_ZERO, UG
from benches.cli.main import main
from benches.thermal.document import load_thermal
from benches.thermal.plateau import MISALIGNMENT_PAIRS, THERMAL_PARAM_NAMES
from tests import REPO_ROOT

BENCH = REPO_ROOT / "benches" / "sim-thermal-white.yaml"
GROUPS = "\n".join(
    f"""        - group:
            name: {g}
            steps:
              - orient: {o}
              - hold: {{}}
              - step_rotate: {{axis: {a}, angle_deg: 45, count: 7}}
              - spin: {{axis: {a}, rate_dps: 30, direction: both, revolutions: 1}}"""
    for g, o, a in (
        ("A", "{x: East, y: North, z: Up}", "y"),
        ("B", "{x: South, y: Down, z: East}", "x"),
        ("C", "{x: Down, y: West, z: North}", "z"),
    )
)
PROCEDURE = "name: short-thermal\ndescription: three plateaus, short holds\nversion: 1\n"
PROCEDURE += "defaults: {settle_s: 1, hold_s: 6, spin_settle_s: 1}\nsteps:\n"
for _t in (15, 25, 35):
    PROCEDURE += f"""  - group:
      name: T{_t}
      steps:
        - soak: {{setpoint_c: {_t}, tolerance_k: 0.3, rate_k_per_min: 0.05, dwell_s: 60, timeout_s: 18000}}
{GROUPS}
"""


@pytest.fixture(scope="module")
def thermal_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("thermal-cert")
    proc = tmp / "short-thermal.yaml"
    proc.write_text(PROCEDURE, encoding="utf-8")
    out = tmp / "run"
    assert main(["run", "--bench", str(BENCH), "--procedure", str(proc), "--out", str(out), "--seed", "3",
                 "--plain"]) == 0  # fmt: skip
    return out


def test_run_of_a_thermal_procedure_issues_the_thermal_calibration_and_certificate(thermal_run: Path) -> None:
    assert (thermal_run / "thermal_calibration.json").is_file()
    assert (thermal_run / "thermal-certificate.pdf").is_file()
    tf = load_thermal(thermal_run / "thermal_calibration.json")
    temps = [p["temperature_K"] - CELSIUS_ZERO for p in tf.plateaus]
    assert len(temps) == 3 and all(abs(t - s) < 0.5 for t, s in zip(temps, (15, 25, 35), strict=True))
    lo, hi = tf.model.temperature_range
    assert (lo, hi) == (min(p["temperature_K"] for p in tf.plateaus), max(p["temperature_K"] for p in tf.plateaus))
    assert [p["direction"] for p in tf.plateaus] == ["cooling", "heating", "heating"]  # from 23 °C ambient


def test_certificate_states_the_model_its_range_and_every_parameter_with_U(thermal_run: Path) -> None:
    assert main(["thermal", str(thermal_run), "--issue-date", "2026-11-27"]) == 0
    tf = load_thermal(thermal_run / "thermal_calibration.json")
    content = json.loads((thermal_run / "thermal-certificate.json").read_text(encoding="utf-8"))
    reader = PdfReader(thermal_run / "thermal-certificate.pdf")
    text = " ".join(" ".join(page.extract_text() for page in reader.pages).split())
    lo, hi = (t - CELSIUS_ZERO for t in tf.model.temperature_range)
    assert "Thermal calibration certificate" in text and "issued 2026-11-27" in text
    assert f"Validity range: {lo:.2f} °C to {hi:.2f} °C" in text
    assert "outside it tablebench correct refuses (default) or warns" in text
    assert "U = 2u (k = 2" in text and f"T_ref = {tf.model.reference - CELSIUS_ZERO:g} °C" in text
    for name in THERMAL_PARAM_NAMES:
        assert f"{name} [" in text, name
    # one page of plots per parameter kind (8 kinds) after the model page, each with images
    assert len(reader.pages) >= 9 and sum(len(p.images) for p in reader.pages) >= 8
    # the stated U on the grid = 2 × the model's standard uncertainty from the coefficients' covariance,
    # recomputed here from the file's coefficients (not from the model code)
    grid = np.asarray(content["grid_K"])
    assert grid[0] == pytest.approx(lo + CELSIUS_ZERO) and grid[-1] == pytest.approx(hi + CELSIUS_ZERO)
    raw = tf.content
    cov = np.asarray(raw["covariance"])
    start = 0
    for p, name in enumerate(raw["names"]):
        n = raw["orders"][p] + 1
        c = np.asarray(raw["coefficients"][start : start + n])
        s = cov[start : start + n, start : start + n]
        start += n
        v = np.vander(grid - raw["reference_K"], n, increasing=True)
        par = content["parameters"][name]
        np.testing.assert_allclose(par["model_at_grid"], v @ c, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(par["U_model_at_grid"], 2 * np.sqrt(np.einsum("ij,jk,ik->i", v, s, v)), rtol=1e-9)
        x = [pl["x"][p] for pl in raw["plateaus"]]
        np.testing.assert_allclose(par["plateau_values"], x)
    # the table rows print the model at the grid ± U in the display unit (b_x in µg)
    bx = content["parameters"]["b_x"]
    assert f"{bx['model_at_grid'][0] / UG:.4g} ± {bx['U_model_at_grid'][0] / UG:.4g}" in text


def _by_hand(raw: dict, f_out: np.ndarray, g_out: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """Independent compensation: the 30 parameters at each sample's temperature from the file's coefficients,
    the gyro inverted per sample, the accelerometer by the model's own inverse, one sample at a time."""
    out = np.zeros((len(temp), 6))
    start_of = np.cumsum([0] + [o + 1 for o in raw["orders"]])
    for i, t in enumerate(temp):
        x = np.array([np.polyval(np.asarray(raw["coefficients"][start_of[p] : start_of[p + 1]])[::-1],
                                 t - raw["reference_K"]) for p in range(30)])  # fmt: skip
        m = np.eye(3) + np.diag(x[21:24])
        for k, (a, b) in enumerate(MISALIGNMENT_PAIRS):
            m[a, b] = x[24 + k]
        w = np.linalg.solve(m, g_out[i] - x[18:21])
        out[i, 3:] = w
        out[i, :3] = correct_accel(x[:18], f_out[i : i + 1], w[None, :])[0]
    return out


def test_correct_applies_the_temperature_model_of_the_recording(thermal_run: Path, tmp_path: Path, capsys) -> None:
    from benches.thermal.identify import window_samples

    cal = thermal_run / "thermal_calibration.json"
    out = tmp_path / "corrected.npy"
    assert main(["correct", str(cal), str(thermal_run), "--out", str(out), "--outside-range", "warn"]) == 0
    got = np.load(out)
    f_out, g_out, temp, _ = window_samples(thermal_run)
    assert got.shape == (len(temp), 6)
    idx = np.linspace(0, len(temp) - 1, 40).astype(int)
    np.testing.assert_allclose(got[idx], _by_hand(json.loads(cal.read_text()), f_out[idx], g_out[idx], temp[idx]),
                               rtol=0, atol=1e-12)  # fmt: skip
    # the compensated static samples: |f| = local g within the noise (the raw output is off by bias and scale)
    static = np.abs(g_out[:, 1]) < 0.01
    err_raw = abs(np.median(np.linalg.norm(f_out[static], axis=1)) - 9.8078)
    err_cor = abs(np.median(np.linalg.norm(got[static, :3], axis=1)) - 9.8078)
    assert err_cor < err_raw


def test_correct_refuses_or_warns_outside_the_calibrated_range(thermal_run: Path, tmp_path: Path, capsys) -> None:
    cal = thermal_run / "thermal_calibration.json"
    tf = load_thermal(cal)
    lo, hi = tf.model.temperature_range
    raw = np.zeros((4, 7))
    raw[:, 2] = 9.81
    raw[:, 6] = [lo, (lo + hi) / 2, hi, hi + 5.0]  # the last one 5 K above the range
    npy = tmp_path / "raw.npy"
    np.save(npy, raw)
    capsys.readouterr()
    assert main(["correct", str(cal), str(npy), "--out", str(tmp_path / "a.npy")]) == 2
    err = capsys.readouterr().err
    assert "1 of 4 samples" in err and "outside the calibrated range" in err and "--outside-range warn" in err
    assert "Traceback" not in err and not (tmp_path / "a.npy").exists()
    assert main(["correct", str(cal), str(npy), "--out", str(tmp_path / "b.npy"), "--outside-range", "warn"]) == 0
    err = capsys.readouterr().err
    assert "warning: 1 of 4 samples" in err and "extrapolated" in err
    got = np.load(tmp_path / "b.npy")
    assert got.shape == (4, 6) and np.all(np.isfinite(got))
    # in range, the three samples equal the independent compensation
    np.testing.assert_allclose(got[:3], _by_hand(tf.content, raw[:3, :3], raw[:3, 3:6], raw[:3, 6]), atol=1e-12)


def test_correct_refuses_an_edited_thermal_calibration(thermal_run: Path, tmp_path: Path, capsys) -> None:
    raw = json.loads((thermal_run / "thermal_calibration.json").read_text(encoding="utf-8"))
    raw["coefficients"][0] += 1e-5
    edited = tmp_path / "thermal_calibration.json"
    edited.write_text(json.dumps(raw), encoding="utf-8")
    npy = tmp_path / "raw.npy"
    np.save(npy, np.zeros((1, 7)) + [0, 0, 9.81, 0, 0, 0, raw["reference_K"]])
    capsys.readouterr()
    assert main(["correct", str(edited), str(npy), "--out", str(tmp_path / "c.npy")]) == 2
    err = capsys.readouterr().err
    assert "do not match its integrity digest" in err and "Traceback" not in err
    assert math.isfinite(raw["reference_K"])
