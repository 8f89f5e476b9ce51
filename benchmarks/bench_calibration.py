"""Benchmark: calibration accuracy on the simulated bench (issue 3).

A Monte Carlo of the ten-step-fast-spin procedure (errors vs truth against the plan's σ, NEES), and the
24-position static baseline side by side with the ten-step sequences (accuracy per parameter vs truth,
and run duration). Section "calibration" of benchmarks/RESULTS.md.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from analysis.identification.model import PARAM_KINDS, PARAM_NAMES
from analysis.units import DISPLAY_UNITS
from benches.identify import identify_run, plan_for
from benches.session import prepare
from benchmarks._results import write_section
from benchmarks.simruns import bench_at_rate, timed_run


def _errors(result: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = np.array([result["parameters"][n]["value"] for n in PARAM_NAMES])
    s = np.array([result["parameters"][n]["sigma"] for n in PARAM_NAMES])
    t = np.array([result["truth"]["values"][n] for n in PARAM_NAMES])
    return x - t, s, np.array([result["parameters"][n]["identifiable"] for n in PARAM_NAMES])


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (``--quick``: 100 Hz and 4 seeds; default 1 kHz and 10 seeds)."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=None)
    args = ap.parse_args(argv)
    rate = 100.0 if args.quick else 1000.0
    seeds = args.seeds or (4 if args.quick else 10)
    bench = bench_at_rate(Path(tempfile.mkdtemp(prefix="tb-cal-")), rate)
    prep = prepare(bench, "ten-step-fast-spin")
    plan = plan_for(prep.compiled, prep.config)
    errs, nees = [], []
    for k in range(seeds):
        folder, _w, _b = timed_run(bench, "ten-step-fast-spin", seed=1000 + k)
        r = identify_run(folder)
        e, _s, _i = _errors(r)
        errs.append(e)
        nees.append(r["truth"]["nees"])
        print(f"seed {k}: NEES {nees[-1]:.1f}")
    errs_a = np.array(errs)
    rms = np.sqrt((errs_a**2).mean(0))
    ratio = rms / plan.sigma_total
    lines = [
        f"Monte Carlo: {seeds} runs of ten-step-fast-spin at {rate:.0f} Hz on the default simulated bench "
        f"(white noise 15 µg/√Hz, flicker bias instability 3 µg, table and unit imperfections).",
        "",
        f"- mean NEES {np.mean(nees):.1f} for 18 states (χ²(18) mean 18; runs: {', '.join(f'{v:.0f}' for v in nees)})",
        f"- achieved RMS error / plan-predicted σ: median {np.median(ratio):.2f}, max {ratio.max():.2f} "
        f"({PARAM_NAMES[int(ratio.argmax())]}) (target ≤ 1.2; with {seeds} runs the RMS itself scatters by "
        f"±{100 / np.sqrt(2 * seeds):.0f} %)",
        "",
    ]
    # side by side: 24-position baseline vs the ten-step sequences, one seed each
    table: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, float]] = {}
    for proc, method in (("twenty-four-position", "batch"), ("ten-step", "kalman"), ("ten-step-fast-spin", "kalman")):
        folder, _w, bench_s = timed_run(bench, proc, seed=77)
        r = identify_run(folder, method=method)
        e, s, ident = _errors(r)
        table[proc] = (e, s, ident, bench_s)
    head = "| parameter | unit | " + " | ".join(f"{p}: error (1σ)" for p in table) + " |"
    lines += [head, "|---|---|" + "---:|" * len(table)]
    for k, name in enumerate(PARAM_NAMES):
        unit, one = DISPLAY_UNITS[PARAM_KINDS[k]]
        cells = []
        for e, s, ident, _b in table.values():
            cells.append(f"{e[k] / one:+.3g} ({s[k] / one:.2g})" + ("" if ident[k] else " n.i."))
        lines.append(f"| {name} | {unit} | " + " | ".join(cells) + " |")
    lines.append("| run duration | min | " + " | ".join(f"{v[3] / 60:.1f}" for v in table.values()) + " |")
    lines += [
        "",
        "n.i. = not identified (prior-dominated): the 24 static positions have rank 15 (no rotation), "
        "and 1.6 °/s spins cannot separate the size effect from bias drift.",
    ]
    body = "\n".join(lines)
    write_section("calibration", "Calibration accuracy on the simulated bench (issue 3)", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
