"""Raw inertial-unit output of the simulated unit (integer counts) and its conversion to SI; counter checks.

The simulated unit produces :class:`RawFrames` (counts in the bench's :class:`CountScale`); the in-process
driver converts them to an SI :class:`~drivers.protocols.ImuBlock` with :func:`frames_to_block`, and the
simulated serial unit puts them on the wire in the project's frame ``tablebench-v1`` unchanged (so both paths
give identical samples) or re-quantised to another described format (:mod:`drivers.sim.serial_unit`).

:class:`CounterTracker` judges a wrapping frame counter: gaps, resets and duplicates counted separately.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from analysis.units import CELSIUS_ZERO
from drivers.protocols import ImuBlock


@dataclass(frozen=True)
class CountScale:
    """SI value of one output count (the unit's datasheet scale), body frame channels.

    Attributes
    ----------
    accel_lsb : float
        m/s² per accelerometer count.
    gyro_lsb : float
        rad/s per gyro count.
    temperature_lsb : float
        K per temperature count (the temperature word is °C × 1/temperature_lsb, signed 16-bit).
    """

    accel_lsb: float
    gyro_lsb: float
    temperature_lsb: float = 0.01


@dataclass
class RawFrames:
    """A run of frames as the unit emits them.

    Attributes
    ----------
    counter : (n,) uint32 frame counter.
    timestamp_ns : (n,) uint64 unit clock time stamp, ns.
    counts : (n, 6) int32 [ax, ay, az, gx, gy, gz] in counts, body frame.
    temperature : (n,) int16 temperature word (°C / temperature_lsb).
    status : (n,) uint16 unit status word.
    """

    counter: NDArray[np.uint32]
    timestamp_ns: NDArray[np.uint64]
    counts: NDArray[np.int32]
    temperature: NDArray[np.int16]
    status: NDArray[np.uint16]

    def __len__(self) -> int:
        return int(self.counter.shape[0])


def empty_frames() -> RawFrames:
    """A RawFrames with no frames."""
    return RawFrames(
        counter=np.zeros(0, np.uint32),
        timestamp_ns=np.zeros(0, np.uint64),
        counts=np.zeros((0, 6), np.int32),
        temperature=np.zeros(0, np.int16),
        status=np.zeros(0, np.uint16),
    )


def concat_frames(parts: list[RawFrames]) -> RawFrames:
    """Concatenate RawFrames in order."""
    parts = [p for p in parts if len(p)]
    if not parts:
        return empty_frames()
    if len(parts) == 1:
        return parts[0]
    return RawFrames(
        counter=np.concatenate([p.counter for p in parts]),
        timestamp_ns=np.concatenate([p.timestamp_ns for p in parts]),
        counts=np.concatenate([p.counts for p in parts]),
        temperature=np.concatenate([p.temperature for p in parts]),
        status=np.concatenate([p.status for p in parts]),
    )


def frames_to_block(frames: RawFrames, scale: CountScale, dropped: int = 0, rejected: int = 0) -> ImuBlock:
    """Convert raw frames to an SI :class:`ImuBlock` (body frame; m/s², rad/s, K)."""
    c = frames.counts.astype(np.float64)
    return ImuBlock(
        counter=frames.counter.astype(np.uint32, copy=False),
        time=frames.timestamp_ns.astype(np.float64) * 1e-9,
        accel=c[:, 0:3] * scale.accel_lsb,
        gyro=c[:, 3:6] * scale.gyro_lsb,
        temperature=frames.temperature.astype(np.float64) * scale.temperature_lsb + CELSIUS_ZERO,
        status=frames.status.astype(np.uint16, copy=False),
        dropped=dropped,
        rejected=rejected,
    )


@dataclass
class CounterCheck:
    """What :meth:`CounterTracker.update` found in one run of frames.

    Attributes
    ----------
    keep : (n,) bool — False for duplicates (a frame repeating the previous counter), which are dropped.
    index : (n,) int64 — sample index of each frame, unwrapped from the counter: a gap advances it by the
        missing frames; a reset (the counter jumping back, or an advance that is not a whole number of steps)
        advances it by one (the unit restarted: the time lost is unknown).
    gaps : int — frames missing (sum over forward jumps of jump/step − 1).
    resets : int — backward jumps / irregular steps.
    duplicates : int — frames repeating the previous counter.
    """

    keep: NDArray[np.bool_]
    index: NDArray[np.int64]
    gaps: int = 0
    resets: int = 0
    duplicates: int = 0


class CounterTracker:
    """Judge a wrapping frame counter across feeds: gaps, resets and duplicates counted separately.

    A counter advancing by ``d`` (mod ``modulus``) from the previous frame is: a duplicate if d = 0; a
    forward step of d/step samples (d/step − 1 missing) if 0 < d ≤ modulus/2 and d is a multiple of
    ``step``; otherwise a reset (the counter jumped back — a unit restart — or moved irregularly). With a
    128-value counter (KVH) a gap of more than 63 frames is indistinguishable from a reset; with a 32-bit one
    a restart at 0 is a reset, never 4.29e9 missing frames.

    Parameters
    ----------
    modulus : int
        Counter period (2³² for a uint32 counter, 128 for KVH, 256 for STIM300); 0: no counter.
    step : int
        Counter advance per sample (STIM300: 2000 Hz / sample rate).
    start_index : int or None
        Sample index of the first frame (None: counter // step).
    """

    def __init__(self, modulus: int, step: int = 1, start_index: int | None = None) -> None:
        self.modulus = int(modulus)
        self.step = int(step)
        self.start_index = start_index
        self.last_raw: int | None = None
        self.last_index: int | None = None
        self.gaps = 0
        self.resets = 0
        self.duplicates = 0

    def update_uncounted(self, n: int) -> CounterCheck:
        """A frame format without a counter: consecutive indices, nothing detectable."""
        first = (self.last_index + 1) if self.last_index is not None else int(self.start_index or 0)
        idx = np.arange(first, first + n, dtype=np.int64)
        if n:
            self.last_index = int(idx[-1])
        return CounterCheck(np.ones(n, dtype=bool), idx)

    def update(self, counter: NDArray[np.integer]) -> CounterCheck:
        """Classify the steps of ``counter`` (raw, in stream order), continuing from the previous call."""
        c = np.asarray(counter, dtype=np.int64)
        n = c.size
        if n == 0:
            return CounterCheck(np.zeros(0, bool), np.zeros(0, np.int64))
        m, step = self.modulus, self.step
        if self.last_raw is None:
            first = self.start_index if self.start_index is not None else int(c[0]) // step
            prev = np.concatenate([[c[0]], c[:-1]])
            base = int(first)
        else:
            prev = np.concatenate([[self.last_raw], c[:-1]])
            base = int(self.last_index)  # type: ignore[arg-type]
        d = (c - prev) % m
        dup = d == 0
        fwd = (d > 0) & (d <= m // 2) & (d % step == 0)
        reset = ~dup & ~fwd
        if self.last_raw is None:
            dup[0], fwd[0], reset[0] = False, False, False
        inc = np.where(fwd, d // step, np.where(reset, 1, 0))
        index = base + np.cumsum(inc)
        gaps = int(np.sum(d[fwd] // step - 1))
        resets = int(reset.sum())
        dups = int(dup.sum())
        self.last_raw = int(c[-1])
        self.last_index = int(index[-1])
        self.gaps += gaps
        self.resets += resets
        self.duplicates += dups
        return CounterCheck(~dup, index, gaps, resets, dups)


def counter_gaps(previous: int | None, counter: NDArray[np.uint32]) -> int:
    """Frames missing according to a 32-bit counter, including the gap after ``previous`` (resets excluded:
    a counter jumping back is a unit restart, not 4.29e9 missing frames; see :class:`CounterTracker`)."""
    if counter.size == 0:
        return 0
    first = int(counter[0])
    if (previous is None or first == (int(previous) + 1) % (1 << 32)) and int(counter[-1]) - first == counter.size - 1:
        # the usual block: the counter goes on from ``previous`` by +1 at every frame (no wrap): no gap. Steps
        # of +1 modulo the dtype's range (uint32: 2³²) with the ends n − 1 apart are +1 steps without a wrap
        if counter.size == 1 or bool(np.all(counter[1:] - counter[:-1] == 1)):
            return 0
    t = CounterTracker(1 << 32, 1)
    if previous is not None:
        t.last_raw, t.last_index = int(previous), 0
    return t.update(counter).gaps
