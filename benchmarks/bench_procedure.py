"""Benchmark: the full ten-step procedure on the simulated bench, as multiples of real time.

In-process device simulators and the wire-level simulators (real pymodbus + serial bytes on loopback),
plus the cost of the streaming identifier during the run at 2 kHz (target: ≤ 20 % slower).
Section "procedure" of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from benches.identify import identify_run
from benchmarks._results import write_section
from benchmarks.simruns import bench_at_rate, timed_run


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (``--quick``: 200 Hz instead of 1 kHz / 2 kHz)."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="tb-proc-"))
    rate, rate_hi = (200.0, 400.0) if args.quick else (1000.0, 2000.0)
    bench = bench_at_rate(tmp, rate)
    rows = []
    offline = None
    for transport in ("in-process", "loopback"):
        folder, wall, bench_s = timed_run(bench, "ten-step", seed=1, transport=transport)
        rows.append((f"ten-step, {rate:.0f} Hz, {transport}", bench_s, wall, bench_s / wall))
        print(rows[-1])
        if offline is None:
            t0 = time.perf_counter()
            identify_run(folder)
            offline = (bench_s, time.perf_counter() - t0)
    hi = bench_at_rate(tmp, rate_hi)
    _f, wall_off, bench_s = timed_run(hi, "ten-step", seed=2)
    _f, wall_on, _ = timed_run(hi, "ten-step", seed=2, live=True)
    rows.append((f"ten-step, {rate_hi:.0f} Hz, in-process, recording only", bench_s, wall_off, bench_s / wall_off))
    rows.append(
        (f"ten-step, {rate_hi:.0f} Hz, in-process, + streaming identifier", bench_s, wall_on, bench_s / wall_on)
    )
    slowdown = wall_on / wall_off - 1.0
    rows.append(
        (
            f"offline identification of the {rate:.0f} Hz ten-step recording (HDF5 → calibration)",
            offline[0],
            offline[1],
            offline[0] / offline[1],
        )
    )
    body = "| run | bench time | wall time | × real time |\n|---|---:|---:|---:|\n"
    body += "\n".join(f"| {n} | {b / 60:.1f} min | {w:.1f} s | **{r:.0f}×** |" for n, b, w, r in rows)
    body += (
        f"\n\nStreaming identifier (filterpy KF, block information updates) during the {rate_hi:.0f} Hz run: "
        f"**{100 * slowdown:+.0f} %** wall time (target ≤ +20 %). Targets: ≥ 100× in-process, ≥ 50× over the "
        "transports; ≥ 1000× for offline identification. Each run records every sample to HDF5 and reads the "
        "table once per 0.2 s block."
    )
    write_section("procedure", "Full procedure on the simulated bench (issue 8)", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
