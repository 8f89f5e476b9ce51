"""Certificate end to end on a synthetic run folder: PDF pages, text, determinism, FAIL, incomplete runs, CLI."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pypdf
import pypdfium2
import pytest

from analysis.units import UG, to_display
from benches.calibration_integrity import with_integrity
from benches.certificate import (
    CertificateError,
    bench_info,
    build_certificate,
    format_with_uncertainty,
    issue_certificate,
)
from benches.cli import main
from tests.certificate_fixtures import BENCH_TEXT, add_analyses, make_run_folder

DATE = "2026-11-22"


@pytest.fixture(scope="module")
def run_ok(tmp_path_factory) -> Path:
    return make_run_folder(tmp_path_factory.mktemp("ok") / "run")


@pytest.fixture(scope="module")
def issued(run_ok) -> tuple[Path, Path, str]:
    return issue_certificate(run_ok, issue_date=DATE)


def _text(pdf: Path) -> list[str]:
    return [p.extract_text() for p in pypdf.PdfReader(str(pdf)).pages]


def test_format_with_uncertainty_follows_gum_rounding():
    assert format_with_uncertainty(104.6712, 5.523) == ("104.7", "5.6")  # U rounded up, value to the same place
    assert format_with_uncertainty(198.39, 61.2) == ("198", "62")
    assert format_with_uncertainty(-0.0004, 0.0123) == ("0.000", "0.013")
    assert format_with_uncertainty(1234.0, 0.0) == ("1234", "—")


def test_pages_render_and_are_not_blank(issued):
    pdf, _, _ = issued
    doc = pypdfium2.PdfDocument(str(pdf))
    try:
        assert len(doc) == len(pypdf.PdfReader(str(pdf)).pages) >= 5
        for i in range(len(doc)):
            img = np.asarray(doc[i].render(scale=40 / 72).to_pil().convert("RGB"), dtype=float) / 255.0
            ink = np.mean(img.mean(axis=2) < 0.9)
            assert ink > 0.01, f"page {i + 1}: only {ink:.2%} of the page is not white"
            assert img.std() > 0.05
    finally:
        doc.close()


def test_pdf_text_has_every_parameter_with_uncertainty_and_unit(issued):
    pdf, js, verdict = issued
    cert = json.loads(js.read_text(encoding="utf-8"))
    text = "\n".join(_text(pdf))
    assert verdict == cert["verdict"] == "PASS"
    assert len(cert["parameters"]) == 18
    for name, p in cert["parameters"].items():
        # the row's U is the JSON's expanded uncertainty (SI) in display units, GUM-rounded — recomputed here
        u_disp = to_display(p["kind"], p["expanded_uncertainty"])
        v_txt, u_txt = format_with_uncertainty(to_display(p["kind"], p["value"]), u_disp)
        assert abs(p["expanded_uncertainty"] - 2 * p["standard_uncertainty"]) <= 1e-12 * p["expanded_uncertainty"]
        row = rf"(?m)^{re.escape(name)} {re.escape(v_txt)} {re.escape(u_txt)} {re.escape(p['display_unit'])} "
        assert re.search(row, text), f"no results row for {name}: {v_txt} ± {u_txt} {p['display_unit']}"
    fixed = ["CALIBRATION CERTIFICATE", "SIM-U-0001", "SIM-T-0001", "Local gravity", "attitude accuracy"]
    fixed += ["Model mismatch", "k = 2", "Signature", "δf_i += τ_ij f_j"]
    for must in [cert["certificate_number"], cert["recording"]["sha256"], *fixed]:
        assert must in text, must


def test_budget_starts_from_the_identification_covariance(issued):
    _, js, _ = issued
    cert = json.loads(js.read_text(encoding="utf-8"))
    keys = [c["key"] for c in cert["uncertainty_budget"]["components"]]
    assert keys == [
        "white_noise", "bias_instability", "attitude", "local_g", "axis_orthogonality", "held_angles", "model_mismatch"
    ]  # fmt: skip
    cal = json.loads((js.parent / "calibration.json").read_text(encoding="utf-8"))
    for name, p in cert["parameters"].items():
        b = p["budget"]
        # white noise ⊕ bias instability is the identification's own u, exactly
        assert math.hypot(b["white_noise"], b["bias_instability"]) == pytest.approx(
            cal["parameters"][name]["sigma"], rel=1e-9
        )
        assert p["standard_uncertainty"] == pytest.approx(np.sqrt(sum(v**2 for v in b.values())), rel=1e-9)
    # WGS-84 normal gravity (30 mGal) dominates the scale factors; the attitude (1″) matters for misalignments
    assert cert["parameters"]["S_x"]["budget"]["local_g"] > cert["parameters"]["S_x"]["budget"]["white_noise"]
    assert (
        cert["parameters"]["tau_xy"]["budget"]["attitude"] > 0.1 * cert["parameters"]["tau_xy"]["budget"]["white_noise"]
    )


def test_same_recording_gives_the_same_bytes_apart_from_the_issue_date(run_ok, issued, tmp_path):
    pdf1, js1, _ = issued
    number = json.loads(js1.read_text(encoding="utf-8"))["certificate_number"]
    # another process, another hash seed, the same number: the same bytes
    code = (
        "import sys; from pathlib import Path; from benches.certificate import build_certificate; "
        "from benches.certificate.pdf import render_pdf; c = build_certificate(sys.argv[1], issue_date=sys.argv[2]); "
        "c.number = sys.argv[3]; Path(sys.argv[4]).write_bytes(render_pdf(c)); "
        "Path(sys.argv[5]).write_text(c.to_json(), encoding='utf-8')"
    )
    pdf2, js2 = tmp_path / "again.pdf", tmp_path / "again.json"
    env = dict(os.environ, PYTHONHASHSEED="12345")
    cmd = [sys.executable, "-c", code, str(run_ok), DATE, number, str(pdf2), str(js2)]
    subprocess.run(cmd, check=True, env=env, capture_output=True, timeout=300)
    assert pdf1.read_bytes() == pdf2.read_bytes()
    assert js1.read_bytes() == js2.read_bytes()
    # a re-issue: a new number that names the one it supersedes, otherwise the same content
    _, js3, _ = issue_certificate(run_ok, tmp_path / "later.pdf", tmp_path / "later.json", issue_date="2027-01-05")
    a, b = json.loads(js1.read_text(encoding="utf-8")), json.loads(js3.read_text(encoding="utf-8"))
    assert a.pop("issue_date") == DATE and b.pop("issue_date") == "2027-01-05"
    assert b.pop("supersedes") == a.pop("certificate_number") != b.pop("certificate_number")
    a.pop("supersedes")
    assert a == b


def test_a_recording_beyond_its_limits_is_marked_fail_with_reasons(tmp_path):
    run = make_run_folder(tmp_path / "bad", shift={"b_x": 1500 * UG})  # limit in benches/sim.yaml: 1000 µg
    pdf, js, verdict = issue_certificate(run, issue_date=DATE)
    cert = json.loads(js.read_text(encoding="utf-8"))
    assert verdict == "FAIL" and cert["parameters"]["b_x"]["verdict"] == "FAIL"
    assert any(r.startswith("b_x") and "exceeds the limit" in r for r in cert["reasons"])
    assert all(p["verdict"] != "FAIL" for n, p in cert["parameters"].items() if n != "b_x")
    first = _text(pdf)[0]
    assert "Result: FAIL" in first and "b_x" in first and "exceeds the limit" in first


def test_incomplete_recording_needs_allow_incomplete_and_says_so_on_page_one(tmp_path, capsys):
    run = make_run_folder(tmp_path / "cut", fail_after=40.0)
    with pytest.raises(CertificateError, match="incomplete.*--allow-incomplete"):
        build_certificate(run, issue_date=DATE)
    assert main(["certificate", str(run), "--issue-date", DATE]) == 2
    err = capsys.readouterr().err
    assert "incomplete" in err and "--allow-incomplete" in err and "Traceback" not in err
    assert not (run / "certificate.pdf").exists()
    # only group A was recorded: parameters the data cannot determine are NOT VERIFIED against their limits
    assert main(["certificate", str(run), "--issue-date", DATE, "--allow-incomplete"]) == 0
    cert = json.loads((run / "certificate.json").read_text(encoding="utf-8"))
    assert cert["complete"] is False and cert["verdict"] == "INCOMPLETE"
    assert cert["incomplete_reason"] and any("cannot identify" in r for r in cert["reasons"])
    first = _text(run / "certificate.pdf")[0]
    assert "INCOMPLETE RUN" in first and "failed" in first


def test_cli_writes_the_named_outputs_and_refuses_a_foreign_calibration(run_ok, tmp_path, capsys):
    out = tmp_path / "x" / "cert.pdf"
    assert main(["certificate", str(run_ok), "--out", str(out), "--issue-date", DATE]) == 0
    assert out.exists() and out.with_suffix(".json").exists()
    assert out.read_bytes()[:5] == b"%PDF-"
    other = tmp_path / "other"
    shutil.copytree(run_ok, other)
    cal = json.loads((other / "calibration.json").read_text(encoding="utf-8"))
    cal["recording_sha256"] = "0" * 64  # a genuine calibration (sealed) of another recording
    (other / "calibration.json").write_text(json.dumps(with_integrity(cal)), encoding="utf-8")
    assert main(["certificate", str(other)]) == 2
    assert "different recording" in capsys.readouterr().err
    cal = json.loads((run_ok / "calibration.json").read_text(encoding="utf-8"))
    del cal["parameters"]["d_y"]["value"]
    (other / "calibration.json").write_text(json.dumps(cal), encoding="utf-8")
    assert main(["certificate", str(other)]) == 2
    assert "parameters.d_y.value is missing" in capsys.readouterr().err
    assert main(["certificate", str(tmp_path / "nowhere")]) == 2
    assert main(["certificate", str(run_ok), "--issue-date", "22/11/2026"]) == 2
    assert "YYYY-MM-DD" in capsys.readouterr().err


def test_noise_periodic_and_drift_analyses_are_included_when_present(tmp_path):
    run = make_run_folder(tmp_path / "an")
    add_analyses(run)
    pdf, js, _ = issue_certificate(run, issue_date=DATE)
    cert = json.loads(js.read_text(encoding="utf-8"))
    assert set(cert["analyses"]) == {"noise", "periodic", "drift"}
    # k = 2 for every ± on the certificate (the analysis file holds the standard uncertainty 0.015)
    # value and U to the same decimal, U to two significant digits (GUM 7.2.6, as in the results table)
    v, u = format_with_uncertainty(14.99, 2 * 0.015)
    assert {"channel": "accel_x", "item": "N", "value": f"{v} ± {u} µg/√Hz (U, k = 2)"} in cert["analyses"]["noise"]
    assert any("12.5" in r["value"] for r in cert["analyses"]["periodic"])
    # periodic.json is SI (rad/s); the certificate shows the gyro's display unit, as in the results table
    assert all("deg/h" in r["value"] and "rad/s" not in r["value"] for r in cert["analyses"]["periodic"])
    assert any(r["item"] == "ARMA(1,1)" for r in cert["analyses"]["drift"])
    assert list(cert["analysis_plots"]) == ["noise/noise.png"]
    text = "\n".join(_text(pdf))
    assert "Noise analysis" in text and f"{v} ± {u} µg/√Hz (U, k = 2)" in text and "ARMA(1,1)" in text


def test_an_unidentified_limited_parameter_makes_the_result_inconclusive(run_ok, tmp_path):
    run = tmp_path / "slow-spin"
    shutil.copytree(run_ok, run)
    cal = json.loads((run / "calibration.json").read_text(encoding="utf-8"))
    for n in ("r_x", "r_y", "r_z"):
        cal["parameters"][n]["identifiable"] = False
    (run / "calibration.json").write_text(json.dumps(with_integrity(cal)), encoding="utf-8")  # as identified
    cert = build_certificate(run, issue_date=DATE, with_plots=False)
    assert cert.verdict == "INCONCLUSIVE"
    assert [p.verdict for p in cert.parameters if p.name.startswith("r_")] == ["NOT EVALUATED"] * 3
    assert any("r_x, r_y, r_z" in w for w in cert.warnings)
    js = json.loads(cert.to_json())
    assert js["compensation"]["use"][15:] == [False] * 3 and all(js["compensation"]["use"][:15])


def test_decision_rule_with_an_uncertainty_as_large_as_the_limit(run_ok, tmp_path):
    run = tmp_path / "tight"
    shutil.copytree(run_ok, run)
    cal = json.loads((run / "calibration.json").read_text(encoding="utf-8"))
    cal["parameters"]["b_y"]["value"] = 0.0
    (run / "calibration.json").write_text(json.dumps(with_integrity(cal)), encoding="utf-8")  # as identified
    first = build_certificate(run, issue_date=DATE, with_plots=False)
    u = {p.name: p.expanded_uncertainty for p in first.parameters}
    x = {p.name: p.value for p in first.parameters}
    base = bench_info(BENCH_TEXT, {}, {})
    cases = {
        "b_y": (0.9 * u["b_y"], "UNDECIDED"),  # |x| = 0 but U ≥ L: no outcome could show conformity
        "b_z": (abs(x["b_z"]) + 0.5 * u["b_z"], "UNDECIDED"),  # inside, U straddles (conditional pass)
        "b_x": (abs(x["b_x"]) + 2 * u["b_x"], "PASS"),
        "S_x": (abs(x["S_x"]) - 0.5 * u["S_x"], "UNDECIDED"),  # outside, U straddles (conditional fail)
        "tau_xy": (0.5 * u["tau_xy"], "FAIL"),  # U ≥ L, but |x| − U > L: certainly out
    }
    bench = dataclasses.replace(base, limits={k: v[0] for k, v in cases.items()})
    cert = build_certificate(run, issue_date=DATE, bench=bench, with_plots=False)
    got = {p.name: p.verdict for p in cert.parameters if p.name in cases}
    assert got == {k: v[1] for k, v in cases.items()}
    assert cert.verdict == "FAIL"


def test_simulated_on_every_page_and_a_traceability_statement(issued):
    pdf, js, _ = issued
    pages = _text(pdf)
    assert len(pages) > 2 and all("SIMULATED BENCH" in p for p in pages)
    text = " ".join("\n".join(pages).split())
    assert "Metrological traceability" in text and "attitude accuracy" in text and "u(g)" in text
    assert "not traceable to SI" in text  # a simulated bench
    assert "only the accelerometer triad is calibrated" in text
    assert "procedure steps completed" in text
    # the legend reconciling the three uncertainty figures
    assert "live display" in text and "calibration.json give u" in text and "U = 2u" in text


def test_reference_standards_from_the_bench_file_with_due_dates(run_ok, tmp_path):
    run = tmp_path / "real"
    shutil.copytree(run_ok, run)
    base = bench_info(BENCH_TEXT, {}, {})
    keys = ("name", "serial_number", "certificate", "calibrated_by", "due")
    stds = [
        dict(zip(keys, ("angle encoders", "E1", "C-1", "Lab", "2000-01-01"), strict=True)),
        dict(zip(keys, ("gravimeter survey", "", "G-7", "", "2999-01-01"), strict=True)),
    ]
    bench = dataclasses.replace(base, reference_standards=stds)
    cert = build_certificate(run, issue_date=DATE, bench=bench, with_plots=False)
    got = {r["certificate"]: r["overdue"] for r in cert.bench["reference_standards"]}
    assert got == {"C-1": True, "G-7": False}
