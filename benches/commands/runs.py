"""``tablebench runs``: list recordings with their status."""

from __future__ import annotations

import argparse
from pathlib import Path

EXAMPLES = """examples:
  tablebench runs                 # recordings under ./runs
  tablebench runs /data/lab1      # recordings under another folder
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``runs`` subcommand."""
    p = sub.add_parser(
        "runs",
        help="list recordings with their status",
        description="List the run folders under DIR (default ./runs) with status, procedure, steps completed "
        "and bench time; interrupted runs can be continued with 'tablebench run --resume RUN'.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("folder", nargs="?", default="runs", metavar="DIR")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench runs``."""
    from benches.session import recording_status
    from core.errors import UsageError

    root = Path(args.folder)
    if not root.is_dir():
        raise UsageError(f"{root}: no such folder (runs are created by 'tablebench run')")
    rows = [recording_status(p) for p in sorted(root.glob("**/recording.h5"))]
    if not rows:
        print(f"no recordings under {root}")
        return 0
    print(f"{'run':50s} {'status':12s} {'procedure':22s} {'steps':>5s} {'bench time':>10s}")
    for r in rows:
        bench_min = f"{float(r.get('bench_s', 0)) / 60:8.1f} m" if "bench_s" in r else ""
        print(
            f"{r['path']:50s} {r['status']:12s} {str(r.get('procedure', '')):22s} "
            f"{r.get('steps_done', ''):>5} {bench_min:>10s}"
        )
        if r["status"] in ("interrupted", "failed", "running"):
            print(f"{'':50s} resume: tablebench run --resume {r['path']}")
    return 0
