"""Frame descriptions and the compiled decoder: the spec's frames decoded exactly (fields and CRC), single-bit
errors rejected, every shipped format round-tripped with garbage, truncation, counter resets and duplicates
injected (exact counts), counter rules, and bad descriptions reported with file:line.

The expected field values below are written from docs/protocols/imu-frames.md (its test frames and the
values it states for them) and from independent ``struct`` unpacking, never from this project's encoder.
"""

from __future__ import annotations

import struct
import zlib
from typing import Any

import numpy as np
import pytest

from analysis.units import CELSIUS_ZERO, DEG, G0
from core.yaml_source import ConfigError, load_yaml_text
from drivers.imu_unit.checksums import CrcEngine, CrcSpec
from drivers.imu_unit.counts import CounterTracker, counter_gaps
from drivers.imu_unit.decoder import FrameCodec, FrameDecoder
from drivers.imu_unit.description import (
    FLAG_BITS,
    TYPES,
    compile_format,
    load_frame,
    parse_description,
    shipped_frames,
)
from drivers.imu_unit.samples import SampleConverter, encode_samples
from tests.drivers.frame_support import (
    KVH_BUILT,
    KVH_MANUAL,
    STIM_93,
    check_damage_counts,
    crc_mpeg2_bitwise,
    decode_in_random_chunks,
)


def _decode(name: str, data: bytes, options: dict | None = None, rate: float = 1000.0):
    fmt = compile_format(load_frame(name), options, rate)
    dec = FrameDecoder(fmt.desc)
    batch, stats = dec.feed(data)
    return fmt, batch, stats, SampleConverter(fmt).convert(batch)


# ---- checksums ----------------------------------------------------------------------------------------


def test_crc_catalogue_check_values_and_references():
    check = np.frombuffer(b"123456789", np.uint8)
    assert int(CrcEngine(CrcSpec.named("crc-32/mpeg-2"))(check)[0]) == 0x0376E6E7
    assert int(CrcEngine(CrcSpec.named("crc-16/ccitt-false"))(check)[0]) == 0x29B1
    assert int(CrcEngine(CrcSpec.named("crc-32"))(check)[0]) == 0xCBF43926
    rng = np.random.default_rng(3)
    rows = rng.integers(0, 256, (80, 37), dtype=np.uint8)
    mpeg = CrcEngine(CrcSpec.named("crc-32/mpeg-2"))(rows)
    assert [int(x) for x in mpeg] == [crc_mpeg2_bitwise(r.tobytes()) for r in rows]
    zl = CrcEngine(CrcSpec.named("crc-32"))(rows)
    assert [int(x) for x in zl] == [zlib.crc32(r.tobytes()) for r in rows]
    assert int(CrcEngine(CrcSpec.named("sum8"))(rows[:1])[0]) == int(rows[0].sum()) % 256


def test_spec_frames_carry_the_crc_the_spec_states():
    for frame, n in ((KVH_MANUAL, 32), (KVH_BUILT, 32)):
        assert struct.unpack(">I", frame[n:])[0] == crc_mpeg2_bitwise(frame[:n])
    # STIM300: the CRC covers the 34 bytes before it plus (-34) mod 4 = 2 zero bytes never sent
    assert struct.unpack(">I", STIM_93[34:])[0] == crc_mpeg2_bitwise(STIM_93[:34] + b"\0\0")


# ---- the spec's frames, exactly ---------------------------------------------------------------------------


def test_kvh_manual_sample_frame_decodes_exactly():
    fmt, batch, stats, s = _decode("kvh-1750-a", KVH_MANUAL)
    assert (stats.frames, stats.rejected, stats.garbage_bytes) == (1, 0, 0)
    v = batch.values
    assert int(v["status"][0]) == 0x77 and int(v["sequence"][0]) == 61 and int(v["temperature"][0]) == 40
    gyro = struct.unpack(">3f", KVH_MANUAL[4:16])
    acc = struct.unpack(">3f", KVH_MANUAL[16:28])
    # default configuration: delta angle in rad per sample (1 kHz) → rad/s; acceleration in g → m/s²
    assert s.gyro[0].tolist() == [g * 1000.0 for g in np.float32(gyro).astype(np.float64)]
    assert s.accel[0].tolist() == [a * G0 for a in np.float32(acc).astype(np.float64)]
    assert s.temperature[0] == 40 + CELSIUS_ZERO
    assert s.status[0] == 0 and s.counter[0] == 61


def test_kvh_constructed_frame_decodes_to_the_stated_values():
    fmt, batch, stats, s = _decode("kvh-1750-a", KVH_BUILT)
    assert stats.frames == 1
    assert np.allclose(batch.values["gyro_x"], 7.27e-8, rtol=1e-7) and batch.values["gyro_y"][0] == 0
    assert np.allclose(batch.values["gyro_z"], -1e-6, rtol=1e-7)
    assert np.allclose([batch.values[f"accel_{a}"][0] for a in "xyz"], [0.001, -0.002, 1.0], rtol=1e-7)
    assert int(batch.values["status"][0]) == 0x77 and int(batch.values["sequence"][0]) == 42
    assert s.temperature[0] == 31 + CELSIUS_ZERO
    assert np.allclose(s.gyro[0], np.array([7.27e-8, 0.0, -1e-6]) * 1000.0, rtol=1e-7, atol=0)
    assert np.allclose(s.accel[0], np.array([0.001, -0.002, 1.0]) * 9.80665, rtol=1e-7)
    # the same frame read as a unit configured for rate in deg/s and Δv in m/s
    _f, _b, _st, s2 = _decode(
        "kvh-1750-a", KVH_BUILT, {"gyro_output": "rate_deg_s", "accel_output": "delta_velocity_m_s"}
    )
    assert np.allclose(s2.gyro[0], np.array([7.27e-8, 0.0, -1e-6]) * DEG, rtol=1e-7)
    assert np.allclose(s2.accel[0], np.array([0.001, -0.002, 1.0]) * 1000.0, rtol=1e-7)


def test_stim300_0x93_constructed_datagram_decodes_to_the_stated_values():
    fmt, batch, stats, s = _decode("stim300-0x93", STIM_93)
    assert (stats.frames, stats.rejected, stats.garbage_bytes) == (1, 0, 0)
    assert fmt.length == 38 and fmt.counter_step == 2
    assert np.array_equal(batch.values["gyro_x"], [8192]) and np.allclose(
        s.gyro[0] / DEG, [0.5, -0.25, 15.0], rtol=1e-14
    )
    lsb_acc = 2.0**-19  # 10 g unit
    assert np.all(np.abs(s.accel[0] / G0 - [0.01, 0.0, 1.0]) <= lsb_acc / 2)
    incl = np.array([s.extras[f"incl_{a}"][0] for a in "xyz"]) / G0
    assert np.all(np.abs(incl - [0.0, -0.02, 1.0]) <= 2.0**-22 / 2)
    assert int(batch.values["counter"][0]) == 16 and s.extras["latency"][0] == 500e-6
    assert s.status[0] == 0
    # the same bytes read as a 30 g unit scale the accelerometers by 2
    _f, _b, _st, s30 = _decode("stim300-0x93", STIM_93, {"accel_range_g": "30"})
    assert np.array_equal(s30.accel, 2 * s.accel)


@pytest.mark.parametrize(
    "frame,name", [(KVH_MANUAL, "kvh-1750-a"), (KVH_BUILT, "kvh-1750-a"), (STIM_93, "stim300-0x93")]
)
def test_every_single_bit_flip_is_rejected(frame, name):
    desc = load_frame(name)
    for bit in range(8 * len(frame)):
        bad = bytearray(frame)
        bad[bit // 8] ^= 1 << (bit % 8)
        batch, stats = FrameDecoder(desc).feed(bytes(bad))
        assert len(batch) == 0, f"bit {bit} flipped was accepted"
        # a flip in the sync bytes leaves no candidate; anywhere else the candidate is rejected once
        assert stats.rejected == (0 if bit < 8 * len(desc.sync) else 1)


def test_stim300_lengths_ids_and_padding_follow_the_spec():
    lengths = {0x90: 18, 0x93: 38, 0xA7: 59}
    for ident, n in lengths.items():
        d = load_frame(f"stim300-0x{ident:02x}")
        assert d.length == n and d.sync == bytes([ident])
    assert load_frame("stim300-0x93").checksum.pad == 2 and load_frame("stim300-0xa7").checksum.pad == 1
    names = set(shipped_frames())
    for base, pps, aux in zip(
        [0x90, 0x91, 0x92, 0x93, 0x94, 0xA5, 0xA6, 0xA7],
        range(0xF0, 0xF8),
        [0x98, 0x99, 0x9A, 0x9B, 0x9C, 0xAD, 0xAE, 0xAF],
        strict=True,
    ):
        b, p, a = (load_frame(f"stim300-0x{i:02x}") for i in (base, pps, aux))
        assert p.length == b.length + 4 and a.length == b.length + 4  # 24-bit field + status byte
        assert {f"stim300-0x{i:02x}" for i in (base, pps, aux)} <= names
    assert {"tablebench-v1", "kvh-1750-a", "kvh-1750-b", "kvh-1750-c"} <= names


def test_kvh_format_c_multiplexed_temperature_is_held_between_its_slots():
    fmt = compile_format(load_frame("kvh-1750-c"), None, 1000.0)
    n = 12
    idx = np.arange(5, 5 + n)  # starts on a magnetometer slot: the first frames take the first temperature
    temp = CELSIUS_ZERO + 20.0 + idx.astype(float)
    rows = encode_samples(fmt, idx, idx / 1000.0, np.zeros((n, 3)), np.zeros((n, 3)), temp)
    s = SampleConverter(fmt).convert(FrameDecoder(fmt.desc).feed(rows.tobytes())[0])
    sent = idx % 4 == 0
    held = np.maximum.accumulate(np.where(sent, np.arange(n), -1))
    expect = np.where(held >= 0, temp[np.maximum(held, 0)], temp[np.flatnonzero(sent)[0]])
    assert np.allclose(s.temperature, expect, rtol=0, atol=1e-4)


# ---- counters ---------------------------------------------------------------------------------------------


def test_counter_rules_gaps_resets_duplicates_counted_separately():
    kvh = CounterTracker(128, 1)
    chk = kvh.update(np.array([125, 126, 127, 0, 1, 3]))
    assert (chk.gaps, chk.resets, chk.duplicates) == (1, 0, 0) and chk.index.tolist() == [125, 126, 127, 128, 129, 131]
    stim = CounterTracker(256, 2)  # 1000 Hz: 2000 Hz ticks advance by 2
    chk = stim.update(np.array([250, 252, 254, 0, 2, 8]))
    assert (chk.gaps, chk.resets) == (2, 0) and chk.index.tolist() == [125, 126, 127, 128, 129, 132]
    chk = stim.update(np.array([8, 10, 3, 5]))  # a duplicate, then an odd step: a reset
    assert (chk.gaps, chk.resets, chk.duplicates) == (0, 1, 1) and chk.keep.tolist() == [False, True, True, True]
    u32 = CounterTracker(1 << 32, 1)
    chk = u32.update(np.array([1000, 1001, 0, 1], dtype=np.uint32))  # unit restarted: not 4.29e9 missing frames
    assert (chk.gaps, chk.resets, chk.duplicates) == (0, 1, 0)
    assert counter_gaps(4_000_000, np.array([0, 1], dtype=np.uint32)) == 0
    assert counter_gaps(2**32 - 2, np.array([1, 2], dtype=np.uint32)) == 2  # wrap with two missing


# ---- every shipped format: round trip with injected faults, exact counts ---------------------------------


def _si_samples(fmt, n: int, rng: np.random.Generator):
    """SI samples inside the format's range (rates ≤ 100 °/s, specific force ≤ 2 g), body frame."""
    accel = rng.uniform(-2 * G0, 2 * G0, (n, 3))
    gyro = rng.uniform(-100 * DEG, 100 * DEG, (n, 3))
    temp = CELSIUS_ZERO + rng.uniform(10, 40, n)
    return accel, gyro, temp


def _quantum(fmt, channel: str) -> float:
    """Largest SI rounding error of a channel (integer LSB / 2, or float32 relative)."""
    for name, c in fmt.conversions.items():
        if isinstance(name, str) and c.channel == channel:
            f = fmt.desc.field_named(name)
            kind = TYPES[f.type][0]
            step = c.factor * (fmt.sample_rate if c.increment else 1.0)
            return np.inf if kind.startswith("f") else step / 2
    raise KeyError(channel)


def _checked_bytes(fmt: Any) -> np.ndarray:
    """Offsets after the sync that the frame's checksum covers, the checksum's own bytes included (all of them
    when it has none). The ADIS bridge's two bytes clocked in during the burst command are covered by nothing
    (tests/drivers/test_frames_epson_hg4930_adis.py shows a flip there passes unchanged)."""
    L, ck = fmt.length, fmt.desc.checksum
    if ck is None:
        return np.arange(len(fmt.desc.sync), L)
    own = range(ck.offset, ck.offset + ck.spec.nbytes)
    return np.array(sorted({*range(max(ck.start, len(fmt.desc.sync)), ck.end), *own}))


@pytest.mark.parametrize("name", [n for n in shipped_frames() if load_frame(n).counter is not None])
def test_round_trip_with_garbage_truncation_resets_and_duplicates(name):
    """(Formats without a counter — VectorNav — have their own round trip in test_frames_more_units.py.)"""
    rate = 500.0
    options = {"gyro_output": "rate"} if name.startswith("stim") else None
    fmt = compile_format(load_frame(name), options, rate)
    L, step = fmt.length, fmt.counter_step
    modulus = fmt.desc.counter.modulus
    rng = np.random.default_rng(zlib.crc32(name.encode()))  # str hash() differs per process: not a seed
    n1, n2 = 300, 200
    # a counter reset after frame n1: the counter jumps back by modulus/2 − step (unambiguous for any modulus)
    jump = (modulus // 2 + step) // step
    idx = np.concatenate([np.arange(10, 10 + n1), np.arange(10 + n1 - 1 + jump, 10 + n1 - 1 + jump + n2)])
    n = idx.size
    accel, gyro, temp = _si_samples(fmt, n, rng)
    rows = encode_samples(fmt, idx, idx / rate, accel, gyro, temp)
    # garbage never starts a candidate frame (of any layout) nor looks like a STIM CR LF trailer
    forbidden = {fmt.desc.sync[0], 0x0D} | {d.sync[0] for _r, d in fmt.desc.alternates}
    allowed = np.array([b for b in range(256) if b not in forbidden], dtype=np.uint8)
    truncated = {40, 120, 400}
    duplicated = {60, 250, 450}
    flipped = {80, 420}
    garbage_before = {5, 90, 200, 350, 470}
    pieces: list[bytes] = []
    garbage_total = 0
    for i in range(n):
        if i in garbage_before:
            g = rng.choice(allowed, int(rng.integers(1, 50))).tobytes()
            pieces.append(g)
            garbage_total += len(g)
        if i in truncated:
            cut = int(rng.integers(len(fmt.desc.sync) + 1, L - 1))
            pieces.append(rows[i, :cut].tobytes())
            garbage_total += cut
            continue
        if i in flipped:
            bad = rows[i].copy()
            byte = int(rng.choice(_checked_bytes(fmt)))  # a byte the frame's check covers
            bad[byte] ^= np.uint8(1 << int(rng.integers(0, 8)))
            pieces.append(bad.tobytes())
            garbage_total += L
            continue
        pieces.append(rows[i].tobytes())
        if i in duplicated:
            pieces.append(rows[i].tobytes())
    data = b"".join(pieces)
    dec, s, _ = decode_in_random_chunks(fmt, data, rng, 3 * L)
    kept = check_damage_counts(dec, s, n, truncated | flipped, duplicated, garbage_total)
    absent = sum(1 << FLAG_BITS[ch] for ch in FLAG_BITS if ch not in {c.channel for c in fmt.conversions.values()})
    absent &= 0x3F  # recorded channels the format does not carry are flagged (and NaN)
    s.status &= np.uint16(~absent & 0xFFFF)
    # all valid, except a multiplexed temperature (KVH C) not yet sent when the first frames were decoded
    first_temp = 0 if not name.endswith("-c") else int(np.argmax(s.index % 4 == 0))
    assert np.all(s.status[first_temp:] == 0)
    assert np.all(np.isin(s.status[:first_temp], [0, 1 << FLAG_BITS["temperature"]]))
    # the samples are the ones sent, within the format's quantisation
    for j, ch in enumerate(("accel_x", "accel_y", "accel_z")):
        if absent & (1 << FLAG_BITS[ch]):
            assert np.all(np.isnan(s.accel[:, j]))
            continue
        q = _quantum(fmt, ch)
        err = np.abs(s.accel[:, j] - accel[kept, j])
        assert np.all(err <= (q * (1 + 1e-9) if np.isfinite(q) else 1e-6 * np.abs(accel[kept, j]) + 1e-12))
    for j, ch in enumerate(("gyro_x", "gyro_y", "gyro_z")):
        q = _quantum(fmt, ch)
        err = np.abs(s.gyro[:, j] - gyro[kept, j])
        assert np.all(err <= (q * (1 + 1e-9) if np.isfinite(q) else 1e-6 * np.abs(gyro[kept, j]) + 1e-12))
    # sample indices: unwrapped through the gaps; after the reset they continue one past the last frame
    before = kept < n1
    assert np.array_equal(s.index[before], idx[kept[before]])
    after = s.index[~before]
    assert np.array_equal(np.diff(after), np.diff(np.flatnonzero(~before) + 0) * 0 + np.diff(kept[~before]))


def test_status_flags_follow_each_formats_meaning():
    fmt = compile_format(load_frame("kvh-1750-a"), None, 1000.0)
    codec = FrameCodec(fmt.desc)
    vals = {"status": np.array([0x77, 0x70, 0x76]), "sequence": np.arange(3)}
    s = SampleConverter(fmt).convert(FrameDecoder(fmt.desc).feed(codec.encode(vals, 3).tobytes())[0])
    gyro_bits = sum(1 << FLAG_BITS[f"gyro_{a}"] for a in "xyz")
    assert s.status.tolist() == [0, gyro_bits, 1 << FLAG_BITS["gyro_x"]]  # 0x70: gyros settling at start-up
    fmt = compile_format(load_frame("stim300-0x91"), None, 1000.0)
    codec = FrameCodec(fmt.desc)
    vals = {"gyro_status": np.array([0, 0x40, 0]), "accel_status": np.array([0, 0, 0x81]), "counter": np.arange(3) * 2}
    s = SampleConverter(fmt).convert(FrameDecoder(fmt.desc).feed(codec.encode(vals, 3).tobytes())[0])
    acc_bits = sum(1 << FLAG_BITS[f"accel_{a}"] for a in "xyz")
    assert s.status.tolist() == [0, gyro_bits, acc_bits]
    assert s.extras["status:accel_status"].tolist() == [0, 0, 0x81]  # the status as sent is kept


# ---- bad descriptions: one line with file:line -------------------------------------------------------------

GOOD = """name: t
sync: [0xAA]
length: 8
fields:
  - {name: a, offset: 1, type: int16, channel: accel_x, unit: g}
  - {name: c, offset: 3, type: uint8}
counter: {field: c, modulus: 256}
checksum: {algorithm: sum8, offset: 7, covers: [0, 7]}
"""


@pytest.mark.parametrize(
    "old,new,line,match",
    [
        ("offset: 3, type: uint8", "offset: 2, type: uint8", 6, "overlaps"),
        ("unit: g", "unit: furlong", 5, "unknown unit"),
        ("type: int16", "type: int17", 5, "not allowed"),
        ("offset: 7, covers", "offset: 9, covers", 8, "out of range"),
        ("modulus: 256", "modulus: 256, stride: 1", 7, "unknown key"),
        ("algorithm: sum8", "algorithm: crc-99", 8, "unknown algorithm"),
        ("channel: accel_x, unit: g", "channel: accel_x, unit: deg/s", 5, "does not fit"),
        ("channel: accel_x, unit: g", "channel: [accel_x], unit: g", 5, "unknown channel"),  # was a TypeError
        ("channel: accel_x, unit: g", "channel: accel_x, unit: [g]", 5, "unknown unit"),  # was a TypeError
    ],
)
def test_bad_description_is_one_line_with_file_and_line(old, new, line, match):
    assert old in GOOD
    data, smap = load_yaml_text(GOOD.replace(old, new), "my-unit.yaml")
    with pytest.raises(ConfigError, match=match) as ei:
        desc = parse_description(data, smap)
        compile_format(desc, None, 1000.0)
    assert str(ei.value).startswith(f"my-unit.yaml:{line}:") and "\n" not in str(ei.value)


def test_a_users_description_file_decodes():
    data, smap = load_yaml_text(GOOD, "my-unit.yaml")
    fmt = compile_format(parse_description(data, smap), None, 100.0)
    rows = FrameCodec(fmt.desc).encode({"a": np.array([1000, -1000]), "c": np.array([7, 8])}, 2)
    s = SampleConverter(fmt).convert(FrameDecoder(fmt.desc).feed(b"\x01\x02" + rows.tobytes())[0])
    assert s.accel[:, 0].tolist() == [1000 * G0, -1000 * G0] and s.counter.tolist() == [7, 8]


@pytest.mark.parametrize("name", ["crc-32/mpeg-2", "crc-16/ccitt-false", "crc-32", "crc-16/xmodem", "crc-8"])
def test_per_position_crc_tables_equal_the_byte_loop(name):
    engine = CrcEngine(CrcSpec.named(name))
    rng = np.random.default_rng(7)
    for m in (1, 2, 17, 55, 600):  # 600: beyond the table path, the byte loop itself
        rows = rng.integers(0, 256, (40, m), dtype=np.uint8)
        assert np.array_equal(engine(rows), engine._bytewise(rows))
