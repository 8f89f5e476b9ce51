"""The registry as the second results sink: `certificate` records into it by itself; an unreachable registry
costs one line and never the certificate; `registry add` later records the same run."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from analysis.units import DISPLAY_UNITS
from benches.results.registry import Registry
from benches.results.registry.queries import history
from tests.certificate_fixtures import make_run_folder

CLI = [sys.executable, "-m", "benches.cli"]


def _env(**kv):
    env = dict(os.environ)
    env.pop("TABLEBENCH_REGISTRY", None)
    env.update(kv)
    return env


def test_certificate_records_into_the_default_registry_of_the_runs_folder(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    p = subprocess.run([*CLI, "certificate", str(run), "--issue-date", "2026-11-27", "--operator", "B. Tech"],
                       capture_output=True, text=True, timeout=600, env=_env(), cwd=tmp_path)  # fmt: skip
    assert p.returncode in (0, 1), p.stderr
    assert "registry" not in p.stderr  # nothing to report
    reg = Registry(f"sqlite:///{tmp_path / 'runs' / 'registry.sqlite'}")
    [row] = history(reg, "SIM-U-0001")
    number = (run.parent / "certificate-register.jsonl").read_text().split('"number": "')[1][:9]
    assert row.certificate_number == number and row.decision is not None and row.operator == "B. Tech"
    assert row.certificate_covariance is not None


def test_an_unreachable_registry_costs_one_line_and_registry_add_records_the_run_later(tmp_path):
    run = make_run_folder(tmp_path / "runs" / "r1")
    down = "postgresql://nobody@127.0.0.1:1/registry"
    p = subprocess.run([*CLI, "certificate", str(run), "--issue-date", "2026-11-27"], capture_output=True, text=True,
                       timeout=600, env=_env(TABLEBENCH_REGISTRY=down), cwd=tmp_path)  # fmt: skip
    assert p.returncode in (0, 1), p.stderr
    assert (run / "certificate.pdf").exists() and (run / "certificate.json").exists()
    lines = [ln for ln in p.stderr.splitlines() if ln.startswith("registry ")]
    assert len(lines) == 1, p.stderr
    assert "127.0.0.1:1" in lines[0] and f"tablebench registry add {run}" in lines[0] and "Traceback" not in p.stderr
    db = f"sqlite:///{tmp_path / 'later.sqlite'}"
    p = subprocess.run([*CLI, "registry", "add", str(run), "--registry", db], capture_output=True, text=True,
                       timeout=600, env=_env(), cwd=tmp_path)  # fmt: skip
    assert p.returncode == 0, p.stderr
    [row] = history(Registry(db), "SIM-U-0001")
    assert row.certificate_number is not None


def test_a_whole_unit_run_records_into_the_registry_by_itself(tmp_path):
    """`run` on the simulated bench (accelerometer and gyro triads: 33 states) records into the registry without
    any further command; the registry keeps every parameter of it (both triads), values as calibration.json's,
    and its full covariance; history, trend, compare and export show the gyro parameters in display units."""
    from tests.simbench import bench_variant, short_ten_step

    bench = bench_variant(tmp_path, rate=100.0)
    proc = tmp_path / "short.yaml"
    proc.write_text(short_ten_step(hold_s=2, warmup_s=5, name="short"), encoding="utf-8")
    url = f"sqlite:///{tmp_path / 'lab.sqlite'}"
    p = subprocess.run([*CLI, "run", "--bench", str(bench), "--procedure", str(proc), "--out", str(tmp_path / "r"),
                        "--plain", "--seed", "4"], capture_output=True, text=True, timeout=600,
                       env=_env(TABLEBENCH_REGISTRY=url), cwd=tmp_path)  # fmt: skip
    assert p.returncode == 0, p.stderr[-2000:]
    assert "registry: could not" not in p.stderr, p.stderr[-2000:]
    [row] = history(Registry(url), "SIM-U-0001")
    assert row.certificate_number
    cal = json.loads((tmp_path / "r" / "calibration.json").read_text(encoding="utf-8"))
    names = list(cal["parameter_names"])
    assert any(n.startswith("gyro_") for n in names)
    assert list(row.names) == names
    for i, n in enumerate(names):
        assert row.values[i] == cal["parameters"][n]["value"], n
    cov = json.loads(row.covariance)
    assert len(cov) == len(names) and all(len(r) == len(names) for r in cov)
    reg = ["--registry", url]
    shown = subprocess.run([*CLI, "registry", "show", "SIM-U-0001", *reg], capture_output=True, text=True,
                           timeout=120, env=_env(), cwd=tmp_path)  # fmt: skip
    assert shown.returncode == 0, shown.stderr
    gyro_b = [ln for ln in shown.stdout.splitlines() if ln.startswith("gyro_b_x")]
    assert gyro_b and DISPLAY_UNITS["gyro_bias"][0] in gyro_b[0].split(), shown.stdout
    out = tmp_path / "trend.png"
    tr = subprocess.run([*CLI, "registry", "trend", "SIM-U-0001", "--param", "gyro_S_y", "--out", str(out), *reg],
                        capture_output=True, text=True, timeout=120, env=_env(), cwd=tmp_path)  # fmt: skip
    assert tr.returncode == 0 and out.stat().st_size > 0, tr.stderr
    ex = tmp_path / "u.json"
    e = subprocess.run([*CLI, "registry", "export", "SIM-U-0001", "--format", "json", "--out", str(ex), *reg],
                       capture_output=True, text=True, timeout=120, env=_env(), cwd=tmp_path)  # fmt: skip
    assert e.returncode == 0, e.stderr
    doc = json.loads(ex.read_text(encoding="utf-8"))
    assert doc["parameter_names"] == names and "gyro_S_y" in doc["calibrations"][0]["parameters"]
