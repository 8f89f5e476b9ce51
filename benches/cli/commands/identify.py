"""``tablebench identify``: identify the unit's error model (accelerometer, and gyro when recorded) from a recording."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    pass

from benches.cli.arguments import add_registry_arguments, sink_options
from benches.cli.work import Work, figure_png
from benches.results import CalibrationDocument, sinks_for_run
from benches.session import combined_covariance_or_none
from core.errors import UsageError
from core.jsonio import write_text_atomic
from core.outputs import check_output

EXAMPLES = """examples:
  tablebench identify runs/20261121-101500-ten-step                 # writes RUN/calibration.json
  tablebench identify RUN --method batch --out /tmp/batch.json      # batch least squares cross-check
  tablebench identify RUN --noise warm-up                           # R estimated from the warm-up record
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``identify`` subcommand."""
    p = sub.add_parser(
        "identify",
        help="identify the unit's error model (accelerometer and gyro triads) from a recording",
        description="Estimate the accelerometer's bias b, scale S, misalignment τ, quadratic d and size effect r "
        "(18 parameters) and, when the recording has gyro data, the gyro's bias, scale, misalignment and "
        "g-sensitivity (gyro_*; docs/methods/gyro-calibration.md) with their covariance from the hold and spin "
        "steps of a recording, with the Kalman filter (one filter over the whole sequence) or batch least "
        "squares. Writes calibration.json next to the recording.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="run folder or recording.h5")
    p.add_argument("--method", choices=("kalman", "batch"), default="kalman")
    p.add_argument(
        "--noise",
        choices=("configured", "warm-up"),
        default="configured",
        help="measurement noise R: the bench's configured VRW, or estimated from the warm-up",
    )
    p.add_argument(
        "--time-base",
        choices=("estimate", "none"),
        default="estimate",
        help="map the table's clock to the unit's with the time base estimated from the run's motions (default; "
        "docs/methods/time-base.md), or take them as one clock (none: for comparisons)",
    )
    p.add_argument("--out", default=None, metavar="FILE.json", help="default: RUN/calibration.json")
    p.add_argument(
        "--accelerometer-only", action="store_true", help="identify the 18 accelerometer parameters only"
    )
    add_registry_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench identify``."""
    from benches.identify import IdentificationError, identify_run  # lazy: filterpy, scipy (--help time)

    folder = Path(args.run) if Path(args.run).is_dir() else Path(args.run).parent
    target = check_output(args.out or folder / "calibration.json")  # before the work: never over an input
    if not target.name.lower().endswith(".json"):
        raise UsageError(f"--out {args.out}: give a .json file name (the calibration is JSON)")
    def compute(work: Work) -> tuple[Any, Any, bytes | None]:
        """Identify, then the certificate's budget for the NEES (in the worker: Ctrl-C answered at once)."""
        work.stage("reading the recording and identifying the model")
        try:
            result = identify_run(
                args.run, method=args.method, noise=args.noise, time_base=args.time_base,
                with_gyro=False if args.accelerometer_only else None,
            )  # fmt: skip
        except IdentificationError as exc:
            raise UsageError(str(exc)) from None
        work.advance(0.8, "the certificate's uncertainty budget (NEES against a simulator's truth)")
        cov = combined_covariance_or_none(result, Path(args.run))
        tb = result.time_base.estimate if result.time_base is not None else None
        png = None
        if tb is not None and tb.events:
            from analysis.timebase.plot import plot_timing_residuals  # lazy: matplotlib (--help time)

            png = figure_png(plot_timing_residuals(tb), 110)
        return result, cov, png

    with Work("identify", 1.0) as work:  # the interrupt and progress of 'run' (benches.cli.work)
        result, cov, png = work.run(compute, work)
        with work.writing():  # all or nothing: a Ctrl-C now is held until the files are complete
            out = sinks_for_run(folder, sink_options(args)).calibration(
                CalibrationDocument(run=folder, result=result, path=target if args.out else None)
            ).path
            if png is not None:
                write_text_atomic(out.parent / "time-base.png", png)
    print(result.summary(cov))
    if png is not None:
        print(f"timing residual around the motions: {out.parent / 'time-base.png'}", file=sys.stderr)
    print(f"calibration: {out}", file=sys.stderr)
    return 0
