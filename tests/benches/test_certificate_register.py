"""Issue 12 item 7: certificate numbers from a register in the runs folder; never reused, never overwritten."""

from __future__ import annotations

import json
import subprocess
import sys

import pypdf
import pytest

from benches.certificate import issue_certificate
from benches.certificate_register import LOCK_NAME, CertificateRegister, RegisterError, write_new
from benches.cli import main
from tests.certificate_fixtures import make_run_folder


def _first_page(pdf) -> str:
    return pypdf.PdfReader(str(pdf)).pages[0].extract_text()


def test_issuing_twice_gives_two_numbers_and_two_pdfs_the_second_naming_the_first(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "run")
    pdf1, js1, _ = issue_certificate(run, issue_date="2026-11-22")
    first = pdf1.read_bytes()
    pdf2, js2, _ = issue_certificate(run, issue_date="2026-11-22")
    assert pdf1 != pdf2 and js1 != js2 and pdf1.read_bytes() == first  # the first PDF is untouched
    c1, c2 = (json.loads(p.read_text(encoding="utf-8")) for p in (js1, js2))
    assert c1["certificate_number"] != c2["certificate_number"]
    assert c1["supersedes"] == "" and c2["supersedes"] == c1["certificate_number"]
    assert f"Supersedes No. {c1['certificate_number']}" in _first_page(pdf2)
    assert c2["certificate_number"] in _first_page(pdf2)
    reg = CertificateRegister(tmp_path / "runs").entries()
    assert [e.number for e in reg] == [c1["certificate_number"], c2["certificate_number"]]
    assert [e.serial for e in reg] == [1, 2]
    # an explicit output that exists is refused (exit 2), and no number is consumed by the refusal
    assert main(["certificate", str(run), "--out", str(pdf1)]) == 2
    assert len(CertificateRegister(tmp_path / "runs").entries()) == 2


def test_numbers_are_monotonic_across_runs_and_never_reused(tmp_path):
    reg = CertificateRegister(tmp_path)
    nums = [
        reg.allocate(tmp_path / f"r{k % 2}", "0" * 64, lambda n: (tmp_path / n, tmp_path / n)).number for k in range(4)
    ]
    assert nums == ["TB-000001", "TB-000002", "TB-000003", "TB-000004"]
    assert reg.latest_for(tmp_path / "r0").number == "TB-000003"
    assert reg.entries()[3].supersedes == "TB-000002"


def test_two_processes_never_get_the_same_number(tmp_path):
    code = (
        "import sys; from pathlib import Path; from benches.certificate_register import CertificateRegister as R; "
        "r = R(Path(sys.argv[1])); "
        "[r.allocate(Path(sys.argv[1]) / sys.argv[2], '0', lambda n: (Path(n), Path(n))) for _ in range(15)]"
    )
    procs = [subprocess.Popen([sys.executable, "-c", code, str(tmp_path), f"run{k}"]) for k in range(3)]
    assert all(p.wait(timeout=120) == 0 for p in procs)
    serials = [e.serial for e in CertificateRegister(tmp_path).entries()]
    assert sorted(serials) == list(range(1, 46)) and len(set(serials)) == 45
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_stale_lock_of_a_dead_process_is_broken_and_files_are_never_overwritten(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (tmp_path / LOCK_NAME).write_text(dead.stdout.strip())
    reg = CertificateRegister(tmp_path).allocate(tmp_path / "r", "0", lambda n: (tmp_path / "a", tmp_path / "b"))
    assert reg.number == "TB-000001"
    target = tmp_path / "x.pdf"
    write_new(target, b"one")
    with pytest.raises(RegisterError, match="never overwritten"):
        write_new(target, b"two")
    assert target.read_bytes() == b"one"
