"""Raw inertial-unit output (integer counts, as on the wire) and its conversion to SI.

The simulated unit produces :class:`RawFrames`; the serial frame codec encodes and decodes exactly these;
the in-process simulated unit and the serial driver both convert them to an SI
:class:`~drivers.protocols.ImuBlock` with :func:`frames_to_block` and the unit's :class:`CountScale`, so
both paths give identical samples.
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


def counter_gaps(previous: int | None, counter: NDArray[np.uint32]) -> int:
    """Frames missing according to the counter (mod 2³²), including the gap after ``previous``."""
    if counter.size == 0:
        return 0
    c = counter.astype(np.int64)
    steps = np.diff(c) % (1 << 32)
    missing = int(np.sum(steps[steps > 0] - 1))
    if previous is not None:
        first = (int(c[0]) - int(previous)) % (1 << 32)
        missing += max(first - 1, 0)
    return missing
