"""End to end over loopback with the simulated unit speaking KVH 1750 format A and STIM300 datagram 0x93:
the real decoder on real bytes, the recording's events, the kept raw stream re-decoded, and the
identification equal to the in-process run within the formats' quantisation."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.identification.model import PARAM_NAMES
from benches.identify import identify_run
from tests import REPO_ROOT
from tests.simbench import run_procedure

RATE = 250.0


def _short_ten_step(tmp_path: Path) -> Path:
    """The published ten-step sequence with short holds and fast spins (the same steps, less bench time)."""
    text = (REPO_ROOT / "procedures" / "ten-step.yaml").read_text(encoding="utf-8")
    for old, new in (
        ("hold_s: 60", "hold_s: 2"),
        ("settle_s: 5", "settle_s: 1"),
        ("spin_settle_s: 10", "spin_settle_s: 1"),
        ("duration_s: 900", "duration_s: 5"),
        ("rate_dps: 1.6", "rate_dps: 30"),
        ("name: ten-step", "name: ten-step-short"),
    ):
        assert old in text
        text = text.replace(old, new)
    p = tmp_path / "ten-step-short.yaml"
    p.write_text(text, encoding="utf-8")
    return p


def _bench(tmp_path: Path, name: str) -> Path:
    text = (REPO_ROOT / "benches" / name).read_text(encoding="utf-8")
    text = re.sub(r"sample_rate_hz: [0-9.]+", f"sample_rate_hz: {RATE}", text)
    text = re.sub(r"anti_alias_hz: [0-9.]+", f"anti_alias_hz: {RATE / 4}", text)
    text = re.sub(r"latency_ms: [0-9.]+", f"latency_ms: {1e3 / (2**0.5 * RATE):.6g}", text)
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize(
    "bench_name,frame,length", [("sim-kvh.yaml", "kvh-1750-a", 36), ("sim-stim300.yaml", "stim300-0x93", 38)]
)
def test_ten_step_over_loopback_in_a_real_format_equals_in_process(tmp_path, bench_name, frame, length):
    proc = _short_ten_step(tmp_path)
    bench = _bench(tmp_path, bench_name)
    wire = run_procedure(tmp_path, bench, str(proc), seed=5, out="loopback", transport="loopback")
    local = run_procedure(tmp_path, bench, str(proc), seed=5, out="in-process", transport="in-process")
    from benches.recording import open_recording

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
    from benches.commands.decode import decode_file

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
    assert a["information"]["rank"] == b["information"]["rank"] == 18


def test_samples_flagged_invalid_are_never_used(tmp_path):
    """Samples whose status flags the accelerometers are left out of the identification and refused by the
    analysis inputs; the same corrupted samples unflagged would wreck the estimate."""
    import shutil

    from benches.analysis_input import InputError, load_input

    proc = _short_ten_step(tmp_path)
    bench = _bench(tmp_path, "sim-kvh.yaml")
    run = run_procedure(tmp_path, bench, str(proc), seed=5, out="clean", transport="in-process")
    base = identify_run(run).to_dict()
    flagged, unflagged = tmp_path / "flagged", tmp_path / "unflagged"
    for folder, flag in ((flagged, True), (unflagged, False)):
        shutil.copytree(run, folder)
        with h5py.File(folder / "recording.h5", "r+") as f:
            steps = f["steps"][()]
            row = steps[[s.decode() if isinstance(s, bytes) else s for s in steps["name"]].index("A/hold-1")]
            a, b = int(row["acq_start"]), int(row["acq_start"]) + 100
            acc = f["imu/accel"]  # stored as int32 counts of attrs["lsb"] when the samples are quantised
            acc[a:b, 0] += round(1.0 / acc.attrs["lsb"]) if "lsb" in acc.attrs else 1.0  # 0.1 g of rubbish on x
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
