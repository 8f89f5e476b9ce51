"""Vectorised decoder (and encoder) of inertial-unit frames compiled from a frame description.

The frame layouts are data (:mod:`drivers.imu_unit.description`, ``drivers/imu_unit/frames/*.yaml``): the project's own
frame ``tablebench-v1``, the KVH 1750/1775 formats A/B/C and the STIM300 datagrams. This module turns a
:class:`~drivers.imu_unit.description.FrameDescription` into

* a structured numpy dtype over one whole frame (every field a strided view of the frame rows; 24-bit
  fields are read as 3-byte sub-arrays and sign-extended),
* a table-driven CRC vectorised over frames (:mod:`drivers.imu_unit.checksums`), with the description's
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
duplicates are judged on the decoded samples (:mod:`drivers.imu_unit.samples`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from drivers.imu_unit.checksums import CrcEngine
from drivers.imu_unit.description import ChecksumDesc, FieldDesc, FrameDescription

log = logging.getLogger(__name__)


@dataclass
class DecodeStats:
    """What one :meth:`FrameDecoder.feed` call (or the decoder's life, :attr:`FrameDecoder.total`) saw."""

    frames: int = 0
    rejected: int = 0
    garbage_bytes: int = 0
    bit_frames: int = 0  # built-in-test frames (a ``role: bit`` layout): recognised, neither data nor garbage
    other_frames: int = 0  # other messages the unit interleaves (a ``role: other`` layout): checked, skipped

    def add(self, other: DecodeStats) -> None:
        self.frames += other.frames
        self.rejected += other.rejected
        self.garbage_bytes += other.garbage_bytes
        self.bit_frames += other.bit_frames
        self.other_frames += other.other_frames


@dataclass
class FrameBatch:
    """Accepted frames in stream order: each field's values (widened to a native dtype), and the raw rows.

    Attributes
    ----------
    values : dict[str, ndarray]
        Field name → (n,) values as on the wire (no scaling).
    rows : ndarray (n, length) uint8
        The frames' bytes (single-layout descriptions; empty for a multi-layout one).
    layout : ndarray (n,) int or None
        Multi-layout descriptions: the layout index of each data frame in stream order (0 = the primary
        layout, k = ``desc.alternates[k - 1]``); None for a single-layout description.
    groups : dict[int, FrameBatch]
        Multi-layout descriptions: layout index → that layout's frames (stream order), with their values.
    bit : dict[str, FrameBatch]
        Built-in-test frames (``role: bit`` layouts) by layout name, with their values and bytes.
    """

    values: dict[str, NDArray] = field(default_factory=dict)
    rows: NDArray[np.uint8] = field(default_factory=lambda: np.zeros((0, 0), np.uint8))
    layout: NDArray[np.intp] | None = None
    groups: dict[int, FrameBatch] = field(default_factory=dict)
    bit: dict[str, FrameBatch] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.rows.shape[0]) if self.layout is None else int(self.layout.shape[0])


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
        # 32-bit fields sent least significant 16-bit word first (each word big-endian): read big-endian, halves swapped
        self._swapped = [f for f in desc.fields if f.low_word_first]
        self._end = np.frombuffer(desc.end, np.uint8)
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
        for f in self._swapped:
            out[f.name] = _swap_words(out[f.name])
        if self.wide:
            b = rows[:, self._wide_idx].astype(np.int32)  # (k, n_wide, 3), bytes in big-endian order
            v = (b[:, :, 0] << 16) | (b[:, :, 1] << 8) | b[:, :, 2]
            if self._wide_signed.any():
                v -= (v >= 1 << 23) * self._wide_signed * (1 << 24)
            for j, f in enumerate(self.wide):
                out[f.name] = v[:, j] if f.type == "int24" else v[:, j].astype(np.uint32)
        return out

    def checksums_ok(self, rows: NDArray[np.uint8]) -> NDArray[np.bool_]:
        """Whether each frame row's checksum checks (all True without a checksum) and its end bytes are
        the described ones."""
        cs = self.desc.checksum
        if self._end.size:
            end_ok = np.all(rows[:, self.length - self._end.size :] == self._end, axis=1)
            if cs is None or self.crc is None:
                return end_ok
            return end_ok & self._checksum_ok(rows, cs)
        if cs is None or self.crc is None:
            return np.ones(rows.shape[0], dtype=bool)
        return self._checksum_ok(rows, cs)

    def _checksum_ok(self, rows: NDArray[np.uint8], cs: ChecksumDesc) -> NDArray[np.bool_]:
        assert self.crc is not None
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
        swapped = {f.name for f in self._swapped}
        for name, v in values.items():
            f = wide.get(name)
            if f is None:
                x = np.asarray(v).astype(self.dtype.fields[name][0], copy=False)
                rec[name] = _swap_words(x) if name in swapped else x
                continue
            x = np.asarray(v).astype(np.int64) & 0xFFFFFF
            b = np.stack([(x >> 16) & 0xFF, (x >> 8) & 0xFF, x & 0xFF], axis=1).astype(np.uint8)
            rec[name] = b if f.byte_order == "big" else b[:, ::-1]
        rows = rec.view(np.uint8).reshape(n, self.length)
        rows[:, : len(self.desc.sync)] = np.frombuffer(self.desc.sync, np.uint8)
        if self._end.size:
            rows[:, self.length - self._end.size :] = self._end
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
        self._after_frame = False  # the carry-over starts right after an accepted frame (a trailer may follow)
        self.total = DecodeStats()
        # multi-layout descriptions ("length by identifier"): every layout's sync, length, codec and role
        self.layouts: list[tuple[str, FrameDescription]] = [("data", desc), *desc.alternates]
        self._multi = len(self.layouts) > 1
        if self._multi:
            self._codecs = [self.codec] + [FrameCodec(d) for _r, d in desc.alternates]
            self._syncs = [np.frombuffer(d.sync, np.uint8) for _r, d in self.layouts]
            self._lens = np.array([d.length for _r, d in self.layouts], dtype=np.int64)
            self._roles = [r for r, _d in self.layouts]
            self._is_bit = np.array([r != "data" for r in self._roles])  # bit and other: never samples
            self._is_other = np.array([r == "other" for r in self._roles])
            self._has_bit = bool(self._is_bit.any())
            self._first = np.zeros(256, dtype=bool)
            self._first[[int(sy[0]) for sy in self._syncs]] = True
            self._recent: list[int] = [0]  # layouts with frames in the latest feed (checked first)

    @property
    def pending_bytes(self) -> int:
        """Bytes held over for the next feed (a possible partial frame)."""
        return int(self._carry.size)

    def reset(self) -> None:
        """Forget the carry-over buffer (after a reconnect)."""
        self._pos += self._carry.size
        self._carry = np.zeros(0, dtype=np.uint8)

    def flush(self) -> DecodeStats:
        """End of stream: the carried bytes can never complete a frame; count them as garbage (a multi-layout
        description first judges the failed candidates held back, so a damaged last frame counts as a reject)."""
        if self._multi and self._carry.size:
            return self._feed_multi(self._carry, final=True)[1]
        st = DecodeStats(garbage_bytes=int(self._carry.size))
        self._pos += self._carry.size
        self._carry = np.zeros(0, dtype=np.uint8)
        self.total.add(st)
        return st

    def feed(self, data: bytes | bytearray | memoryview | NDArray[np.uint8]) -> tuple[FrameBatch, DecodeStats]:
        """Decode as many complete frames as ``data`` (plus the carry-over) holds; see the module docstring."""
        new = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data.astype(np.uint8)
        buf = np.concatenate([self._carry, new]) if self._carry.size else new
        if self._multi:
            return self._feed_multi(buf)
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
        trailer_bytes, decided_end = self._trailers(buf, good, good + L, decided_end)
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

    def _trailers(
        self, buf: NDArray[np.uint8], good: NDArray[np.intp], ends: NDArray[np.intp], decided_end: int
    ) -> tuple[int, int]:
        """(trailer bytes after accepted frames, decided end): an optional trailer (STIM300 CR LF) right after a
        frame is not garbage, also when the frame ended the previous feed (the carry then starts after it)."""
        t = self._trailer.size
        if not t:
            return 0, decided_end
        big = np.iinfo(np.int64).max
        nxt = np.append(good[1:], big) if good.size else good  # the start of the frame after each accepted one
        if self._after_frame:  # a frame ended where the carry-over starts: a virtual end at 0
            ends = np.concatenate([[0], ends])
            nxt = np.concatenate([[good[0] if good.size else big], nxt])
        self._after_frame = bool(ends.size) and int(ends[-1]) == decided_end
        fits = ends + t <= buf.size
        e = ends[fits]
        tr = buf[e] == self._trailer[0]
        for j in range(1, t if tr.any() else 0):
            tr &= buf[e + j] == self._trailer[j]
        tr &= e + t <= nxt[fits]  # the trailer must not overlap the next frame
        if tr.size and tr[-1] and int(e[-1]) + t > decided_end:
            decided_end = int(e[-1]) + t
            self._after_frame = False
        return int(tr.sum()) * t, decided_end

    def _feed_multi(self, buf: NDArray[np.uint8], final: bool = False) -> tuple[FrameBatch, DecodeStats]:
        """:meth:`feed` for a multi-layout description: the layout is chosen by the sync/identifier bytes.

        Candidates of every layout are found in one pass (a 256-entry table of the layouts' first sync bytes,
        then each layout's remaining sync bytes), each layout's candidates are checked with its own checksum
        in bulk, and accepted frames of all layouts are merged in stream order (earliest first where
        candidates overlap). Positions below ``n − longest + 1`` are decided; a shorter frame already
        complete beyond that is decided too, so a stream's last short frame is never held back. A failed
        candidate beyond the decided region waits (it may be payload of a longer frame not yet complete);
        ``final`` (end of stream) decides everything.
        """
        n = buf.size
        stats = DecodeStats()
        m = n if final else max(n - int(self._lens.max()) + 1, 0)
        cands = self._multi_candidates(buf)
        ks = [k for k in cands.checked if cands.pos[k].size]
        seen = [k for k in ks if cands.ok[k].any()]
        if seen:
            self._recent = seen
        pos, lay, ok, within = _merge_in_stream_order(cands, ks)
        lens = self._lens[lay]
        g = np.flatnonzero(ok) if not ok.all() else np.arange(ok.size)
        if g.size > 1 and (pos[g[1:]] < pos[g[:-1]] + lens[g[:-1]]).any():
            g = g[_non_overlapping_var(pos[g], lens[g])]
        good, glen = pos[g], lens[g]
        gend = good + glen
        decided_end = max(int(gend[-1]), m) if good.size else m
        if g.size < ok.size:  # failed candidates
            stats.rejected = self._count_rejects(pos[~ok], lens[~ok], good, gend, decided_end)
        trailer_bytes, decided_end = self._trailers(buf, good, gend, decided_end)
        stats.garbage_bytes = int(decided_end - int(glen.sum()) - trailer_bytes)
        batch = self._multi_batch(cands, seen, lay[g], within[g], good.size, stats)
        self._carry = buf[decided_end:].copy()
        self._pos += decided_end
        self.total.add(stats)
        return batch, stats

    def _multi_candidates(self, buf: NDArray[np.uint8]) -> _Candidates:
        """Every layout's candidate frames in ``buf`` with their checksum verdicts (see :meth:`_feed_multi`).

        1. the layouts the stream used lately (usually one): all their candidates, as a single layout would;
        2. the other layouts, only where no frame was accepted in 1 (identifier bytes inside accepted frames
           are payload: not checked), and only the layouts whose first sync byte occurs there (garbage).
        """
        n = buf.size
        nl = len(self._syncs)
        cands = _Candidates(pos=[np.zeros(0, np.intp)] * nl, ok=[np.zeros(0, bool)] * nl, rows={}, checked=[])

        def check(k: int, pool: NDArray[np.intp] | None) -> None:
            cands.checked.append(k)
            sync, L = self._syncs[k], int(self._lens[k])
            if pool is None:  # the whole buffer
                c = np.flatnonzero(buf[: max(n - L + 1, 0)] == sync[0])
            else:
                c = pool[buf[pool] == sync[0]]
                c = c[c + L <= n]
            for j in range(1, sync.size):
                if not c.size:
                    break
                c = c[buf[c + j] == sync[j]]
            if c.size:
                cands.rows[k] = buf[c[:, None] + np.arange(L)]
                cands.ok[k] = self._codecs[k].checksums_ok(cands.rows[k])
                cands.pos[k] = c

        for k in self._recent:
            check(k, None)
        rest = self._outside_accepted(buf, cands)
        if rest.size:
            present = np.zeros(256, bool)
            present[buf[rest]] = True
            for k in range(nl):
                if k not in self._recent and present[self._syncs[k][0]]:
                    check(k, rest)
        return cands

    def _outside_accepted(self, buf: NDArray[np.uint8], cands: _Candidates) -> NDArray[np.intp]:
        """Positions outside the frames accepted so far (garbage, trailers, a damaged frame, the tail) that
        hold some layout's first sync byte, gathered at once."""
        n = buf.size
        pos_l, ok_l = cands.pos, cands.ok
        if len(self._recent) == 1:
            k0 = self._recent[0]
            acc = pos_l[k0] if ok_l[k0].all() else pos_l[k0][ok_l[k0]]
            acc_end = acc + self._lens[k0]
        else:
            acc = np.concatenate([pos_l[k][ok_l[k]] for k in self._recent])
            acc_end = np.concatenate([pos_l[k][ok_l[k]] + self._lens[k] for k in self._recent])
            o = np.argsort(acc, kind="stable")
            acc, acc_end = acc[o], np.maximum.accumulate(acc_end[o])
        seg_start = np.concatenate([[0], acc_end])
        seg_len = np.maximum(np.concatenate([acc, [n]]) - seg_start, 0)
        total = int(seg_len.sum())
        if total == n:
            return np.flatnonzero(self._first[buf])
        if total:
            offs = np.cumsum(seg_len) - seg_len
            idx = np.repeat(seg_start - offs, seg_len) + np.arange(total)
            return idx[self._first[buf[idx]]]
        return np.zeros(0, np.intp)

    def _count_rejects(
        self,
        bad: NDArray[np.intp],
        blen: NDArray[np.int64],
        good: NDArray[np.intp],
        gend: NDArray[np.intp],
        decided_end: int,
    ) -> int:
        """Rejected candidates among the failed ones ``bad`` (lengths ``blen``): those in the decided region,
        not payload of an accepted frame, not already counted, not overlapping one another."""
        keepb = bad < decided_end  # a failed candidate beyond the decided region is judged again next feed
        if good.size and bad.size:
            inside = np.searchsorted(good, bad, side="right") - 1
            keepb &= ~((inside >= 0) & (bad < gend[np.maximum(inside, 0)]))  # payload of an accepted frame
        keepb &= bad + self._pos >= self._reject_end
        bad, blen = bad[keepb], blen[keepb]
        if bad.size > 1 and (bad[1:] < bad[:-1] + blen[:-1]).any():
            kb = _non_overlapping_var(bad, blen)
            bad, blen = bad[kb], blen[kb]
        if bad.size:
            self._reject_end = max(self._reject_end, int((bad + blen).max()) + self._pos)
        return int(bad.size)

    def _multi_batch(
        self,
        cands: _Candidates,
        seen: list[int],
        glay: NDArray[np.intp],
        gwithin: NDArray[np.intp],
        n_good: int,
        stats: DecodeStats,
    ) -> FrameBatch:
        """The accepted frames (layout ``glay``, index ``gwithin`` among their layout's candidates) as a
        :class:`FrameBatch`: data layouts in groups, built-in-test frames apart, common fields merged."""
        if self._has_bit:
            is_bit = self._is_bit[glay]
            data = ~is_bit
            batch = FrameBatch(layout=glay[data])
            n_other = int(self._is_other[glay].sum())
            stats.frames, stats.bit_frames = int(data.sum()), int(is_bit.sum()) - n_other
            stats.other_frames = n_other
        else:
            batch = FrameBatch(layout=glay)
            stats.frames = int(glay.size)
        for k in seen if len(seen) > 1 else seen[:1] if n_good else []:
            if len(seen) == 1 and n_good == cands.pos[k].size:  # every candidate accepted: rows as gathered
                rows = cands.rows[k]
            else:
                rows = cands.rows[k][gwithin[glay == k]]
                if not rows.shape[0]:
                    continue
            fb = FrameBatch(self._codecs[k].values(rows), rows)
            if self._roles[k] == "bit":
                batch.bit[self.layouts[k][1].name] = fb
            elif self._roles[k] == "other":
                continue
            else:
                batch.groups[k] = fb
        if len(batch.groups) == 1:  # the usual case: every data frame in one layout (its values as they are)
            only = next(iter(batch.groups.values()))
            batch.values, batch.rows = only.values, only.rows
        elif batch.groups:  # fields every data layout has (counter, gyros…), merged in stream order
            common = set.intersection(*(set(gb.values) for gb in batch.groups.values()))
            lay_d = batch.layout
            for name in sorted(common):
                out = np.zeros(lay_d.size, dtype=np.result_type(*(gb.values[name] for gb in batch.groups.values())))
                for k, gb in batch.groups.items():
                    out[lay_d == k] = gb.values[name]
                batch.values[name] = out
        return batch


@dataclass
class _Candidates:
    """Per layout: candidate positions, checksum verdicts and gathered rows; the layouts checked, in order."""

    pos: list[NDArray[np.intp]]
    ok: list[NDArray[np.bool_]]
    rows: dict[int, NDArray[np.uint8]]
    checked: list[int]


def _merge_in_stream_order(
    cands: _Candidates, ks: list[int]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_], NDArray[np.intp]]:
    """(position, layout, checksum ok, index within its layout) of the candidates of layouts ``ks``, in
    stream order."""
    if len(ks) == 1:  # one layout had candidates: already in stream order
        k = ks[0]
        pos, ok = cands.pos[k], cands.ok[k]
        return pos, np.full(pos.size, k, np.intp), ok, np.arange(pos.size)
    if not ks:
        e = np.zeros(0, np.intp)
        return e, e, np.zeros(0, bool), e
    pos = np.concatenate([cands.pos[k] for k in ks])
    lay = np.concatenate([np.full(cands.pos[k].size, k, np.intp) for k in ks])
    ok = np.concatenate([cands.ok[k] for k in ks])
    within = np.concatenate([np.arange(cands.pos[k].size) for k in ks])
    order = np.argsort(pos, kind="stable")
    return pos[order], lay[order], ok[order], within[order]


def _non_overlapping_var(pos: NDArray[np.intp], lengths: NDArray[np.int64]) -> NDArray[np.intp]:
    """:func:`_non_overlapping` for frames of different lengths (loops only when some overlap: rare)."""
    keep: list[int] = []
    end = -1
    for i, (p, L) in enumerate(zip(pos.tolist(), lengths.tolist(), strict=True)):
        if p >= end:
            keep.append(i)
            end = p + L
    return np.asarray(keep, dtype=np.intp)


def _non_overlapping(pos: NDArray[np.intp], length: int) -> NDArray[np.intp]:
    """Indices of a greedy earliest-first choice of non-overlapping frames (loops only over overlaps: rare)."""
    keep: list[int] = []
    end = -1
    for i, p in enumerate(pos.tolist()):
        if p >= end:
            keep.append(i)
            end = p + length
    return np.asarray(keep, dtype=np.intp)


def _swap_words(v: NDArray) -> NDArray:
    """Swap the 16-bit halves of 32-bit integers (keeps the dtype; its own inverse)."""
    u = np.asarray(v).astype(np.int64) & 0xFFFFFFFF
    w = ((u & 0xFFFF) << 16) | (u >> 16)
    if np.asarray(v).dtype.kind == "i":
        w = w - ((w >> 31) & 1) * (1 << 32)
    return w.astype(np.asarray(v).dtype)
