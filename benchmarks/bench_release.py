"""Benchmark: this code against an earlier release, stage by stage, alternating, in one run (issue 32).

``python -m benchmarks.bench_release [--base COMMIT] [--rounds N] [--procedure P] [--certificate-only]``

The earlier release is checked out as a git worktree (``benchmarks/out/release-<commit>``, detached) and run with
the same Python environment: each stage is a separate process whose ``PYTHONPATH`` is the tree being measured
(the check at the start prints which tree each side really imported). Rounds alternate the order of the two
trees, so the drift of a shared machine's speed (±25 % over minutes here) hits both alike; the figures are
medians over rounds, and the ratio now / base is what RESULTS.md reports next to the absolute times.

Stages (each tree on its own recording of the same procedure and seed):
- ``--help``: ``tablebench --help`` (and ``python -c pass`` as the floor);
- the whole in-process ``tablebench run`` and its parts, timed from the lines it prints: start-up to the first
  step, the motion phase (simulation + recording + streaming identifier), identification (to the
  ``calibration:`` line, said as soon as the run folder has calibration.json), the registry record (from that
  line to the ``registry:`` line; a tree without a registry, such as the release, has no such row and its
  certificate span starts at its ``calibration:`` line), certificate;
- offline ``identify RUN`` and ``certificate RUN`` on the recording, and ``identify RUN --accelerometer-only``
  (this code) against the release's identify (which identified the accelerometer's 18 states): like for like;
- an ARMA(1,1) exact-ML fit, n = 5000, mean fixed (one BLAS thread on both sides);
- the recording's size.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
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
ts, cs = [], []
for _ in range(15):
    t0, c0 = time.perf_counter(), time.process_time(); fit_arma(x, 1, 1, **kw)
    ts.append(time.perf_counter() - t0); cs.append(time.process_time() - c0)
print(sorted(ts)[len(ts) // 2], sorted(cs)[len(cs) // 2])
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


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of a running process (all its threads), from /proc (0 where there is none)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _wait_cpu(proc: subprocess.Popen) -> tuple[int, float]:
    """Wait for ``proc``; its exit status and its CPU seconds (user + system, from wait4)."""
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, usage.ru_utime + usage.ru_stime


def timed(cmd: list[str], tree: Path) -> tuple[float, float]:
    """Wall and CPU seconds of one command run in ``tree``."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=tree, env=env_for(tree), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert proc.stderr is not None
    err = proc.stderr.read()
    code, cpu = _wait_cpu(proc)
    if code != 0:
        raise RuntimeError(f"{' '.join(cmd[-4:])} failed in {tree}: {err.decode(errors='replace')[-400:]}")
    return time.perf_counter() - t0, cpu


def timed_run(tree: Path, procedure: str, folder: Path, seed: int) -> dict[str, tuple[float, float]]:
    """The whole ``tablebench run`` and its parts, from the times its lines arrive (wall) and the process's CPU
    time read from /proc at those moments."""
    cmd = [sys.executable, "-c", CLI, "run", "--procedure", procedure, "--out", str(folder), "--plain",
           "--seed", str(seed)]  # fmt: skip
    t0 = time.perf_counter()
    marks: dict[str, tuple[float, float]] = {}
    proc = subprocess.Popen(cmd, cwd=tree, env=env_for(tree), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, bufsize=1)  # fmt: skip
    assert proc.stdout is not None
    for line in proc.stdout:
        now = time.perf_counter() - t0
        for key, pattern in MARKS:
            if key not in marks and re.match(pattern, line):
                marks[key] = (now, _cpu_s(proc.pid))
    code, cpu = _wait_cpu(proc)
    if code != 0:
        raise RuntimeError(f"run failed in {tree}")
    return run_stages(marks, (time.perf_counter() - t0, cpu))


MARKS = (("first_step", r"step "), ("motion_end", r"run complete"), ("calibration", r"calibration:"),
         ("registry", r"registry: (?!certificate )"), ("certificate", r"certificate:"))  # fmt: skip
"""The lines of ``tablebench run`` whose arrival ends a stage: (mark, how the line starts, a regular expression);
the first of each. The registry's line for the calibration, not the one for the certificate
(``registry: certificate …``, said while the certificate is issued)."""
REGISTRY = "— registry record"


def run_stages(
    marks: dict[str, tuple[float, float]], total: tuple[float, float]
) -> dict[str, tuple[float, float]]:
    """The run's stages (wall, CPU) from the marks of :data:`MARKS`. The registry record (``calibration:`` to
    ``registry:``) is a row only when the run said where the registry put the calibration; the certificate then
    starts at the registry line, else (a tree without a registry, or a registry that could not record) at the
    calibration line."""

    def span(a: str, b: str) -> tuple[float, float]:
        return marks[b][0] - marks[a][0], marks[b][1] - marks[a][1]

    out = {
        "run (whole, in-process)": total,
        "— start-up to the first step": marks["first_step"],
        "— motion phase": span("first_step", "motion_end"),
        "— identification after the run": span("motion_end", "calibration"),
    }
    registry = "registry" in marks and marks["registry"][0] <= marks.get("certificate", (float("inf"),))[0]
    if registry:
        out[REGISTRY] = span("calibration", "registry")
    if "certificate" in marks:
        out["— certificate"] = span("registry" if registry else "calibration", "certificate")
    return out


LIKE_FOR_LIKE = "identify RUN, accelerometer only (offline, 18 states)"
"""The stage that compares like with like: the release identified the accelerometer's 18 states; this code
identifies the whole unit (33) unless told ``--accelerometer-only`` (the base tree runs its plain identify)."""


def certificate_round(tree: Path, procedure: str, seed: int) -> dict[str, tuple[float, float]]:
    """The quick mode (``--certificate-only``): the in-process run (its certificate span is the figure) and the
    offline ``certificate RUN`` once for ``tree``."""
    work = Path(tempfile.mkdtemp(prefix="tb-release-"))
    try:
        run = work / "run"
        out = timed_run(tree, procedure, run, seed)
        out["certificate RUN (offline)"] = timed([sys.executable, "-c", CLI, "certificate", str(run), "--out",
                                                  str(work / "cert.pdf")], tree)  # fmt: skip
        return out
    finally:
        shutil.rmtree(work, ignore_errors=True)


def one_round(tree: Path, procedure: str, seed: int, accel_flag: bool = False) -> dict[str, tuple[float, float]]:
    """Every stage once for ``tree``: (wall, CPU) seconds; the recording's size as (MB, MB). ``accel_flag``: the
    tree knows ``identify --accelerometer-only`` (:data:`LIKE_FOR_LIKE`)."""
    work = Path(tempfile.mkdtemp(prefix="tb-release-"))
    try:
        run = work / "run"
        out = {"python -c pass (floor)": timed([sys.executable, "-c", "pass"], tree)}
        out["tablebench --help"] = timed([sys.executable, "-c", CLI, "--help"], tree)
        out.update(timed_run(tree, procedure, run, seed))
        out["identify RUN (offline)"] = timed([sys.executable, "-c", CLI, "identify", str(run), "--out",
                                               str(work / "cal.json")], tree)  # fmt: skip
        out[LIKE_FOR_LIKE] = timed([sys.executable, "-c", CLI, "identify", str(run), "--out", str(work / "cal18.json")]
                                   + (["--accelerometer-only"] if accel_flag else []), tree)  # fmt: skip
        out["certificate RUN (offline)"] = timed([sys.executable, "-c", CLI, "certificate", str(run), "--out",
                                                  str(work / "cert.pdf")], tree)  # fmt: skip
        arma = subprocess.run([sys.executable, "-c", ARMA], cwd=tree, env=env_for(tree), capture_output=True,
                              text=True, check=True)  # fmt: skip
        wall, cpu = (float(x) for x in arma.stdout.split())
        out["ARMA(1,1) exact ML, n = 5000, mean fixed"] = (wall, cpu)
        size = (run / "recording.h5").stat().st_size / 1e6
        out["recording size (MB)"] = (size, size)
        return out
    finally:
        shutil.rmtree(work, ignore_errors=True)


def results_from_log(log: Path) -> dict[str, list[dict[str, tuple[float, float]]]]:
    """The per-round figures of the complete rounds in a log of this script (both trees measured)."""
    rounds: dict[int, dict[str, dict[str, tuple[float, float]]]] = {}
    for line in log.read_text().splitlines():
        m = re.match(r"round (\d+) (base|now): (.*)$", line)
        if m:
            stages = re.findall(r"(.+?) ([0-9.e+-]+)/([0-9.e+-]+)(?:, |$)", m.group(3))
            rounds.setdefault(int(m.group(1)), {})[m.group(2)] = {k: (float(w), float(c)) for k, w, c in stages}
    done = [r for _, r in sorted(rounds.items()) if len(r) == 2]
    return {k: [r[k] for r in done] for k in ("base", "now")}


def stage_order(results: dict[str, list[dict[str, tuple[float, float]]]]) -> list[str]:
    """Every stage either tree has in any round, in the order the rounds list them (this code's first; a stage
    only one tree has, e.g. the registry record the release lacks, keeps its place after its predecessor)."""
    order: list[str] = []
    for k in ("now", "base"):
        for r in results[k]:
            for i, s in enumerate(r):
                if s not in order:
                    prev = list(r)[i - 1] if i else None
                    order.insert(order.index(prev) + 1 if prev in order else len(order), s)
    return order


def _median(values: list[float]) -> float | None:
    return statistics.median(values) if values else None


def table(results: dict[str, list[dict[str, tuple[float, float]]]]) -> str:
    """The Markdown table: per stage, median wall and CPU of each tree and the medians of the per-round ratios.

    A stage is never dropped: one that a tree does not have (the release has no registry record) shows "—" for
    that tree and for the ratio; medians are over the rounds that have the stage, ratios over the rounds in
    which both trees have it (paired round by round)."""
    rows = ["| stage | base wall | now wall | **now / base (wall)** | base CPU | now CPU | **now / base (CPU)** |",
            "|---|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    pairs = list(zip(results["base"], results["now"], strict=False))
    for s in stage_order(results):
        unit = " MB" if "MB" in s else " s"
        w = [_median([r[s][0] for r in results[k] if s in r]) for k in ("base", "now")]
        c = [_median([r[s][1] for r in results[k] if s in r]) for k in ("base", "now")]
        both = [(b[s], n[s]) for b, n in pairs if s in b and s in n and b[s][0] > 0 and b[s][1] > 0]
        rw = _median([n[0] / b[0] for b, n in both])
        rc = _median([n[1] / b[1] for b, n in both])

        def fig(x: float | None, bold: bool = False, ratio: bool = False, unit: str = unit) -> str:
            if x is None:
                return "—"
            text = f"{x:.2f}" if ratio else f"{x:.3g}{unit}"
            return f"**{text}**" if bold else text

        if "MB" in s:
            rows.append(f"| {s} | {fig(w[0])} | {fig(w[1])} | {fig(rw, True, True)} | | | |")
        else:
            rows.append(f"| {s} | {fig(w[0])} | {fig(w[1])} | {fig(rw, True, True)} | {fig(c[0])} | {fig(c[1])} | "
                        f"{fig(rc, True, True)} |")  # fmt: skip
    return "\n".join(rows) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the comparison and write the "release" section of RESULTS.md."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", default=DEFAULT_BASE, help=f"the earlier commit (default {DEFAULT_BASE})")
    ap.add_argument(
        "--now",
        default=None,
        help="measure this commit (a frozen worktree) instead of the working tree, e.g. while editing",
    )
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--procedure", default="ten-step-fast-spin")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--section", default="release", help="the RESULTS.md section to (re)write")
    ap.add_argument(
        "--certificate-only",
        action="store_true",
        help="quick mode: only the in-process run (its stages, the certificate among them) and the offline "
        "certificate, alternating the same way",
    )
    ap.add_argument("--title", default=None, help="its title (default: against the earlier release BASE)")
    ap.add_argument(
        "--from-log",
        default=None,
        metavar="LOG",
        help="write the section from the 'round …' lines an earlier (interrupted) run printed",
    )
    args = ap.parse_args(argv)
    base = tree_for(args.base)
    trees = {"base": base, "now": tree_for(args.now) if args.now else ROOT}
    for tree in trees.values():
        check_tree(tree)
    results: dict[str, list[dict[str, tuple[float, float]]]] = {k: [] for k in trees}
    out_json = ROOT / "benchmarks" / "out" / f"release-{args.section}.json"
    if args.from_log:
        results = results_from_log(Path(args.from_log))
        args.rounds = len(results["now"])
    for r in range(0 if args.from_log else args.rounds):
        order = ("base", "now") if r % 2 == 0 else ("now", "base")
        for key in order:
            if args.certificate_only:
                results[key].append(certificate_round(trees[key], args.procedure, args.seed))
            else:
                results[key].append(one_round(trees[key], args.procedure, args.seed, accel_flag=key == "now"))
            print(f"round {r + 1} {key}: " + ", ".join(f"{k} {w:.6g}/{c:.6g}" for k, (w, c) in
                                                       results[key][-1].items()), flush=True)  # fmt: skip
        out_json.write_text(json.dumps({"base": args.base, "now": args.now, "results": results}, indent=1))
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=trees["now"], capture_output=True,
                          text=True).stdout.strip()  # fmt: skip
    now = f"`{head}`" if args.now else f"`{head}` + working tree"
    body = (
        f"This code ({now}) against the earlier release `{args.base}`, same Python environment, each stage a "
        f"separate process importing its own tree; `{args.procedure}` on the default simulated bench, seed "
        f"{args.seed}; {args.rounds} rounds, the two trees alternated round by round (base first in odd rounds); "
        "one BLAS thread on both sides. Wall and CPU (user + system of the process, all threads; for the run's "
        "parts read from /proc when each part's line arrives) are medians over rounds; the ratios are medians of "
        "the per-round ratios (each round's two trees ran minutes apart, so a drift of the shared machine's speed "
        "cancels). On a machine shared by several busy processes the CPU ratio is the steadier figure.\n\n"
        + table(results)
    )
    if args.certificate_only:
        write_section(args.section, f"{args.title or 'Certificate against the earlier release ' + args.base} "
                      "(issue 32, quick mode)", body)  # fmt: skip
        print(body)
        return 0
    floor = statistics.median(r["python -c pass (floor)"][0] for r in results["now"])
    helps = statistics.median(r["tablebench --help"][0] for r in results["now"])
    body += (
        f"\n`tablebench --help` now = {helps / floor:.1f}× `python -c pass` (wall; target ≤ 8×). Targets (issue 32): "
        "whole run ≤ 0.9×, identification ≤ 1.0×, certificate ≤ 1.0× and ≤ 1 s, `--help` ≤ 1.0×, ARMA fit ≤ 1.0×, "
        "recording size unchanged.\n"
    )
    write_section(args.section, f"{args.title or 'Against the earlier release ' + args.base}, stage by stage "
                  "(issue 32)", body)  # fmt: skip
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
