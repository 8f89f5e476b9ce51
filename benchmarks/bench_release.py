"""Benchmark: this code against an earlier release, stage by stage, alternating, in one run (issue 32).

``python -m benchmarks.bench_release [--base COMMIT] [--rounds N] [--procedure P]``

The earlier release is checked out as a git worktree (``benchmarks/out/release-<commit>``, detached) and run with
the same Python environment: each stage is a separate process whose ``PYTHONPATH`` is the tree being measured
(the check at the start prints which tree each side really imported). Rounds alternate the order of the two
trees, so the drift of a shared machine's speed (±25 % over minutes here) hits both alike; the figures are
medians over rounds, and the ratio now / base is what RESULTS.md reports next to the absolute times.

Stages (each tree on its own recording of the same procedure and seed):
- ``--help``: ``tablebench --help`` (and ``python -c pass`` as the floor);
- the whole in-process ``tablebench run`` and its parts, timed from the lines it prints: start-up to the first
  step, the motion phase (simulation + recording + streaming identifier), identification, certificate;
- offline ``identify RUN`` and ``certificate RUN`` on the recording;
- an ARMA(1,1) exact-ML fit, n = 5000, mean fixed (one BLAS thread on both sides);
- the recording's size.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks._results import write_section

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_BASE = "bef15fd"
"""The release before the regressions issue 32 measured (the previous release's code)."""

CLI = "import sys; from benches.cli import main; sys.exit(main(sys.argv[1:]))"
ARMA = """
import inspect, time, numpy as np
try:
    from analysis.drift.arma import fit_arma
except ImportError:
    from analysis.drift_arma import fit_arma
rng = np.random.default_rng(5)
e = rng.normal(size=5100)
x = np.empty_like(e); x[0] = e[0]
for k in range(1, e.size):
    x[k] = 0.6 * x[k - 1] + e[k] + 0.3 * e[k - 1]
x = x[100:]
kw = {"include_mean": False} if "include_mean" in inspect.signature(fit_arma).parameters else {}
fit_arma(x, 1, 1, **kw)
ts = []
for _ in range(15):
    t0 = time.perf_counter(); fit_arma(x, 1, 1, **kw); ts.append(time.perf_counter() - t0)
print(sorted(ts)[len(ts) // 2])
"""


def tree_for(commit: str) -> Path:
    """A detached worktree of ``commit`` under benchmarks/out (made once, reused)."""
    sha = subprocess.run(["git", "rev-parse", "--short", commit], cwd=ROOT, capture_output=True, text=True,
                         check=True).stdout.strip()  # fmt: skip
    path = ROOT / "benchmarks" / "out" / f"release-{sha}"
    if not (path / "benches").is_dir():
        path.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run(["git", "worktree", "add", "--detach", "--force", str(path), sha], cwd=ROOT, check=True,
                       capture_output=True)  # fmt: skip
    return path


def env_for(tree: Path) -> dict[str, str]:
    """The environment of a stage process measuring ``tree`` (same interpreter and packages, its code first)."""
    env = dict(os.environ)
    env.update(PYTHONPATH=str(tree), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
               MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")  # fmt: skip
    return env


def check_tree(tree: Path) -> None:
    """Refuse to measure if the stage process would import the code of another tree."""
    out = subprocess.run([sys.executable, "-c", "import benches; print(benches.__file__)"], cwd=tree,
                         env=env_for(tree), capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    if not Path(out).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"bench_release: {tree} imports benches from {out}; cannot compare")
    print(f"  {tree}: imports {out}", flush=True)


def timed(cmd: list[str], tree: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, cwd=tree, env=env_for(tree), capture_output=True, check=True)
    return time.perf_counter() - t0


def timed_run(tree: Path, procedure: str, folder: Path, seed: int) -> dict[str, float]:
    """The whole ``tablebench run`` and its parts, from the times its lines arrive."""
    cmd = [sys.executable, "-c", CLI, "run", "--procedure", procedure, "--out", str(folder), "--plain",
           "--seed", str(seed)]  # fmt: skip
    t0 = time.perf_counter()
    marks: dict[str, float] = {}
    proc = subprocess.Popen(cmd, cwd=tree, env=env_for(tree), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, bufsize=1)  # fmt: skip
    assert proc.stdout is not None
    for line in proc.stdout:
        now = time.perf_counter() - t0
        for key, prefix in (("first_step", "step "), ("motion_end", "run complete"), ("calibration", "calibration:"),
                            ("certificate", "certificate:")):  # fmt: skip
            if line.startswith(prefix) and key not in marks:
                marks[key] = now
    if proc.wait() != 0:
        raise RuntimeError(f"run failed in {tree}")
    total = time.perf_counter() - t0
    return {
        "run (whole, in-process)": total,
        "— start-up to the first step": marks["first_step"],
        "— motion phase": marks["motion_end"] - marks["first_step"],
        "— identification after the run": marks["calibration"] - marks["motion_end"],
        "— certificate": marks["certificate"] - marks["calibration"],
    }


def one_round(tree: Path, procedure: str, seed: int) -> dict[str, float]:
    """Every stage once for ``tree``."""
    work = Path(tempfile.mkdtemp(prefix="tb-release-"))
    run = work / "run"
    out = {"python -c pass (floor)": timed([sys.executable, "-c", "pass"], tree)}
    out["tablebench --help"] = timed([sys.executable, "-c", CLI, "--help"], tree)
    out.update(timed_run(tree, procedure, run, seed))
    out["identify RUN (offline)"] = timed([sys.executable, "-c", CLI, "identify", str(run), "--out",
                                           str(work / "cal.json")], tree)  # fmt: skip
    out["certificate RUN (offline)"] = timed([sys.executable, "-c", CLI, "certificate", str(run), "--out",
                                              str(work / "cert.pdf")], tree)  # fmt: skip
    arma = subprocess.run([sys.executable, "-c", ARMA], cwd=tree, env=env_for(tree), capture_output=True, text=True,
                          check=True)  # fmt: skip
    out["ARMA(1,1) exact ML, n = 5000, mean fixed"] = float(arma.stdout.strip())
    out["recording size (MB)"] = (run / "recording.h5").stat().st_size / 1e6
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the comparison and write the "release" section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", default=DEFAULT_BASE, help=f"the earlier commit (default {DEFAULT_BASE})")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--procedure", default="ten-step-fast-spin")
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args(argv)
    base = tree_for(args.base)
    trees = {"base": base, "now": ROOT}
    for tree in trees.values():
        check_tree(tree)
    results: dict[str, list[dict[str, float]]] = {k: [] for k in trees}
    for r in range(args.rounds):
        order = ("base", "now") if r % 2 == 0 else ("now", "base")
        for key in order:
            results[key].append(one_round(trees[key], args.procedure, args.seed))
            print(f"round {r + 1} {key}: " + ", ".join(f"{k} {v:.3g}" for k, v in results[key][-1].items()), flush=True)
    stages = list(results["now"][0])
    med = {k: {s: statistics.median(r[s] for r in results[k]) for s in stages} for k in trees}
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout
    body = (
        f"This code (`{head.strip()}` + working tree) against the earlier release `{args.base}`, same Python "
        f"environment, each stage a separate process importing its own tree; `{args.procedure}` on the default "
        f"simulated bench, seed {args.seed}; medians of {args.rounds} rounds, the two trees alternated round by "
        "round; one BLAS thread on both sides.\n\n"
        "| stage | base | now | now / base |\n|---|---:|---:|---:|\n"
    )
    for s in stages:
        unit = "" if "MB" in s else " s"
        ratio = med["now"][s] / med["base"][s]
        body += f"| {s} | {med['base'][s]:.3g}{unit} | {med['now'][s]:.3g}{unit} | **{ratio:.2f}** |\n"
    floor = med["now"]["python -c pass (floor)"]
    body += (
        f"\n`tablebench --help` now = {med['now']['tablebench --help'] / floor:.1f}× `python -c pass` "
        "(target ≤ 8×). Targets (issue 32): whole run ≤ 0.9×, identification ≤ 1.0×, certificate ≤ 1.0× and ≤ 1 s, "
        "`--help` ≤ 1.0×, ARMA fit ≤ 1.0×, recording size unchanged.\n"
    )
    write_section("release", f"Against the earlier release {args.base}, stage by stage (issue 32)", body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
