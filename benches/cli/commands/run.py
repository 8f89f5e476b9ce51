"""``tablebench run``: run a procedure on a bench, recording everything (the technician's command)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from benches.cli.arguments import (
    add_bench_argument,
    add_procedure_arguments,
    add_registry_arguments,
    check_seed,
    parse_overrides,
    sink_options,
)
from benches.live.run_view import RunView
from benches.live.server import DEFAULT_HOST, DEFAULT_PORT, parse_address
from benches.progress import ProgressDisplay
from benches.results import sinks_for_run
from benches.session import (
    Prepared,
    SessionError,
    copy_inputs,
    execute,
    identify_and_certify,
    new_run_folder,
    prepare,
    recorded_overrides,
    recording_status,
    unfinished_work,
)
from core.errors import UsageError

if TYPE_CHECKING:
    from benches.identify import LiveIdentifier
    from benches.runner import SampleObserver

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
    add_bench_argument(p)
    add_procedure_arguments(p)
    p.add_argument("--out", default=None, metavar="DIR", help="run folder (default: runs/<UTC time>-<procedure>)")
    p.add_argument("--seed", type=int, default=None, help="simulator seed (simulated benches; default from the bench)")
    p.add_argument("--resume", default=None, metavar="RUN", help="continue an interrupted run folder")
    p.add_argument(
        "--transport",
        choices=("in-process", "loopback"),
        default=None,
        help="simulated benches: in-process (no bytes), or the real drivers over real wires on loopback",
    )
    p.add_argument("--no-identify", action="store_true", help="only record (no plan, no identification)")
    p.add_argument("--no-certificate", action="store_true", help="do not issue a certificate at the end")
    p.add_argument("--plain", action="store_true", help="plain progress lines even on a terminal")
    p.add_argument(
        "--live",
        nargs="?",
        const="",
        default=None,
        metavar="[HOST:]PORT",
        help=f"serve a read-only live view of the run in a browser (default {DEFAULT_HOST}:{DEFAULT_PORT}; "
        "another HOST only if you name it); every run also writes RUN/live.jsonl for 'tablebench view RUN'",
    )
    p.add_argument(
        "--live-linger",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="with --live: keep serving the finished run's results this long before exiting (default 0)",
    )
    add_registry_arguments(p)
    p.set_defaults(func=run)


def _say(*parts: object, err: bool = True) -> None:
    """Print, but never fail because the terminal is gone (SIGHUP: EIO/EPIPE on stderr)."""
    try:
        print(*parts, file=sys.stderr if err else sys.stdout, flush=True)
    except OSError:
        pass


class _StopSignalsRaise:
    """While identifying and certifying: SIGTERM/SIGHUP end the work like Ctrl-C (KeyboardInterrupt)."""

    def __enter__(self) -> _StopSignalsRaise:
        self._old: dict = {}
        if threading.current_thread() is threading.main_thread():
            for name in ("SIGTERM", "SIGHUP"):
                sig = getattr(signal, name, None)
                if sig is not None:
                    self._old[sig] = signal.signal(sig, self._raise)
        return self

    @staticmethod
    def _raise(signum: int, _frame: object) -> None:
        raise KeyboardInterrupt

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


def run(args: argparse.Namespace) -> int:
    """Execute ``tablebench run`` (with its live view: RUN/live.jsonl, and the page with ``--live``)."""
    if not 0 <= args.live_linger < 86400:
        raise UsageError(f"--live-linger {args.live_linger}: must be 0 or more seconds, less than a day")
    view = RunView(parse_address(args.live) if args.live is not None else None, args.live_linger, say=_say)
    try:
        return _run(args, view)
    finally:
        view.close()


def _run(args: argparse.Namespace, view: RunView) -> int:
    from benches.identify import IdentificationError, LiveIdentifier, plan_for  # lazy: filterpy, scipy (--help time)

    check_seed(args.seed)
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
        st = recording_status(folder / "recording.h5")
        if st.get("status") == "DAMAGED":
            raise UsageError(f"{st['problem']} (resume refuses to append to a damaged recording)")
        if args.seed is not None and st.get("seed") != args.seed:
            raise UsageError(
                f"--seed {args.seed} differs from the run's recorded seed {st.get('seed')}; a resumed run continues "
                "with its own seed (omit --seed)"
            )
        if st.get("status") == "complete":
            todo = unfinished_work(folder)
            if args.no_identify or not todo:
                raise UsageError(
                    f"{folder}: the run is already complete (recording, calibration and certificate); nothing to resume"
                )
            _say(f"{folder}: the recording is complete; finishing what was not done: {', '.join(todo)}")
            prep = prepare(folder / "bench.yaml", folder / "procedure.yaml", recorded_overrides(folder))
            return _finish(args, folder, prep, [], todo, view)
        prep = prepare(folder / "bench.yaml", folder / "procedure.yaml", recorded_overrides(folder))
    else:
        prep = prepare(args.bench, args.procedure, parse_overrides(args.set))
        try:  # a bad --out is refused before the plan is printed and before anything moves
            folder = new_run_folder(args.out, Path(prep.procedure_path).stem)
        except SessionError as exc:
            raise UsageError(str(exc)) from None
    _say(f"bench: {prep.config.name} ({prep.bench_path})")
    ov = ", ".join(f"{k}={v:g}" for k, v in sorted(prep.overrides.items()))
    _say(
        f"procedure: {prep.compiled.name} ({prep.procedure_path}), {len(prep.compiled.steps)} steps, "
        f"estimated {prep.estimated_s / 60:.1f} min of bench time" + (f"; overrides (--set): {ov}" if ov else "")
    )
    live: list[LiveIdentifier] = []
    identify = not args.no_identify
    if identify:
        try:
            plan = plan_for(prep.compiled, prep.config)
        except IdentificationError as exc:
            _say(f"plan: not available ({exc}); the run will only record")
            identify = False
        else:
            _say("pre-run plan (predicted 1σ):")
            _say(plan.table())
            from benches.certificate.noise_report import is_static_record  # lazy: matplotlib (--help time)

            if is_static_record(prep.compiled.steps):
                _say(
                    "this procedure is a static record (one attitude, no rotation): the run ends with a NOISE REPORT "
                    "of the unit's noise terms, not a calibration certificate; the plan's NOT IDENTIFIED rows are "
                    "expected (for a calibration: --procedure ten-step)"
                )

    def observers(progress: ProgressDisplay) -> list[SampleObserver]:
        out: list[SampleObserver] = []
        if identify:
            live.append(LiveIdentifier(prep.config, progress))
            out.append(live[0])
        info = {"bench": prep.config.name, "procedure": prep.compiled.name, "run_folder": str(folder)}
        rate = float(prep.config.unit.sample_rate)
        out.append(view.make_observer(prep.compiled.steps, rate, prep.estimated_s, info, live[0] if live else None))
        return out

    try:
        copy_inputs(prep, folder)
        _say(f"run folder: {folder}")
        view.open(folder)
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
    view.run_ended(result.status, result.reason)
    if result.status != "complete":
        _say(f"run {result.status}: {result.reason}")
        if result.at_rest:
            _say(f"the table was brought to rest; the recording keeps every completed step: {folder}/recording.h5")
        else:
            _say(
                f"WARNING: THE TABLE MAY STILL BE MOVING: {result.rest_problem}. Check the table and stop it at its "
                "controller (emergency stop) before anyone approaches it."
            )
            _say(f"the recording keeps every completed step: {folder}/recording.h5")
        _say(f"resume with: tablebench run --resume {folder}")
        return 130 if result.status == "interrupted" else 1
    _say(f"run complete: {result.samples} samples ({result.bench_seconds / 60:.1f} min of bench time)")
    if not result.at_rest:
        _say(f"WARNING: THE TABLE MAY STILL BE MOVING: {result.rest_problem}. Check the table before approaching it.")
    _say(f"recording: {folder}/recording.h5", err=False)
    if not identify:
        return 0
    todo = ["identification"] + ([] if args.no_certificate else ["certificate"])
    return _finish(args, folder, prep, live, todo, view)


def _finish(
    args: argparse.Namespace,
    folder: Path,
    prep: Prepared,
    live: list[LiveIdentifier],
    todo: list[str],
    view: RunView,
) -> int:
    """Identify and certify a run whose recording is complete (:func:`benches.session.identify_and_certify`);
    an interruption says what is left to do."""
    if args.no_certificate:
        todo = [t for t in todo if t != "certificate"]
    done: list[str] = []
    try:
        with _StopSignalsRaise():
            identify_and_certify(
                folder,
                todo,
                live=live[0] if live else None,
                say=_say,
                done=done,
                prep=prep,
                sinks=sinks_for_run(folder, sink_options(args), say=_say, tell=lambda line: _say(line, err=False)),
            )
    except KeyboardInterrupt:
        left = [t for t in todo if t not in done]
        if not left:  # only a further sink's record was cut short (the session said which and how to redo it)
            _say(f"interrupted after the results were written ({folder} is complete)")
            return 130
        _say(
            f"interrupted after the recording completed ({folder}/recording.h5 is complete and intact); "
            f"not done: {', '.join(left)}"
        )
        _say(f"finish with: tablebench run --resume {folder}   (or: tablebench certificate {folder})")
        return 130
    view.publish_results()
    return 0
