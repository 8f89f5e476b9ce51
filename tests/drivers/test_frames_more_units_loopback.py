"""The simulated unit speaking each further frame format over loopback: a shortened ten-step run decoded from
real bytes identifies the same parameters as the in-process run (as the KVH and STIM300 formats do)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from analysis.identification.model import PARAM_NAMES
from benches.identify import identify_run
from benches.recording import open_recording
from tests.simbench import bench_variant, run_procedure, short_ten_step

RATE = 250.0


NEW_FORMATS = [
    ("xsens-mti-mtdata2", 151),
    ("vectornav-vn100-imu", 58),
    ("epson-g370-burst", 36),
    ("honeywell-hg4930", 44),
    ("adis16475-usb-iss", 35),
]
COUNTED = {"xsens-mti-mtdata2", "adis16475-usb-iss"}  # the others send no usable frame counter


@pytest.mark.parametrize("frame,length", NEW_FORMATS)
def test_ten_step_over_loopback_in_each_new_format_equals_in_process(tmp_path: Path, frame, length):
    proc = tmp_path / "ten-step-short.yaml"
    proc.write_text(short_ten_step(hold_s=2, warmup_s=5, name="ten-step-short"), encoding="utf-8")
    bench = bench_variant(
        tmp_path,
        rate=RATE,
        source="sim-xsens.yaml",
        name="bench.yaml",
        frame=("frame: xsens-mti-mtdata2", f"frame: {frame}"),
    )
    wire = run_procedure(tmp_path, bench, str(proc), seed=5, out="loopback", transport="loopback")
    local = run_procedure(tmp_path, bench, str(proc), seed=5, out="in-process", transport="in-process")
    with open_recording(wire) as rec:
        events = [e.message for e in rec.events()]
        n = rec.n_samples
        smp = rec.samples(fields=("counter", "status"))
    assert any(f"frame {frame}" in e for e in events)
    assert not any("missing" in e or "reset" in e or "rejected" in e for e in events)
    assert np.all(smp.status == 0)
    if frame in COUNTED:
        assert np.array_equal(smp.counter, np.arange(n))
    assert len((wire / "unit-raw.bin").read_bytes()) == n * length
    a = identify_run(wire).to_dict()
    b = identify_run(local).to_dict()
    xa = np.array([a["parameters"][p]["value"] for p in PARAM_NAMES])
    xb = np.array([b["parameters"][p]["value"] for p in PARAM_NAMES])
    sb = np.array([b["parameters"][p]["u_white"] for p in PARAM_NAMES])
    dev = np.max(np.abs(xa - xb) / sb)
    assert dev < 5e-3, f"largest difference {dev:.2e} σ"
    assert a["information"]["rank"] == b["information"]["rank"] == len(a["parameters"])  # full rank, whole unit


@pytest.mark.slow
@pytest.mark.parametrize("frame", [f for f, _n in NEW_FORMATS])
def test_whole_ten_step_fast_spin_over_loopback_equals_in_process(tmp_path: Path, frame):
    """The whole shipped ten-step-fast-spin (≈ 49 min of bench time, 250 Hz) in each new format."""
    bench = bench_variant(
        tmp_path,
        rate=RATE,
        source="sim-xsens.yaml",
        name="bench.yaml",
        frame=("frame: xsens-mti-mtdata2", f"frame: {frame}"),
    )
    wire = run_procedure(tmp_path, bench, "ten-step-fast-spin", seed=7, out="loopback", transport="loopback")
    local = run_procedure(tmp_path, bench, "ten-step-fast-spin", seed=7, out="in-process", transport="in-process")
    a = identify_run(wire).to_dict()
    b = identify_run(local).to_dict()
    xa = np.array([a["parameters"][p]["value"] for p in PARAM_NAMES])
    xb = np.array([b["parameters"][p]["value"] for p in PARAM_NAMES])
    sb = np.array([b["parameters"][p]["u_white"] for p in PARAM_NAMES])
    dev = np.max(np.abs(xa - xb) / sb)
    print(f"{frame}: largest difference {dev:.2e} sigma")
    assert dev < 5e-3, f"largest difference {dev:.2e} σ"
