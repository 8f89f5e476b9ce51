"""``tablebench thermal``: the thermal calibration of a recorded thermal run (docs/methods/thermal.md).

Identifies every plateau (and ramp segment) of the run, fits each parameter as a polynomial in the unit's
temperature (orders by BIC), writes ``thermal_calibration.json`` into the run folder and issues the thermal
certificate (``thermal-certificate.pdf`` + ``.json``): tables and plots of every parameter against
temperature with U(k = 2) bands, the model and its validity range.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benches.cli.arguments import bounded
from core.errors import UsageError
from core.outputs import check_output

EXAMPLES = """examples:
  tablebench thermal runs/20261127-thermal-plateaus
  tablebench thermal RUN --reference-c 25 --max-order 2 --issue-date 2026-11-27
  tablebench correct RUN/thermal_calibration.json OTHER_RUN --out corrected.npy   # apply it
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``thermal`` subcommand."""
    p = sub.add_parser(
        "thermal",
        help="thermal calibration of a run: parameters against temperature, thermal_calibration.json, certificate",
        description="Cut a recorded thermal run into its plateaus (each soak step opens one), identify the "
        "accelerometer (18) and gyro (12) parameters at each with their covariance, fit every parameter as a "
        "polynomial in (T - T_ref) of the unit's own temperature (orders by BIC), and write "
        "RUN/thermal_calibration.json and the thermal certificate RUN/thermal-certificate.pdf + .json.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="run folder of a thermal procedure (or its recording.h5)")
    p.add_argument("--reference-c", type=bounded(-100.0, 200.0), default=None, metavar="T",
                   help="T_ref of the model, °C (default: the mean plateau temperature, whole °C)")  # fmt: skip
    p.add_argument("--max-order", type=int, default=3, choices=range(0, 6), metavar="N",
                   help="highest polynomial order BIC may choose (0-5, default 3)")  # fmt: skip
    p.add_argument("--rate-term", action="store_true", help="fit a dT/dt coefficient too (ramp runs)")
    p.add_argument("--issue-date", default=None, metavar="YYYY-MM-DD", help="pin the certificate's issue date")
    p.add_argument("--no-certificate", action="store_true", help="write thermal_calibration.json only")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench thermal``."""
    src = Path(args.run)
    if src.is_file() and src.suffix.lower() not in (".h5", ".hdf5"):
        raise UsageError(f"{src}: not a run folder or its recording.h5; give the folder of a thermal run")
    run_dir = src.parent if src.is_file() else src
    if not run_dir.is_dir():
        raise UsageError(f"{args.run}: no such run folder")
    for name in ("thermal_calibration.json", "thermal-certificate.pdf", "thermal-certificate.json"):
        check_output(run_dir / name, "RUN")
    from benches.thermal.calibrate import thermal_calibrate  # lazy: filterpy, scipy (--help time)

    ref = None if args.reference_c is None else args.reference_c + 273.15
    cal, pdf = thermal_calibrate(src, reference=ref, max_order=args.max_order, rate_term=args.rate_term,
                                 issue_date=args.issue_date, certificate=not args.no_certificate)  # fmt: skip
    print(cal)
    if pdf is not None:
        print(pdf)
    return 0
