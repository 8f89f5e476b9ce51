"""The serial frame codec: CRC, layout, round trip, resynchronisation, rejection and gap counting."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from drivers.imu_counts import RawFrames, concat_frames
from drivers.imu_frame import (
    FRAME_SIZE,
    FrameDecoder,
    crc16_ccitt_false,
    encode_frames,
)


def _frames(n: int, start: int = 0, seed: int = 0) -> RawFrames:
    rng = np.random.default_rng(seed)
    idx = np.arange(start, start + n, dtype=np.int64)
    return RawFrames(
        counter=(idx % (1 << 32)).astype(np.uint32),
        timestamp_ns=(idx * 1_000_000).astype(np.uint64),
        counts=rng.integers(-(2**31), 2**31 - 1, (n, 6), dtype=np.int32),
        temperature=rng.integers(-32768, 32767, n).astype(np.int16),
        status=rng.integers(0, 65535, n).astype(np.uint16),
    )


def _crc_bitwise(data: bytes) -> int:
    """Independent bit-by-bit CRC-16/CCITT-FALSE (reference for the table-driven one)."""
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def _same(a: RawFrames, b: RawFrames) -> bool:
    return all(
        np.array_equal(getattr(a, f), getattr(b, f))
        for f in ("counter", "timestamp_ns", "counts", "temperature", "status")
    )


def test_crc_catalogue_check_value_and_bitwise_reference():
    assert int(crc16_ccitt_false(np.frombuffer(b"123456789", np.uint8))[0]) == 0x29B1
    rng = np.random.default_rng(3)
    rows = rng.integers(0, 256, (50, 42), dtype=np.uint8)
    got = crc16_ccitt_false(rows)
    assert [int(x) for x in got] == [_crc_bitwise(r.tobytes()) for r in rows]


def test_layout_is_the_documented_little_endian_one():
    f = _frames(1, start=0x01020304, seed=1)
    raw = encode_frames(f)
    assert len(raw) == FRAME_SIZE
    assert raw[:4] == bytes([0xA5, 0x5A, 0x01, 38])
    counter, ts = struct.unpack_from("<IQ", raw, 4)
    assert counter == 0x01020304 and ts == int(f.timestamp_ns[0])
    assert list(struct.unpack_from("<6i", raw, 16)) == f.counts[0].tolist()
    temp, status, crc = struct.unpack_from("<hHH", raw, 40)
    assert (temp, status) == (int(f.temperature[0]), int(f.status[0]))
    assert crc == _crc_bitwise(raw[2:44])


@pytest.mark.parametrize("chunk", [1, 7, 45, 46, 47, 1000, 10**6])
def test_round_trip_any_chunking(chunk):
    f = _frames(300, seed=2)
    raw = encode_frames(f)
    dec = FrameDecoder()
    parts = [dec.feed(raw[i : i + chunk])[0] for i in range(0, len(raw), chunk)]
    out = concat_frames(parts)
    assert _same(out, f)
    assert dec.total.rejected == 0 and dec.total.dropped == 0 and dec.total.garbage_bytes == 0
    assert dec.pending_bytes == 0


def test_garbage_resync_and_flipped_bits_rejected_with_correct_data_after():
    f = _frames(200, seed=4)
    raw = bytearray(encode_frames(f))
    rng = np.random.default_rng(5)
    # flip one bit inside frames 10 and 50 (after the sync word), and insert garbage before frame 100
    for k in (10, 50):
        pos = k * FRAME_SIZE + 20
        raw[pos] ^= 0x10
    garbage = bytes([0xA5, 0x5A, 0x01, 38]) + rng.integers(0, 256, 61, dtype=np.uint8).tobytes()  # a fake header
    data = bytes(raw[: 100 * FRAME_SIZE]) + garbage + bytes(raw[100 * FRAME_SIZE :])
    dec = FrameDecoder()
    out = concat_frames([dec.feed(data[i : i + 333])[0] for i in range(0, len(data), 333)])
    keep = np.ones(200, bool)
    keep[[10, 50]] = False
    assert np.array_equal(out.counter, f.counter[keep])
    assert np.array_equal(out.counts, f.counts[keep])
    assert dec.total.rejected == 3  # two flipped frames + the fake header in the garbage
    assert dec.total.dropped == 2
    assert dec.total.garbage_bytes == 2 * FRAME_SIZE + len(garbage)


def test_leading_partial_frame_and_counter_wrap():
    f = _frames(20, start=(1 << 32) - 5, seed=6)
    raw = encode_frames(f)
    dec = FrameDecoder()
    out, st = dec.feed(raw[17:])  # starts mid-frame: first frame lost
    assert np.array_equal(out.counter, f.counter[1:])
    assert st.dropped == 0 and st.garbage_bytes == FRAME_SIZE - 17 and st.rejected == 0
    more = _frames(3, start=20 + (1 << 32) - 5 + 2, seed=7)  # two frames missing across the wrap point
    out2, st2 = dec.feed(encode_frames(more))
    assert st2.dropped == 2 and len(out2) == 3


def test_random_corruption_never_yields_a_wrong_frame():
    """Seeded Monte Carlo: whatever is accepted is an original frame, in order; losses are all counted."""
    f = _frames(2000, seed=8)
    raw = np.frombuffer(encode_frames(f), np.uint8).copy()
    rng = np.random.default_rng(9)
    hits = rng.choice(raw.size, 300, replace=False)
    raw[hits] ^= rng.integers(1, 256, hits.size).astype(np.uint8)
    dec = FrameDecoder()
    data = raw.tobytes()
    out = concat_frames([dec.feed(data[i : i + 4096])[0] for i in range(0, len(data), 4096)])
    idx = out.counter.astype(np.int64)
    assert np.all(np.diff(idx) > 0)
    assert np.array_equal(out.counts, f.counts[idx])
    assert np.array_equal(out.timestamp_ns, f.timestamp_ns[idx])
    damaged = np.unique(hits // FRAME_SIZE)
    assert dec.total.dropped == int(idx[-1] - idx[0] + 1) - len(out)
    assert len(out) == 2000 - damaged.size
    assert dec.total.rejected <= damaged.size


def test_overlapping_valid_candidates_resolved_earliest_first():
    got = FrameDecoder._non_overlapping(np.array([0, 10, 46, 60, 92, 200]))
    assert got.tolist() == [0, 46, 92, 200]
