"""Thermal calibration on the simulated bench: the 5-plateau Monte Carlo (coefficient recovery against
U(k = 2), BIC order selection, residual after compensation) and the simulation speed as a multiple of real
time (bench time of the run / wall time of the same run).

Run: ``python -m benchmarks.bench_thermal`` (``--seeds N``, default 20).
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from benches.thermal.montecarlo import PLATEAUS_C, SOAK, run_montecarlo
from benchmarks._results import write_section


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args()
    mc = run_montecarlo(range(args.seeds), progress=lambda m: print(m, flush=True))
    rows = []
    for by_triad in (False, True):
        for cls, (out, hit, res, n) in sorted(mc.fractions(by_triad).items()):
            rows.append(f"| {cls} | {n} | {100 * out:.1f} % | {100 * hit:.1f} % | {100 * res:.1f} % |")
    speed = np.array(mc.speed)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    temps = ", ".join(f"{t:g}" for t in PLATEAUS_C)
    body = f"""5 plateaus ({temps} °C) in the simulated chamber, each soaked (unit within
{SOAK.tolerance:g} K, < {SOAK.rate_limit * 60:g} K/min for {SOAK.dwell:g} s), then the ten-step groups (24 holds of
30 s, a revolution each way at 30 °/s about three body axes) at 50 Hz; per-plateau identification of 18 accelerometer +
12 gyro parameters with covariance; the thermal model fitted with BIC orders (0–3). {len(mc.seeds)} seeds.
"outside U" counts the coefficients (fitted at the simulated orders) whose |error| exceeds 2u; "BIC" is the share
of parameters whose chosen order equals the simulated one; "residual" the share of 17 temperatures across the
range where the compensated truth differs from the model by more than its U(k = 2).

| parameter class | coefficients | outside U(k=2) | BIC order = simulated | residual outside U |
|---|---|---|---|---|
{chr(10).join(rows)}

Speed: bench time / wall time of each run: median **{np.median(speed):.0f}x**, minimum {speed.min():.0f}x real time;
bench time / the process's CPU time: median {np.median(mc.cpu_speed):.0f}x (bench time
{np.mean(mc.bench_seconds) / 3600:.2f} h per run; machine load average {load:.1f} on 2 shared cores, so the wall-clock
ratio is what this shared machine gave, the CPU ratio what the simulation costs)."""
    write_section("thermal", "Thermal calibration (issue 29)", body)
    print(body)


if __name__ == "__main__":
    main()
