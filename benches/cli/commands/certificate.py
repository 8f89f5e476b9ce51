"""``tablebench certificate``: issue the calibration certificate (PDF + JSON) of a run."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from benches.cli.arguments import add_registry_arguments, sink_options
from benches.cli.work import Work
from benches.recording import RecordingError
from benches.results import sinks_for_run
from core.errors import UsageError
from core.outputs import check_output

EXAMPLES = """examples:
  tablebench certificate runs/20261122-101500-ten-step
  tablebench certificate RUN --out cert.pdf --json cert.json --issue-date 2026-11-22
  tablebench certificate RUN --allow-incomplete      # an interrupted run: marked INCOMPLETE on page 1

a static record (one attitude, no rotation: the static-noise procedure) gets a NOISE REPORT instead
(RUN/noise-report.pdf and .json: the noise terms of its record with U, k = 2; no conformity statement).
exit codes: 0 issued (PASS / INCONCLUSIVE / INCOMPLETE / NO LIMITS / NOISE REPORT), 1 issued and marked FAIL,
            2 cannot issue (bad input, incomplete run without --allow-incomplete)
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``certificate`` subcommand."""
    p = sub.add_parser(
        "certificate",
        help="issue the calibration certificate (PDF + JSON) of a run",
        description="Build the calibration certificate of a run folder from its recording.h5 and calibration.json "
        "(plus noise/periodic/drift analyses if present): unit and bench identity, procedure digest, results with "
        "expanded uncertainties (k = 2, GUM budget), pass/fail against the bench file's limits, plots, warnings, "
        "and the recording's SHA-256. The same recording gives the same bytes apart from the issue date.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="run folder (holding recording.h5 and calibration.json)")
    p.add_argument("--out", default=None, metavar="FILE.pdf", help="PDF output (default: RUN/certificate.pdf)")
    p.add_argument("--json", default=None, metavar="FILE.json", help="JSON output (default: the PDF path with .json)")
    p.add_argument("--issue-date", default=None, metavar="YYYY-MM-DD", help="pin the issue date (default: today UTC)")
    p.add_argument(
        "--allow-incomplete",
        action="store_true",
        help="issue a certificate for an interrupted or failed run (says so prominently on page 1)",
    )
    add_registry_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench certificate``."""
    from benches.certificate import (  # lazy: fpdf, matplotlib, filterpy (--help time)
        CertificateError,
        build_certificate,
        publish_certificate,
    )

    if args.out is not None and not str(args.out).lower().endswith(".pdf"):
        raise UsageError(f"--out {args.out}: give a .pdf file name")
    if args.json is not None and not str(args.json).lower().endswith(".json"):
        raise UsageError(f"--json {args.json}: give a .json file name")
    run_dir = Path(args.run).parent if Path(args.run).is_file() else Path(args.run)
    own = [run_dir / "calibration.json", *run_dir.glob("*/*.json"), *run_dir.glob("*.json")]  # its inputs
    if args.out is not None:
        check_output(args.out, "--out", inputs=own)
        check_output(args.json or Path(args.out).with_suffix(".json"), "--json", inputs=own)
    elif args.json is not None:
        check_output(args.json, "--json", inputs=own)
    def build(work: Work):  # noqa: ANN202 - a Certificate (lazy import)
        work.stage("reading the run, checking the calibration, budget, decision rule and plots")
        return build_certificate(args.run, issue_date=args.issue_date, allow_incomplete=args.allow_incomplete)

    try:
        with Work("certificate", 1.0) as work:  # the interrupt and progress of 'run'
            cert = work.run(build, work)
            with work.writing():  # numbered, rendered and written: all or nothing
                pdf, js = publish_certificate(
                    cert, args.run, args.out, args.json, sinks_for_run(args.run, sink_options(args))
                )
    except (CertificateError, RecordingError) as exc:
        raise UsageError(str(exc)) from None
    verdict = cert.verdict
    if cert.is_noise_report:  # a static record: its noise, no calibration
        print(f"noise report (a static record: no calibration parameters, no conformity statement): {pdf}",
              file=sys.stderr)  # fmt: skip
    else:
        print(f"certificate {verdict}: {pdf}", file=sys.stderr)
    print(pdf)
    print(js)
    return 1 if verdict == "FAIL" else 0
