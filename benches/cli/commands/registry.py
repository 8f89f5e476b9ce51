"""``tablebench registry``: the calibration registry (every calibration of every unit; ``docs/registry.md``)."""

from __future__ import annotations

import argparse
import datetime as _dt
import sys
from pathlib import Path

from benches.cli.arguments import add_registry_arguments
from core.errors import OutputError, UsageError

EXAMPLES = """examples:
  tablebench registry add runs/20261127-101500-ten-step       # idempotent: adding twice changes nothing
  tablebench registry list
  tablebench registry show SIM-U-0001                          # history, as found / as left, s_r and s_R
  tablebench registry trend SIM-U-0001 --param b_x --out b_x.png
  tablebench registry compare runs/RUN_A runs/RUN_B           # E_n per parameter
  tablebench registry due                                      # ILAC-G24 methods 1 and 2
  tablebench registry export SIM-U-0001 --format json --out SIM-U-0001.json
  TABLEBENCH_REGISTRY=postgresql://lab@dbhost/calibrations tablebench registry list

where: --registry URL, else $TABLEBENCH_REGISTRY, else registry.sqlite in the runs folder (--runs, default runs/)
exit codes: 0 done, 2 bad input or registry not reachable (one line saying what to do)
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``registry`` subcommand and its actions."""
    p = sub.add_parser(
        "registry",
        help="the calibration registry: history, trends, comparisons, due dates, exports",
        description="Keep every calibration of every unit in one database (SQLite in the runs folder by default, "
        "a lab's PostgreSQL by URL): unit and configuration, bench, procedure and its SHA-256, the recording's "
        "digest, every parameter with its covariance and budget, decision, certificate and what it supersedes, "
        "operator, and as found (the previous calibration applied to this run's data) beside as left. 'run' "
        "and 'certificate' record into it automatically.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    acts = p.add_subparsers(dest="action", metavar="ACTION")

    def action(name: str, help_: str) -> argparse.ArgumentParser:
        a = acts.add_parser(name, help=help_, description=help_)
        add_registry_arguments(a)
        a.add_argument("--runs", default="runs", metavar="DIR", help="runs folder of the default SQLite registry")
        a.set_defaults(func=run, action=name)
        return a

    a = action("add", "record a run folder (idempotent)")
    a.add_argument("run", metavar="RUN", nargs="+", help="run folder(s) holding calibration.json")
    a.add_argument("--configuration", default=None, metavar="V", help="unit configuration version (default 1; a "
                   "re-soldered or re-mounted unit is a new configuration)")  # fmt: skip
    action("list", "every unit with its number of calibrations")
    a = action("show", "a unit's history: calibrations, as found / as left, repeatability and reproducibility")
    a.add_argument("serial", metavar="SERIAL")
    a = action("trend", "one parameter over time: values ± U, control limits, E_n between calibrations (PNG)")
    a.add_argument("serial", metavar="SERIAL")
    a.add_argument("--param", required=True, metavar="P", help="parameter name, e.g. b_x, S_y, tau_xz")
    a.add_argument("--out", required=True, metavar="FILE.png")
    a = action("compare", "E_n per parameter between two calibrations")
    a.add_argument("run_a", metavar="RUN_A", help="run folder, recording SHA-256 or calibration digest (prefix)")
    a.add_argument("run_b", metavar="RUN_B")
    a = action("due", "recalibration due dates (ILAC-G24 method 1 staircase and method 2 control chart)")
    a.add_argument("serial", metavar="SERIAL", nargs="?", help="one unit (default: every unit)")
    a.add_argument("--now", default=None, metavar="YYYY-MM-DD", help="the date to judge against (default today)")
    a = action("export", "a unit's history as JSON (with the compensation equation) or CSV")
    a.add_argument("serial", metavar="SERIAL")
    a.add_argument("--format", choices=("json", "csv"), default="json")
    a.add_argument("--out", required=True, metavar="FILE")
    p.set_defaults(func=run, action=None)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench registry ACTION``."""
    from benches.results.registry import commands as impl  # lazy: sqlalchemy (--help time)

    if args.action is None:
        raise UsageError("give an action: add, list, show, trend, compare, due or export (tablebench registry -h)")
    if args.action == "due" and args.now is not None:
        try:
            _dt.date.fromisoformat(args.now)
        except ValueError:
            raise UsageError(f"--now {args.now!r}: expected YYYY-MM-DD") from None
    if getattr(args, "out", None) is not None:
        out = Path(args.out)
        if out.exists() and out.is_dir():
            raise OutputError(f"--out {out}: is a folder; give a file name")
    text = impl.ACTIONS[args.action](args)
    if text:
        try:
            print(text)
        except OSError:
            pass
    sys.stdout.flush()
    return 0
