"""Issue 24 acceptance: the project's own real-time bench.

The simulated ACUTROL is served on loopback TCP (reached through pyvisa-py, as a real one over Ethernet), the unit
streams KVH 1750 format-A frames from its own server thread in real time on its own clock (40 ppm off the
host's), in bursts of 8 frames (40 ms at 200 Hz), and the drivers use the host's real clock: nothing is
stepped by the host as in the polled simulated benches. A short procedure with a 30 °/s spin in both
directions, then identification: every identified parameter within 4 u of the unit's truth, the time base
found (offset and rate with u) and consistent with the realised clocks. About a minute of real time.
"""

from __future__ import annotations

import numpy as np
import pytest

from benches.bench_config import load_bench
from benches.identify import identify_run
from benches.recording import open_recording
from tests.simbench import bench_variant, run_procedure

PROCEDURE = """\
name: realtime-short
description: Level hold, three 90 degree steps about body y, a 30 deg/s spin both ways about body y.
version: 1
defaults:
  settle_s: 1
  hold_s: 3
  spin_settle_s: 1
steps:
  - warmup: {duration_s: 3, at: {x: East, y: North, z: Up}}
  - orient: {x: East, y: North, z: Up}
  - hold: {}
  - step_rotate: {axis: y, angle_deg: 90, count: 3}
  - spin: {axis: y, rate_dps: 30, direction: both, revolutions: 1}
"""

REALTIME = """  transport: loopback
  realtime: true
  clocks: {mode: separate, unit_rate_value_ppm: 40, batch_frames: 8}
"""


@pytest.fixture(scope="module")
def realtime_run(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201
    """One real-time run and its identification (about a minute), shared by the checks below."""
    tmp_path = tmp_path_factory.mktemp("realtime")
    bench = bench_variant(tmp_path, rate=200.0, source="sim-kvh.yaml", rt=("  transport: loopback\n", REALTIME))
    cfg = load_bench(bench)
    assert cfg.simulation.realtime and cfg.simulation.clocks.unit_rate == pytest.approx(40e-6)
    proc = tmp_path / "realtime-short.yaml"
    proc.write_text(PROCEDURE, encoding="utf-8")
    run = run_procedure(tmp_path, bench, str(proc), seed=24)
    res = identify_run(run, method="batch")
    with open_recording(run / "recording.h5") as rec:
        truth = rec.truth().parameters
        timing = rec.timing()
    return res, truth, timing


def _off(res, names) -> dict[str, float]:  # noqa: ANN001
    err = res.truth.error_over_u
    return {n: round(err[n], 2) for n in names if abs(err[n]) >= 4}


def test_real_time_bench_with_its_own_unit_clock_identifies_within_4_u(realtime_run):
    res, truth, timing = realtime_run
    # the unit really streamed on its own: blocks arrived in bursts, timed by the host's real clock
    assert np.all(np.isfinite(timing.block_host_time)) and np.all(np.isfinite(timing.table_host_answer))
    assert truth["unit_clock_rate"] == pytest.approx(40e-6)
    tb = res.time_base.estimate
    assert tb is not None and tb.method == "gyro" and len(tb.events) >= 4
    assert abs(tb.offset - truth["clock_offset"]) < 4 * tb.u_offset, tb.summary()
    assert abs(tb.rate - truth["clock_rate"]) < 4 * tb.u_rate, tb.summary()
    ident = [n for n, p in res.parameters.items() if p.identified and not n.startswith("gyro_")]
    assert ident, "nothing identified"  # the gyro's: the next test
    assert _off(res, ident) == {}


def test_real_time_bench_gyro_parameters_within_4_u(realtime_run):
    """The gyro's scale factors rest on the reference second: the controller clock's rate against the host's,
    measured from the fastest readings (minimum request→answer delay) and its u carried 1:1 (issue 24: gyro_S_y
    was 4–27 u off while that rate came from every reading, ±49 ppm on a loaded host, and its u was dropped)."""
    res, truth, _timing = realtime_run
    gyro = [n for n, p in res.parameters.items() if p.identified and n.startswith("gyro_")]
    assert gyro and _off(res, gyro) == {}
    ck = res.time_base.estimate.check
    e_c, u_c = ck["controller_vs_host_rate"], ck["u_controller_vs_host_rate"]
    assert abs(e_c - truth["controller_clock_rate"]) < 4 * u_c, (e_c, u_c, truth["controller_clock_rate"])
    assert not [w for w in res.warnings if w.startswith("timing misfit")], res.warnings
