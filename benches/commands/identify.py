"""``tablebench identify``: identify the 18-parameter accelerometer model from a recording."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from benches.calibration_result import CalibrationResult

EXAMPLES = """examples:
  tablebench identify runs/20261121-101500-ten-step                 # writes RUN/calibration.json
  tablebench identify RUN --method batch --out /tmp/batch.json      # batch least squares cross-check
  tablebench identify RUN --noise warm-up                           # R estimated from the warm-up record
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``identify`` subcommand."""
    p = sub.add_parser(
        "identify",
        help="identify the accelerometer error model from a recording",
        description="Estimate bias b, scale S, misalignment τ, quadratic d and size effect r (18 parameters) with "
        "their covariance from the hold and spin steps of a recording, with the Kalman filter (one filter over "
        "the whole sequence) or batch least squares. Writes calibration.json next to the recording.",
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
    p.add_argument("--out", default=None, metavar="FILE.json", help="default: RUN/calibration.json")
    p.set_defaults(func=run)


def format_result(result: CalibrationResult) -> str:
    """A readable table of a calibration result (u = the identification's combined standard uncertainty)."""
    from analysis.units import DISPLAY_UNITS

    lines = [f"{'param':8s} {'value':>12s} {'u (k=1)':>10s} {'unit':7s} {'err/u':>7s}  note"]
    truth = result.extra.get("truth") or {}
    for name, p in result.parameters.items():
        unit, one = DISPLAY_UNITS[p.kind]
        e = truth.get("error_over_u", {}).get(name)
        note = "" if p.identified else "NOT IDENTIFIED (prior-dominated; not applied)"
        e_txt = "" if e is None else f"{e:7.2f}"
        lines.append(f"{name:8s} {p.value / one:12.4f} {p.u / one:10.4f} {unit:7s} {e_txt:>7s}  {note}")
    info = result.extra.get("information") or {}
    cond = info.get("condition")
    cond_txt = f"{cond:.3g}" if isinstance(cond, float) else str(cond)
    lines.append(f"information rank {info.get('rank')}/18, condition {cond_txt}; method {result.method}")
    lines.append(
        "u = the identification's combined standard uncertainty (white noise ⊕ correlated bias instability, "
        "k = 1); the certificate adds table, gravity and model components and states U = 2u"
    )
    if truth:
        lines.append(f"NEES {truth['nees']:.2f} over {truth['dof']} identified states (simulator truth)")
    else:
        lines.append("no simulator truth in the recording (a real bench): errors against truth not computed")
    lines += [f"warning: {w}" for w in result.extra.get("warnings", [])]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench identify``."""
    from benches.identify import IdentificationError, identify_run, write_calibration
    from core.errors import UsageError

    try:
        result = identify_run(args.run, method=args.method, noise=args.noise)
    except IdentificationError as exc:
        raise UsageError(str(exc)) from None
    folder = Path(args.run) if Path(args.run).is_dir() else Path(args.run).parent
    out = write_calibration(result, args.out or folder / "calibration.json")
    print(format_result(result))
    print(f"calibration: {out}", file=sys.stderr)
    return 0
