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

PUBLIC_FRAMES = [("xsens-mti-mtdata2", XSENS_MTI300)]


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


@pytest.mark.parametrize("name,frame", PUBLIC_FRAMES)
def test_every_single_bit_flip_of_a_public_frame_is_rejected(name, frame):
    desc = load_frame(name)
    for bit in range(8 * len(frame)):
        bad = bytearray(frame)
        bad[bit // 8] ^= 1 << (bit % 8)
        batch, stats = FrameDecoder(desc).feed(bytes(bad))
        assert len(batch) == 0, f"bit {bit} flipped was accepted"
        assert stats.rejected == (0 if bit < 8 * len(desc.sync) else 1)


def test_xsens_clipping_flags_the_channel():
    frame = bytearray(XSENS_MTI300)
    frame[146:150] = struct.pack(">I", 0x00401403)  # accel z (bit 10) and gyro y (bit 12) clipped
    frame[150] = (-sum(frame[1:150])) % 256
    _b, stats, s = _decode("xsens-mti-mtdata2", bytes(frame))
    from drivers.imu_unit.description import FLAG_BITS

    assert stats.frames == 1
    assert s.status[0] == (1 << FLAG_BITS["accel_z"]) | (1 << FLAG_BITS["gyro_y"])
