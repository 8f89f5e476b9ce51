"""``tablebench check``: validate a procedure against a bench without moving anything."""

from __future__ import annotations

import argparse
from pathlib import Path

from analysis.units import format_hms
from benches.arguments import parse_overrides
from benches.bench_config import load_bench
from core.yaml_source import ConfigError
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure
from procedures.paths import default_bench_path, resolve_bench, resolve_procedure, shipped_procedures
from procedures.steps import CompiledProcedure

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
    p.add_argument("procedure", metavar="FILE", help="procedure YAML file, or a shipped name like ten-step")
    p.add_argument(
        "--bench",
        metavar="FILE",
        default=None,
        help="bench YAML file or shipped name (default: benches/sim.yaml here, else the shipped sim bench)",
    )
    p.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a procedure parameter (from its parameters: block), e.g. --set duration_s=60; repeatable",
    )
    p.add_argument("--quiet", action="store_true", help="print only the one-line verdict")
    p.set_defaults(func=run)


def check_against_unit(compiled: CompiledProcedure, sample_rate: float) -> None:
    """Every acquisition step must last at least one sample period of the unit; ConfigError otherwise."""
    for s in compiled.steps:
        if s.acquires and s.duration * sample_rate < 1.0:
            raise ConfigError(
                compiled.path,
                s.line,
                f"step {s.name!r}: {s.duration:g} s is shorter than one sample at the unit's {sample_rate:g} Hz; "
                f"allowed: at least {1.0 / sample_rate:g} s",
            )


def run(args: argparse.Namespace) -> int:
    """Load, compile and check; print the summary; 0 if valid (errors raise → exit 2)."""
    proc_path = resolve_procedure(args.procedure)
    bench_path = resolve_bench(args.bench) if args.bench else default_bench_path()
    overrides = parse_overrides(args.set)
    proc = load_procedure(proc_path, overrides)
    config = load_bench(bench_path)
    limits = config.turntable.limits
    compiled = compile_procedure(proc, limits=limits, mounting=config.unit.mounting)
    check_against_unit(compiled, float(config.unit.sample_rate))
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
