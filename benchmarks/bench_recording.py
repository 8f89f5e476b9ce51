"""Recording size and run speed: the checksummed, compressed recording (quantised counts + shuffle + gzip-1)
against the uncompressed float64 storage of format 1 ("today's", 70 B/sample), measured in the same run on
the same simulated runs (same seed, same samples).

Reported: MB per hour of bench time at 1 kHz (file size on disk / bench hours), bytes per sample, and run
speed (bench time / wall time of the whole run: simulation + runner + recorder). Alternatives measured
alongside: float64 + gzip-1 and counts + lzf. Each configuration runs ``--repeat`` times, alternating; the
fastest wall time counts (a shared 2-core machine). Section "recording" of benchmarks/RESULTS.md.

Run: ``python -m benchmarks.bench_recording`` (``--quick``: shorter runs).
"""

from __future__ import annotations

import argparse
import io
import tempfile
import time
from pathlib import Path

from benches.recording import open_recording
from benches.session import execute, prepare
from benchmarks._results import write_section
from benchmarks.simruns import bench_at_rate

STORAGES = ("plain", "counts+gzip", "float+gzip", "counts+lzf")
LABELS = {
    "plain": "format 1 storage: float64, uncompressed (today's)",
    "counts+gzip": "counts + shuffle + gzip-1 (the default)",
    "float+gzip": "float64 + shuffle + gzip-1",
    "counts+lzf": "counts + shuffle + lzf",
}


def _one(
    bench: Path, procedure: str, overrides: dict[str, float], storage: str
) -> tuple[float, float, float, float, int, int]:
    prep = prepare(bench, procedure, overrides)
    folder = Path(tempfile.mkdtemp(prefix="tb-rec-")) / "run"
    folder.mkdir(parents=True)
    t0, c0, th0 = time.perf_counter(), time.process_time(), time.thread_time()
    res = execute(prep, folder, seed=4, transport=None, live=False, stream=io.StringIO(), storage=storage)
    wall, cpu, thread = time.perf_counter() - t0, time.process_time() - c0, time.thread_time() - th0
    if res.status != "complete":
        raise RuntimeError(res.reason)
    path = folder / "recording.h5"
    t1 = time.perf_counter()
    with open_recording(path) as rec:  # verified read of everything
        n = rec.n_samples
    read = time.perf_counter() - t1
    b = res.bench_seconds
    return b / wall, b / cpu, b / thread, read, path.stat().st_size, n


def _load() -> str:
    try:
        import os

        return "load average " + ", ".join(f"{x:.1f}" for x in os.getloadavg()) + f" on {os.cpu_count()} CPUs"
    except OSError:
        return "unknown"


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and write its RESULTS.md section."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="tb-recb-"))
    bench = bench_at_rate(tmp, 1000.0)
    cases = [
        ("static-noise", {"duration_s": 300.0 if args.quick else 1800.0, "warmup_s": 60.0}),
        ("ten-step-fast-spin", {}),
    ]
    if args.quick:
        cases = cases[:1]
    lines = [
        "| procedure (1 kHz) | storage | MB per hour of bench time | B/sample | size vs today | run speed, wall "
        "(× real time) | wall speed vs today | bench s per CPU s | CPU speed vs today | runner-thread CPU speed "
        "vs today | verified read, s |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    ratios: dict[tuple[str, str], tuple[float, float, float, float]] = {}
    for procedure, overrides in cases:
        best: dict[str, list[float]] = {}
        for _ in range(args.repeat):
            for storage in STORAGES:
                speed, cpu_speed, th_speed, read, size, n = _one(bench, procedure, overrides, storage)
                old = best.get(storage)
                best[storage] = [
                    max(speed, old[0]) if old else speed,
                    max(cpu_speed, old[1]) if old else cpu_speed,
                    max(th_speed, old[2]) if old else th_speed,
                    min(read, old[3]) if old else read,
                    size,
                    n,
                ]
                print(procedure, storage, f"{speed:.1f}x wall", f"{cpu_speed:.1f}x cpu", f"{th_speed:.1f}x thread",
                      f"{size / n:.2f} B/sample", f"read {read:.2f} s", flush=True)  # fmt: skip
        ref_speed, ref_cpu, ref_th, _, ref_size, _ = best["plain"]
        for storage in STORAGES:
            sp, cp, th, _, size, _ = best[storage]
            ratios[(procedure, storage)] = (size / ref_size, sp / ref_speed, cp / ref_cpu, th / ref_th)
        for storage in STORAGES:
            speed, cpu_speed, th_speed, read, size, n = best[storage]
            mb_h = size / 1e6 / (n / 1000.0 / 3600.0)
            lines.append(
                f"| {procedure} ({n / 1000 / 60:.0f} min) | {LABELS[storage]} | {mb_h:.1f} | {size / n:.1f} | "
                f"{size / ref_size:.3f} | {speed:.0f} | {speed / ref_speed:.2f} | {cpu_speed:.0f} | "
                f"{cpu_speed / ref_cpu:.2f} | {th_speed / ref_th:.2f} | {read:.2f} |"
            )
    d = [ratios[k] for k in ratios if k[1] == "counts+gzip"]
    size_r = max(x[0] for x in d)
    size_ok = "met" if size_r <= 1 / 3 else "NOT met"
    lines.append("")
    lines.append(
        f"Default storage against today's: size ≤ {size_r:.3f} (target ≤ 1/3: {size_ok}); "
        f"wall speed ≥ {min(x[1] for x in d):.2f} (target ≥ 1: "
        f"{'met' if min(x[1] for x in d) >= 1 else 'NOT met on this machine'}); runner-thread CPU speed ≥ "
        f"{min(x[3] for x in d):.2f}, all-threads CPU speed ≥ {min(x[2] for x in d):.2f}."
    )
    body = "\n".join(lines) + (
        "\n\nEvery storage carries Fletcher-32 on every chunk and a SHA-256 per step; 'size vs today' and "
        "'speed vs today' are ratios to the format-1 storage measured in the same run (target: size ≤ 1/3, "
        "speed not lower). Run speed is the whole simulated run (world + runner + recorder), best of "
        f"{args.repeat}: wall (bench s per wall s; the default storage encodes its chunks in a worker thread, so "
        "on a free second core compression overlaps the run) and CPU (bench s per CPU s of all threads: the work "
        "compression adds), and the runner thread's own CPU time (what the run waits for when a core is free: "
        "the default storage leaves hashing, quantising and compression to its encoder thread). "
        "'verified read' opens the recording and checks every checksum. Machine load during the run: " + _load() + "."
    )
    write_section("recording", "Recording size and speed (issue 12)", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
