"""``tablebench run`` of a thermal procedure on the simulated thermal bench: the soak waits for the unit's own
temperature, the ramp moves the set point while the sequence repeats, the chamber's readings are recorded, and
the exit path leaves the chamber at its safe set point, stopped."""

from __future__ import annotations

from pathlib import Path

from benches.cli.main import main
from benches.recording import open_recording
from tests import REPO_ROOT

PROCEDURE = """name: short-thermal
description: a soak, a hold, a short ramp with a repeated hold
version: 1
defaults: {settle_s: 1, hold_s: 5}
steps:
  - soak: {setpoint_c: 25, tolerance_k: 1.0, rate_k_per_min: 1.0, dwell_s: 20, timeout_s: 10800}
  - orient: {x: East, y: North, z: Up}
  - hold: {}
  - ramp:
      from_c: 25
      to_c: 26
      rate_k_per_min: 1.0
      soak: {tolerance_k: 1.0, rate_k_per_min: 1.0, dwell_s: 10}
      steps:
        - orient: {x: East, y: North, z: Up}
        - hold: {duration_s: 20}
"""


def test_run_soaks_ramps_records_and_leaves_the_chamber_safe(tmp_path: Path, capsys) -> None:
    proc = tmp_path / "short.yaml"
    proc.write_text(PROCEDURE, encoding="utf-8")
    out = tmp_path / "run"
    bench = str(REPO_ROOT / "benches" / "sim-thermal.yaml")
    assert main(["run", "--bench", bench, "--procedure", str(proc), "--out", str(out), "--no-identify"]) == 0
    with open_recording(out / "recording.h5") as rec:
        assert rec.header.status == "complete"
        names = [s.name for s in rec.complete_steps()]
        assert names[:5] == ["soak", "orient", "hold", "ramp-soak", "ramp-start"]
        assert sum(1 for n in names if n.startswith("hold~")) >= 3  # 60 s of ramp / ~21 s per repetition
        messages = [e.message for e in rec.events()]
    readings = [m for m in messages if m.startswith("chamber: setpoint_K=")]
    assert readings and all("air_K=" in m and "unit_K=" in m for m in readings)
    assert any(m.startswith("chamber: soaked") for m in messages)
    assert any(m == "chamber: ramp reached 26 °C" for m in messages)
    assert messages[-1] == "chamber at its safe set point 25 °C and stopped" or any(
        m == "chamber at its safe set point 25 °C and stopped" for m in messages
    )


def test_a_run_interrupted_mid_plateau_resumes_at_that_plateaus_soak() -> None:
    from benches.session import plateau_soak
    from procedures.compiler import compile_procedure
    from procedures.loader import load_procedure_text
    from tests.procedures.test_thermal_steps import CHAMBER, LIMITS

    text = PROCEDURE.replace("  - ramp:", "  - soak: {setpoint_c: 30}\n  - hold: {}\n  - ramp:")
    steps = list(compile_procedure(load_procedure_text(text), limits=LIMITS, chamber=CHAMBER).steps)
    names = [s.name for s in steps]
    # stopped in the first plateau's hold: soak again at 25 °C; in the second plateau's hold: at 30 °C
    assert plateau_soak(steps, {0, 1}).name == "soak"
    assert plateau_soak(steps, set(range(names.index("hold#2")))).name == "soak#2"
    assert plateau_soak(steps, set(range(names.index("soak#2")))) is None  # resumes at the soak itself
    assert plateau_soak(steps, set()) is None
