"""Layouts by identifier (one description, several sync/identifier bytes with their own lengths and fields) and
KVH built-in-test frames.

Expected values are written from docs/protocols/imu-frames.md (its test frames, lengths, CRC coverage with zero
padding, the KVH BIT frames' 8-bit sum) and an independent bit-by-bit CRC, never from this project's encoder.
"""

from __future__ import annotations

import io
import struct
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pytest

from analysis.units import CELSIUS_ZERO, DEG, G0
from benches.cli import main
from core.yaml_source import ConfigError, load_yaml_text
from drivers.imu_unit.decoder import FrameDecoder
from drivers.imu_unit.description import FLAG_BITS, compile_format, load_frame, parse_description
from drivers.imu_unit.samples import SampleConverter, encode_samples
from tests.drivers.frame_support import (
    KVH_BUILT,
    KVH_MANUAL,
    STIM_93,
    check_damage_counts,
    crc_mpeg2_bitwise,
    decode_in_random_chunks,
)


def _bit_frame(header: bytes, payload: bytes) -> bytes:
    """A KVH built-in-test frame as the spec says: header, payload, then the 8-bit sum of all preceding bytes."""
    body = header + payload
    return body + bytes([sum(body) % 256])


# ---- STIM300, any datagram -------------------------------------------------------------------------------


def test_stim300_description_selects_the_layout_by_identifier_with_the_specs_lengths_and_padding():
    d = load_frame("stim300")
    layouts = {desc.sync[0]: desc for _r, desc in [("data", d), *d.alternates]}
    ids = [*range(0x90, 0x95), 0xA5, 0xA6, 0xA7, *range(0xF0, 0xF8), *range(0x98, 0x9D), 0xAD, 0xAE, 0xAF]
    assert sorted(layouts) == sorted(ids)
    assert (layouts[0x90].length, layouts[0x93].length, layouts[0xA7].length) == (18, 38, 59)
    for ident, desc in layouts.items():  # CRC over everything before it, then (-n) mod 4 zero bytes
        n = desc.checksum.offset
        assert desc.checksum.start == 0 and desc.checksum.end == n and desc.checksum.pad == (-n) % 4, hex(ident)
    assert layouts[0x93].checksum.pad == 2 and layouts[0xA7].checksum.pad == 1


def test_stim300_spec_datagram_decodes_exactly_through_the_any_datagram_description():
    assert struct.unpack(">I", STIM_93[34:])[0] == crc_mpeg2_bitwise(STIM_93[:34] + b"\0\0")
    fmt = compile_format(load_frame("stim300"), None, 1000.0)
    dec = FrameDecoder(fmt.desc)
    batch, stats = dec.feed(STIM_93 + b"\r\n")
    assert (stats.frames, stats.rejected, stats.garbage_bytes, stats.bit_frames) == (1, 0, 0, 0)
    assert batch.layout.tolist() == [0]
    v = batch.values
    assert [int(v[f"gyro_{a}"][0]) for a in "xyz"] == [8192, -4096, 15 * 2**14]  # 0.5, -0.25, 15 °/s at 2^-14
    assert int(v["counter"][0]) == 16 and int(v["latency"][0]) == 500
    s = SampleConverter(fmt).convert(batch)
    assert np.allclose(s.gyro[0] / DEG, [0.5, -0.25, 15.0], rtol=1e-14)
    assert np.all(np.abs(s.accel[0] / G0 - [0.01, 0.0, 1.0]) <= 2.0**-19 / 2)  # 10 g unit
    incl = np.array([s.extras[f"incl_{a}"][0] for a in "xyz"]) / G0
    assert np.all(np.abs(incl - [0.0, -0.02, 1.0]) <= 2.0**-22 / 2)
    assert s.status[0] == 0 and s.extras["latency"][0] == 500e-6


def test_stim300_any_datagram_rejects_every_single_bit_flip():
    desc = load_frame("stim300")
    for bit in range(8 * len(STIM_93)):
        bad = bytearray(STIM_93)
        bad[bit // 8] ^= 1 << (bit % 8)
        dec = FrameDecoder(desc)
        batch, stats = dec.feed(bytes(bad))
        dec.flush()
        assert len(batch) == 0 and dec.total.frames == 0, f"bit {bit} flipped was accepted"
        if bit >= 8:  # a flip after the identifier: the 0x93 candidate fails its CRC, counted once
            assert dec.total.rejected == 1
        else:  # the identifier may become another one (0x92, 0x91…): at most one reject, never a frame
            assert dec.total.rejected <= 1
        assert dec.total.garbage_bytes == len(STIM_93)


def test_mixed_identifier_stream_round_trip_exact_counts():
    rate = 1000.0
    fmt = compile_format(load_frame("stim300"), {"gyro_output": "rate"}, rate)
    by_id = {f.desc.sync[0]: f for _r, f in fmt.alternates}
    by_id[fmt.desc.sync[0]] = fmt
    ids = [0x93, 0x90, 0xA7, 0xF3, 0x9B, 0x91]
    rng = np.random.default_rng(11)
    step = fmt.counter_step
    assert step == 2
    n1, n2 = 250, 150
    jump = (256 // 2 + step) // step  # a counter reset: jumps back by modulus/2 − step
    idx = np.concatenate([np.arange(3, 3 + n1), np.arange(3 + n1 - 1 + jump, 3 + n1 - 1 + jump + n2)])
    n = idx.size
    which = np.array(ids)[rng.integers(0, len(ids), n)]
    accel = rng.uniform(-2 * G0, 2 * G0, (n, 3))
    gyro = rng.uniform(-100 * DEG, 100 * DEG, (n, 3))
    temp = CELSIUS_ZERO + rng.uniform(10, 40, n)
    frames: list[bytes] = [b""] * n
    for ident in ids:
        sel = np.flatnonzero(which == ident)
        f = by_id[ident]
        rows = encode_samples(f, idx[sel], idx[sel] / rate, accel[sel], gyro[sel], temp[sel])
        for j, r in zip(sel.tolist(), rows, strict=True):
            frames[j] = r.tobytes()
    identifiers = {d.sync[0] for _r, d in [("data", fmt.desc), *fmt.desc.alternates]}
    allowed = np.array([b for b in range(256) if b not in identifiers | {0x0D}], np.uint8)
    truncated, flipped, duplicated = {30, 200}, {70, 330}, {45, 300}
    garbage_before = {0, 100, 260, 390}
    pieces: list[bytes] = []
    garbage = 0
    for i in range(n):
        if i in garbage_before:
            g = rng.choice(allowed, int(rng.integers(1, 30))).tobytes()
            pieces.append(g)
            garbage += len(g)
        fr = frames[i]
        if i in truncated:
            pieces.append(fr[: len(fr) // 2])
            garbage += len(fr) // 2
            continue
        if i in flipped:
            bad = bytearray(fr)
            bad[5] ^= 0x04
            pieces.append(bytes(bad))
            garbage += len(fr)
            continue
        pieces.append(fr + (b"\r\n" if i % 3 == 0 else b""))  # the optional CR LF: not garbage
        if i in duplicated:
            pieces.append(fr)
    data = b"".join(pieces)
    dec, s, layouts = decode_in_random_chunks(fmt, data, rng, 150)  # some chunks shorter than any datagram
    lost = truncated | flipped
    kept = check_damage_counts(dec, s, n, lost, duplicated, garbage)
    # each frame decoded with its own layout: the identifier sequence comes back, duplicates included
    sent = [int(which[i]) for i in range(n) if i not in lost for _ in range(2 if i in duplicated else 1)]
    order = [d.sync[0] for _r, d in [("data", fmt.desc), *fmt.desc.alternates]]
    assert [order[k] for k in np.concatenate(layouts).tolist()] == sent
    assert np.all(np.abs(s.gyro - gyro[kept]) <= 2.0**-14 * DEG / 2 * (1 + 1e-9))
    has_acc = which[kept] != 0x90
    assert np.all(np.abs(s.accel[has_acc] - accel[kept][has_acc]) <= 2.0**-19 * G0 / 2 * (1 + 1e-9))
    acc_bits = sum(1 << FLAG_BITS[f"accel_{a}"] for a in "xyz")
    assert np.all(np.isnan(s.accel[~has_acc])) and np.all(s.status[~has_acc] & acc_bits == acc_bits)
    assert np.all(s.status[has_acc] == 0)
    before = kept < n1
    assert np.array_equal(s.index[before], idx[kept[before]])


@pytest.mark.parametrize("name", ["stim300-0x93", "stim300"])
def test_cr_lf_after_a_datagram_is_not_garbage_even_split_across_feeds(name):
    desc = load_frame(name)
    data = (STIM_93 + b"\r\n") * 3 + STIM_93 + b"\r" + b"\x00"
    for size in (1, 2, 37, 38, 39, 40):
        dec = FrameDecoder(desc)
        for i in range(0, len(data), size):
            dec.feed(data[i : i + size])
        dec.flush()
        # 4 datagrams, 3 CR LF trailers; a lone CR and the 0x00 byte are garbage
        assert (dec.total.frames, dec.total.rejected, dec.total.garbage_bytes) == (4, 0, 2), size


@pytest.mark.parametrize(
    "layouts,words",
    [
        ("  - stim300-0x93\n  - stim300-0x93\n", ["same sync"]),
        ("  - stim300-0x93\n  - stim300-0x9z\n", ["unknown frame format"]),
        ("  - stim300\n", ["no nesting"]),
        ("  - {frame: stim300-0x93, role: maybe}\n", ["not allowed"]),
        ("  - {frame: kvh-1750-bit-aa, role: bit}\n", ["role: data"]),
        ("  - stim300-0x93\n  - kvh-1750-bit-aa\n", ["counter"]),
    ],
)
def test_bad_layouts_are_one_line_with_file_and_line(layouts, words):
    text = "name: mine\nlayouts:\n" + layouts
    data, smap = load_yaml_text(text, "mine.yaml")
    with pytest.raises(ConfigError) as ei:
        parse_description(data, smap)
    msg = str(ei.value)
    assert msg.startswith("mine.yaml:") and "\n" not in msg and all(w in msg for w in words), msg


# ---- KVH built-in-test frames ----------------------------------------------------------------------------

BIT_AA = _bit_frame(bytes.fromhex("fe8100aa"), bytes([1, 2, 3, 4, 5, 0xF0]))
BIT_AB = _bit_frame(bytes.fromhex("fe8100ab"), bytes([0x10, 0x20, 0x30, 0x40, 0x50, 0x60, 0x70, 0xFF]))


def test_kvh_bit_frames_are_recognised_counted_and_kept_not_garbage():
    assert len(BIT_AA) == 11 and len(BIT_AB) == 13
    fmt = compile_format(load_frame("kvh-1750-a"), None, 1000.0)
    dec = FrameDecoder(fmt.desc)
    batch, stats = dec.feed(KVH_MANUAL + BIT_AA + KVH_BUILT + BIT_AB)
    assert (stats.frames, stats.bit_frames, stats.rejected, stats.garbage_bytes) == (2, 2, 0, 0)
    assert batch.values["sequence"].tolist() == [61, 42]
    aa, ab = batch.bit["kvh-1750-bit-aa"], batch.bit["kvh-1750-bit-ab"]
    assert aa.rows[0].tobytes() == BIT_AA and ab.rows[0].tobytes() == BIT_AB
    assert [int(aa.values[f"bit_byte_{i}"][0]) for i in range(4, 10)] == [1, 2, 3, 4, 5, 0xF0]
    assert [int(ab.values[f"bit_byte_{i}"][0]) for i in range(4, 12)] == list(BIT_AB[4:12])
    s = SampleConverter(fmt).convert(batch)
    assert len(s) == 2 and s.counter.tolist() == [61, 42] and (s.gaps, s.resets) == (0, 1)


def test_kvh_bit_frame_with_a_flipped_bit_is_rejected():
    desc = load_frame("kvh-1750-b")
    for bit in range(32, 8 * len(BIT_AA)):  # after the header
        bad = bytearray(BIT_AA)
        bad[bit // 8] ^= 1 << (bit % 8)
        dec = FrameDecoder(desc)
        dec.feed(bytes(bad))
        dec.flush()
        assert (dec.total.bit_frames, dec.total.rejected, dec.total.garbage_bytes) == (0, 1, 11), bit


def test_decode_command_counts_bit_frames(tmp_path):
    cap = tmp_path / "kvh.bin"
    cap.write_bytes(KVH_MANUAL + BIT_AA + b"\x00\x01" + KVH_BUILT + BIT_AB)
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        rc = main(["decode", "--frame", "kvh-1750-a", str(cap)])
    assert rc == 0, err.getvalue()
    text = out.getvalue()
    assert "frames 2, rejected (bad checksum) 0, garbage bytes 2," in text
    assert "built-in-test frames 2 " in text


def test_serial_driver_keeps_bit_frames_for_the_caller_and_reports_them():
    from drivers.imu_unit.serial_unit import SerialInertialUnit

    fmt = compile_format(load_frame("kvh-1750-a"), None, 1000.0)
    from tests.drivers.transcript import ByteTranscript

    port = ByteTranscript([], initial=KVH_MANUAL + BIT_AA + KVH_BUILT)  # free-running: the host sends nothing
    unit = SerialInertialUnit(port, fmt, 1000.0, timeout=0.5)
    block = unit.read(2)
    assert len(block.time) == 2 and block.rejected == 0
    assert unit.bit_frames == [("kvh-1750-bit-aa", BIT_AA)] and unit.bit_total == 1
    assert any("1 built-in-test frame(s) received" in e for e in block.events)
    port.done()
