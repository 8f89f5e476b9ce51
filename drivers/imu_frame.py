"""Binary frame format of the serial inertial unit, with a vectorised encoder and a resynchronising decoder.

Frame layout (46 bytes, little-endian, no padding)::

    offset size type     field
    0      2    u8[2]    sync word 0xA5 0x5A
    2      1    u8       frame type/version (FRAME_VERSION = 0x01)
    3      1    u8       payload length (PAYLOAD_LENGTH = 38: counter .. status)
    4      4    uint32   frame counter (wraps at 2**32)
    8      8    uint64   time stamp, ns (the unit's sample clock)
    16     24   int32[6] counts [ax, ay, az, gx, gy, gz], body frame b
    40     2    int16    temperature word, °C / temperature_lsb (0.01 °C per count by default)
    42     2    uint16   status word
    44     2    uint16   CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no xor-out)
                         over bytes 2..43 (everything after the sync word)

The counts are converted to SI by :func:`drivers.imu_counts.frames_to_block` with the unit's
:class:`~drivers.imu_counts.CountScale`; this module deals only in :class:`~drivers.imu_counts.RawFrames`.

Decoding (:class:`FrameDecoder`) never loops over bytes in Python: sync candidates are found with numpy
comparisons over the whole buffer, the CRC of every candidate is computed at once (a loop over the 42 byte
positions with a 256-entry table lookup, vectorised over candidates), and accepted frames are gathered with
one fancy-indexing operation and viewed through a structured dtype. After garbage or a corrupted frame the
decoder resynchronises on the next position whose header and CRC check. Bytes that cannot yet be decided
(a possible frame start too close to the end of the buffer) are carried over to the next ``feed``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.imu_counts import RawFrames, counter_gaps, empty_frames

log = logging.getLogger(__name__)

SYNC = (0xA5, 0x5A)
FRAME_VERSION = 0x01
FRAME_SIZE = 46
PAYLOAD_LENGTH = 38
CRC_START = 2  # CRC covers bytes [CRC_START, CRC_END)
CRC_END = 44

FRAME_DTYPE = np.dtype(
    [
        ("sync", "u1", (2,)),
        ("version", "u1"),
        ("length", "u1"),
        ("counter", "<u4"),
        ("timestamp_ns", "<u8"),
        ("counts", "<i4", (6,)),
        ("temperature", "<i2"),
        ("status", "<u2"),
        ("crc", "<u2"),
    ]
)
assert FRAME_DTYPE.itemsize == FRAME_SIZE


def _crc16_table() -> NDArray[np.uint16]:
    table = np.zeros(256, dtype=np.uint16)
    for b in range(256):
        crc = b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
        table[b] = crc & 0xFFFF
    return table


CRC16_TABLE = _crc16_table()


def crc16_ccitt_false(data: NDArray[np.uint8]) -> NDArray[np.uint16]:
    """CRC-16/CCITT-FALSE of every row of ``data`` (shape (k, m) uint8), vectorised over rows.

    Loops over the m byte positions (table lookup), never over rows. ``crc16_ccitt_false(b"123456789")``
    is 0x29B1 (the catalogue check value).
    """
    d = np.atleast_2d(np.asarray(data, dtype=np.uint8))
    crc = np.full(d.shape[0], 0xFFFF, dtype=np.uint16)
    for j in range(d.shape[1]):
        idx = ((crc >> np.uint16(8)) ^ d[:, j]).astype(np.uint8)
        crc = (crc << np.uint16(8)) ^ CRC16_TABLE[idx]
    return crc


def encode_frames(frames: RawFrames) -> bytes:
    """Encode raw frames into the wire format (vectorised; one CRC pass over all frames)."""
    n = len(frames)
    rec = np.zeros(n, dtype=FRAME_DTYPE)
    rec["sync"] = SYNC
    rec["version"] = FRAME_VERSION
    rec["length"] = PAYLOAD_LENGTH
    rec["counter"] = frames.counter
    rec["timestamp_ns"] = frames.timestamp_ns
    rec["counts"] = frames.counts
    rec["temperature"] = frames.temperature
    rec["status"] = frames.status
    raw = rec.view(np.uint8).reshape(n, FRAME_SIZE)
    rec["crc"] = crc16_ccitt_false(raw[:, CRC_START:CRC_END])
    return rec.tobytes()


def slice_frames(frames: RawFrames, start: int, stop: int | None = None) -> RawFrames:
    """Frames ``start:stop`` (copies)."""
    s = slice(start, stop)
    return RawFrames(
        counter=frames.counter[s].copy(),
        timestamp_ns=frames.timestamp_ns[s].copy(),
        counts=frames.counts[s].copy(),
        temperature=frames.temperature[s].copy(),
        status=frames.status[s].copy(),
    )


@dataclass
class DecodeStats:
    """What one :meth:`FrameDecoder.feed` call saw.

    Attributes
    ----------
    frames : int
        Frames accepted.
    rejected : int
        Frame headers (sync + version + length) whose CRC did not check and that were not inside an
        accepted frame. A rejected frame is also missing from the counter sequence, so it is counted in
        ``dropped`` too.
    dropped : int
        Frames missing according to the counter (including the gap from the previous feed).
    garbage_bytes : int
        Bytes skipped while (re)synchronising (not part of any accepted frame).
    """

    frames: int = 0
    rejected: int = 0
    dropped: int = 0
    garbage_bytes: int = 0


class FrameDecoder:
    """Streaming decoder of the unit's frames: carry-over buffer, bulk sync search, bulk CRC, resync.

    Attributes
    ----------
    total : DecodeStats
        Totals since construction.
    last_counter : int or None
        Counter of the last accepted frame.
    """

    def __init__(self) -> None:
        self._carry = np.zeros(0, dtype=np.uint8)
        self.last_counter: int | None = None
        self.total = DecodeStats()

    @property
    def pending_bytes(self) -> int:
        """Bytes held over for the next feed (a possible partial frame)."""
        return int(self._carry.size)

    def reset(self) -> None:
        """Forget the carry-over buffer and the counter history (after a reconnect)."""
        self._carry = np.zeros(0, dtype=np.uint8)
        self.last_counter = None

    def feed(self, data: bytes | bytearray | memoryview) -> tuple[RawFrames, DecodeStats]:
        """Decode as many complete frames as ``data`` (plus the carry-over) holds.

        Returns
        -------
        frames : RawFrames
            Accepted frames in stream order.
        stats : DecodeStats
            Counts for this call (also accumulated in :attr:`total`).
        """
        new = np.frombuffer(bytes(data), dtype=np.uint8)
        buf = np.concatenate([self._carry, new]) if self._carry.size else new
        n = buf.size
        stats = DecodeStats()
        last_start = n - FRAME_SIZE  # last position where a whole frame fits
        if last_start < 0:
            self._carry = buf.copy()
            return empty_frames(), stats
        # Header candidates among positions that can hold a whole frame (decided region).
        m = last_start + 1
        cand = np.flatnonzero(
            (buf[:m] == SYNC[0])
            & (buf[1 : m + 1] == SYNC[1])
            & (buf[2 : m + 2] == FRAME_VERSION)
            & (buf[3 : m + 3] == PAYLOAD_LENGTH)
        )
        if cand.size:
            body = buf[cand[:, None] + np.arange(CRC_START, CRC_END)]
            crc_calc = crc16_ccitt_false(body)
            crc_wire = buf[cand + CRC_END].astype(np.uint16) | (buf[cand + CRC_END + 1].astype(np.uint16) << 8)
            good = cand[crc_calc == crc_wire]
            bad = cand[crc_calc != crc_wire]
        else:
            good = cand
            bad = cand
        if good.size > 1 and np.any(np.diff(good) < FRAME_SIZE):
            good = self._non_overlapping(good)
        if good.size:
            # Candidates that failed the CRC but lie inside an accepted frame are payload, not rejects.
            inside = np.searchsorted(good, bad, side="right") - 1
            covered = (inside >= 0) & (bad < good[np.maximum(inside, 0)] + FRAME_SIZE)
            bad = bad[~covered]
            decided_end = max(int(good[-1]) + FRAME_SIZE, m)
        else:
            decided_end = m
        stats.rejected = int(bad.size)
        stats.frames = int(good.size)
        stats.garbage_bytes = int(decided_end - good.size * FRAME_SIZE)
        self._carry = buf[decided_end:].copy()
        if good.size:
            raw = buf[good[:, None] + np.arange(FRAME_SIZE)]
            rec = np.ascontiguousarray(raw).view(FRAME_DTYPE).reshape(-1)
            frames = RawFrames(
                counter=rec["counter"].astype(np.uint32),
                timestamp_ns=rec["timestamp_ns"].astype(np.uint64),
                counts=rec["counts"].astype(np.int32),
                temperature=rec["temperature"].astype(np.int16),
                status=rec["status"].astype(np.uint16),
            )
            stats.dropped = counter_gaps(self.last_counter, frames.counter)
            self.last_counter = int(frames.counter[-1])
        else:
            frames = empty_frames()
        if stats.rejected or stats.garbage_bytes:
            log.info(
                "imu stream: %d frame(s) rejected (bad CRC), %d byte(s) skipped while resynchronising",
                stats.rejected,
                stats.garbage_bytes,
            )
        if stats.dropped:
            log.info("imu stream: %d frame(s) missing from the counter sequence", stats.dropped)
        t = self.total
        t.frames += stats.frames
        t.rejected += stats.rejected
        t.dropped += stats.dropped
        t.garbage_bytes += stats.garbage_bytes
        return frames, stats

    @staticmethod
    def _non_overlapping(good: NDArray[np.intp]) -> NDArray[np.intp]:
        """Greedy earliest-first choice among CRC-valid candidates that overlap (rare: loops over frames)."""
        keep: list[int] = []
        end = -1
        for p in good.tolist():
            if p >= end:
                keep.append(p)
                end = p + FRAME_SIZE
        return np.asarray(keep, dtype=np.intp)
