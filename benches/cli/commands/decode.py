"""``tablebench decode``: decode a raw capture from an inertial unit into samples, with a link summary.

How a technician checks a new unit's link before a run (capture a few seconds of the serial line to a file,
e.g. ``cat /dev/ttyUSB0 > capture.bin`` after setting the baud rate), and how a run's kept raw stream
(``RUN/unit-raw.bin``, bench option ``unit.keep_raw``) is re-decoded after a decoding mistake was found.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from benches.bench_config import load_bench, unit_frame_format
from benches.cli.arguments import bounded
from benches.recording import write_decoded_samples
from core.errors import UsageError
from core.outputs import check_output
from drivers.imu_unit.decoder import DecodeStats, FrameDecoder
from drivers.imu_unit.description import FrameFormat, compile_format, load_frame, shipped_frames
from drivers.imu_unit.samples import SampleConverter, Samples
from drivers.imu_unit.serial_unit import concat_samples

EXAMPLES = """examples:
  tablebench decode --frame kvh-1750-a capture.bin --out samples.csv
  tablebench decode --frame stim300-0x93 --option accel_range_g=30 --rate 500 capture.bin --out s.npy
  tablebench decode --unit-config benches/sim-kvh.yaml runs/RUN/unit-raw.bin --out samples.npy
  tablebench decode --frame my-unit.yaml capture.bin          # summary only
  tablebench decode --frame auto capture.bin                  # which shipped format is the unit sending?
"""

CHUNK = 1 << 18
"""Bytes decoded per feed (a few thousand frames: cache-friendly, and memory stays flat for long captures)."""


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "decode",
        help="decode a raw unit capture (frames → SI samples) and summarise the link",
        description="Decode a raw byte capture of an inertial unit's serial stream with a frame description "
        "(shipped name or .yaml; see drivers/imu_unit/frames/README.md) into one row per frame: time (s), "
        "sample index, counter as sent, accel x/y/z (m/s²), gyro x/y/z (rad/s), temperature (K), status flags "
        "(bit set = invalid), then the format's other channels (SI) and raw status fields. Prints frames, rejects, "
        "garbage bytes, counter gaps, resets and duplicates.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("capture", metavar="CAPTURE.bin", help="raw bytes as read from the unit")
    p.add_argument(
        "--frame",
        default=None,
        metavar="FORMAT|FILE.yaml",
        help="frame format: a shipped name, a description .yaml, or 'auto' (detect among the shipped ones)",
    )
    p.add_argument(
        "--unit-config",
        default=None,
        metavar="BENCH.yaml",
        help="take the frame format, its options and the sample rate from this bench file's unit section",
    )
    p.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a frame option (the unit's configuration, e.g. gyro_output=rate); repeatable",
    )
    p.add_argument(
        "--rate",
        type=bounded(0.0, 1e6, low_open=True),
        default=None,
        help="sample rate, Hz (default: the bench's, else 1000)",
    )
    p.add_argument("--out", default=None, metavar="OUT.npy|OUT.csv|OUT.h5", help="write the samples here")
    p.set_defaults(func=run)


def _format(args: argparse.Namespace) -> FrameFormat:

    options: dict[str, str] = {}
    frame, rate = args.frame, args.rate
    if args.unit_config is not None:
        bench = load_bench(args.unit_config)
        if frame is None and not args.option and rate is None:
            return unit_frame_format(bench.unit)
        frame = frame or bench.unit.frame
        options.update({k: str(v) for k, v in bench.unit.frame_options.items()})
        rate = rate if rate is not None else bench.unit.sample_rate
        if frame == "tablebench-v1":
            s = bench.unit.scale
            options.update(accel_lsb=str(s.accel_lsb), gyro_lsb=str(s.gyro_lsb), temperature_lsb=str(s.temperature_lsb))
    if frame is None:
        raise UsageError("give --frame FORMAT|FILE.yaml or --unit-config BENCH.yaml")
    for item in args.option:
        name, eq, value = item.partition("=")
        if not eq or not name.strip():
            raise UsageError(f"--option {item!r}: expected NAME=VALUE, e.g. --option gyro_output=rate")
        options[name.strip()] = value.strip()
    rate = 1000.0 if rate is None else rate
    if not np.isfinite(rate) or rate <= 0:
        raise UsageError(f"--rate must be a positive number of Hz, got {rate}")
    if frame == "auto":
        frame = _detect(Path(args.capture))
    desc = load_frame(frame, Path.cwd())
    try:
        return compile_format(desc, options, rate, where="--option")
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def detect_formats(data: bytes) -> list[tuple[int, str]]:
    """(frames with a valid checksum, name) of every shipped format in ``data``, most frames first."""
    found = []
    for name in shipped_frames():
        dec = FrameDecoder(load_frame(name))
        dec.feed(data)
        if dec.total.frames:
            found.append((dec.total.frames, name))
    return sorted(found, reverse=True)


def _detect(path: Path) -> str:
    try:
        with path.open("rb") as fh:
            head = fh.read(1 << 16)
    except OSError as exc:
        raise UsageError(f"{path}: cannot read the capture ({exc.strerror})") from None
    found = detect_formats(head)
    if not found:
        raise UsageError(
            f"{path}: no shipped frame format found in the first {len(head)} bytes; check the baud rate, or give "
            "--frame FILE.yaml for the unit's own format"
        )
    print(
        f"detected {found[0][1]} ({found[0][0]} frames in the first {len(head)} bytes); the output units and "
        "range are the unit's configuration, not in the frame: give them with --option"
    )
    return found[0][1]


def decode_file(path: Path, fmt: FrameFormat) -> tuple[Samples, DecodeStats]:
    """Decode a whole capture file in chunks; returns (samples, decode statistics)."""
    dec = FrameDecoder(fmt.desc)
    conv = SampleConverter(fmt)
    parts = []
    try:
        fh = path.open("rb")
    except OSError as exc:
        raise UsageError(f"{path}: cannot read the capture ({exc.strerror})") from None
    with fh:
        while True:
            chunk = fh.read(CHUNK)
            if not chunk:
                break
            batch, _st = dec.feed(chunk)
            if len(batch):
                parts.append(conv.convert(batch))
    dec.flush()
    stats: DecodeStats = dec.total
    return concat_samples(parts), stats


def columns(samples: Samples) -> tuple[list[str], np.ndarray]:
    """Column names and the (n, k) float64 table of decoded samples."""
    names = ["time", "index", "counter", "accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z"]
    names += ["temperature", "status"]
    cols = [samples.time, samples.index, samples.counter, *samples.accel.T, *samples.gyro.T]
    cols += [samples.temperature, samples.status]
    for k in sorted(samples.extras):
        names.append(k.replace("status:", "raw_status_"))
        cols.append(samples.extras[k])
    table = (
        np.column_stack([np.asarray(c, dtype=np.float64) for c in cols]) if len(samples) else np.zeros((0, len(names)))
    )
    return names, table


def run(args: argparse.Namespace) -> int:
    fmt = _format(args)
    path = Path(args.capture)
    if not path.is_file():
        raise UsageError(f"{path}: no such capture file")
    if args.out is not None and Path(args.out).suffix.lower() not in (".npy", ".csv", ".h5"):
        raise UsageError(f"--out {args.out}: give a .npy, .csv or .h5 file name")
    size = path.stat().st_size
    if size == 0:
        raise UsageError(f"{path}: the capture is empty")
    samples, stats = decode_file(path, fmt)
    n = len(samples)
    t = conv_text(fmt)
    print(f"{path}: {size} bytes, format {t}")
    print(
        f"frames {stats.frames}, rejected (bad checksum) {stats.rejected}, garbage bytes {stats.garbage_bytes}, "
        f"counter gaps {samples.gaps} frame(s), resets {samples.resets}, duplicates {samples.duplicates} (dropped)"
    )
    if stats.bit_frames or any(r == "bit" for r, _f in fmt.alternates):
        print(f"built-in-test frames {stats.bit_frames} (recognised; not samples, not garbage)")
    if stats.other_frames or any(r == "other" for r, _f in fmt.alternates):
        print(f"other messages {stats.other_frames} (checked and skipped; not samples, not garbage)")
    if n == 0:
        raise UsageError(
            f"{path}: no valid {fmt.name} frame in {size} bytes; check --frame, the baud rate and the unit's output "
            "format"
        )
    invalid = int(np.count_nonzero(samples.status))
    span = float(samples.time[-1] - samples.time[0]) if n > 1 else 0.0
    print(f"samples {n} over {span:.3f} s; flagged invalid by the unit's status: {invalid}")
    if args.out is not None:
        names, table = columns(samples)
        out = check_output(args.out)
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            if out.suffix.lower() == ".npy":
                np.save(out, table)
            elif out.suffix.lower() == ".h5":
                summary = {
                    "frame_format": fmt.name,
                    "capture": str(path),
                    "frames": stats.frames,
                    "rejected": stats.rejected,
                    "garbage_bytes": stats.garbage_bytes,
                    "gaps": samples.gaps,
                    "resets": samples.resets,
                    "duplicates": samples.duplicates,
                    "bit_frames": stats.bit_frames,
                    "other_frames": stats.other_frames,
                }
                write_decoded_samples(out, names, table, summary)
            else:
                np.savetxt(out, table, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
        except OSError as exc:
            raise UsageError(f"--out {out}: cannot write ({exc.strerror})") from None
        print(f"wrote {out} ({n} rows; columns: {', '.join(names)})", file=sys.stdout)
    return 0


def conv_text(fmt: FrameFormat) -> str:
    """The format line of the summary."""
    return fmt.describe()
