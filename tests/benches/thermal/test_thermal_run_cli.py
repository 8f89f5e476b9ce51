"""``tablebench run`` of a thermal procedure on the simulated thermal bench: the soak waits for the unit's own
temperature, the ramp moves the set point while the sequence repeats, the chamber's readings are recorded, and
the exit path leaves the chamber at its safe set point, stopped."""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import numpy as np

from analysis.units import celsius_to_kelvin
from benches.cli.main import main
from benches.recording import open_recording
from benches.thermal.record import chamber_readings
from tests import REPO_ROOT
from tests.simbench import CLI, start_cli, wait_for_step

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
        assert rec.aux_names() == ["chamber"]  # the chamber's own recording group, not only event lines
        aux = rec.aux("chamber")
        from_group = chamber_readings(rec)
    assert aux.units == {"setpoint": "K", "air": "K", "unit": "K", "running": "1", "alarm": "1"}
    assert len(aux.time) >= 3 and np.all(np.diff(aux.time) > 0)
    assert np.all(aux.channels["running"] == 1.0) and np.all(aux.channels["alarm"] == 0.0)
    sp, unit = aux.channels["setpoint"], aux.channels["unit"]
    assert sp[0] == celsius_to_kelvin(25.0) and celsius_to_kelvin(25.5) < sp.max() <= celsius_to_kelvin(26.0)  # ramp
    assert np.all(np.abs(unit - celsius_to_kelvin(25.5)) < 3.0)  # the unit's channel, K (not °C, not counts)
    assert from_group.source == "aux" and np.array_equal(from_group.time, aux.time)
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


def test_older_recording_without_the_aux_group_gives_the_chamber_readings_from_the_event_log(tmp_path: Path) -> None:
    """A recording made before /aux/chamber existed: the same readings come from its event lines."""
    from benches.recording import Hdf5Recorder

    rec = Hdf5Recorder(tmp_path / "recording.h5", attrs={"sample_rate_hz": 100.0})
    rec.event(0.0, "info", "chamber: soak to 25 °C")
    rec.event(30.0, "info", "chamber: setpoint_K=298.150 air_K=297.900 unit_K=296.500 running=True alarm=False (x)")
    rec.event(60.0, "info", "chamber: setpoint_K=298.150 air_K=298.100 unit_K=nan running=True alarm=False (x)")
    rec.close()
    with open_recording(tmp_path / "recording.h5") as r:
        got = chamber_readings(r)
    assert got.source == "events"
    np.testing.assert_array_equal(got.time, [30.0, 60.0])
    np.testing.assert_array_equal(got.channels["air"], [297.9, 298.1])
    assert got.channels["unit"][0] == 296.5 and np.isnan(got.channels["unit"][1])


TWO_PLATEAUS = """name: two-plateaus
description: two soaks with a hold after each
version: 1
defaults: {settle_s: 1, hold_s: 5}
steps:
  - soak: {setpoint_c: 25, tolerance_k: 1.0, rate_k_per_min: 1.0, dwell_s: 20, timeout_s: 10800}
  - orient: {x: East, y: North, z: Up}
  - hold: {}
  - soak: {setpoint_c: 30, tolerance_k: 1.0, rate_k_per_min: 1.0, dwell_s: 20, timeout_s: 10800}
  - orient: {x: East, y: North, z: Up}
  - hold: {duration_s: 600}
  - hold: {}
"""


def test_a_run_stopped_in_the_second_plateau_resumes_at_its_soak_end_to_end(tmp_path: Path) -> None:
    proc_file = tmp_path / "two.yaml"
    proc_file.write_text(TWO_PLATEAUS, encoding="utf-8")
    out = tmp_path / "run"
    bench = str(REPO_ROOT / "benches" / "sim-thermal.yaml")
    args = ["run", "--bench", bench, "--procedure", str(proc_file), "--out", str(out), "--plain", "--no-identify"]
    env_cwd = tmp_path
    p = start_cli(args, env_cwd)
    wait_for_step(p, "hold#2")  # inside the second plateau (its soak done)
    os.kill(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err[-2000:]
    with open_recording(out / "recording.h5") as rec:
        done = [s.name for s in rec.complete_steps()]
    assert "soak#2" in done and "hold#3" not in done
    res = subprocess.run(CLI + ["run", "--resume", str(out), "--plain"], cwd=env_cwd, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    with open_recording(out / "recording.h5") as rec:
        assert rec.header.status == "complete"
        events = [(e.time, e.message) for e in rec.events()]
        steps = {s.name: s for s in rec.steps}
    resumed = [t for t, m in events if m == "resumed mid-plateau: soak soak#2 again"]
    assert len(resumed) == 1, [m for _, m in events]
    soaked_after = [t for t, m in events if m.startswith("chamber: soaked") and t >= resumed[0]]
    assert soaked_after, "the resumed run did not soak at the second plateau again"
    # the steps after the interruption were acquired after that soak, at the second plateau's temperature
    rate = 100.0
    assert steps["hold#2"].acq_start / rate >= soaked_after[0] - 1.0
