"""Vectorised decoder (and encoder) of inertial-unit frames compiled from a frame description.

The frame layouts are data (:mod:`drivers.imu_frame_desc`, ``drivers/frames/*.yaml``): the project's own
frame ``tablebench-v1``, the KVH 1750/1775 formats A/B/C and the STIM300 datagrams. This module turns a
:class:`~drivers.imu_frame_desc.FrameDescription` into

* a structured numpy dtype over one whole frame (every field a strided view of the frame rows; 24-bit
  fields are read as 3-byte sub-arrays and sign-extended),
* a table-driven CRC vectorised over frames (:mod:`drivers.imu_frame_crc`), with the description's
  coverage and zero padding (STIM300: the CRC covers ``(-n) mod 4`` zero bytes that are never sent),

and decodes a byte stream without a per-frame Python loop: sync candidates are found with numpy comparisons
over the whole buffer, the frames starting at every candidate are gathered into a 2-D byte array with one
fancy-indexing operation, their checksums computed at once, and the accepted rows viewed through the
structured dtype. After garbage, a truncated or a corrupted frame the decoder resynchronises on the next
position whose sync and checksum check. Bytes that cannot yet be decided (a possible frame start too close
to the end of the buffer) are carried over to the next :meth:`FrameDecoder.feed`.

Counting (per feed and in totals): ``frames`` accepted; ``rejected`` candidate frames (sync matched, checksum
failed) that do not lie inside an accepted frame or inside an earlier rejected one (so a damaged frame counts
once even when a one-byte identifier recurs in its payload); ``garbage_bytes`` bytes not part of an accepted
frame (an optional trailer such as STIM300's CR LF after a frame is not garbage). Counter gaps, resets and
duplicates are judged on the decoded samples (:mod:`drivers.imu_frame_samples`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivers.imu_frame_crc import CrcEngine
from drivers.imu_frame_desc import FieldDesc, FrameDescription

log = logging.getLogger(__name__)


@dataclass
class DecodeStats:
    """What one :meth:`FrameDecoder.feed` call (or the decoder's life, :attr:`FrameDecoder.total`) saw."""

    frames: int = 0
    rejected: int = 0
    garbage_bytes: int = 0

    def add(self, other: DecodeStats) -> None:
        self.frames += other.frames
        self.rejected += other.rejected
        self.garbage_bytes += other.garbage_bytes


@dataclass
class FrameBatch:
    """Accepted frames in stream order: each field's values (widened to a native dtype), and the raw rows.

    Attributes
    ----------
    values : dict[str, ndarray]
        Field name → (n,) values as on the wire (no scaling).
    rows : ndarray (n, length) uint8
        The frames' bytes.
    """

    values: dict[str, NDArray] = field(default_factory=dict)
    rows: NDArray[np.uint8] = field(default_factory=lambda: np.zeros((0, 0), np.uint8))

    def __len__(self) -> int:
        return int(self.rows.shape[0])


class FrameCodec:
    """The compiled layout of one description: structured dtype, 24-bit fields, checksum engine."""

    def __init__(self, desc: FrameDescription) -> None:
        self.desc = desc
        self.length = desc.length
        names, formats, offsets = [], [], []
        self.wide: list[FieldDesc] = []  # 24-bit fields
        for f in desc.fields:
            names.append(f.name)
            offsets.append(f.offset)
            if f.size == 3:
                formats.append(("u1", (3,)))
                self.wide.append(f)
            else:
                formats.append(f.dtype())
        self.dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": desc.length})
        self._wide_idx = np.array(
            [[f.offset + i for i in ((0, 1, 2) if f.byte_order == "big" else (2, 1, 0))] for f in self.wide],
            dtype=np.intp,
        ).reshape(-1, 3)
        self._wide_signed = np.array([f.type == "int24" for f in self.wide], dtype=np.int32)
        cs = desc.checksum
        self.crc = CrcEngine(cs.spec) if cs is not None else None
        if cs is not None:
            self._crc_dtype = np.dtype(
                ("<" if cs.byte_order == "little" else ">") + {1: "u1", 2: "u2", 4: "u4"}[cs.spec.nbytes]
            )

    # ---- fields ------------------------------------------------------------------------------------------
    def values(self, rows: NDArray[np.uint8]) -> dict[str, NDArray]:
        """Field values of contiguous frame rows (k, length): strided views of one structured view; the
        24-bit fields of the frame are gathered and sign-extended together."""
        rec = np.ascontiguousarray(rows).view(self.dtype).reshape(-1)
        out: dict[str, NDArray] = {f.name: rec[f.name] for f in self.desc.fields if f.size != 3}
        if self.wide:
            b = rows[:, self._wide_idx].astype(np.int32)  # (k, n_wide, 3), bytes in big-endian order
            v = (b[:, :, 0] << 16) | (b[:, :, 1] << 8) | b[:, :, 2]
            if self._wide_signed.any():
                v -= (v >= 1 << 23) * self._wide_signed * (1 << 24)
            for j, f in enumerate(self.wide):
                out[f.name] = v[:, j] if f.type == "int24" else v[:, j].astype(np.uint32)
        return out

    def checksums_ok(self, rows: NDArray[np.uint8]) -> NDArray[np.bool_]:
        """Whether each frame row's checksum checks (all True without a checksum)."""
        cs = self.desc.checksum
        if cs is None or self.crc is None:
            return np.ones(rows.shape[0], dtype=bool)
        body = rows[:, cs.start : cs.end]
        if cs.pad:
            body = np.concatenate([body, np.zeros((rows.shape[0], cs.pad), np.uint8)], axis=1)
        calc = self.crc(body)
        wire = np.ascontiguousarray(rows[:, cs.offset : cs.offset + cs.spec.nbytes]).view(self._crc_dtype).reshape(-1)
        return calc.astype(np.uint64) == wire.astype(np.uint64)

    # ---- encoding ----------------------------------------------------------------------------------------
    def encode(self, values: dict[str, NDArray], n: int) -> NDArray[np.uint8]:
        """Frames (n, length) uint8 from raw field values (missing fields are 0); sync and checksum filled in.

        Values are cast to the field types (24-bit fields wrap to 24 bits); the caller quantises and clips.
        """
        rec = np.zeros(n, dtype=self.dtype)
        wide = {f.name: f for f in self.wide}
        for name, v in values.items():
            f = wide.get(name)
            if f is None:
                rec[name] = np.asarray(v).astype(self.dtype.fields[name][0], copy=False)
                continue
            x = np.asarray(v).astype(np.int64) & 0xFFFFFF
            b = np.stack([(x >> 16) & 0xFF, (x >> 8) & 0xFF, x & 0xFF], axis=1).astype(np.uint8)
            rec[name] = b if f.byte_order == "big" else b[:, ::-1]
        rows = rec.view(np.uint8).reshape(n, self.length)
        rows[:, : len(self.desc.sync)] = np.frombuffer(self.desc.sync, np.uint8)
        cs = self.desc.checksum
        if cs is not None and self.crc is not None:
            body = rows[:, cs.start : cs.end]
            if cs.pad:
                body = np.concatenate([body, np.zeros((n, cs.pad), np.uint8)], axis=1)
            crc = self.crc(body).astype(self._crc_dtype)
            rows[:, cs.offset : cs.offset + cs.spec.nbytes] = crc.view(np.uint8).reshape(n, cs.spec.nbytes)
        return rows


class FrameDecoder:
    """Streaming decoder of one frame format: carry-over buffer, bulk sync search, bulk checksum, resync.

    Parameters
    ----------
    desc : FrameDescription

    Attributes
    ----------
    total : DecodeStats
        Totals since construction.
    """

    def __init__(self, desc: FrameDescription) -> None:
        self.codec = FrameCodec(desc)
        self.desc = desc
        self._sync = np.frombuffer(desc.sync, np.uint8)
        self._trailer = np.frombuffer(desc.trailer, np.uint8)
        self._carry = np.zeros(0, dtype=np.uint8)
        self._pos = 0  # stream offset of the carry-over's first byte
        self._reject_end = 0  # stream offset where the span of the last counted reject ends
        self.total = DecodeStats()

    @property
    def pending_bytes(self) -> int:
        """Bytes held over for the next feed (a possible partial frame)."""
        return int(self._carry.size)

    def reset(self) -> None:
        """Forget the carry-over buffer (after a reconnect)."""
        self._pos += self._carry.size
        self._carry = np.zeros(0, dtype=np.uint8)

    def flush(self) -> DecodeStats:
        """End of stream: the carried bytes can never complete a frame; count them as garbage."""
        st = DecodeStats(garbage_bytes=int(self._carry.size))
        self._pos += self._carry.size
        self._carry = np.zeros(0, dtype=np.uint8)
        self.total.add(st)
        return st

    def feed(self, data: bytes | bytearray | memoryview | NDArray[np.uint8]) -> tuple[FrameBatch, DecodeStats]:
        """Decode as many complete frames as ``data`` (plus the carry-over) holds; see the module docstring."""
        new = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data.astype(np.uint8)
        buf = np.concatenate([self._carry, new]) if self._carry.size else new
        n = buf.size
        L = self.codec.length
        stats = DecodeStats()
        m = n - L + 1  # positions where a whole frame fits (the decided region)
        if m <= 0:
            self._carry = buf.copy()
            return FrameBatch(rows=np.zeros((0, L), np.uint8)), stats
        sync = self._sync
        hit = buf[:m] == sync[0]
        for j in range(1, sync.size):
            hit &= buf[j : m + j] == sync[j]
        cand = np.flatnonzero(hit)
        rows = buf[cand[:, None] + np.arange(L)] if cand.size else np.zeros((0, L), np.uint8)
        ok = self.codec.checksums_ok(rows)
        if ok.all():  # the common case of a clean stream with a multi-byte sync
            good, bad, good_rows = cand, cand[:0], rows
        else:
            good, bad, good_rows = cand[ok], cand[~ok], rows[ok]
        if good.size > 1 and (np.diff(good) < L).any():
            keep = _non_overlapping(good, L)
            good_rows = good_rows[keep]
            good = good[keep]
        decided_end = max(int(good[-1]) + L, m) if good.size else m
        if bad.size:
            if good.size:
                # candidates inside an accepted frame are payload, not rejects
                inside = np.searchsorted(good, bad, side="right") - 1
                covered = (inside >= 0) & (bad < good[np.maximum(inside, 0)] + L)
                bad = bad[~covered]
            bad = bad[bad + self._pos >= self._reject_end]  # inside a reject counted in an earlier feed
            if bad.size > 1 and (np.diff(bad) < L).any():
                bad = bad[_non_overlapping(bad, L)]  # a damaged frame is one reject, whatever its payload holds
            if bad.size:
                self._reject_end = max(self._reject_end, int(bad[-1]) + L + self._pos)
        stats.rejected = int(bad.size)
        stats.frames = int(good.size)
        trailer_bytes = 0
        if self._trailer.size and good.size:
            t = self._trailer.size
            ends = good + L
            fits = ends + t <= n
            e = ends[fits]
            tr = buf[e] == self._trailer[0]
            for j in range(1, t if tr.any() else 0):
                tr &= buf[e + j] == self._trailer[j]
            nxt = np.append(good[1:], np.iinfo(np.int64).max)[fits]
            tr &= e + t <= nxt  # the trailer must not overlap the next frame
            trailer_bytes = int(tr.sum()) * t
            if tr.size and tr[-1] and int(e[-1]) + t > decided_end:
                decided_end = int(e[-1]) + t
        garbage = decided_end - good.size * L - trailer_bytes
        stats.garbage_bytes = int(garbage)
        self._carry = buf[decided_end:].copy()
        self._pos += decided_end
        batch = (
            FrameBatch(self.codec.values(good_rows), good_rows)
            if good.size
            else FrameBatch(rows=np.zeros((0, L), np.uint8))
        )
        self.total.add(stats)
        return batch, stats


def _non_overlapping(pos: NDArray[np.intp], length: int) -> NDArray[np.intp]:
    """Indices of a greedy earliest-first choice of non-overlapping frames (loops only over overlaps: rare)."""
    keep: list[int] = []
    end = -1
    for i, p in enumerate(pos.tolist()):
        if p >= end:
            keep.append(i)
            end = p + length
    return np.asarray(keep, dtype=np.intp)
