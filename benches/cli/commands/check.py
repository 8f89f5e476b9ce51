"""``tablebench check``: validate a procedure against a bench without moving anything."""

from __future__ import annotations

import argparse
from pathlib import Path

from analysis.units import format_hms
from benches.cli.arguments import add_bench_argument, add_procedure_arguments, parse_overrides
from benches.session import prepare
from procedures.paths import shipped_procedures

EXAMPLES = """\
examples:
  tablebench check ten-step                      # a shipped procedure against the default bench (sim)
  tablebench check ten-step-fast-spin --bench benches/sim.yaml
  tablebench check my-procedure.yaml --bench lab-table-2.yaml
  tablebench check static-noise --set duration_s=60   # override a procedure parameter

exit codes: 0 the procedure is valid on this bench; 2 it is not (one line: FILE:LINE: step 'NAME': ...).
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``check`` subcommand."""
    p = subparsers.add_parser(
        "check",
        help="validate a procedure against a bench (limits, attitudes, rates, duration); nothing moves",
        description="Load a procedure file, compile it for a bench (table limits, unit mounting) and print its "
        "steps: attitudes in body-axis words, spins, acquisition time and the estimated duration. Names of "
        f"shipped procedures work as FILE: {', '.join(shipped_procedures())}.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_procedure_arguments(p, positional=True)
    add_bench_argument(p)
    p.add_argument("--quiet", action="store_true", help="print only the one-line verdict")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Load, compile and check; print the summary; 0 if valid (errors raise → exit 2)."""
    prep = prepare(args.bench, args.procedure, parse_overrides(args.set))  # the same step as plan and run
    proc_path, bench_path, config, compiled = prep.procedure_path, prep.bench_path, prep.config, prep.compiled
    limits = config.turntable.limits
    if not args.quiet:
        print(compiled.summary(limits))
        if compiled.parameters:
            print("parameters: " + ", ".join(f"{k}={v:g}" for k, v in compiled.parameters.items()))
    est = compiled.estimated_duration(limits)
    print(
        f"OK: {Path(proc_path)} is valid on bench {config.name} ({bench_path}); "
        f"estimated duration {format_hms(est)}"
    )
    return 0
