"""``tablebench runs``: list recordings with their status; salvage the intact steps of a damaged one."""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from benches.recording import RecordingError, recording_file, salvage
from benches.session import recording_status
from core.errors import UsageError

EXAMPLES = """examples:
  tablebench runs                 # recordings under ./runs
  tablebench runs /data/lab1      # recordings under another folder
  tablebench runs --salvage runs/20261121-101500-ten-step
        # a damaged recording: copy its intact steps to runs/20261121-101500-ten-step-salvaged,
        # then continue it with: tablebench run --resume runs/20261121-101500-ten-step-salvaged

exit codes: 0 listed, every recording intact; 2 bad input, or listed with some recording DAMAGED
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``runs`` subcommand."""
    p = sub.add_parser(
        "runs",
        help="list recordings with their status; salvage a damaged one",
        description="List the run folders under DIR (default ./runs) with status, procedure, steps completed, "
        "bench time and procedure overrides (--set); every recording's checksums are verified, a damaged one is "
        "listed as DAMAGED with the dataset and step. Interrupted runs can be continued with 'tablebench run "
        "--resume RUN'; --salvage RUN copies the intact steps of a damaged recording to a new run folder.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("folder", nargs="?", default="runs", metavar="DIR")
    p.add_argument("--salvage", default=None, metavar="RUN", help="copy the intact steps of RUN to a new run folder")
    p.add_argument("--out", default=None, metavar="DIR", help="with --salvage: the new folder (default RUN-salvaged)")
    p.set_defaults(func=run)


def _salvage(args: argparse.Namespace) -> int:
    src = Path(args.salvage)
    folder = src.parent if src.is_file() else src
    if not recording_file(folder).exists():
        raise UsageError(f"--salvage {args.salvage}: no recording.h5 there")
    out = Path(args.out) if args.out else folder.with_name(folder.name + "-salvaged")
    if out.exists():
        raise UsageError(f"--out {out}: already exists; choose a new folder")
    try:
        out.mkdir(parents=True)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    try:
        kept = salvage(recording_file(folder), out / "recording.h5")
    except RecordingError:
        shutil.rmtree(out, ignore_errors=True)
        raise
    for name in ("bench.yaml", "procedure.yaml"):
        if (folder / name).exists():
            shutil.copyfile(folder / name, out / name)
    print(f"salvaged {kept} intact step(s) of {folder} into {out}", file=sys.stderr)
    print(f"continue with: tablebench run --resume {out}", file=sys.stderr)
    print(out)
    return 0


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench runs``."""
    if args.salvage is not None:
        return _salvage(args)
    if args.out is not None:
        raise UsageError(f"--out {args.out}: applies only with --salvage RUN")
    root = Path(args.folder)
    if not root.is_dir():
        raise UsageError(f"{root}: no such folder (runs are created by 'tablebench run')")
    rows = [recording_status(p) for p in sorted(root.glob("**/recording.h5"))]
    if not rows:
        print(f"no recordings under {root}")
        return 0
    print(f"{'run':50s} {'status':12s} {'procedure':22s} {'steps':>5s} {'bench time':>10s}  overrides")
    for r in rows:
        bench_min = f"{float(r.get('bench_s', 0)) / 60:8.1f} m" if "bench_s" in r else ""
        ov = r.get("overrides") or {}
        ov_txt = " ".join(f"{k}={v:g}" for k, v in sorted(ov.items())) if ov else "-"
        print(
            f"{r['path']:50s} {r['status']:12s} {str(r.get('procedure', '')):22s} "
            f"{r.get('steps_done', ''):>5} {bench_min:>10s}  {ov_txt}"
        )
        if r["status"] == "DAMAGED":
            print(f"{'':50s} {r['problem']}")
        elif r.get("tail"):
            print(f"{'':50s} {r['tail']}")
        elif r.get("integrity") == "not verifiable":
            print(f"{'':50s} integrity cannot be verified (recording without checksums)")
        if r["status"] in ("interrupted", "failed", "running"):
            print(f"{'':50s} resume: tablebench run --resume {r['path']}")
    damaged = [r for r in rows if r["status"] == "DAMAGED"]
    if damaged:  # each damage is printed once, in its row; the error line only counts and says what to do
        where = ", ".join(f"{r['path']}/recording.h5" for r in damaged[:3]) + (", ..." if len(damaged) > 3 else "")
        raise UsageError(
            f"{len(damaged)} of {len(rows)} recording(s) DAMAGED, listed above ({where}); copy the intact steps "
            f"of one with: tablebench runs --salvage {damaged[0]['path']}"
        )
    return 0
