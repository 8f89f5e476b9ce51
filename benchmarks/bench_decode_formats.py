"""Benchmark: ``tablebench decode`` on captures of each further unit format, as multiples of real time.

For VectorNav, Xsens MTi, Epson M-G370, Honeywell HG4930 and the ADIS16475 bridge format (and KVH 1750 format
A as the reference decoded in the same run) a capture file of ``seconds`` of data is written once at the unit's
rate (1 kHz; the HG4930 at its real stream: 100 Hz inertial messages, each after five 20-byte control messages,
all checked), with light damage (1 % of frames preceded by garbage, 0.1 % with a flipped bit, so the
resynchronisation path runs too). Then the capture is decoded exactly as ``tablebench decode`` does it
(:func:`benches.cli.commands.decode.decode_file`: the file read in chunks, frames found and checked, converted to
SI samples with counter checks), best of 3. The figure is seconds of data per second of decoding (× real time)
by the wall clock and by the CPU time of the process (the machine is shared: the wall clock includes waiting for
a core), and the CPU ratio against KVH format A in the same run. Full size: 60 s per format; ``--quick``: 10 s.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from analysis.units import CELSIUS_ZERO, DEG, G0
from benches.cli.commands.decode import decode_file
from benchmarks._results import write_section
from drivers.imu_unit.decoder import FrameCodec
from drivers.imu_unit.description import compile_format, load_frame
from drivers.imu_unit.samples import encode_samples

FORMATS = [
    ("kvh-1750-a", 1000.0),
    ("vectornav-vn100-imu", 1000.0),
    ("xsens-mti-mtdata2", 1000.0),
    ("epson-g370-burst", 1000.0),
    ("honeywell-hg4930", 100.0),
    ("adis16475-usb-iss", 1000.0),
]


def capture(name: str, rate: float, seconds: float, seed: int = 0) -> tuple[object, bytes, int]:
    """(format, capture bytes, data frames expected to decode) for ``seconds`` at ``rate`` with light damage."""
    fmt = compile_format(load_frame(name), None, rate)
    n = int(seconds * rate)
    rng = np.random.default_rng(seed)
    idx = np.arange(n, dtype=np.int64)
    rows = encode_samples(
        fmt,
        idx,
        idx / rate,
        rng.uniform(-2 * G0, 2 * G0, (n, 3)),
        rng.uniform(-100 * DEG, 100 * DEG, (n, 3)),
        np.full(n, CELSIUS_ZERO + 25.0),
        codec=FrameCodec(fmt.desc),
    )
    flip = rng.random(n) < 0.001
    rows[np.flatnonzero(flip), len(fmt.desc.sync) + 3] ^= np.uint8(0x10)  # a byte every checksum covers
    garbage = rng.random(n) < 0.01
    forbidden = {fmt.desc.sync[0], 0x0D} | {d.sync[0] for _r, d in fmt.desc.alternates}
    allowed = np.array([b for b in range(256) if b not in forbidden], np.uint8)
    others = [(r, d) for r, d in fmt.desc.alternates if r == "other"]
    before = b""
    if others:  # the HG4930's control messages: five before each inertial message
        d = others[0][1]
        c = FrameCodec(d)
        ctl = c.encode({f.name: np.zeros(5 * n, np.int64) for f in d.fields}, 5 * n).reshape(n, 5 * d.length)
    parts = []
    for i in range(n):
        if garbage[i]:
            parts.append(rng.choice(allowed, int(rng.integers(1, 40))).tobytes())
        if others:
            parts.append(ctl[i].tobytes())
        parts.append(rows[i].tobytes() + fmt.desc.trailer)
    return fmt, before + b"".join(parts), int(n - flip.sum())


def timed(path: Path, fmt, expected: int, repeat: int = 3) -> tuple[float, float]:
    """Fastest of ``repeat`` decodes of ``path`` the way ``tablebench decode`` does it: (wall s, CPU s)."""
    walls, cpus = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        samples, stats = decode_file(path, fmt)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        assert len(samples) == expected and stats.frames == expected, (fmt.name, len(samples), expected)
    return min(walls), min(cpus)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="10 s of data per format instead of 60 s")
    args = ap.parse_args(argv)
    seconds = 10.0 if args.quick else 60.0
    load0 = os.getloadavg()[0]
    res: dict[str, tuple[int, float, float, float]] = {}
    with tempfile.TemporaryDirectory(prefix="tb-bench-decode-") as tmp:
        for name, rate in FORMATS:
            fmt, data, expected = capture(name, rate, seconds)
            path = Path(tmp) / f"{name}.bin"
            path.write_bytes(data)
            wall, cpu = timed(path, fmt, expected)
            res[name] = (len(data), rate, seconds / wall, seconds / cpu)
            print(
                f"{name:22s} {len(data) / seconds / 1e3:7.1f} kB/s of data: {seconds / wall:8,.0f}× wall, "
                f"{seconds / cpu:8,.0f}× CPU"
            )
    load1 = os.getloadavg()[0]
    ref_cpu = res["kvh-1750-a"][3]
    rows = [
        f"| `{n}` | {r:g} Hz | {b / seconds / 1e3:,.1f} | **{w:,.0f}×** | **{c:,.0f}×** | {c / ref_cpu:.2f} |"
        for n, (b, r, w, c) in res.items()
    ]
    new = {n: v for n, v in res.items() if n != "kvh-1750-a"}
    body = [
        f"`tablebench decode`'s path (`decode_file`: the capture read in chunks, frames found, checksums checked, SI "
        f"samples with counter checks) on {seconds:.0f}-s captures written at the unit's rate (1 % of frames "
        "preceded by garbage, 0.1 % with a flipped bit; the HG4930 capture is its real stream, five 20-byte control "
        "messages before each 100 Hz inertial message, all checked). × real time = seconds of data per second of "
        "decoding, best of 3, by the wall clock and by the process's CPU time; KVH 1750 format A decoded in the same "
        "run is the reference. Target ≥ 1000×.",
        "",
        "| format | rate | kB/s of data | wall | CPU | CPU vs `kvh-1750-a` |",
        "|---|---|---|---|---|---|",
        *rows,
        "",
        f"Slowest new format: {min(v[2] for v in new.values()):,.0f}× by the wall clock, "
        f"{min(v[3] for v in new.values()):,.0f}× by CPU time. Load average {load0:.1f} → {load1:.1f} on "
        f"{os.cpu_count()} cores during this run (the machine is shared: with a load above the core count the wall "
        "clock includes time spent waiting for a core, and the CPU column is the decoder's own speed).",
    ]
    write_section("decode-new-formats", "`tablebench decode` on the further unit formats (issue 28)", "\n".join(body))


if __name__ == "__main__":
    main()
