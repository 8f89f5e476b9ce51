"""Inertial-unit driver for the binary serial frame stream (:mod:`drivers.imu_frame`).

:class:`SerialInertialUnit` implements :class:`drivers.protocols.InertialUnit` over any pyserial-like port
(``serial.Serial`` for a real RS-232/RS-422/USB line, ``serial.serial_for_url("socket://127.0.0.1:PORT")``
for the simulated unit on loopback). The driver never opens or closes the port; it sets the port's read
``timeout`` to a short poll interval.

Two modes:

free-running (``polled=False``)
    The unit streams frames at its sample rate; ``read(n)`` returns the next n decoded frames, keeping any
    surplus for the next call.
polled burst (``polled=True``)
    ``read(n)`` sends ``BURST n`` (ASCII, CR-LF) and the unit answers with exactly the frames of the next n
    samples. The simulated unit produces frames only when asked, so the simulated clock advances exactly with
    what the host consumed (bit-identical runs over the wire and in process).

A read is bounded in time: if no byte arrives for ``timeout`` seconds, or the connection is lost, a
:class:`~drivers.protocols.LinkError` is raised. In polled mode a burst is complete when the frame with the
expected last counter arrives, or when the line has been idle for ``burst_idle_s`` after data (the tail of
the burst was lost: the missing frames show up as dropped). Rejected (bad CRC) and dropped (counter gap)
frames are counted per block (``ImuBlock.rejected`` / ``dropped``), in totals, and logged.
"""

from __future__ import annotations

import logging
import time
from typing import Any

from drivers.imu_counts import CountScale, RawFrames, concat_frames, counter_gaps, empty_frames, frames_to_block
from drivers.imu_frame import FRAME_SIZE, DecodeStats, FrameDecoder, slice_frames
from drivers.protocols import ImuBlock, LinkError

log = logging.getLogger(__name__)

MAX_BURST = 1_000_000
"""Largest frame count one ``BURST`` request may ask for (longer reads send several requests)."""


class SerialInertialUnit:
    """Binary-frame inertial unit on a serial-like port.

    Parameters
    ----------
    port : pyserial-like object
        Already open; needs ``read(n)``, ``write(b)`` and a writable ``timeout`` attribute.
    scale : CountScale
        SI value of one count (body frame channels).
    sample_rate : float
        Nominal sample rate, Hz.
    timeout : float
        Longest wait for data before :class:`LinkError`, s.
    polled : bool
        Use burst requests (see module docstring).
    burst_idle_s : float
        Polled mode: idle time after data that ends an incomplete burst, s. Long enough that a loaded host
        never cuts a healthy burst short (which would shift block boundaries), short enough that a lost tail
        costs little.
    name : str
        For messages.
    """

    def __init__(
        self,
        port: Any,
        scale: CountScale,
        sample_rate: float,
        timeout: float = 2.0,
        *,
        polled: bool = False,
        burst_idle_s: float = 0.2,
        name: str = "inertial unit",
    ) -> None:
        if sample_rate <= 0:
            raise ValueError(f"{name}: sample_rate must be > 0 Hz, got {sample_rate}")
        if timeout <= 0:
            raise ValueError(f"{name}: timeout must be > 0 s, got {timeout}")
        self.port = port
        self.scale = scale
        self._rate = float(sample_rate)
        self.timeout = float(timeout)
        self.polled = bool(polled)
        self.burst_idle_s = float(burst_idle_s)
        self.name = name
        self.decoder = FrameDecoder()
        self._pending: RawFrames = empty_frames()
        self._last_counter: int | None = None
        self.rejected_total = 0
        self.dropped_total = 0
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

    def _take(self, frames: RawFrames, n: int) -> RawFrames:
        if len(frames) <= n:
            self._pending = empty_frames()
            return frames
        self._pending = slice_frames(frames, n)
        return slice_frames(frames, 0, n)

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
        got: list[RawFrames] = [self._pending] if len(self._pending) else []
        have = len(self._pending)
        self._pending = empty_frames()
        stats = DecodeStats()
        if have < n:
            want = n - have
            # The burst's last counter is estimated from its first received frame: if that frame was lost the
            # estimate is too high and the idle rule ends the burst (slow but safe); it is never too low, so a
            # burst is never cut short while its frames are still arriving.
            expected_last: int | None = None
            received_any = False
            if self.polled:
                reqs = [min(MAX_BURST, want - k) for k in range(0, want, MAX_BURST)]
                self._io(self.port.write, "".join(f"BURST {r}\r\n" for r in reqs).encode("ascii"))
            deadline = time.monotonic() + self.timeout
            idle_since: float | None = None
            while have < n:
                chunk = self._io(self.port.read, max(FRAME_SIZE, (n - have) * FRAME_SIZE - self.decoder.pending_bytes))
                now = time.monotonic()
                if chunk:
                    received_any = True
                    deadline = now + self.timeout
                    idle_since = None
                    frames, st = self.decoder.feed(chunk)
                    stats.rejected += st.rejected
                    stats.garbage_bytes += st.garbage_bytes
                    if len(frames):
                        got.append(frames)
                        have += len(frames)
                        if expected_last is None and self.polled:
                            expected_last = (int(frames.counter[0]) + want - 1) % (1 << 32)
                        if self.polled and int(frames.counter[-1]) == expected_last:
                            break  # the burst's last frame arrived: anything missing was lost
                    continue
                if now >= deadline:
                    raise LinkError(
                        f"{self.name}: no data for {self.timeout:.3g} s ({have} of {n} frames received); "
                        "check the cable/port, the unit's power and (polled mode) that it answers BURST requests"
                    )
                if self.polled and received_any:
                    idle_since = idle_since or now
                    if now - idle_since >= self.burst_idle_s:
                        break  # the end of the burst was lost
        frames = self._take(concat_frames(got), n)
        dropped = counter_gaps(self._last_counter, frames.counter)
        if len(frames):
            self._last_counter = int(frames.counter[-1])
        self.rejected_total += stats.rejected
        self.dropped_total += dropped
        block = frames_to_block(frames, self.scale, dropped=dropped, rejected=stats.rejected)
        if dropped or stats.rejected or stats.garbage_bytes:
            msg = (
                f"{self.name}: {dropped} frame(s) dropped, {stats.rejected} rejected (bad CRC), "
                f"{stats.garbage_bytes} byte(s) skipped"
            )
            block.events.append(msg)
            log.warning(msg)
        return block

    def close(self) -> None:
        """Release the driver (the port is the caller's to close)."""
        self._closed = True
