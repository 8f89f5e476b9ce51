"""Frame descriptions of more inertial units, each checked against a frame taken from public material (the
source is named at each frame), every single-bit flip rejected; the checksum kinds they need, against
independent references written here from their definitions."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from analysis.units import CELSIUS_ZERO
from drivers.imu_unit.checksums import CrcEngine, CrcSpec
from drivers.imu_unit.decoder import FrameDecoder
from drivers.imu_unit.description import compile_format, load_frame
from drivers.imu_unit.samples import SampleConverter

# Xsens MTi-300, a real captured MTData2 packet (firmware 1.8.2): Scottapotamas/xsens-mti,
# test/test_xsens_mti_parse_messages.c, test_parse_mdata2_full, with the values MT Manager printed for it.
XSENS_MTI300 = bytes.fromhex(
    "faff3692102002918d10600401363fa62010103f35e0423f31cd15bd9f49dbbda938cf40200cbd635a90411d08d43e5faa5040100c"
    "b91168003cc901003a0f7d0040300cbc3b29803c35fc003ca46e0080200c3caea241bb56d800bad5ac018030103f80000037df8801"
    "b6898000b608c000c0200cbefbfbf23f33c485bfa0a2c108100442168000301004000186e1e0200400400003dd"
)

# VectorNav VN-100 user manual UM001 (firmware v2.1), §4.3.7 example case 1: group 1, YawPitchRoll only,
# with the values the manual states (yaw +43.578686°, pitch +1.8847202°, roll -2.0249654e-3°; CRC 0x9288).
VN_MANUAL_YPR = bytes.fromhex("fa01080093502e42833ef13f48b504bb9288")
VN_YPR_DESCRIPTION = """
name: vn-ypr
byte_order: little
sync: [0xFA, 0x01, 0x08, 0x00]
length: 18
fields:
  - {name: yaw, offset: 4, type: float32}
  - {name: pitch, offset: 8, type: float32}
  - {name: roll, offset: 12, type: float32}
checksum: {algorithm: crc-16/xmodem, offset: 16, covers: [1, 16], byte_order: big}
"""


def _vn_ypr():
    from core.yaml_source import load_yaml_text
    from drivers.imu_unit.description import parse_description

    data, smap = load_yaml_text(VN_YPR_DESCRIPTION, "vn-ypr.yaml")
    return parse_description(data, smap)


PUBLIC_FRAMES = [("xsens-mti-mtdata2", XSENS_MTI300), ("vn-ypr", VN_MANUAL_YPR)]


def _decode(name: str, data: bytes, rate: float = 400.0):
    fmt = compile_format(load_frame(name), None, rate)
    batch, stats = FrameDecoder(fmt.desc).feed(data)
    return batch, stats, SampleConverter(fmt).convert(batch)


def test_simple_sums_against_their_definitions():
    data = bytes(range(1, 41)) + b"\xff\xfe\x80\x01"
    rows = np.frombuffer(data, np.uint8)[None, :]
    total = sum(data)
    assert int(CrcEngine(CrcSpec.named("sum8"))(rows)[0]) == total % 256
    assert int(CrcEngine(CrcSpec.named("sum8-neg"))(rows)[0]) == (-total) % 256
    assert (total + int(CrcEngine(CrcSpec.named("sum8-neg"))(rows)[0])) % 256 == 0
    assert int(CrcEngine(CrcSpec.named("sum16"))(rows)[0]) == total % 65536
    be = sum(struct.unpack(f">{len(data) // 2}H", data)) % 65536
    le = sum(struct.unpack(f"<{len(data) // 2}H", data)) % 65536
    assert int(CrcEngine(CrcSpec.named("sum16-words"))(rows)[0]) == be
    assert int(CrcEngine(CrcSpec.named("sum16-words-le"))(rows)[0]) == le


def test_xsens_mti300_capture_decodes_to_the_printed_values():
    batch, stats, s = _decode("xsens-mti-mtdata2", XSENS_MTI300)
    assert (stats.frames, stats.rejected, stats.garbage_bytes) == (1, 0, 0)
    assert int(batch.values["packet_counter"][0]) == 37261 and int(batch.values["sample_time_fine"][0]) == 20332454
    # printed with 8 decimals: equal within half a unit of the last printed digit
    np.testing.assert_allclose(s.accel[0], [-0.05550629, 9.81465530, 0.21842313], rtol=0, atol=5.01e-9)
    np.testing.assert_allclose(s.gyro[0], [0.02131760, -0.00327826, -0.00163019], rtol=0, atol=5.01e-9)
    assert s.temperature[0] == pytest.approx(37.625 + CELSIUS_ZERO)
    assert s.time is None or s.time[0] == pytest.approx(2033.2454)
    assert s.status[0] == 0  # status word 0x00400003: no clipping


@pytest.mark.parametrize("name,frame", PUBLIC_FRAMES, ids=[n for n, _ in PUBLIC_FRAMES])
def test_every_single_bit_flip_of_a_public_frame_is_rejected(name, frame):
    desc = _vn_ypr() if name == "vn-ypr" else load_frame(name)
    for bit in range(8 * len(frame)):
        bad = bytearray(frame)
        bad[bit // 8] ^= 1 << (bit % 8)
        batch, stats = FrameDecoder(desc).feed(bytes(bad))
        assert len(batch) == 0, f"bit {bit} flipped was accepted"
        assert stats.rejected == (0 if bit < 8 * len(desc.sync) else 1)


def test_vectornav_manual_example_decodes_with_the_shipped_conventions():
    """The manual's packet read with the conventions of the shipped VectorNav description (little-endian
    payload, CRC-16/XMODEM over every byte after the sync, sent MSB first)."""
    batch, stats = FrameDecoder(_vn_ypr()).feed(VN_MANUAL_YPR)
    assert (stats.frames, stats.rejected) == (1, 0)
    assert batch.values["yaw"][0] == pytest.approx(43.578686, abs=5e-7)
    assert batch.values["pitch"][0] == pytest.approx(1.8847202, abs=5e-8)
    assert batch.values["roll"][0] == pytest.approx(-2.0249654e-3, abs=5e-11)
    shipped = load_frame("vectornav-vn100-imu")
    assert shipped.byte_order == "little" and shipped.checksum.spec.algorithm == "crc-16/xmodem"
    assert (shipped.checksum.start, shipped.checksum.byte_order) == (1, "big")


def test_xsens_clipping_flags_the_channel():
    frame = bytearray(XSENS_MTI300)
    frame[146:150] = struct.pack(">I", 0x00401403)  # accel z (bit 10) and gyro y (bit 12) clipped
    frame[150] = (-sum(frame[1:150])) % 256
    _b, stats, s = _decode("xsens-mti-mtdata2", bytes(frame))
    from drivers.imu_unit.description import FLAG_BITS

    assert stats.frames == 1
    assert s.status[0] == (1 << FLAG_BITS["accel_z"]) | (1 << FLAG_BITS["gyro_y"])


def test_vectornav_round_trip_through_the_simulated_units_encoder_with_damage():
    """No counter in the VectorNav output: frames are found by sync and CRC alone; garbage and a corrupted
    frame cost exactly that frame; the samples are the ones sent (float32) and the time is TimeStartup."""
    from drivers.imu_unit.samples import encode_samples
    from tests.drivers.frame_support import decode_in_random_chunks

    rate = 400.0
    fmt = compile_format(load_frame("vectornav-vn100-imu"), None, rate)
    rng = np.random.default_rng(7)
    n = 300
    idx = np.arange(n)
    accel = rng.normal(0, 5, (n, 3))
    gyro = rng.normal(0, 1, (n, 3))
    temp = np.full(n, 298.15)
    rows = encode_samples(fmt, idx, idx / rate, accel, gyro, temp)
    allowed = np.array([b for b in range(256) if b != 0xFA], dtype=np.uint8)
    pieces, flipped = [], {50, 200}
    for i in range(n):
        if i % 37 == 5:
            pieces.append(rng.choice(allowed, 11).tobytes())
        r = rows[i].copy()
        if i in flipped:
            r[20] ^= 0x10
        pieces.append(r.tobytes())
    dec, s, _ = decode_in_random_chunks(fmt, b"".join(pieces), rng, 3 * fmt.length)
    kept = np.array([i for i in range(n) if i not in flipped])
    assert dec.total.frames == kept.size and dec.total.rejected == len(flipped)
    np.testing.assert_array_equal(s.accel, accel[kept].astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(s.gyro, gyro[kept].astype(np.float32).astype(np.float64))
    np.testing.assert_allclose(s.time, kept / rate, atol=1e-9)
