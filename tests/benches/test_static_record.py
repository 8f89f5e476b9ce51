"""Issue 26, a static noise record on the simulated bench: it gets a NOISE REPORT (not a calibration certificate of
"not evaluated" lines), its live progress shows no number for what the motion cannot see, and nothing blames
"spins too slow"; the progress display never shows the elapsed time past its own estimate.

The noise terms of the report are checked against the simulator's configured white noise (benches/sim.yaml:
15 µg/√Hz velocity random walk, 0.01 °/√h angle random walk), an independent reference.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import pypdfium2
import pytest

from benches.certificate import build_certificate
from benches.certificate.noise_report import is_static_record
from benches.cli import main
from benches.progress import ProgressDisplay
from benches.recording import open_recording
from benches.session import verdict_explanation
from tests.certificate_fixtures import make_run_folder

VRW_UG = 15.0  # benches/sim.yaml unit.noise.vrw_ug_per_sqrt_hz
ARW_DPSH = 0.01  # benches/sim.yaml unit.noise.arw_deg_per_sqrt_h


def _run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def _pages(pdf: Path) -> list[str]:
    doc = pypdfium2.PdfDocument(str(pdf))
    try:
        return [" ".join(doc[i].get_textpage().get_text_range().split()) for i in range(len(doc))]
    finally:
        doc.close()


@pytest.fixture(scope="module")
def static_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``tablebench run --procedure static-noise`` (a 2-minute record after a 10 s warm-up), identified and
    documented by ``run`` itself."""
    tmp = tmp_path_factory.mktemp("static")
    code, out, err = _run_cli(["run", "--procedure", "static-noise", "--set", "duration_s=120", "--set",
                               "warmup_s=10", "--seed", "4", "--plain", "--out", str(tmp / "run")])  # fmt: skip
    assert code == 0, err[-3000:]
    return tmp / "run", out + err


def test_a_static_record_gets_a_noise_report_not_a_calibration_certificate(static_run):
    run, text = static_run
    assert (run / "noise-report.pdf").exists() and not (run / "certificate.pdf").exists()
    assert "noise report: " in text and "\ncertificate: " not in text
    assert "static record (one attitude, no rotation): the run ends with a NOISE REPORT" in text  # said up front
    pages = _pages(run / "noise-report.pdf")
    whole = " ".join(pages)
    assert "NOISE REPORT" in pages[0] and "CALIBRATION CERTIFICATE" not in whole
    assert "NOT EVALUATED" not in whole and "not evaluated" not in whole
    assert "no calibration, no conformity statement" in pages[0]
    for ch in ("accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"):
        assert re.search(rf"{ch} N \d+\.\d+ ± \d+\.\d+ (µg/√Hz|deg/√h) \(U, k = 2\)", whole), ch
    report = json.loads((run / "noise-report.json").read_text(encoding="utf-8"))
    assert report["document"] == report["verdict"] == "NOISE REPORT"
    assert "parameters" not in report and report["noise"]["step"] == "record"


def test_the_noise_report_finds_the_simulators_white_noise(static_run):
    """N of every channel within its U (k = 2) of the configured VRW / ARW (plus 3 %: the anti-alias filter)."""
    run, _ = static_run
    report = json.loads((run / "noise-report.json").read_text(encoding="utf-8"))
    chans = report["noise"]["analysis"]["channels"]
    assert len(chans) == 6
    for ch, c in chans.items():
        n = c["terms_display"]["N"]
        truth = VRW_UG if ch.startswith("accel") else ARW_DPSH
        assert abs(n["value"] - truth) <= 2 * n["sigma"] + 0.03 * truth, (ch, n, truth)


def test_live_progress_shows_no_number_for_what_a_static_record_cannot_see(static_run):
    _run, text = static_run
    live = [ln for ln in text.splitlines() if "% record |" in ln or "% warmup |" in ln]
    assert live, text[-2000:]
    for ln in live:
        for name in ("S_z", "r_x", "r_y", "r_z", "tau_xy"):
            assert not re.search(rf"\b{name} -?\d", ln), f"{name} shown as a number in: {ln}"
    assert any("r_x not identified yet" in ln for ln in live), live[-1]


def test_nothing_blames_spins_too_slow_for_a_static_record(static_run, tmp_path):
    _run, text = static_run
    assert "too slow" not in text
    cert = {"parameters": {n: {"verdict": "NOT EVALUATED", "limit": 0.06} for n in ("r_x", "r_y", "r_z")}}
    (tmp_path / "c.json").write_text(json.dumps(cert), encoding="utf-8")
    lines = " ".join(verdict_explanation(tmp_path / "c.json", "INCONCLUSIVE", spins=False))
    assert "too slow" not in lines and "no spin steps" in lines
    lines = " ".join(verdict_explanation(tmp_path / "c.json", "INCONCLUSIVE", spins=True))
    assert "too slow" in lines  # with (slow) spins it is the reason


def test_only_one_attitude_without_rotation_is_a_static_record(static_run, tmp_path):
    run, _ = static_run
    with open_recording(run / "recording.h5") as rec:
        assert is_static_record(rec.steps)
    moving = make_run_folder(tmp_path / "ten-step-like")
    with open_recording(moving / "recording.h5") as rec:
        assert not is_static_record(rec.steps)
    assert build_certificate(moving, issue_date="2026-11-27", with_plots=False).document == "CALIBRATION CERTIFICATE"


def test_progress_never_shows_elapsed_past_its_own_estimate():
    out = io.StringIO()
    p = ProgressDisplay(3211.0, stream=out, live=False, min_interval_s=0.0)
    p.step("record")
    for t in (0.0, 1600.0, 3211.0, 3238.0, 3300.0):  # 0:53:58 against a 0:53:31 estimate, and beyond
        p.update(t, force=True)
    lines = [ln for ln in out.getvalue().splitlines() if "bench " in ln]
    assert len(lines) == 5
    for ln in lines:
        m = re.search(r"bench (\d+):(\d\d):(\d\d)/(\d+):(\d\d):(\d\d)", ln)
        if m:
            a = [int(x) for x in m.groups()]
            assert a[0] * 3600 + a[1] * 60 + a[2] <= a[3] * 3600 + a[4] * 60 + a[5], ln
        assert not re.search(r"ETA -\d", ln), ln  # never a negative ETA ("--:--:--": unknown)
    assert "past the 0:53:31 estimate" in lines[3]


def test_the_live_views_estimates_show_no_number_for_what_the_motion_cannot_see(static_run):
    """The run's live feed (RUN/live.jsonl, what the browser view shows): an estimate the motion does not see is
    null and flagged, not the prior's number; one it sees (the gyro's level-axis biases) is a number."""
    run, _ = static_run
    events = [json.loads(ln) for ln in (run / "live.jsonl").read_text(encoding="utf-8").splitlines() if ln.strip()]
    names = [p["name"] for p in next(e for e in events if e["event"] == "run")["data"]["parameters"]]
    est = [e["data"] for e in events if e["event"] == "estimates"]
    assert est, "no live estimates"
    for d in est:
        for name in ("S_x", "tau_xy", "r_x", "r_y", "r_z", "gyro_S_x"):
            i = names.index(name)
            assert d["values"][i] is None and d["u"][i] is None and d["identified"][i] is False, (name, d["step"])
    last = est[-1]
    i = names.index("gyro_b_x")
    assert last["identified"][i] is True and isinstance(last["values"][i], float)


def test_the_noise_report_is_deterministic(static_run):
    from benches.certificate.pdf import render_pdf

    run, _ = static_run
    a = build_certificate(run, issue_date="2026-11-27")
    b = build_certificate(run, issue_date="2026-11-27")
    assert a.is_noise_report and a.to_json() == b.to_json()
    assert render_pdf(a) == render_pdf(b)


def test_the_noise_report_quotes_the_analyses_run_on_the_record(static_run, tmp_path):
    """noise / periodic / drift run on the record (RUN/noise, …) are quoted after the report's own noise terms,
    as a certificate quotes them."""
    import shutil

    from benches.certificate.pdf import render_pdf
    from tests.certificate_fixtures import add_analyses

    run = tmp_path / "run"
    shutil.copytree(static_run[0], run)
    add_analyses(run)
    doc = pypdfium2.PdfDocument(render_pdf(build_certificate(run, issue_date="2026-11-27")))
    try:
        text = " ".join(" ".join(doc[i].get_textpage().get_text_range().split()) for i in range(len(doc)))
    finally:
        doc.close()
    assert "NOISE REPORT" in text and "Noise analysis of the run folder" in text
    assert "Periodic error" in text and "Drift model" in text and "ARMA(1,1)" in text
