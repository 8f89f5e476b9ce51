"""Issue 24 acceptance on the simulated bench with separate clocks: the estimated time base against the realised one.

The simulator draws the unit's oscillator error, the controller clock's offset and rate, transport latencies with
jitter and batching (drivers.sim.config.ClockModel); the recording's truth holds the realised mapping. Here the
bounds are the issue's: offsets up to ±20 ms, rates up to ±100 ppm. A fast version runs three seeds; the slow
one twenty (issue 24: ≥ 20 seeds).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from benches.bench_config import load_bench
from benches.identify import identify_run
from benches.recording import open_recording
from tests.simbench import bench_variant, run_procedure

SHORT = """\
name: timebase-short
description: Level hold, three 45 degree steps about body y, spins both ways about body y and z.
version: 1
defaults:
  settle_s: 1
  hold_s: 4
  spin_settle_s: 1
steps:
  - warmup: {duration_s: 5, at: {x: East, y: North, z: Up}}
  - orient: {x: East, y: North, z: Up}
  - hold: {}
  - step_rotate: {axis: y, angle_deg: 45, count: 3}
  - spin: {axis: y, rate_dps: 30, direction: both, revolutions: 1}
  - orient: {x: South, y: Down, z: East}
  - hold: {}
  - spin: {axis: x, rate_dps: 30, direction: both, revolutions: 1}
"""

CLOCKS = """  clocks:
    mode: separate
    unit_rate_ppm: 100
    controller_rate_ppm: 20
    controller_offset_ms: 20
    batch_frames: 10
"""


@pytest.fixture(scope="module")
def clock_bench(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("clocks")
    bench = bench_variant(tmp, rate=200.0, clocks=("  seed: 20261122\n", "  seed: 20261122\n" + CLOCKS))
    proc = tmp / "timebase-short.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    return tmp, bench, proc


def _check_seed(tmp, bench, proc, seed):
    run = run_procedure(tmp, bench, str(proc), seed=seed, out=f"s{seed}")
    res = identify_run(run, method="batch")
    tb = res.time_base.estimate
    with open_recording(run / "recording.h5") as rec:
        truth = rec.truth().parameters
    off, rate = truth["clock_offset"], truth["clock_rate"]
    assert tb is not None and tb.method == "gyro"
    z_off = (tb.offset - off) / tb.u_offset
    z_rate = (tb.rate - rate) / tb.u_rate
    return z_off, z_rate, tb, res


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_estimated_offset_and_rate_within_3_sigma_of_the_realised(clock_bench, seed):
    z_off, z_rate, tb, res = _check_seed(*clock_bench, seed)
    assert abs(z_off) < 3 and abs(z_rate) < 3, (z_off, z_rate, tb.summary())
    assert tb.check.get("consistent") is True, tb.check  # the host's clock agrees with the motions
    # identification on the corrected clock: every identified parameter within 4 u of the truth
    err = res.truth.error_over_u
    ident = [n for n, p in res.parameters.items() if p.identified]
    assert all(abs(err[n]) < 4 for n in ident), err
    # calibration.json carries it with its u and method
    d = res.to_dict()["time_base"]  # calibration.json
    assert d["method"] == "gyro" and d["u_offset_s"] > 0 and d["u_rate"] > 0
    assert set(d["effect_u"]) == set(res.parameters)


def test_ideal_clocks_keep_one_clock(tmp_path):
    bench = bench_variant(tmp_path, rate=200.0, clocks=("  seed: 20261122\n", "  seed: 20261122\n  clocks: ideal\n"))
    cfg = load_bench(bench)
    assert cfg.simulation.clocks.mode == "ideal"
    proc = tmp_path / "p.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    run = run_procedure(tmp_path, bench, str(proc), seed=5)
    with open_recording(run / "recording.h5") as rec:
        t = rec.truth().parameters
        tim = rec.timing()
        table = rec.table()
        k = tim.table_sample_index
        ts = rec.samples(fields=("time",)).time
    assert t["clock_offset"] == 0.0 and t["clock_rate"] == 0.0
    # one clock: each reading is stamped at the time of the next sample (the unit's clock)
    np.testing.assert_allclose(table.time, k / 200.0, atol=1e-9)
    assert ts.size > 0
    tb = identify_run(run, method="batch").time_base.estimate
    assert abs(tb.offset) < 3 * tb.u_offset + 1e-9 and abs(tb.rate) < 3 * tb.u_rate + 1e-12


def test_separate_clocks_are_deterministic(tmp_path):
    bench = bench_variant(tmp_path, rate=200.0)
    proc = tmp_path / "p.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    a = run_procedure(tmp_path, bench, str(proc), seed=9, out="a")
    b = run_procedure(tmp_path, bench, str(proc), seed=9, out="b")
    with open_recording(a / "recording.h5") as ra, open_recording(b / "recording.h5") as rb:
        assert [s.sha256 for s in ra.steps] == [s.sha256 for s in rb.steps]
        ta, tb_ = ra.timing(), rb.timing()
        for name in ("table_controller_time", "table_host_request", "table_host_answer", "block_host_time"):
            np.testing.assert_array_equal(getattr(ta, name), getattr(tb_, name))
        assert np.all(np.isfinite(ta.table_controller_time)) and np.all(np.isfinite(ta.block_host_time))


@pytest.mark.slow
def test_twenty_seeds_offset_and_rate_within_3_sigma(clock_bench):
    zs = []
    for seed in range(100, 120):
        z_off, z_rate, _tb, _res = _check_seed(*clock_bench, seed)
        zs.append((z_off, z_rate))
    z = np.array(zs)
    print("z offset", np.round(z[:, 0], 2), "z rate", np.round(z[:, 1], 2))
    assert np.all(np.abs(z) < 3), z
    assert math.sqrt(np.mean(z**2)) < 1.5, z  # the stated σ is not grossly inflated or deflated


def test_declared_hardware_timing_is_used_and_checked(tmp_path):
    """A bench declaring a PPS line: one clock is used (identity), the estimate from the motions checks it."""
    bench = bench_variant(
        tmp_path,
        rate=200.0,
        clocks=("  seed: 20261122\n", "  seed: 20261122\n  clocks: ideal\n"),
        pps=("  latency_ms:", "  time_reference: pps\n  latency_ms:"),
    )
    assert load_bench(bench).unit.time_reference == "pps"
    proc = tmp_path / "p.yaml"
    proc.write_text(SHORT, encoding="utf-8")
    run = run_procedure(tmp_path, bench, str(proc), seed=6)
    res = identify_run(run, method="batch")
    tb = res.time_base.estimate
    assert tb.method == "hardware" and tb.offset == 0.0 and tb.rate == 0.0
    assert tb.check["hardware"]["consistent"] is True  # one clock really: the motions agree
    assert any("hardware timing declared (pps)" in n for n in tb.notes)
