"""Benchmark: ``benches.identify.identify_run`` of this tree against an earlier commit's, in one process (issue 32).

``python -m benchmarks.bench_identify_run [--base COMMIT] [--run RUN] [--rounds N]``

Both trees are imported whole into one process, each with its own modules (the earlier commit's worktree,
:func:`benchmarks.bench_release.tree_for`; ``sys.modules`` holds one tree's packages at a time and is swapped
before every call, so lazy imports inside a call find their own tree). Each side opens (and verifies) the same
recording once as its own ``RecordedRun``, so the timed call is the identification alone, not the read. The
calibration results (``CalibrationResult.to_dict``, the same recording so no field differs by the clock) must be
identical on both sides for every method timed (checked first; the benchmark refuses to time otherwise); CPU
times are medians over rounds alternating the order, one BLAS thread. ``--run`` takes a finished run folder;
without it a ``ten-step-fast-spin`` run, seed 7, is made once under ``benchmarks/out/identify-run`` (30 windows of
60 000 samples, 33 states).
"""

from __future__ import annotations

import argparse
import hashlib
import importlib
import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType

from benchmarks._same_run import one_blas_thread

one_blas_thread()

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("analysis", "benches", "core", "drivers", "procedures")
CASES = {
    "Kalman (default: accelerometer + gyro, time base estimated)": {},
    "Kalman, accelerometer only": {"with_gyro": False},
    "batch least squares": {"method": "batch"},
}


def _ours() -> dict[str, ModuleType]:
    return {k: v for k, v in sys.modules.items() if k.split(".")[0] in PACKAGES}


def load_tree(tree: Path) -> dict[str, ModuleType]:
    """Import ``benches.identify`` and ``benches.recorded_run`` from ``tree`` alone; its modules (not installed)."""
    for k in list(_ours()):
        del sys.modules[k]
    sys.path.insert(0, str(tree))
    importlib.invalidate_caches()
    try:
        importlib.import_module("benches.identify")
        importlib.import_module("benches.recorded_run")
    finally:
        sys.path.remove(str(tree))
    mods = _ours()
    if not Path(mods["benches.identify"].__file__ or "").resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"bench_identify_run: {tree} did not provide benches.identify; cannot compare")
    return mods


def use(mods: dict[str, ModuleType]) -> ModuleType:
    """Make ``mods`` the process's packages; their ``benches.identify``."""
    for k in list(_ours()):
        del sys.modules[k]
    sys.modules.update(mods)
    return mods["benches.identify"]


def default_run() -> Path:
    folder = ROOT / "benchmarks" / "out" / "identify-run"
    if not (folder / "calibration.json").exists():
        folder.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "benches.cli", "run", "--procedure", "ten-step-fast-spin", "--seed", "7",
                        "--out", str(folder), "--plain", "--registry", "off"], cwd=ROOT, check=True,
                       capture_output=True)  # fmt: skip
    return folder


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="42446eb", help="earlier commit (default: main before this work)")
    ap.add_argument("--run", type=Path, default=None)
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args(argv)
    from benchmarks._results import write_section
    from benchmarks._same_run import alternate, thread_note
    from benchmarks.bench_release import tree_for

    run = args.run or default_run()
    base_tree = tree_for(args.base)
    trees = {"base": load_tree(base_tree), "this": load_tree(ROOT)}
    runs = {}
    for side, mods in trees.items():
        use(mods)
        runs[side] = mods["benches.recorded_run"].open_run(run)

    def call(side: str, kw: dict) -> object:
        return use(trees[side]).identify_run(runs[side], **kw)

    rows, checks = [], []
    for label, kw in CASES.items():
        digests = {s: hashlib.sha256(json.dumps(call(s, kw).to_dict(), sort_keys=True).encode()).hexdigest()
                   for s in trees}  # fmt: skip
        if digests["base"] != digests["this"]:
            raise SystemExit(f"bench_identify_run: {label}: the calibration results differ; not timing")
        checks.append(f"{label}: {digests['this'][:16]}")
        times, _ = alternate({s: (lambda s=s, kw=kw: call(s, kw)) for s in trees}, args.rounds)
        med = {s: sorted(v)[len(v) // 2] for s, v in times.items()}
        pairs = sorted(t / b for t, b in zip(times["this"], times["base"], strict=True))
        rows.append(f"| {label} | {med['base'] * 1e3:.0f} ms | {med['this'] * 1e3:.0f} ms | "
                    f"**{med['this'] / med['base']:.2f}** ({pairs[0]:.2f}–{pairs[-1]:.2f}) |")  # fmt: skip
        print(rows[-1], flush=True)
    git = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    sha = git.stdout.strip()
    body = (
        f"`identify_run` on an opened, verified recording ({run.name}: `ten-step-fast-spin`, seed 7 unless `--run` "
        f"names another), both trees in one process, {args.rounds} rounds alternating the order, median CPU; "
        f"{thread_note()}:\n\n"
        f"| method | base `{args.base}` | this tree (`{sha}`) | this / base (range of the paired ratios) |\n"
        "|---|---|---|---|\n" + "\n".join(rows) + "\n\n"
        "The calibration result (`CalibrationResult.to_dict`, every field) is identical on both sides for each "
        "method (checked before timing; sha256 of its JSON: " + "; ".join(checks) + ").\n\n"
        "What the identification stopped paying for (issue 32, the same values bit for bit, each checked by a "
        "test against the operation it replaces): numpy operations over (n, 3) arrays or into three columns of "
        "a wide row-major block run with an inner loop three values long, once per row — the regressors, z and "
        "the hold means are now written or summed column by column (analysis.columns, the models' fill_base and "
        "fill_measurement); z = y − ideal is formed inside the Gram's blocks instead of as (n, 6) arrays; the "
        "gimbal rotations write each product into scratch arrays and the result's columns; a spin's body rate "
        "is formed once (from its encoder angles' rate), a hold's constant reported rates are filled instead "
        "of interpolated. What is left is mostly arithmetic each sample needs: the gimbal angles' sines and "
        "cosines (≈ 0.09 s), the interpolation, the Gram products and the time base. Batch least squares "
        "spends most of its time in `batch_identify` itself (not changed here)."
    )
    write_section("identify-run", "identify_run against an earlier commit, one process (issue 32, cert)", body)


if __name__ == "__main__":
    main()
