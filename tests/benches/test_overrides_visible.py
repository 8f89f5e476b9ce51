"""Issue 12: a --set override is visible in the recording's header, `tablebench runs`, calibration.json and
the certificate (JSON and PDF)."""

from __future__ import annotations

import json

import pypdf

from benches.cli import main
from benches.recording import open_recording
from tests.simbench import bench_variant


def test_set_override_is_visible_everywhere(tmp_path, capsys):
    bench = bench_variant(tmp_path, rate=50.0)
    run = tmp_path / "runs" / "noise"
    argv = ["run", "--bench", str(bench), "--procedure", "static-noise", "--seed", "1", "--plain"]
    argv += ["--set", "duration_s=20", "--set", "warmup_s=5", "--out", str(run)]
    assert main(argv) == 0
    with open_recording(run) as rec:
        assert rec.header.procedure_overrides == {"duration_s": 20.0, "warmup_s": 5.0}
    capsys.readouterr()
    assert main(["runs", str(tmp_path / "runs")]) == 0
    assert "duration_s=20 warmup_s=5" in capsys.readouterr().out
    cal = json.loads((run / "calibration.json").read_text(encoding="utf-8"))
    assert cal["run"]["procedure_overrides"] == {"duration_s": 20.0, "warmup_s": 5.0}
    # a static record gets a noise report (issue 26) instead of a calibration certificate: the same blocks
    cert = json.loads((run / "noise-report.json").read_text(encoding="utf-8"))
    assert cert["procedure"]["procedure_overrides"] == {"duration_s": 20.0, "warmup_s": 5.0}
    text = " ".join(p.extract_text() for p in pypdf.PdfReader(str(run / "noise-report.pdf")).pages)
    assert "duration_s = 20" in " ".join(text.split()) and "warmup_s = 5" in " ".join(text.split())
