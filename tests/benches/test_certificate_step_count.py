"""Issue 12 (content): the certificate's step counts match the run — for a run of a procedure with many steps
that was interrupted, certified as incomplete, then resumed and certified again (the issue saw "35/36 steps"
printed for an interrupted 56-step run)."""

from __future__ import annotations

import os
import signal
import subprocess

from pypdf import PdfReader

from benches.bench_config import load_bench
from benches.certificate import build_certificate
from benches.recording import open_recording
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure_text
from tests.simbench import CLI, bench_variant, short_ten_step, start_cli, wait_for_step

SHORT = short_ten_step(hold_s=3, warmup_s=5)


def _compiled_steps(bench, text: str) -> int:
    cfg = load_bench(bench)
    proc = load_procedure_text(text, "short-ten-step.yaml")
    return len(compile_procedure(proc, limits=cfg.turntable.limits, mounting=cfg.unit.mounting).steps)


def _recorded(out) -> tuple[int, int]:
    with open_recording(out / "recording.h5") as rec:
        return len(rec.steps), sum(s.status == "complete" for s in rec.steps)


def test_certificate_step_counts_match_an_interrupted_then_resumed_run(tmp_path):
    bench = bench_variant(tmp_path, rate=200.0)
    proc = tmp_path / "short-ten-step.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    n_total = _compiled_steps(bench, SHORT)
    assert n_total > 40  # a procedure with many steps
    out = tmp_path / "run"
    p = start_cli(["run", "--bench", str(bench), "--procedure", str(proc), "--seed", "5", "--plain", "--no-identify",
                "--out", str(out)], tmp_path)  # fmt: skip
    wait_for_step(p, "C/hold-2")
    os.kill(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err[-2000:]

    # interrupted: the certificate of the completed steps counts them against the whole procedure
    n_rec, n_done = _recorded(out)
    assert 0 < n_done < n_total and n_rec <= n_total
    res = subprocess.run(CLI + ["identify", str(out)], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    rec = build_certificate(out, allow_incomplete=True, with_plots=False).recording
    assert (rec["steps_complete"], rec["steps"], rec["steps_recorded"]) == (n_done, n_total, n_rec)

    # resumed to the end: every step of the procedure recorded and complete, and the certificate says so
    res = subprocess.run(CLI + ["run", "--resume", str(out), "--plain"], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    n_rec, n_done = _recorded(out)
    assert n_rec == n_done == n_total
    rec = build_certificate(out, with_plots=False).recording
    assert rec["status"] == "complete"
    assert (rec["steps_complete"], rec["steps"], rec["steps_recorded"]) == (n_total, n_total, n_total)
    pdfs = sorted(out.glob("*.pdf"))  # the certificate the resumed run issued prints the same count
    assert pdfs, sorted(x.name for x in out.iterdir())
    text = " ".join("".join(page.extract_text() for page in PdfReader(pdfs[-1]).pages).split())
    assert f"{n_total} of {n_total} procedure steps completed" in text, text[:3000]
