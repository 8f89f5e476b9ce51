"""Shared by the frame tests: the spec's test frames and an independent bit-by-bit CRC-32/MPEG-2 (written from
docs/protocols/imu-frames.md, never from this project's encoder), and the decoding of a damaged stream in random
chunks with the counts every such test checks."""

from __future__ import annotations

import numpy as np

from drivers.imu_unit.decoder import FrameDecoder
from drivers.imu_unit.description import FrameFormat
from drivers.imu_unit.samples import SampleConverter, Samples
from drivers.imu_unit.serial_unit import concat_samples

KVH_MANUAL = bytes.fromhex("fe81ff5537a96a6e38586c1fb75bf862bf803e78bb650d283b0a37ac773d00284bfa34d8")
KVH_BUILT = bytes.fromhex("fe81ff55339c1f3f00000000b58637bd3a83126fbb03126f3f800000772a001f4db75c56")
STIM_93 = bytes.fromhex("93002000fff00003c0000000147b00000008000000000000feb852400000001001f4e549ab2c")


def crc_mpeg2_bitwise(data: bytes) -> int:
    """Independent bit-by-bit CRC-32/MPEG-2 (reference for the table-driven engine)."""
    crc = 0xFFFFFFFF
    for b in data:
        crc ^= b << 24
        for _ in range(8):
            crc = ((crc << 1) ^ 0x04C11DB7) & 0xFFFFFFFF if crc & 0x80000000 else (crc << 1) & 0xFFFFFFFF
    return crc


def decode_in_random_chunks(
    fmt: FrameFormat, data: bytes, rng: np.random.Generator, max_chunk: int
) -> tuple[FrameDecoder, Samples, list[np.ndarray]]:
    """Feed ``data`` in random chunks of 1 … ``max_chunk`` − 1 bytes (some shorter than a frame); returns the
    decoder (its ``total`` statistics), the samples and each batch's layout indices."""
    dec = FrameDecoder(fmt.desc)
    conv = SampleConverter(fmt)
    parts, layouts = [], []
    pos = 0
    while pos < len(data):
        k = int(rng.integers(1, max_chunk))
        batch, _ = dec.feed(data[pos : pos + k])
        pos += k
        if len(batch):
            layouts.append(batch.layout)
            parts.append(conv.convert(batch))
    dec.flush()
    return dec, concat_samples(parts), layouts


def check_damage_counts(
    dec: FrameDecoder, s: Samples, n: int, lost: set[int], duplicated: set[int], garbage: int
) -> np.ndarray:
    """The exact counts of a stream of ``n`` frames with ``lost`` ones (truncated or corrupted: rejected, a gap
    each), ``duplicated`` ones sent twice, ``garbage`` bytes in all and one counter reset; returns the indices of
    the frames kept."""
    kept = np.array([i for i in range(n) if i not in lost])
    assert dec.total.frames == kept.size + len(duplicated)
    assert dec.total.rejected == len(lost)
    assert dec.total.garbage_bytes == garbage
    assert (s.gaps, s.resets, s.duplicates) == (len(lost), 1, len(duplicated))
    assert len(s) == kept.size
    return kept
