"""Run every benchmark in turn (each writes its own section of benchmarks/RESULTS.md).

``python -m benchmarks.run_all [--quick]``. Benchmarks run one at a time: they measure ratios against a
reference in the same run, and running them concurrently on a 2-core machine would distort both sides.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

BENCHMARKS = (
    "bench_simulation",
    "bench_transports",
    "bench_frames",
    "bench_decode_formats",
    "bench_procedure",
    "bench_identification",
    "bench_calibration",
    "bench_noise",
    "bench_periodic",
    "bench_drift",
    "bench_recording",
)


def main(argv: list[str] | None = None) -> int:
    """Run all benchmarks; returns non-zero if any failed."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    ap.add_argument("--only", nargs="*", default=None, help="names of benchmarks to run")
    args = ap.parse_args(argv)
    root = Path(__file__).resolve().parent.parent
    failed = []
    for name in args.only or BENCHMARKS:
        cmd = [sys.executable, "-m", f"benchmarks.{name}"] + (["--quick"] if args.quick else [])
        print(f"== {' '.join(cmd[1:])}", flush=True)
        if subprocess.run(cmd, cwd=root).returncode != 0:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
