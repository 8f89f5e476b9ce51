"""Benchmark: decoding every shipped frame format, as multiples of real time at 1 kHz.

For each description in ``drivers/frames/`` a stream of ``seconds`` × 1000 frames is encoded once (SI
samples in range; 1 % of frames preceded by garbage and 0.1 % with a flipped bit, so the resynchronisation
path runs too), then decoded the way the serial driver does it: fed in chunks of 0.2 s of data (the
runner's block) and of 1 s, checksums verified, fields extracted and converted to SI samples with counter checks
(:class:`drivers.imu_frame.FrameDecoder` + :class:`drivers.imu_frame_samples.SampleConverter`). The figure
is bench seconds decoded per wall second (× real time), the reference being real time itself; the decoded
count is checked against the frames sent. Also: one 60-s feed (a capture file decoded by ``tablebench
decode``). Full size: 60 s per format; ``--quick``: 10 s.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from analysis.units import CELSIUS_ZERO, DEG, G0
from benchmarks._results import write_section
from drivers.imu_frame import FrameCodec, FrameDecoder
from drivers.imu_frame_desc import compile_format, load_frame, shipped_frames
from drivers.imu_frame_samples import SampleConverter, encode_samples

RATE = 1000.0


def stream(name: str, seconds: float, seed: int = 0) -> tuple[object, bytes, int]:
    """(format, bytes, frames expected to decode) for ``seconds`` at 1 kHz with light corruption."""
    fmt = compile_format(load_frame(name), None, RATE)
    n = int(seconds * RATE)
    rng = np.random.default_rng(seed)
    idx = np.arange(n, dtype=np.int64)
    rows = encode_samples(
        fmt,
        idx,
        idx / RATE,
        rng.uniform(-2 * G0, 2 * G0, (n, 3)),
        rng.uniform(-100 * DEG, 100 * DEG, (n, 3)),
        np.full(n, CELSIUS_ZERO + 25.0),
        codec=FrameCodec(fmt.desc),
    )
    flip = rng.random(n) < 0.001
    r = np.flatnonzero(flip)
    rows[r, len(fmt.desc.sync) + 1] ^= np.uint8(0x10)
    garbage = rng.random(n) < 0.01
    parts = []
    start = 0
    allowed = np.array([b for b in range(256) if b not in (fmt.desc.sync[0], 0x0D)], np.uint8)
    for i in np.flatnonzero(garbage).tolist():
        parts.append(rows[start:i].tobytes())
        parts.append(rng.choice(allowed, int(rng.integers(1, 40))).tobytes())
        start = i
    parts.append(rows[start:].tobytes())
    return fmt, b"".join(parts), int(n - flip.sum())


def decode_speed(fmt, data: bytes, expected: int, chunk: int) -> float:
    """Wall seconds to decode ``data`` in feeds of ``chunk`` bytes (decoder + SI conversion)."""
    dec = FrameDecoder(fmt.desc)
    conv = SampleConverter(fmt)
    got = 0
    t0 = time.perf_counter()
    for i in range(0, len(data), chunk):
        batch, _ = dec.feed(data[i : i + chunk])
        if len(batch):
            got += len(conv.convert(batch))
    dt = time.perf_counter() - t0
    assert got == expected, (fmt.name, got, expected)
    return dt


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="10 s of data per format instead of 60 s")
    args = ap.parse_args(argv)
    seconds = 10.0 if args.quick else 60.0
    rows = []
    worst = worst_s = np.inf
    for name in shipped_frames():
        fmt, data, expected = stream(name, seconds)
        t_block = min(decode_speed(fmt, data, expected, int(0.2 * RATE * fmt.length)) for _ in range(3))
        t_second = min(decode_speed(fmt, data, expected, int(RATE * fmt.length)) for _ in range(3))
        t_whole = min(decode_speed(fmt, data, expected, len(data)) for _ in range(3))
        rt_block, rt_second, rt_whole = seconds / t_block, seconds / t_second, seconds / t_whole
        worst = min(worst, rt_block)
        worst_s = min(worst_s, rt_second)
        rows.append(
            f"| `{name}` | {fmt.length} | {len(data) / t_second / 1e6:.1f} | {rt_block:,.0f}× | {rt_second:,.0f}× "
            f"| {rt_whole:,.0f}× |"
        )
        print(
            f"{name:16s} {fmt.length:3d} B  0.2 s feeds {rt_block:6.0f}×, 1 s feeds {rt_second:6.0f}×, "
            f"one feed {rt_whole:6.0f}×"
        )
    body = [
        f"{seconds:.0f} s of 1 kHz frames per format (1 % preceded by garbage, 0.1 % with a flipped bit), decoded to "
        "SI samples with checksum and counter checks; × real time = bench seconds per wall second (target ≥ 1000×).",
        "",
        "| format | bytes | MB/s (1 s feeds) | × real time, 0.2 s feeds | 1 s feeds | one feed |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        f"Slowest format: {worst:,.0f}× real time with 0.2 s feeds (the runner's block: fixed per-call costs "
        f"dominate), {worst_s:,.0f}× with 1 s feeds. Measured on a shared 2-core machine under load "
        f"(load average {os.getloadavg()[0]:.1f} at the end of this run): the figures move with the load.",
    ]
    write_section("frames", "Frame decoding (every shipped format, 1 kHz)", "\n".join(body))


if __name__ == "__main__":
    main()
