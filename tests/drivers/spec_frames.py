"""Reference material for the frame tests, written from ../shared/spec/imu-frames.md, never from this project's
encoder: the spec's test frames and an independent bit-by-bit CRC-32/MPEG-2."""

from __future__ import annotations

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
