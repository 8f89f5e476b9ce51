"""Benchmark: the GUM budget of a run (``budget_for_run`` → ``build_budget``) against an earlier commit's, one process.

``python -m benchmarks.bench_budget [--base COMMIT] [--run RUN] [--rounds N] [--stage ROUNDS]``

The earlier commit's three budget modules (``analysis/identification/budget.py``, ``table_axes.py`` and
``benches/certificate/budget.py``, read with ``git show``) are loaded beside this tree's under other module names
(their imports of one another renamed; everything else, the step geometry included, is this tree's), so both
sides run in the same process on the same step geometry of the same recording: the components must be the same
bits (checked first; the benchmark refuses to time otherwise), and the CPU times are medians over rounds that
alternate the order. ``--run`` takes a finished run folder; without it a ``ten-step-fast-spin`` run, seed 7, is
made once under ``benchmarks/out/budget-run`` (33 states: the whole unit, every type-B input of the certificate).
Works for a base whose three files have this tree's interfaces (the budget's since issue 25).

``--stage ROUNDS`` adds the stage the budget is part of: the in-process ``tablebench run`` of that procedure and
seed, its "identification after the run" span (:func:`benchmarks.bench_release.timed_run`: from the "run
complete" line to the "calibration:" line, CPU of the process), the base commit's worktree
(:func:`benchmarks.bench_release.tree_for`) against this tree, alternating, medians.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType

import numpy as np

from benchmarks._results import write_section

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_BASE = "6fd3cac"
"""main before the budget's memo (this helper's first change)."""
FILES = {
    "_base_budget": "analysis/identification/budget.py",
    "_base_table_axes": "analysis/identification/table_axes.py",
    "_base_cert_budget": "benches/certificate/budget.py",
}


def load_base(commit: str, where: Path) -> ModuleType:
    """The base commit's ``benches.certificate.budget`` (with its own identification budget and table axes)."""
    renames = {
        "from analysis.identification.budget import": "from _base_budget import",
        "from analysis.identification.table_axes import": "from _base_table_axes import",
    }
    mods: dict[str, ModuleType] = {}
    for name, path in FILES.items():
        text = subprocess.run(["git", "show", f"{commit}:{path}"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout  # fmt: skip
        for old, new in renames.items():
            text = text.replace(old, new)
        file = where / f"{name}.py"
        file.write_text(text, encoding="utf-8")
        spec = importlib.util.spec_from_file_location(name, file)
        assert spec is not None and spec.loader is not None
        mods[name] = importlib.util.module_from_spec(spec)
        sys.modules[name] = mods[name]
        spec.loader.exec_module(mods[name])
    return mods["_base_cert_budget"]


def run_folder(run: str | None) -> Path:
    """The run to measure on: ``run``, or a seed-7 ten-step-fast-spin run made once under benchmarks/out."""
    if run:
        return Path(run)
    folder = ROOT / "benchmarks" / "out" / "budget-run"
    if not (folder / "calibration.json").exists():
        folder.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "benches.cli", "run", "--procedure", "ten-step-fast-spin", "--seed", "7",
                        "--out", str(folder), "--plain"], cwd=ROOT, check=True, capture_output=True)  # fmt: skip
    return folder


def stage_rows(base: str, rounds: int) -> str:
    """Table rows: the in-process run's "identification after the run" and whole-run CPU, base against this tree."""
    from benchmarks.bench_release import check_tree, timed_run, tree_for

    trees = {"base": tree_for(base), "now": ROOT}
    for t in trees.values():
        check_tree(t)
    got: dict[str, list[dict[str, tuple[float, float]]]] = {k: [] for k in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(rounds):
            for k in list(trees) if r % 2 == 0 else list(trees)[::-1]:
                got[k].append(timed_run(trees[k], "ten-step-fast-spin", Path(tmp) / f"{k}{r}", 7))
    rows = ""
    for stage in ("— identification after the run", "run (whole, in-process)"):
        b, n = (statistics.median(x[stage][1] for x in got[k]) for k in trees)
        label = f"in-process `run`: {stage.lstrip('— ')}, CPU ({rounds} rounds)"
        rows += f"| {label} | {b:.2f} s | {n:.2f} s | {n / b:.2f} |\n"
    return rows


def main(argv: list[str] | None = None) -> None:
    """Time both budgets, alternating; write the ``budget-speed`` section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default=DEFAULT_BASE)
    ap.add_argument("--run", default=None)
    ap.add_argument("--rounds", type=int, default=11)
    ap.add_argument("--stage", type=int, default=0, help="rounds of the in-process run's stage timing (0: none)")
    args = ap.parse_args(argv)
    from benches.calibration_result import CalibrationResult
    from benches.certificate import budget as now
    from benches.certificate import build
    from benches.recorded_run import run_of

    folder = run_folder(args.run)
    cal = CalibrationResult.load(folder / "calibration.json")
    with tempfile.TemporaryDirectory() as tmp:
        base = load_base(args.base, Path(tmp))
        with run_of(folder) as rr:
            cal_run = cal.run.to_mapping() if cal.run is not None else {}
            binfo = build.bench_info_of(rr.config if rr.bench_text.strip() else None, cal_run, rr.header.as_dict())
            geo = build._geometry(rr, binfo, cal)
        kw = dict(
            g=binfo.g, g_uncertainty=binfo.g_uncertainty, g_source=binfo.g_source,
            attitude_accuracy=binfo.attitude_accuracy,
            bias_instability=None if binfo.bias_instability is None else np.asarray(binfo.bias_instability),
            gyro_bias_instability=None if binfo.gyro_bias_instability is None else np.asarray(
                binfo.gyro_bias_instability),
            latitude=None if binfo.latitude_deg is None else math.radians(float(binfo.latitude_deg)),
            azimuth_uncertainty=binfo.azimuth_uncertainty,
        )  # fmt: skip
        sides = {"base": base.budget_for_run, "now": now.budget_for_run}
        got = {k: f(cal, geo, **kw) for k, f in sides.items()}
        pairs = list(zip(got["base"].components, got["now"].components, strict=True))
        same = got["base"].notes == got["now"].notes and all(
            a.key == b.key and a.source == b.source and a.covariance.tobytes() == b.covariance.tobytes()
            for a, b in pairs
        )
        if not same:
            raise SystemExit("bench_budget: the two budgets differ; not timing (the change must keep the numbers)")
        times: dict[str, list[float]] = {k: [] for k in sides}
        for r in range(args.rounds):
            for k in list(sides) if r % 2 == 0 else list(sides)[::-1]:
                c0 = time.process_time()
                sides[k](cal, geo, **kw)
                times[k].append(time.process_time() - c0)
    mb, mn = statistics.median(times["base"]), statistics.median(times["now"])
    stage = stage_rows(args.base, args.stage) if args.stage > 0 else ""
    n_states, n_steps = cal.error_model.n_params, len(geo)
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                           text=True).stdout.strip()  # fmt: skip
    body = (
        f"`budget_for_run` of a `ten-step-fast-spin` run (seed 7 unless `--run` names another; {n_states} states, "
        f"{n_steps} steps, {len(pairs)} components), same process, same step geometry, {args.rounds} rounds "
        f"alternating the order, median CPU (one BLAS thread as run by `run_all`):\n\n"
        f"| | base `{args.base}` | this tree (`{head}`{' + changes' if dirty else ''}) | this / base |\n"
        "|---|---|---|---|\n"
        f"| GUM budget, CPU | {mb * 1e3:.1f} ms | {mn * 1e3:.1f} ms | **{mn / mb:.2f}** |\n{stage}\n"
        "Every component's covariance, its source text and the notes are the same bits on both sides (checked "
        "before timing). `run` forms the budget once (its NEES line and its certificate share it); the offline "
        "`identify RUN` (NEES line) and `certificate RUN` form it again each."
        + (
            " The in-process rows compare whole trees: they include every change between the base and this tree, "
            "not only the budget's."
            if stage
            else ""
        )
    )
    write_section("budget-speed", "GUM budget cost against an earlier commit (issue 32)", body)
    print(body)


if __name__ == "__main__":
    main()
