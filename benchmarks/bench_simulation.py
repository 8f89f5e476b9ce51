"""Simulation speed: a 40-minute calibration-like run at 1 kHz through ``SimInertialUnit``, as multiples of
real time (the reference: bench time of the generated data). Also reported against a machine-speed reference
measured in the same run: drawing the same number of 6-channel Gaussian samples with numpy.

Run: ``python -m benchmarks.bench_simulation`` (``--quick``: 4 minutes of bench time).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

from analysis.units import DEG
from benches.bench_config import load_bench
from benchmarks._results import write_section
from drivers.protocols import TableStatus
from drivers.sim.inprocess import SimInertialUnit, SimTurntable
from drivers.sim.world import SimulatedWorld

BENCH = Path(__file__).resolve().parents[1] / "benches" / "sim.yaml"


def _script(total_s: float) -> list[tuple[str, object, float]]:
    """Segments of a calibration-like run: (kind, argument, hold seconds), about half static, half spinning."""
    seq: list[tuple[str, object, float]] = []
    poses = [(0, 0, 0), (0, 0, math.pi / 2), (0, math.pi / 2, 0), (math.pi / 2, 0, math.pi), (0, -math.pi / 2, 0)]
    i = 0
    while sum(s[2] for s in seq) < total_s:
        seq.append(("move", poses[i % len(poses)], 60.0))
        seq.append(("spin", (i % 3, (30.0 + 20 * (i % 4)) * DEG), 60.0))
        seq.append(("stop", None, 5.0))
        i += 1
    return seq


def run(total_s: float, block_s: float = 0.2) -> dict[str, float]:
    """Generate ``total_s`` of bench time; return timing figures."""
    bench = load_bench(BENCH)
    world = SimulatedWorld.from_bench(bench)
    table, unit = SimTurntable(world), SimInertialUnit(world)
    n_block = int(round(block_s * unit.sample_rate))
    samples = 0
    spin_samples = 0
    t0 = time.perf_counter()
    c0 = time.process_time()
    for kind, arg, hold in _script(total_s):
        if kind == "move":
            table.move_to(list(arg))  # type: ignore[arg-type]
        elif kind == "spin":
            table.stop()
            axis, rate = arg  # type: ignore[misc]
            table.spin(axis, rate)
        else:
            table.stop()
        for _ in range(int(round(hold / block_s))):
            blk = unit.read(n_block)
            st = table.read_state()
            table.heartbeat()
            samples += len(blk)
            if st.status & TableStatus.AT_RATE:
                spin_samples += len(blk)
        if samples >= total_s * unit.sample_rate:
            break
    elapsed = time.perf_counter() - t0
    cpu = time.process_time() - c0
    bench_s = world.time
    # machine reference: the same number of 6-channel normal draws
    rng = np.random.default_rng(0)
    t1 = time.perf_counter()
    for _ in range(max(1, samples // 200_000)):
        rng.standard_normal((200_000, 6))
    ref = time.perf_counter() - t1
    return {
        "bench_s": bench_s,
        "samples": float(samples),
        "spin_fraction": spin_samples / max(samples, 1),
        "elapsed_s": elapsed,
        "x_real_time": bench_s / elapsed,
        "x_real_time_cpu": bench_s / cpu,
        "us_per_sample": elapsed / samples * 1e6,
        "x_randn_reference": elapsed / ref,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="4 minutes of bench time instead of 40")
    args = ap.parse_args()
    total = 240.0 if args.quick else 2400.0
    rows = []
    for block_s in (0.2, 1.0):
        r = run(total, block_s)
        rows.append(
            f"| {block_s:g} s | {r['bench_s'] / 60:.1f} min | {r['samples']:.0f} | {100 * r['spin_fraction']:.0f} % | "
            f"{r['elapsed_s']:.2f} s | **{r['x_real_time']:.0f}×** | {r['x_real_time_cpu']:.0f}× | "
            f"{r['us_per_sample']:.2f} | "
            f"{r['x_randn_reference']:.1f}× |"
        )
    body = (
        "Bench `benches/sim.yaml` (1 kHz, anti-alias filter, bias instability as 9 Gauss–Markov processes per "
        "channel, time-stamp jitter), a calibration-like script (holds at 5 attitudes, spins at 30–90 °/s on "
        "each axis, stops), read through `SimInertialUnit` with a table reading and a heartbeat per block, like "
        "the runner (its default block is 0.2 s). Reference: real time of the bench data; second reference: "
        "numpy drawing the same number of N(0,1) 6-vectors in the same run.\n\n"
        "| block | bench time | samples | spinning | wall time | × real time (wall) | × real time (CPU) | µs / sample "
        "| cost vs randn(n, 6) |\n"
        "|---|---|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n\n"
        "Target: ≥ 200× real time (a 40-minute calibration generated in a few seconds). Machine load average "
        f"(1 min) at the end of the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; the randn column "
        "compares against work measured under the same conditions."
    )
    print(body)
    write_section("simulation", "Simulation speed (simulated world + in-process unit)", body)


if __name__ == "__main__":
    main()
