"""The simulated inertial unit on a loopback TCP socket, speaking the serial frame format.

A :class:`SerialUnitServer` listens on 127.0.0.1 (ephemeral port by default) in a background thread and
serves one client at a time with the bytes the unit would put on its serial line: the samples of
``world.produce(n)`` encoded by :func:`encode_frames` in any described frame format (the project's
``tablebench-v1`` carries the model's integer counts unchanged; KVH, STIM300 or a user's format re-quantise
the SI samples to that format's fields, increments = rate × sample interval). Connect to it with
``serial.serial_for_url(f"socket://127.0.0.1:{server.port}")``.

Host → unit commands (ASCII lines, CR-LF or LF terminated; the unit never answers in text):

``BURST <n>``
    Polled mode: produce exactly ``n`` samples (advancing the one simulated clock by n sample periods) and
    send their frames. The clock advances only with what the host asked for, so a polled run is
    deterministic whatever the speed of the machine.
``STREAM <factor>``
    Free-running mode: produce frames continuously at ``factor`` × real time (``STREAM 1`` is a real unit
    streaming at its sample rate; ``STREAM 0`` stops). The simulated clock then advances with wall time.

Injected corruption (:class:`Corruption`, seeded) is applied to the outgoing frames for link tests:
garbage bytes inserted before a frame, a flipped bit in a frame, or a frame omitted.
"""

from __future__ import annotations

import logging
import select
import socket
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from drivers.imu_unit.counts import CountScale, RawFrames, frames_to_block
from drivers.imu_unit.decoder import FrameCodec
from drivers.imu_unit.description import DEFAULT_FRAME, FrameFormat, load_frame
from drivers.imu_unit.samples import encode_samples
from drivers.imu_unit.serial_unit import MAX_BURST, count_format
from drivers.sim.tcp_server import SingleClientServer

if TYPE_CHECKING:
    from drivers.sim.world import SimulatedWorld

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Corruption:
    """Seeded link corruption applied per outgoing frame (probabilities in [0, 1]).

    Attributes
    ----------
    garbage : float
        Probability of inserting 1–``garbage_max`` random bytes before a frame.
    flip : float
        Probability of flipping one random bit of a frame (after the sync bytes: the CRC catches it).
    drop : float
        Probability of omitting a frame.
    garbage_max : int
    seed : int
    """

    garbage: float = 0.0
    flip: float = 0.0
    drop: float = 0.0
    garbage_max: int = 64
    seed: int = 0

    @property
    def active(self) -> bool:
        return self.garbage > 0 or self.flip > 0 or self.drop > 0


def encode_frames(
    frames: RawFrames, fmt: FrameFormat | None = None, scale: CountScale | None = None, codec: FrameCodec | None = None
) -> bytes:
    """Wire bytes of simulated frames in format ``fmt`` (None: ``tablebench-v1``).

    ``tablebench-v1`` carries the counts as they are; any other format gets the SI samples (converted with
    ``scale``, a CountScale) quantised to its own fields, with the frame counter ``index × step mod modulus``.
    """
    n = len(frames)
    if fmt is None or fmt.desc.name == DEFAULT_FRAME:
        codec = codec or FrameCodec(fmt.desc if fmt is not None else load_frame(DEFAULT_FRAME))
        c = frames.counts
        values = {
            "counter": frames.counter,
            "timestamp": frames.timestamp_ns,
            "accel_x": c[:, 0],
            "accel_y": c[:, 1],
            "accel_z": c[:, 2],
            "gyro_x": c[:, 3],
            "gyro_y": c[:, 4],
            "gyro_z": c[:, 5],
            "temperature": frames.temperature,
            "status": frames.status,
        }
        return codec.encode(values, n).tobytes()
    if scale is None:
        raise ValueError("encoding simulated counts into another format needs the count scale")
    b = frames_to_block(frames, scale)
    rows = encode_samples(fmt, frames.counter.astype(np.int64), b.time, b.accel, b.gyro, b.temperature, codec=codec)
    return rows.tobytes()


class _Corrupter:
    def __init__(self, spec: Corruption) -> None:
        self.spec = spec
        self.rng = np.random.default_rng(spec.seed)
        self.injected = {"garbage": 0, "flip": 0, "drop": 0}
        self.lost_counters: list[int] = []  # counters of frames flipped or omitted (for tests)

    def apply(self, data: bytes, n: int, index: np.ndarray, sync_len: int = 2) -> bytes:
        s = self.spec
        length = len(data) // n
        frames = np.frombuffer(data, dtype=np.uint8).reshape(n, length).copy()
        flip = self.rng.random(n) < s.flip
        if flip.any():
            rows = np.flatnonzero(flip)
            byte = self.rng.integers(sync_len, length, rows.size)
            bit = self.rng.integers(0, 8, rows.size)
            frames[rows, byte] ^= (1 << bit).astype(np.uint8)
        keep = self.rng.random(n) >= s.drop
        garbage_before = self.rng.random(n) < s.garbage
        lost = flip | ~keep
        if lost.any():
            self.lost_counters.extend(np.asarray(index)[lost].tolist())
        self.injected["flip"] += int(flip.sum())
        self.injected["drop"] += int((~keep).sum())
        self.injected["garbage"] += int((garbage_before & keep).sum())
        if not garbage_before.any():
            return frames[keep].tobytes()
        parts: list[bytes] = []
        start = 0
        for i in np.flatnonzero(garbage_before & keep).tolist():  # loop over insertions only
            parts.append(frames[start:i][keep[start:i]].tobytes())
            k = int(self.rng.integers(1, s.garbage_max + 1))
            parts.append(self.rng.integers(0, 256, k, dtype=np.uint8).tobytes())
            start = i
        parts.append(frames[start:][keep[start:]].tobytes())
        return b"".join(parts)


class SerialUnitServer(SingleClientServer):
    """Serve a :class:`~drivers.sim.world.SimulatedWorld`'s unit as a byte stream on 127.0.0.1.

    Parameters
    ----------
    world : SimulatedWorld
        The world whose ``produce`` drives the stream (shared with the table controller).
    port : int
        TCP port (0: ephemeral; read :attr:`port` after construction).
    corruption : Corruption or None
        Injected link faults.
    stream_factor : float
        Free-running speed at connection (0: polled mode until the host sends ``STREAM``).
    chunk_s : float
        In free-running mode, wall-clock period between writes, s.
    frame : FrameFormat or None
        The format the unit speaks (None: ``tablebench-v1`` with the world's count scale).
    """

    def __init__(
        self,
        world: SimulatedWorld,
        port: int = 0,
        *,
        corruption: Corruption | None = None,
        stream_factor: float = 0.0,
        chunk_s: float = 0.01,
        frame: FrameFormat | None = None,
    ) -> None:
        self.world = world
        self.frame = frame if frame is not None else count_format(world.scale, world.sample_rate)
        self._codec = FrameCodec(self.frame.desc)
        self.corruption = corruption if corruption is not None and corruption.active else None
        self._corrupter = _Corrupter(self.corruption) if self.corruption else None
        self.initial_stream_factor = float(stream_factor)
        self.chunk_s = float(chunk_s)
        self.frames_sent = 0
        self._listen(port, "sim-imu-serial")
        self._thread.start()
        log.info("simulated unit serving on 127.0.0.1:%d", self.port)

    @property
    def url(self) -> str:
        """pyserial URL of the server (``socket://127.0.0.1:PORT``)."""
        return f"socket://127.0.0.1:{self.port}"

    @property
    def lost_counters(self) -> list[int]:
        """Counters of the frames the injected corruption destroyed (flipped or omitted)."""
        return list(self._corrupter.lost_counters) if self._corrupter else []

    @property
    def injected(self) -> dict[str, int]:
        """Counts of injected faults so far (garbage insertions, flipped frames, dropped frames)."""
        return dict(self._corrupter.injected) if self._corrupter else {"garbage": 0, "flip": 0, "drop": 0}

    name = "simulated unit"

    def _send(self, conn: socket.socket, n: int) -> None:
        frames = self.world.produce(n)
        data = encode_frames(frames, self.frame, self.world.scale, self._codec)
        if self._corrupter is not None and len(frames):
            data = self._corrupter.apply(data, len(frames), frames.counter, len(self.frame.desc.sync))
        conn.sendall(data)
        self.frames_sent += len(frames)

    def _handle(self, conn: socket.socket) -> None:
        buf = b""
        factor = self.initial_stream_factor
        rate = float(self.world.sample_rate)
        t0 = time.monotonic()
        if factor > 0:
            self.world.anchor_wall_clock(t0, factor)
        streamed = 0
        while not self._stop.is_set():
            r, _, _ = select.select([conn], [], [], self.chunk_s if factor > 0 else 0.05)
            if r:
                chunk = conn.recv(4096)
                if not chunk:
                    return
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    cmd = line.strip().decode("ascii", "replace").split()
                    if not cmd:
                        continue
                    word = cmd[0].upper()
                    try:
                        arg = float(cmd[1]) if len(cmd) > 1 else None
                    except ValueError:
                        arg = None
                    if word == "BURST" and arg is not None and 1 <= arg <= MAX_BURST and arg == int(arg):
                        self._send(conn, int(arg))
                    elif word == "STREAM" and arg is not None and arg >= 0:
                        factor = arg
                        t0, streamed = time.monotonic(), 0
                        self.world.anchor_wall_clock(t0, factor)
                    else:
                        log.warning("simulated unit: ignoring unknown command %r", line[:80])
            if factor > 0:
                due = int((time.monotonic() - t0) * rate * factor) - streamed
                if due > 0:
                    self._send(conn, due)
                    streamed += due
