"""End to end over loopback with the simulated unit speaking KVH 1750 format A and STIM300 datagram 0x93:
the real decoder on real bytes, the recording's events, the kept raw stream re-decoded, and the
identification equal to the in-process run within the formats' quantisation."""

from __future__ import annotations

from pathlib import Path

import h5py  # only to craft a damaged copy as another tool would
import numpy as np
import pytest

from analysis.identification.model import PARAM_NAMES
from benches.identify import identify_run
from benches.recording import open_recording
from tests.simbench import bench_variant, run_procedure, short_ten_step

RATE = 250.0


def _short_ten_step(tmp_path: Path) -> Path:
    p = tmp_path / "ten-step-short.yaml"
    p.write_text(short_ten_step(hold_s=2, warmup_s=5, name="ten-step-short"), encoding="utf-8")
    return p


@pytest.mark.parametrize(
    "bench_name,frame,length", [("sim-kvh.yaml", "kvh-1750-a", 36), ("sim-stim300.yaml", "stim300-0x93", 38)]
)
def test_ten_step_over_loopback_in_a_real_format_equals_in_process(tmp_path, bench_name, frame, length):
    proc = _short_ten_step(tmp_path)
    bench = bench_variant(tmp_path, rate=RATE, source=bench_name, name=bench_name)
    wire = run_procedure(tmp_path, bench, str(proc), seed=5, out="loopback", transport="loopback")
    local = run_procedure(tmp_path, bench, str(proc), seed=5, out="in-process", transport="in-process")
    with open_recording(wire) as rec:  # the one reader (accel may be stored as counts)
        events = [e.message for e in rec.events()]
        n = rec.n_samples
        smp = rec.samples(fields=("counter", "accel", "status"))
        counter, accel, status = smp.counter, smp.accel, smp.status
    assert any(f"frame {frame}" in e for e in events)
    if frame.startswith("kvh"):
        assert any("increments per sample" in e and "dividing by the sample interval" in e for e in events)
    assert any("unit-raw.bin" in e for e in events)
    assert not any("missing" in e or "reset" in e or "rejected" in e for e in events)
    assert np.array_equal(counter, np.arange(n)) and np.all(status == 0)
    # the raw stream is kept: every byte of every frame, and re-decoding it gives the recorded samples
    raw = (wire / "unit-raw.bin").read_bytes()
    assert len(raw) == n * length
    from benches.bench_config import load_bench, unit_frame_format
    from benches.cli.commands.decode import decode_file

    samples, stats = decode_file(wire / "unit-raw.bin", unit_frame_format(load_bench(bench).unit))
    assert stats.frames == n and stats.rejected == 0 and np.array_equal(samples.accel, accel)
    # identification equal within the formats' quantisation (float32 in g; 2^-19 g and 2^-14 °/s LSBs):
    # the quantisation noise is < 1e-3 of the white noise per sample, so estimates move by ≪ their σ
    a = identify_run(wire).to_dict()
    b = identify_run(local).to_dict()
    xa = np.array([a["parameters"][p]["value"] for p in PARAM_NAMES])
    xb = np.array([b["parameters"][p]["value"] for p in PARAM_NAMES])
    sb = np.array([b["parameters"][p]["u_white"] for p in PARAM_NAMES])
    assert np.max(np.abs(xa - xb) / sb) < 0.05
    assert a["information"]["rank"] == b["information"]["rank"] == len(b["parameter_names"]) == 33  # whole unit
    # a unit without a temperature channel records NaN: the calibration says "none" and can be written (strict JSON)
    from core.jsonio import dumps

    for r in (a, b):
        t = r["run"]["temperature_k"]
        assert all(v is None or np.isfinite(v) for v in t.values())
        dumps(r)  # raises on a non-finite number


def test_samples_flagged_invalid_are_never_used(tmp_path):
    """Samples whose status flags the accelerometers are left out of the identification and refused by the
    analysis inputs; the same corrupted samples unflagged would wreck the estimate."""
    import shutil

    from benches.cli.analysis_input import InputError, load_input

    proc = _short_ten_step(tmp_path)
    bench = bench_variant(tmp_path, rate=RATE, source="sim-kvh.yaml", name="sim-kvh.yaml")
    run = run_procedure(tmp_path, bench, str(proc), seed=5, out="clean", transport="in-process")
    base = identify_run(run).to_dict()
    flagged, unflagged = tmp_path / "flagged", tmp_path / "unflagged"
    for folder, flag in ((flagged, True), (unflagged, False)):
        shutil.copytree(run, folder)
        with open_recording(folder) as rec:
            a = rec.step("A/hold-1").acq_start
            b = a + 100
        with h5py.File(folder / "recording.h5", "r+") as f:  # crafted as another tool would: no checksums
            f.attrs["format_version"] = 1  # edited data no longer match the step SHA-256 of a format-2 file
            d = f["imu/accel"]
            lsb = d.attrs.get("lsb")
            d[a:b, 0] += 1.0 if lsb is None else int(round(1.0 / lsb))  # 0.1 g of rubbish on x
            if flag:
                f["imu/status"][a:b] = 1  # accel_x invalid
    xs = {}
    for key, folder in (("base", None), ("flagged", flagged), ("unflagged", unflagged)):
        r = base if folder is None else identify_run(folder).to_dict()
        xs[key] = np.array([r["parameters"][p]["value"] for p in PARAM_NAMES])
    sigma = np.array([base["parameters"][p]["u_white"] for p in PARAM_NAMES])
    assert np.max(np.abs(xs["flagged"] - xs["base"]) / sigma) < 0.5
    assert np.max(np.abs(xs["unflagged"] - xs["base"]) / sigma) > 5.0
    with pytest.raises(InputError, match=r"100 sample\(s\) of accel_x flagged invalid"):
        load_input(flagged, channels="accel_x")
    assert load_input(flagged, channels="gyro_x").channels["gyro_x"].size > 0  # other channels stay usable
