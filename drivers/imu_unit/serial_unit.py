"""Inertial-unit driver for a binary serial frame stream in any described format (:mod:`drivers.imu_unit.decoder`).

:class:`SerialInertialUnit` implements :class:`drivers.protocols.InertialUnit` over any pyserial-like port
(``serial.Serial`` for a real RS-232/RS-422/USB line, ``serial.serial_for_url("socket://127.0.0.1:PORT")``
for the simulated unit on loopback). The frame format is a compiled description
(:class:`~drivers.imu_unit.description.FrameFormat`: the project's ``tablebench-v1``, KVH 1750/1775 A/B/C, STIM300
datagrams, or a user's own). The driver never opens or closes the port; it sets the port's read ``timeout``
to a short poll interval.

Two modes:

free-running (``polled=False``)
    The unit streams frames at its sample rate; ``read(n)`` returns the next n decoded samples, keeping any
    surplus for the next call.
polled burst (``polled=True``)
    ``read(n)`` sends ``BURST n`` (ASCII, CR-LF) and the unit answers with exactly the frames of the next n
    samples. The simulated unit produces frames only when asked, so the simulated clock advances exactly with
    what the host consumed (bit-identical runs over the wire and in process).

A read is bounded in time: if no byte arrives for ``timeout`` seconds, or the connection is lost, a
:class:`~drivers.protocols.LinkError` is raised. In polled mode a burst is complete when the frame with the
expected last sample index arrives, or when the line has been idle for ``burst_idle_s`` after data (the tail
of the burst was lost: the missing frames show up as dropped).

Link accounting per block (``ImuBlock``): ``rejected`` (checksum failures), ``dropped`` (counter gaps),
``resets`` (counter jumped back) and ``duplicates`` (repeated counter; dropped) are counted separately, in
totals, logged, and put in ``block.events`` for the recording. The first block's events also say which
format and unit configuration were used and what was converted (increments → rates). With ``raw_sink``
every byte read from the port is written there first, so a decoding mistake can be corrected later by
re-decoding the raw stream (``tablebench decode``).
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any, BinaryIO

import numpy as np

from drivers.imu_unit.counts import CountScale
from drivers.imu_unit.decoder import DecodeStats, FrameDecoder
from drivers.imu_unit.description import FrameFormat, compile_format, load_frame
from drivers.imu_unit.samples import SampleConverter, Samples
from drivers.protocols import ImuBlock, LinkError

log = logging.getLogger(__name__)

MAX_BURST = 1_000_000
"""Largest frame count one ``BURST`` request may ask for (longer reads send several requests)."""

MAX_BIT_KEPT = 100
"""Built-in-test frames kept by the driver (the latest ones) for the caller (:attr:`SerialInertialUnit.bit_frames`)."""


def count_format(scale: CountScale, sample_rate: float) -> FrameFormat:
    """The project's own frame ``tablebench-v1`` with a count scale (SI per count)."""
    opts = {"accel_lsb": scale.accel_lsb, "gyro_lsb": scale.gyro_lsb, "temperature_lsb": scale.temperature_lsb}
    return compile_format(load_frame("tablebench-v1"), opts, sample_rate)


def _empty() -> Samples:
    z = np.zeros(0)
    return Samples(
        np.zeros(0, np.int64), np.zeros(0, np.int64), z, np.zeros((0, 3)), np.zeros((0, 3)), z, np.zeros(0, np.uint16)
    )


def _slice(s: Samples, start: int, stop: int | None = None) -> Samples:
    sl = slice(start, stop)
    return Samples(
        s.index[sl],
        s.counter[sl],
        s.time[sl],
        s.accel[sl],
        s.gyro[sl],
        s.temperature[sl],
        s.status[sl],
        {k: v[sl] for k, v in s.extras.items()},
    )


def concat_samples(parts: list[Samples]) -> Samples:
    """Concatenate samples in order (counts summed)."""
    parts = [p for p in parts if len(p) or p.gaps or p.resets or p.duplicates]
    if not parts:
        return _empty()
    if len(parts) == 1:
        return parts[0]
    keys = set.intersection(*(set(p.extras) for p in parts)) if all(len(p) for p in parts) else set()
    return Samples(
        np.concatenate([p.index for p in parts]),
        np.concatenate([p.counter for p in parts]),
        np.concatenate([p.time for p in parts]),
        np.concatenate([p.accel for p in parts]),
        np.concatenate([p.gyro for p in parts]),
        np.concatenate([p.temperature for p in parts]),
        np.concatenate([p.status for p in parts]),
        {k: np.concatenate([p.extras[k] for p in parts]) for k in keys},
        sum(p.gaps for p in parts),
        sum(p.resets for p in parts),
        sum(p.duplicates for p in parts),
    )


class SerialInertialUnit:
    """Binary-frame inertial unit on a serial-like port.

    Parameters
    ----------
    port : pyserial-like object
        Already open; needs ``read(n)``, ``write(b)`` and a writable ``timeout`` attribute.
    frame : FrameFormat or CountScale
        The unit's compiled frame format; a :class:`~drivers.imu_unit.counts.CountScale` means the project's
        own frame ``tablebench-v1`` with that count scale.
    sample_rate : float
        Nominal sample rate, Hz.
    timeout : float
        Longest wait for data before :class:`LinkError`, s.
    polled : bool
        Use burst requests (see module docstring).
    burst_idle_s : float
        Polled mode: idle time after data that ends an incomplete burst, s.
    name : str
        For messages.
    raw_sink : binary file or None
        Every byte read is written here (the raw stream kept beside the recording).
    raw_name : str
        How the events name the raw file.
    start_index : int or None
        Sample index of the first frame (None: from its counter).
    clock : callable
        Host clock (s): each block carries the time its last chunk of bytes arrived (``ImuBlock.host_time``).
    """

    def __init__(
        self,
        port: Any,
        frame: FrameFormat | CountScale,
        sample_rate: float,
        timeout: float = 2.0,
        *,
        polled: bool = False,
        burst_idle_s: float = 0.2,
        name: str = "inertial unit",
        raw_sink: BinaryIO | None = None,
        raw_name: str = "",
        start_index: int | None = None,
        clock: Any = time.monotonic,
    ) -> None:
        if sample_rate <= 0:
            raise ValueError(f"{name}: sample_rate must be > 0 Hz, got {sample_rate}")
        if timeout <= 0:
            raise ValueError(f"{name}: timeout must be > 0 s, got {timeout}")
        self.port = port
        self.format = frame if isinstance(frame, FrameFormat) else count_format(frame, sample_rate)
        if abs(self.format.sample_rate - sample_rate) > 1e-9 * sample_rate:
            raise ValueError(
                f"{name}: the frame format was compiled for {self.format.sample_rate} Hz, not {sample_rate}"
            )
        self._rate = float(sample_rate)
        self.timeout = float(timeout)
        self.polled = bool(polled)
        self.burst_idle_s = float(burst_idle_s)
        self.name = name
        self.decoder = FrameDecoder(self.format.desc)
        self.converter = SampleConverter(self.format, start_index)
        self.raw_sink = raw_sink
        self.raw_name = raw_name
        self._pending: Samples = _empty()
        self._clock = clock
        self._rx_time = math.nan
        self.rejected_total = 0
        self.dropped_total = 0
        self.resets_total = 0
        self.duplicates_total = 0
        self.invalid_total = 0
        self.bit_total = 0
        self.bit_frames: list[tuple[str, bytes]] = []
        """The latest built-in-test frames received (layout name, bytes), at most :data:`MAX_BIT_KEPT`."""
        self._announced = False
        self._closed = False
        try:
            self.port.timeout = min(0.02, self.timeout)
        except (AttributeError, ValueError):  # pragma: no cover - a port without a settable timeout
            pass

    @property
    def sample_rate(self) -> float:
        """Nominal sample rate, Hz."""
        return self._rate

    def _io(self, fn: Any, *args: Any) -> Any:
        try:
            return fn(*args)
        except Exception as exc:  # serial.SerialException, OSError, socket errors
            raise LinkError(f"{self.name}: serial link failed ({exc.__class__.__name__}: {exc})") from exc

    def _take(self, s: Samples, n: int) -> Samples:
        if len(s) <= n:
            self._pending = _empty()
            return s
        self._pending = _slice(s, n)
        head = _slice(s, 0, n)
        head.gaps, head.resets, head.duplicates = s.gaps, s.resets, s.duplicates
        return head

    def read(self, n: int) -> ImuBlock:
        """Return the next ``n`` samples (fewer only if frames were lost); SI, body frame.

        Raises
        ------
        LinkError
            No data for ``timeout`` s, or the connection was lost.
        ValueError
            ``n`` < 1.
        """
        if self._closed:
            raise LinkError(f"{self.name}: driver is closed")
        n = int(n)
        if n < 1:
            raise ValueError(f"{self.name}: read(n) needs n >= 1, got {n}")
        got: list[Samples] = [self._pending] if len(self._pending) else []
        have = len(self._pending)
        self._pending = _empty()
        stats = DecodeStats()
        L = self.format.length
        if have < n:
            want = n - have
            # The burst's last index is estimated from its first received frame: if that frame was lost the
            # estimate is too high and the idle rule ends the burst (slow but safe); it is never too low, so a
            # burst is never cut short while its frames are still arriving.
            expected_last: int | None = None
            received_any = False
            if self.polled:
                reqs = [min(MAX_BURST, want - k) for k in range(0, want, MAX_BURST)]
                self._io(self.port.write, "".join(f"BURST {r}\r\n" for r in reqs).encode("ascii"))
            deadline = time.monotonic() + self.timeout
            frame_deadline = deadline  # bytes that never form a valid frame must not keep the read alive
            garbage_seen = 0
            idle_since: float | None = None
            while have < n:
                chunk = self._io(self.port.read, max(L, (n - have) * L - self.decoder.pending_bytes))
                now = time.monotonic()
                if chunk:
                    self._rx_time = float(self._clock())
                    if self.raw_sink is not None:
                        self.raw_sink.write(chunk)
                    received_any = True
                    deadline = now + self.timeout
                    idle_since = None
                    batch, st = self.decoder.feed(chunk)
                    stats.add(st)
                    for bname, bb in batch.bit.items():
                        self.bit_frames.extend((bname, r.tobytes()) for r in bb.rows)  # rare: a loop is fine
                    del self.bit_frames[:-MAX_BIT_KEPT]
                    garbage_seen += st.garbage_bytes
                    if not len(batch) and now >= frame_deadline:
                        raise LinkError(
                            f"{self.name}: {garbage_seen} byte(s) received in {self.timeout:.3g} s but no valid "
                            f"{self.format.name} frame; check the frame format and options, the baud rate and "
                            "the unit's output configuration (tablebench decode on a capture shows what arrives)"
                        )
                    if len(batch):
                        frame_deadline = now + self.timeout
                        s = self.converter.convert(batch)
                        got.append(s)
                        have += len(s)
                        if len(s) and expected_last is None and self.polled:
                            expected_last = int(s.index[0]) + want - 1
                        if self.polled and len(s) and expected_last is not None and int(s.index[-1]) >= expected_last:
                            break  # the burst's last frame arrived: anything missing was lost
                    continue
                if now >= deadline:
                    raise LinkError(
                        f"{self.name}: no data for {self.timeout:.3g} s ({have} of {n} frames received); "
                        "check the cable/port, the unit's power, the frame format "
                        f"({self.format.name}) and (polled mode) that it answers BURST requests"
                    )
                if self.polled and received_any:
                    idle_since = idle_since or now
                    if now - idle_since >= self.burst_idle_s:
                        break  # the end of the burst was lost
        s = self._take(concat_samples(got), n)
        return self._block(s, stats)

    def _block(self, s: Samples, stats: DecodeStats) -> ImuBlock:
        invalid = int(np.count_nonzero(s.status & ~self.converter.absent_flags))  # a channel never sent is no fault
        self.rejected_total += stats.rejected
        self.dropped_total += s.gaps
        self.resets_total += s.resets
        self.duplicates_total += s.duplicates
        self.invalid_total += invalid
        self.bit_total += stats.bit_frames
        block = ImuBlock(
            counter=(s.index % (1 << 32)).astype(np.uint32),
            time=s.time,
            accel=s.accel,
            gyro=s.gyro,
            temperature=s.temperature,
            status=s.status,
            dropped=s.gaps,
            rejected=stats.rejected,
            resets=s.resets,
            duplicates=s.duplicates,
            host_time=self._rx_time,
        )
        if not self._announced:
            self._announced = True
            block.events.append(f"{self.name}: {self.format.describe()}")
            if self.raw_sink is not None:
                block.events.append(
                    f"{self.name}: raw serial stream kept in {self.raw_name or 'the raw file'}; re-decode with "
                    f"'tablebench decode --frame {self.format.name} …'"
                )
        parts = []
        if s.gaps:
            parts.append(f"{s.gaps} frame(s) missing (counter gaps)")
        if s.resets:
            parts.append(f"{s.resets} counter reset(s) (unit restart?)")
        if s.duplicates:
            parts.append(f"{s.duplicates} duplicate frame(s) dropped")
        if stats.rejected:
            parts.append(f"{stats.rejected} frame(s) rejected (bad checksum)")
        if stats.garbage_bytes:
            parts.append(f"{stats.garbage_bytes} byte(s) skipped while resynchronising")
        if stats.bit_frames:
            parts.append(f"{stats.bit_frames} built-in-test frame(s) received (kept in bit_frames)")
        if invalid:
            parts.append(f"{invalid} sample(s) flagged invalid by the unit's status")
        if parts:
            msg = f"{self.name}: " + ", ".join(parts)
            block.events.append(msg)
            log.warning(msg)
        return block

    def close(self) -> None:
        """Release the driver (the port and the raw sink are the caller's to close)."""
        self._closed = True
        if self.raw_sink is not None:
            try:
                self.raw_sink.flush()
            except (OSError, ValueError):  # pragma: no cover - already closed
                pass
