"""``tablebench scalefactor``: gyro scale factor, nonlinearity and asymmetry from a rate-transfer run."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from core.errors import OutputError, UsageError

EXAMPLES = """examples:
  tablebench run --procedure gyro-rate-transfer                     # the test itself (≈ 2.5 h of bench time)
  tablebench scalefactor runs/RUN                                    # writes RUN/rate_transfer.json
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``scalefactor`` subcommand."""
    p = sub.add_parser(
        "scalefactor",
        help="gyro scale factor, nonlinearity and asymmetry (IEEE 952/1431) from a rate-transfer run",
        description="For each gyro axis spun about (procedure gyro-rate-transfer): the least-squares line of the "
        "mean output against the reference rate (encoder angle over time + Earth rate), the scale-factor "
        "nonlinearity (largest residual, ppm of full-scale output) and asymmetry (ppm), each with U (k = 2). "
        "See docs/methods/gyro-calibration.md.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="run folder or recording.h5")
    p.add_argument("--out", default=None, metavar="FILE.json", help="default: RUN/rate_transfer.json")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench scalefactor``."""
    from benches.identify import IdentificationError  # lazy: scipy (--help time)
    from benches.rate_transfer import rate_transfer_run, write_rate_transfer  # lazy: scipy (--help time)

    folder = Path(args.run) if Path(args.run).is_dir() else Path(args.run).parent
    out = Path(args.out) if args.out else folder / "rate_transfer.json"
    if args.out and not out.parent.is_dir():
        raise OutputError(f"{out}: its folder {out.parent} does not exist or is not a folder; choose another --out")
    try:
        report = rate_transfer_run(args.run)
    except (IdentificationError, ValueError) as exc:
        raise UsageError(f"{args.run}: {exc}") from None
    try:
        write_rate_transfer(report, out)
    except OSError as exc:
        raise OutputError(f"{out}: cannot be written ({exc}); choose another --out") from None
    print(report["summary"])
    print(f"rate transfer: {out}", file=sys.stderr)
    return 0
