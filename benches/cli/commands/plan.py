"""``tablebench plan``: predict the identification accuracy of a procedure on a bench before any motion."""

from __future__ import annotations

import argparse

from analysis.identification.plan_legend import PLAN_LEGEND
from benches.cli.arguments import add_bench_argument, add_procedure_arguments, parse_overrides
from benches.session import prepare
from core.errors import UsageError

EXAMPLES = """examples:
  tablebench plan                                          # ten-step on the simulated bench
  tablebench plan --procedure ten-step-fast-spin
  tablebench plan --bench benches/lab1.yaml --procedure twenty-four-position
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``plan`` subcommand."""
    p = sub.add_parser(
        "plan",
        help="predict parameter uncertainties of a procedure before running it",
        description="Predict, from the procedure's geometry and durations and the unit's noise and bias stability, "
        "the 1σ of every accelerometer parameter, the information rank, and which parameters will not be "
        "identified and what change would fix it. Nothing moves.",
        epilog="the table's " + "\n".join(PLAN_LEGEND) + "\n\n" + EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_bench_argument(p)
    add_procedure_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench plan``."""
    from benches.identify import IdentificationError, plan_for  # lazy: filterpy, scipy (--help time)

    prep = prepare(args.bench, args.procedure, parse_overrides(args.set))
    try:
        plan = plan_for(prep.compiled, prep.config)
    except IdentificationError as exc:
        raise UsageError(str(exc)) from None
    print(
        f"plan: procedure {prep.compiled.name} on bench {prep.config.name} "
        f"({prep.estimated_s / 60:.1f} min of bench time)"
    )
    print(plan.table())
    return 0
