"""Thermal calibration on the simulated bench, THROUGH THE RUNNER: per seed ``tablebench run`` of the thermal
procedure (5 plateaus, the ten-step sequence at each) on benches/sim-thermal-white.yaml, then its thermal
identification; the Monte Carlo (coefficient recovery against U(k = 2), BIC order selection, residual after
compensation) and the simulation speed as a multiple of real time (bench time of the run / wall time of the
same run, and / its process CPU time).

Run: ``python -m benchmarks.bench_thermal`` (``--seeds N``, default 20).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import os

import numpy as np

from benches.thermal.montecarlo import BENCH, MC_SOAK, PLATEAUS_C, MonteCarlo, run_montecarlo
from benchmarks._results import write_section


def _one_seed(seed: int, workdir: str | None) -> MonteCarlo:
    return run_montecarlo([seed], progress=lambda m: print(m, flush=True), workdir=workdir)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--workdir", default=None, help="where the run folders go while a seed runs")
    ap.add_argument("--jobs", type=int, default=1, help="seeds run in this many processes at once")
    args = ap.parse_args()
    mc = MonteCarlo()
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        for part in pool.map(_one_seed, range(args.seeds), [args.workdir] * args.seeds):
            mc.merge(part)
    comp = sorted(mc.compensated_outside().items())
    comp_rows = "\n".join(f"| {c} | {n} | {100 * f:.1f} % |" for c, (f, n) in comp)
    rows = []
    for by_triad in (False, True):
        for cls, (out, hit, res, n) in sorted(mc.fractions(by_triad).items()):
            rows.append(f"| {cls} | {n} | {100 * out:.1f} % | {100 * hit:.1f} % | {100 * res:.1f} % |")
    speed = np.array(mc.speed)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    temps = ", ".join(f"{t:g}" for t in PLATEAUS_C)
    body = f"""Through the runner: `tablebench run` of procedures/thermal-plateaus.yaml (soak tightened to
`{MC_SOAK}`) on `{BENCH.name}` (chamber served on loopback in the Espec dialect, recording written), then
`benches.thermal.identify.identify_thermal` of the recording. 5 plateaus ({temps} °C), the ten-step groups
(24 holds of 30 s, a revolution each way at 30 °/s about three body axes) at 100 Hz at each; per-plateau
identification of 18 accelerometer + 12 gyro parameters with covariance; the thermal model fitted with BIC
orders (0–3). {len(mc.seeds)} seeds.
"outside U" counts the coefficients (fitted at the simulated orders) whose |error| exceeds 2u; "BIC" is the share
of parameters whose chosen order equals the simulated one; "residual" the share of 17 temperatures across the
range where the compensated truth differs from the model by more than its U(k = 2).

| parameter class | coefficients | outside U(k=2) | BIC order = simulated | residual outside U |
|---|---|---|---|---|
{chr(10).join(rows)}

After compensation (`tablebench correct`'s `thermal_correct` applied to the simulated unit's exact outputs at
each temperature of the certificate's model table: both ends of the validity range and every 10 °C): share
of checks where the residual bias or scale factor exceeds the U(k = 2) the certificate states there (a 95 %
interval: about 5 % expected).

| residual | checks | beyond the stated U |
|---|---|---|
{comp_rows}

Speed of `tablebench run` (the runner, recording included; identification not counted): bench time / wall time
of each run: median **{np.median(speed):.0f}x**, minimum {speed.min():.0f}x real time; bench time / the process's
CPU time: median **{np.median(mc.cpu_speed):.0f}x**, minimum {np.min(mc.cpu_speed):.0f}x (bench time
{np.mean(mc.bench_seconds) / 3600:.2f} h per run; machine load average {load:.1f} on 2 shared cores, so the wall-clock
ratio is what this shared machine gave, the CPU ratio what the simulation costs)."""
    write_section("thermal", "Thermal calibration (issue 29)", body)
    print(body)


if __name__ == "__main__":
    main()
