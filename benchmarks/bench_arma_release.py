"""Benchmark: the ARMA(1,1) exact-ML stage of :mod:`benchmarks.bench_release` alone, more rounds (issue 32).

``python -m benchmarks.bench_arma_release [--base COMMIT | --base-tree DIR] [--rounds N]``

The same measurement as bench_release's ARMA stage (its ``ARMA`` snippet: n = 5000, mean fixed, 15 fits after a
warm-up, median; one BLAS thread; each tree in its own process on the same interpreter), without the ~15-minute
run stages, so that enough rounds fit in a few minutes for a stable ratio on a shared machine. Rounds alternate
the order of the two trees; the figure is the median of the per-round CPU ratios now / base.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
from pathlib import Path

from benchmarks._results import write_section
from benchmarks.bench_release import ARMA, DEFAULT_BASE, ROOT, env_for, tree_for


def arma_once(tree: Path) -> tuple[float, float]:
    """(wall, CPU) seconds of one fit, medians over the snippet's 15 fits, in a fresh process on ``tree``."""
    out = subprocess.run([sys.executable, "-c", ARMA], cwd=tree, env=env_for(tree), capture_output=True, text=True,
                         check=True).stdout.split()  # fmt: skip
    return float(out[0]), float(out[1])


def main(argv: list[str] | None = None) -> int:
    """Alternate the two trees ``--rounds`` times and write the "release-arma" section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", default=DEFAULT_BASE, help=f"the earlier commit (default {DEFAULT_BASE})")
    ap.add_argument("--base-tree", default=None, help="an existing checkout of the earlier commit to use instead")
    ap.add_argument("--rounds", type=int, default=9)
    args = ap.parse_args(argv)
    trees = {"base": Path(args.base_tree) if args.base_tree else tree_for(args.base), "now": ROOT}
    res: dict[str, list[tuple[float, float]]] = {"base": [], "now": []}
    for r in range(args.rounds):
        for key in ("base", "now") if r % 2 == 0 else ("now", "base"):
            res[key].append(arma_once(trees[key]))
        print(f"round {r + 1}: base {res['base'][-1][1] * 1e3:.2f} ms, now {res['now'][-1][1] * 1e3:.2f} ms CPU",
              flush=True)  # fmt: skip
    ratio = [n[1] / b[1] for b, n in zip(res["base"], res["now"], strict=True)]
    wall = [n[0] / b[0] for b, n in zip(res["base"], res["now"], strict=True)]
    med = {k: [statistics.median(v[i] for v in res[k]) for i in (0, 1)] for k in res}
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True).stdout.strip()  # fmt: skip
    changed = ["git", "diff", "--quiet", "HEAD", "--", ".", ":!benchmarks/RESULTS.md"]
    tree = " + working tree" if subprocess.run(changed, cwd=ROOT).returncode else ""
    body = (
        f"This code (`{head}`{tree}) against the earlier release `{args.base}`: bench_release's ARMA stage alone "
        f"(ARMA(1,1) exact ML, n = 5000, mean fixed; 15 fits per process, median; one BLAS thread), "
        f"{args.rounds} rounds alternating the two trees.\n\n"
        "| | base | now | **now / base** (median of per-round ratios; min–max) |\n|---|---:|---:|---:|\n"
        f"| CPU per fit | {med['base'][1] * 1e3:.2f} ms | {med['now'][1] * 1e3:.2f} ms | "
        f"**{statistics.median(ratio):.2f}** ({min(ratio):.2f}–{max(ratio):.2f}) |\n"
        f"| wall per fit | {med['base'][0] * 1e3:.2f} ms | {med['now'][0] * 1e3:.2f} ms | "
        f"**{statistics.median(wall):.2f}** ({min(wall):.2f}–{max(wall):.2f}) |\n\nTarget (issue 32): ≤ 1.0×.\n"
    )
    write_section("release-arma", f"ARMA fit against the earlier release {args.base} (issue 32)", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
