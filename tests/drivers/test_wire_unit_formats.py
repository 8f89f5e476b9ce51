"""The unit's frame format from the bench (keys, errors with file:line), the simulated unit speaking KVH and
STIM300 to the real serial driver (corruption counted), link events, and ``tablebench decode``."""

from __future__ import annotations

import io
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import pytest
import serial

from analysis.units import G0
from benches.bench_config import load_bench, load_bench_text, unit_frame_format
from benches.cli import main
from core.yaml_source import ConfigError
from drivers.imu_unit.counts import frames_to_block
from drivers.imu_unit.description import compile_format, load_frame
from drivers.imu_unit.samples import encode_samples
from drivers.imu_unit.serial_unit import SerialInertialUnit
from drivers.sim.serial_unit import Corruption, SerialUnitServer
from tests import REPO_ROOT, line_of
from tests.drivers.wire_support import make_world

BENCHES = REPO_ROOT / "benches"
KVH = (BENCHES / "sim-kvh.yaml").read_text(encoding="utf-8")


def test_shipped_format_benches_load_with_their_options():
    kvh = load_bench(BENCHES / "sim-kvh.yaml")
    assert kvh.unit.frame == "kvh-1750-a" and kvh.unit.keep_raw
    fmt = unit_frame_format(kvh.unit)
    assert fmt.options["gyro_output"] == "delta_angle_rad" and fmt.increments() == ["gyro_x", "gyro_y", "gyro_z"]
    stim = load_bench(BENCHES / "sim-stim300.yaml")
    fmt = unit_frame_format(stim.unit)
    assert fmt.counter_step == 2 and fmt.options["accel_range_g"] == "10"
    assert load_bench(BENCHES / "sim.yaml").unit.frame == "tablebench-v1"


@pytest.mark.parametrize(
    "old,new,needle,words",
    [
        ("frame: kvh-1750-a ", "frame: kvh-9999 ", "frame:", ["unknown frame format", "kvh-1750-a"]),
        ("gyro_output: delta_angle_rad", "gyro_output: furlongs", "frame_options", ["not allowed", "rate_rad_s"]),
        ("accel_output: g,", "accel_outptu: g,", "frame_options", ["unknown option", "accel_output"]),
        ("keep_raw: true", "keep_raw: 3", "keep_raw", ["true or false"]),
        ("frame: kvh-1750-a ", "frame: missing.yaml ", "frame:", ["not found"]),
    ],
)
def test_bad_unit_format_keys_name_the_bench_line(tmp_path, old, new, needle, words):
    assert old in KVH
    text = KVH.replace(old, new)
    p = tmp_path / "bench.yaml"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as ei:
        load_bench(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}:{line_of(text, needle)}:"), msg
    assert all(w in msg for w in words), msg


def test_stim_counter_step_must_divide_2000_hz(tmp_path):
    text = (
        (BENCHES / "sim-stim300.yaml")
        .read_text(encoding="utf-8")
        .replace("sample_rate_hz: 1000.0", "sample_rate_hz: 300")
    )
    text = text.replace("anti_alias_hz: 250.0", "anti_alias_hz: 70")
    with pytest.raises(ConfigError, match="must divide 2000 Hz"):
        load_bench_text(text, tmp_path / "b.yaml")


def test_a_users_description_next_to_the_bench(tmp_path):
    (tmp_path / "my-unit.yaml").write_text(
        (REPO_ROOT / "drivers/imu_unit/frames/kvh-1750-a.yaml").read_text().replace("name: kvh-1750-a", "name: mine"),
        encoding="utf-8",
    )
    p = tmp_path / "bench.yaml"
    p.write_text(KVH.replace("frame: kvh-1750-a ", "frame: my-unit.yaml "), encoding="utf-8")
    assert unit_frame_format(load_bench(p).unit).name == "mine"


@pytest.mark.parametrize(
    "name,options",
    [
        ("kvh-1750-a", None),
        ("kvh-1750-b", {"gyro_output": "rate_deg_s"}),
        ("stim300-0x93", None),
        ("stim300-0xa7", None),
    ],
)
def test_simulated_unit_speaks_the_format_to_the_serial_driver(name, options):
    world = make_world(3)
    fmt = compile_format(load_frame(name), options, world.sample_rate)
    srv = SerialUnitServer(world, frame=fmt, corruption=Corruption(garbage=0.02, flip=0.02, drop=0.01, seed=4))
    port = serial.serial_for_url(srv.url, timeout=0.02)
    try:
        unit = SerialInertialUnit(port, fmt, world.sample_rate, timeout=2.0, polled=True)
        blocks = [unit.read(250) for _ in range(6)]
    finally:
        port.close()
        srv.close()
    ref = make_world(3)
    truth = frames_to_block(ref.produce(1500), ref.scale)
    idx = np.concatenate([b.counter for b in blocks]).astype(np.int64)
    accel = np.concatenate([b.accel for b in blocks])
    assert np.all(np.diff(idx) > 0)
    assert np.allclose(accel, truth.accel[idx], rtol=0, atol=2.0**-19 * G0)  # within the format's quantisation
    lost = np.asarray(srv.lost_counters)
    missing = np.setdiff1d(np.arange(int(idx[-1]) + 1), idx)
    assert np.array_equal(missing, lost[lost <= idx[-1]])
    assert sum(b.dropped for b in blocks) == missing.size - int(idx[0])
    assert sum(b.resets for b in blocks) == 0 and sum(b.duplicates for b in blocks) == 0
    assert 0 < sum(b.rejected for b in blocks) <= srv.injected["flip"] + srv.injected["garbage"]
    assert f"frame {name}" in blocks[0].events[0]
    assert any("missing" in e for b in blocks for e in b.events)


def _capture(tmp_path: Path, name: str, n: int = 400) -> Path:
    fmt = compile_format(load_frame(name), None, 1000.0)
    idx = np.arange(n)
    accel = np.tile([0.0, 0.0, G0], (n, 1))
    rows = encode_samples(fmt, idx, idx / 1000.0, accel, np.zeros((n, 3)), np.full(n, 300.0))
    data = (
        rows[:100].tobytes() + b"\x00\x01garbage" + rows[100:200].tobytes() + rows[199].tobytes() + rows[250:].tobytes()
    )
    p = tmp_path / f"{name}.bin"
    p.write_bytes(data)
    return p


def _cli(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        rc = main(list(args))
    return rc, out.getvalue(), err.getvalue()


def test_decode_command_summary_and_outputs(tmp_path):
    cap = _capture(tmp_path, "stim300-0x93")
    rc, out, err = _cli("decode", "--frame", "stim300-0x93", str(cap), "--out", str(tmp_path / "s.csv"))
    assert rc == 0, err
    assert "frames 351, rejected (bad checksum) 0, garbage bytes 9" in out
    assert "counter gaps 50 frame(s), resets 0, duplicates 1 (dropped)" in out
    table = np.loadtxt(tmp_path / "s.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "s.csv").read_text().splitlines()[0].split(",")
    assert table.shape[0] == 350 and header[:3] == ["time", "index", "counter"]
    assert np.allclose(table[:, header.index("accel_z")], G0, atol=2.0**-19 * G0)
    rc, out, _ = _cli("decode", "--frame", "stim300-0x93", str(cap), "--out", str(tmp_path / "s.npy"))
    assert rc == 0 and np.load(tmp_path / "s.npy").shape == table.shape
    rc, out, err = _cli("decode", "--frame", "stim300-0x93", str(cap), "--out", str(tmp_path / "s.h5"))
    assert rc == 0, err
    import h5py

    with h5py.File(tmp_path / "s.h5", "r") as f:  # the test reads the file independently of the project's reader
        assert f.attrs["frame_format"] == "stim300-0x93" and int(f.attrs["duplicates"]) == 1
        assert int(f.attrs["gaps"]) == 50 and int(f.attrs["frames"]) == 351
        for j, name in enumerate(header):
            ds = f["samples"][name]
            assert ds.fletcher32 and np.array_equal(ds[()], table[:, j], equal_nan=True)
    from benches.recording import RecordingError, open_recording

    with pytest.raises(RecordingError):
        open_recording(tmp_path / "s.h5")  # decoded samples are not a recording: a clear error, not a traceback


@pytest.mark.parametrize(
    "args,words",
    [
        (["--frame", "kvh-1750-a", "CAP"], ["no valid kvh-1750-a frame"]),
        (["--frame", "nope", "CAP"], ["unknown frame format"]),
        (["--frame", "stim300-0x93", "--option", "accel_range_g=7", "CAP"], ["not allowed"]),
        (["--frame", "stim300-0x93", "--option", "bogus", "CAP"], ["NAME=VALUE"]),
        (["--frame", "stim300-0x93", "--rate", "300", "CAP"], ["2000 Hz"]),
        (["--frame", "stim300-0x93", "MISSING"], ["no such capture"]),
        (["--frame", "stim300-0x93", "CAP", "--out", "x.txt"], [".npy, .csv or .h5"]),
        (["CAP"], ["--frame"]),
    ],
)
def test_decode_bad_input_is_one_line_exit_2(tmp_path, args, words):
    cap = _capture(tmp_path, "stim300-0x93")
    argv = ["decode"] + [str(cap) if a == "CAP" else str(tmp_path / a) if a == "MISSING" else a for a in args]
    rc, _out, err = _cli(*argv)
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert all(w in err for w in words), err


def test_a_unit_speaking_another_format_is_a_link_error_not_a_hang():
    import time

    from drivers.protocols import LinkError

    world = make_world(2)
    kvh = compile_format(load_frame("kvh-1750-a"), None, world.sample_rate)
    srv = SerialUnitServer(world, frame=kvh, stream_factor=5.0)  # streams KVH frames
    port = serial.serial_for_url(srv.url, timeout=0.02)
    try:
        stim = compile_format(load_frame("stim300-0x93"), None, world.sample_rate)
        unit = SerialInertialUnit(port, stim, world.sample_rate, timeout=0.5, polled=False)
        t0 = time.monotonic()
        with pytest.raises(LinkError, match="no valid stim300-0x93 frame"):
            unit.read(100_000)
        assert time.monotonic() - t0 < 3.0
    finally:
        port.close()
        srv.close()


@pytest.mark.parametrize("name", ["kvh-1750-c", "stim300-0x93", "stim300-0xf5", "tablebench-v1"])
def test_decode_auto_detects_the_shipped_format(tmp_path, name):
    cap = _capture(tmp_path, name)
    rc, out, err = _cli("decode", "--frame", "auto", str(cap))
    assert rc == 0, err
    assert out.startswith(f"detected {name} (") and "frames 351," in out
