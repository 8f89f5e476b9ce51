"""``tablebench run``: run a procedure on a bench, recording everything (the technician's command)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

EXAMPLES = """examples:
  tablebench run                                   # ten-step procedure on the simulated bench
  tablebench run --procedure ten-step-fast-spin --seed 7
  tablebench run --transport loopback              # same, over real ACL (pyvisa-py) + serial bytes on loopback
  tablebench run --bench benches/lab1.yaml --procedure procedures/twenty-four-position.yaml
  tablebench run --resume runs/20261121-101500-ten-step    # continue an interrupted run

exit codes: 0 complete, 1 failed (fault, lost link), 2 bad input (nothing moved), 130 interrupted
"""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``run`` subcommand."""
    p = sub.add_parser(
        "run",
        help="run a procedure on a bench and record it",
        description="Run a calibration procedure on a bench: load and check the bench and the procedure (nothing "
        "moves if anything is wrong), print the pre-run plan, run every step with a progress display, record "
        "to RUN/recording.h5, then identify and issue a certificate. Ctrl-C stops the table safely and keeps "
        "every completed step; --resume continues.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--bench", default=None, help="bench file (default: the shipped simulated bench benches/sim.yaml)")
    p.add_argument("--procedure", default=None, help="procedure file or shipped name (default: ten-step)")
    p.add_argument("--out", default=None, metavar="DIR", help="run folder (default: runs/<UTC time>-<procedure>)")
    p.add_argument("--seed", type=int, default=None, help="simulator seed (simulated benches; default from the bench)")
    p.add_argument("--resume", default=None, metavar="RUN", help="continue an interrupted run folder")
    p.add_argument(
        "--transport",
        choices=("in-process", "loopback"),
        default=None,
        help="simulated benches: in-process (no bytes), or the real drivers over real wires on loopback",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a procedure parameter (its parameters: block), e.g. --set duration_s=600; repeatable",
    )
    p.add_argument("--no-identify", action="store_true", help="only record (no plan, no identification)")
    p.add_argument("--no-certificate", action="store_true", help="do not issue a certificate at the end")
    p.add_argument("--plain", action="store_true", help="plain progress lines even on a terminal")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench run``."""
    from benches.commands.check import parse_overrides
    from benches.session import (
        SessionError,
        copy_inputs,
        execute,
        new_run_folder,
        prepare,
        recorded_overrides,
        recording_status,
    )
    from core.errors import UsageError

    if args.seed is not None and args.seed < 0:
        raise UsageError("--seed must be a non-negative integer")
    if args.resume is not None:
        folder = Path(args.resume)
        if folder.is_file():
            folder = folder.parent
        if not (folder / "recording.h5").exists():
            raise UsageError(f"--resume {args.resume}: no recording.h5 there; give a run folder printed by 'run'")
        if args.bench or args.procedure:
            raise UsageError("--resume uses the run's own bench and procedure copies; omit --bench/--procedure")
        if args.set:
            raise UsageError("--resume uses the run's recorded procedure parameters; omit --set")
        if recording_status(folder / "recording.h5").get("status") == "complete":
            raise UsageError(f"{folder}: the run is already complete; nothing to resume")
        prep = prepare(folder / "bench.yaml", folder / "procedure.yaml", recorded_overrides(folder))
    else:
        prep = prepare(args.bench, args.procedure, parse_overrides(args.set))
    from benches.identify import IdentificationError, LiveIdentifier, identify_run, plan_for, write_calibration

    print(f"bench: {prep.config.name} ({prep.bench_path})", file=sys.stderr)
    print(
        f"procedure: {prep.compiled.name} ({prep.procedure_path}), {len(prep.compiled.steps)} steps, "
        f"estimated {prep.estimated_s / 60:.1f} min of bench time",
        file=sys.stderr,
    )
    live: list[LiveIdentifier] = []
    identify = not args.no_identify
    if identify:
        try:
            plan = plan_for(prep.compiled, prep.config)
        except IdentificationError as exc:
            print(f"plan: not available ({exc}); the run will only record", file=sys.stderr)
            identify = False
        else:
            print("pre-run plan (predicted 1σ):", file=sys.stderr)
            print(plan.table(), file=sys.stderr)

    def observers(progress):
        if not identify:
            return []
        live.append(LiveIdentifier(prep.config, progress))
        return live

    try:
        folder = folder if args.resume is not None else new_run_folder(args.out, Path(prep.procedure_path).stem)
        copy_inputs(prep, folder)
        print(f"run folder: {folder}", file=sys.stderr)
        result = execute(
            prep,
            folder,
            seed=args.seed,
            transport=args.transport,
            resume=args.resume is not None,
            live=False if args.plain else None,
            observers=observers,
        )
    except SessionError as exc:
        raise UsageError(str(exc)) from None
    if result.status != "complete":
        print(f"run {result.status}: {result.reason}", file=sys.stderr)
        print(
            f"the table was brought to rest; the recording keeps every completed step: {folder}/recording.h5",
            file=sys.stderr,
        )
        print(f"resume with: tablebench run --resume {folder}", file=sys.stderr)
        return 130 if result.status == "interrupted" else 1
    print(
        f"run complete: {result.samples} samples ({result.bench_seconds / 60:.1f} min of bench time)", file=sys.stderr
    )
    print(f"recording: {folder}/recording.h5")
    if identify:
        try:
            result = identify_run(folder, method="kalman")
        except IdentificationError as exc:
            print(f"identification not possible: {exc}", file=sys.stderr)
            return 0
        if live and live[0].filter.n_samples:
            # the live filter saw the same samples and readings (except replayed ones on resume)
            import numpy as np

            offline = np.array([result["parameters"][n]["value"] for n in result["parameter_names"]])
            diff = np.abs(live[0].filter.estimate - offline) / np.array(
                [result["parameters"][n]["sigma_white"] for n in result["parameter_names"]]
            )
            result["live_vs_offline_max_sigma"] = float(diff.max())
        path = write_calibration(result, folder / "calibration.json")
        from benches.commands.identify import format_result

        print(format_result(result), file=sys.stderr)
        print(f"calibration: {path}")
        if not args.no_certificate:
            try:
                from benches.certificate import issue_certificate
            except ImportError:
                print("certificate: not available in this installation", file=sys.stderr)
            else:
                pdf, js, verdict = issue_certificate(folder)
                print(f"certificate: {pdf} ({verdict})")
    return 0
