"""A technician's run, end to end: load and check, plan, open the bench, run, record, identify, certify.

This module wires the pieces together; every piece lives elsewhere (bench files: ``bench_config``;
procedures: ``procedures``; drivers: ``factory``; the run: ``runner``; the file: ``recording``).
Nothing moves until the bench file and the procedure have been loaded, compiled and checked against the
table's limits.
"""

from __future__ import annotations

import datetime as _dt
import json
import shutil
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from core.errors import UserError
from core.provenance import software_version, text_sha256
from core.yaml_source import ConfigError
from procedures.compiler import compile_procedure
from procedures.loader import load_procedure
from procedures.paths import default_bench_path, resolve_bench, resolve_procedure
from procedures.steps import CompiledProcedure, Soak, Step

from .bench_config import BenchConfig, chamber_limits, load_bench, noise_problem
from .progress import ProgressDisplay
from .recorded_run import RecordedRun, open_run
from .recording import Hdf5Recorder, RecordingError, open_recording
from .results.chain import sinks_for_run
from .results.sink import CalibrationDocument, ResultSinks
from .runner import Runner, RunResult, SampleObserver
from .thermal.steps import is_thermal_run

if TYPE_CHECKING:
    from .calibration_result import CalibrationResult
    from .identify import LiveIdentifier  # lazy at run time: filterpy, scipy (--help time)

DEFAULT_PROCEDURE = "ten-step"


class SessionError(UserError, RuntimeError):
    """A run cannot start or resume; the message says why and what to do."""


@dataclass
class Prepared:
    """A bench and a procedure loaded, compiled and checked (nothing has moved)."""

    bench_path: Path
    procedure_path: Path
    config: BenchConfig
    compiled: CompiledProcedure
    estimated_s: float
    overrides: dict[str, float]


def prepare(
    bench: str | Path | None, procedure: str | Path | None, overrides: dict[str, float] | None = None
) -> Prepared:
    """THE preparation step of ``check``, ``plan`` and ``run``: load the bench and the procedure (with parameter
    overrides), compile it for the bench's table and mounting, and check it against the unit (every acquisition
    lasts at least one sample). All three commands accept and reject exactly the same inputs; ConfigError if
    wrong."""
    bench_path = resolve_bench(bench) if bench else default_bench_path()
    procedure_path = resolve_procedure(procedure or DEFAULT_PROCEDURE)
    config = load_bench(bench_path)
    problem = noise_problem(config)  # the one "is this bench usable" rule of check, plan, run and identify
    if problem is not None:
        raise ConfigError(bench_path, None, problem.replace(f"bench {config.name!r}: ", "", 1))
    proc = load_procedure(procedure_path, overrides or None)
    compiled = compile_procedure(
        proc, limits=config.turntable.limits, mounting=config.unit.mounting, chamber=chamber_limits(config)
    )
    check_against_unit(compiled, float(config.unit.sample_rate))
    return Prepared(
        bench_path,
        procedure_path,
        config,
        compiled,
        compiled.estimated_duration(config.turntable.limits),
        dict(overrides or {}),
    )


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


def recorded_overrides(folder: Path) -> dict[str, float]:
    """The procedure parameter overrides a run was started with (stored in its recording)."""
    with open_recording(folder / "recording.h5") as rec:
        return dict(rec.header.procedure_overrides)


def new_run_folder(out: str | Path | None, procedure_name: str) -> Path:
    """``--out DIR`` if given (must not already hold a recording), else ``runs/<UTC time>-<procedure>``."""
    if out is not None:
        folder = Path(out)
    else:
        stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%d-%H%M%S")
        folder = Path("runs") / f"{stamp}-{procedure_name}"
        k = 1
        while folder.exists():
            k += 1
            folder = Path("runs") / f"{stamp}-{procedure_name}-{k}"
    if (folder / "recording.h5").exists():
        raise SessionError(f"{folder} already holds a recording; choose another --out or use --resume {folder}")
    if folder.exists() and not folder.is_dir():
        raise SessionError(f"--out {folder}: is a file, not a folder; choose a folder for the run")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SessionError(f"--out {folder}: cannot create the run folder ({exc.strerror}); choose another") from None
    return folder


def unfinished_work(folder: Path) -> list[str]:
    """What a run with a complete recording has not done yet: "identification" and/or "certificate"."""
    todo = []
    if not (folder / "calibration.json").exists():
        todo.append("identification")
    if not any(folder.glob("certificate*.pdf")):
        todo.append("certificate")
    return todo


def execute(
    prep: Prepared,
    folder: Path,
    *,
    seed: int | None,
    transport: str | None,
    resume: bool = False,
    observers: Callable[[ProgressDisplay], Iterable[SampleObserver]] | None = None,
    stream: TextIO | None = None,
    live: bool | None = None,
    storage: str = "counts+gzip",
) -> RunResult:
    """Open the bench, run the procedure into ``folder/recording.h5`` and close everything.

    With ``resume``, the recording is continued after its last complete step: a simulated bench replays the
    completed steps (deterministic, not recorded); a real bench skips them. ``storage`` (benchmarks):
    "counts+gzip" (the default: quantised counts + shuffle + gzip-1), "float+gzip", "counts+lzf", or "plain"
    (float64, uncompressed: the format-1 storage), all with Fletcher-32 and per-step SHA-256.
    """
    from benches.factory import open_bench  # lazy: scipy, pymodbus (--help time)

    stream = stream or sys.stderr
    config = prep.config
    compiled = prep.compiled
    rec_path = folder / "recording.h5"
    steps = list(compiled.steps)
    replay: list[int] = []
    resume_soak = None
    start_sample = 0
    if resume:
        with open_recording(rec_path) as rec:
            done = rec.complete_steps()
            if rec.header.status == "complete":
                raise SessionError(f"{folder}: the run is already complete; nothing to resume")
            if rec.header.procedure_sha256 != compiled.sha256:
                raise SessionError(f"{folder}: the procedure text differs from the recorded one; cannot resume")
            if seed is not None and seed != rec.header.seed:
                raise SessionError(
                    f"{folder}: --seed {seed} differs from the recorded seed {rec.header.seed}; a resumed run must "
                    "continue with the same seed (omit --seed)"
                )
            seed = rec.header.seed
            recorded = rec.header.transport
            if transport is not None and recorded and transport != recorded:
                raise SessionError(
                    f"{folder}: --transport {transport} differs from the run's recorded transport {recorded}; a "
                    f"resumed run continues on its own transport (omit --transport)"
                )
            if recorded:
                transport = recorded  # a loopback run resumes on loopback, never silently in-process
        start_sample = done[-1].end_sample if done else 0
        done_idx = [s.index for s in done]
        resume_soak = plateau_soak(steps, set(done_idx))
        if config.simulation is not None:
            replay = done_idx
        else:
            steps = [s for s in steps if s.index not in set(done_idx)]
    bench = open_bench(config, seed=seed, transport=transport, run_folder=folder)
    try:
        world = getattr(bench, "world", None)
        if resume:
            recorder = Hdf5Recorder(rec_path, resume=True)
        else:
            truth = None
            if world is not None:
                truth = dict(world.truth())
                truth.update(world.truth_arrays())
            attrs = _header_attrs(prep, seed, world is not None, bench.transport)
            scale = getattr(config.unit, "scale", None)
            quanta = {"time": 1e-9}  # the unit clock in ns (drivers decode time stamps as ns · 1e-9)
            if scale is not None:
                quanta.update(accel=scale.accel_lsb, gyro=scale.gyro_lsb)
            counts, _, comp = storage.partition("+")
            if counts != "counts":
                quanta = {}
            recorder = Hdf5Recorder(
                rec_path,
                attrs=attrs,
                bench_text=config.text,
                procedure_text=compiled.text,
                truth=truth,
                quanta=quanta,
                compression=comp or None,
            )
        try:
            progress = ProgressDisplay(prep.estimated_s, stream=stream, live=live)
            recorder.event(0.0, "info", f"{'resumed' if resume else 'started'} on {bench.describe()}")
            runner = Runner(
                bench.turntable,
                bench.unit,
                steps,
                recorder,
                position_tolerance=config.turntable.position_tolerance,
                observers=list(observers(progress)) if observers is not None else (),
                progress=progress,
                aux=bench.aux,
                resume_soak=resume_soak,
                aux_every=getattr(bench, "aux_every", None),
            )
            try:
                result = runner.run(replay=replay, start_sample=start_sample)
            finally:
                progress.close()
        finally:
            recorder.close()
    finally:
        bench.close()
    return result


def plateau_soak(steps: list[Step], done: set[int]) -> Step | None:
    """The soak to run again when a thermal run resumes: the last soak before the first step not done, unless that
    step is the soak itself (None: no soak before it, or the run resumes at a soak)."""
    first = next((s for s in steps if s.index not in done), None)
    if first is None or isinstance(first, Soak):
        return None
    soaks = [s for s in steps if isinstance(s, Soak) and s.index < first.index]
    return soaks[-1] if soaks else None


def _header_attrs(prep: Prepared, seed: int | None, simulated: bool, transport: str) -> dict[str, object]:
    """The recording's root attributes of a new run (``benches/RECORDING.md``)."""
    config, compiled = prep.config, prep.compiled
    return {
        "software_version": software_version(),
        "seed": -1 if seed is None else int(seed),
        "bench_name": config.name,
        "bench_file": str(prep.bench_path),
        "procedure_name": compiled.name,
        "procedure_file": str(prep.procedure_path),
        "procedure_sha256": compiled.sha256,
        "procedure_overrides": dict(prep.overrides),
        "bench_sha256": text_sha256(config.text),
        "sample_rate_hz": float(config.unit.sample_rate),
        "simulated": simulated,
        "transport": transport,
        "site_g": float(config.site.g),
        "site_g_source": config.site.g_source,
    }


def copy_inputs(prep: Prepared, folder: Path) -> None:
    """Keep copies of the bench and procedure files next to the recording (provenance, resume)."""
    for src, name in ((prep.bench_path, "bench.yaml"), (prep.procedure_path, "procedure.yaml")):
        dst = folder / name
        if not dst.exists():
            shutil.copyfile(src, dst)


def recording_status(path: Path) -> dict[str, object]:
    """Summary of one recording for ``tablebench runs`` (verified; a damaged one says so in ``problem``)."""
    try:
        with open_recording(path) as rec:
            h = rec.header
            return {
                "path": str(path.parent),
                "status": h.status,
                "procedure": h.procedure_name or "?",
                "bench": h.bench_name or "?",
                "created": h.created_utc or "?",
                "steps_done": len(rec.complete_steps()),
                "bench_s": rec.n_samples / h.sample_rate_hz,
                "overrides": dict(h.procedure_overrides),
                "seed": h.seed,
                "integrity": "verified" if rec.integrity_verified else "not verifiable",
                "tail": rec.unfinished_tail,
            }
    except RecordingError as exc:
        return {"path": str(path.parent), "status": "DAMAGED", "problem": str(exc)}


__all__ = [
    "Prepared",
    "SessionError",
    "unfinished_work",
    "copy_inputs",
    "execute",
    "new_run_folder",
    "prepare",
    "recording_status",
]


def identify_and_certify(
    folder: Path,
    todo: list[str],
    *,
    live: LiveIdentifier | None = None,
    say: Callable[..., None] = print,
    done: list[str] | None = None,
    prep: Prepared | None = None,
    sinks: ResultSinks | None = None,
) -> list[str]:
    """The end of the session: identify the complete recording (calibration.json) and issue its certificate.

    Parameters
    ----------
    folder : Path
        The run folder.
    todo : list of str
        "identification" and/or "certificate".
    live : benches.identify.LiveIdentifier, optional
        The live filter of the run, compared with the offline result.
    say : callable
        ``say(text, err=True)`` for the closing lines (``err=False``: a result path for stdout).
    done : list, optional
        Appended with each finished item as it finishes (so an interruption can say what is left).
    prep : Prepared, optional
        The bench and procedure the run was prepared with: the recording is opened once
        (:class:`benches.recorded_run.RecordedRun`) and its bench and procedure are not parsed again.
    sinks : benches.results.ResultSinks, optional
        Where the calibration and the certificate go (default: the run folder, then the registry;
        :func:`benches.results.sinks_for_run`). The calibration's line is said as soon as the run folder has
        it, then each further sink's own line (``registry: …``) when it has recorded it (its ``tell``).
    """
    done = [] if done is None else done
    try:
        recorded = open_run(
            folder,
            config=None if prep is None else prep.config,
            compiled=None if prep is None else prep.compiled,
            overrides=None if prep is None else prep.overrides,
            written=prep is not None,  # this process wrote it: the recorder's verification (benches.recording.written)
        )
    except RecordingError:
        recorded = None  # identification and certificate name the problem themselves
    try:
        sinks = sinks if sinks is not None else sinks_for_run(folder, say=say, tell=lambda line: say(line, err=False))
        return _identify_and_certify(folder, todo, recorded, live, say, done, sinks)
    finally:
        if recorded is not None:
            recorded.close()


def _identify_and_certify(
    folder: Path,
    todo: list[str],
    recorded: RecordedRun | None,
    live: LiveIdentifier | None,
    say: Callable[..., None],
    done: list[str],
    sinks: ResultSinks,
) -> list[str]:
    from benches.identify import IdentificationError, identify_run  # lazy: filterpy, scipy (--help time)

    source: Path | RecordedRun = folder if recorded is None else recorded
    if recorded is not None and _thermal(folder, recorded, todo, say, done):
        return done
    if "identification" in todo:
        try:
            result = identify_run(source, method="kalman")
        except IdentificationError as exc:
            say(f"identification not possible: {exc}")
            return done
        if live is not None and live.filter.n_samples:
            # the live filter saw the same samples and readings (except replayed ones on resume)
            u_white = np.array([p.u_white for p in result.parameters.values()])
            result.live_vs_offline_max_u = float(np.max(np.abs(live.filter.estimate - result.x) / u_white))
        kept = sinks.keep("calibration", CalibrationDocument(run=folder, result=result))  # the run folder
        done.append("identification")
        say(result.summary(combined_covariance_or_none(result, source)))
        say(sinks.report("calibration", kept) or f"calibration: {kept.path}", err=False)
        try:
            sinks.copy("calibration", kept)  # the registry: its own line when recorded, one line when it cannot
        except KeyboardInterrupt:
            say(f"interrupted while the registry recorded the calibration (the run folder keeps it); record it "
                f"later with: tablebench registry add {folder}")  # fmt: skip
            raise
    if "certificate" in todo:
        from benches.certificate import (  # lazy: fpdf, matplotlib, filterpy (--help time)
            NOISE_REPORT,
            issue_certificate,
        )

        pdf, js, verdict = issue_certificate(folder, recorded=recorded, sinks=sinks)
        done.append("certificate")
        if verdict == NOISE_REPORT:  # a static record: its noise, no calibration (benches.certificate.noise_report)
            say(f"noise report: {pdf} (a static record: its noise terms; no calibration, no conformity statement)",
                err=False)  # fmt: skip
            return done
        say(f"certificate: {pdf} ({verdict})", err=False)
        for line in verdict_explanation(js, verdict, spins=_has_spins(folder)):
            say(line)
    return done


def _thermal(folder: Path, recorded: RecordedRun, todo: list[str], say: Callable[..., None], done: list[str]) -> bool:
    """A thermal run (a completed soak step): its thermal calibration and certificate instead of one calibration
    over every temperature (benches.thermal.calibrate); False for any other run."""
    if not is_thermal_run(recorded):
        return False
    from benches.identify import IdentificationError  # lazy: filterpy, scipy (--help time)
    from benches.thermal.calibrate import thermal_calibrate  # lazy: filterpy, scipy, fpdf (--help time)

    try:
        cal, pdf = thermal_calibrate(recorded, certificate="certificate" in todo, say=lambda m: say(m))
    except IdentificationError as exc:
        say(f"thermal calibration not possible: {exc}")
        return True
    done.extend(["identification"] + (["certificate"] if pdf is not None else []))
    say(f"thermal calibration: {cal}", err=False)
    if pdf is not None:
        say(f"thermal certificate: {pdf}", err=False)
    return True


def combined_covariance_or_none(result: CalibrationResult, source: Path | RecordedRun) -> np.ndarray | None:
    """The certificate's type A + B covariance of ``result`` for its NEES line against a simulator's truth
    (``run`` and ``identify`` judge it as the certificate states u); None on a real bench (no truth) or when
    the budget cannot be formed (the line then says the type-B terms are not in it)."""
    if result.truth is None or not result.truth.nees_states:
        return None
    from benches.certificate import CertificateError, combined_covariance  # lazy: matplotlib (--help time)

    try:
        return combined_covariance(result, source)
    except CertificateError:
        return None


def _has_spins(folder: Path) -> bool | None:
    """Whether the run's recording holds a spin step (None if unreadable)."""
    try:
        with open_recording(folder / "recording.h5") as rec:
            return any(s.kind == "spin" for s in rec.complete_steps())
    except RecordingError:
        return None


def verdict_explanation(certificate_json: Path, verdict: str, *, spins: bool | None = True) -> list[str]:
    """Plain words for the run's closing lines: why the certificate says what it says, and what to do.
    ``spins``: whether the run had spin steps (a static record cannot see the size effect at all)."""
    if verdict != "INCONCLUSIVE":
        return []
    try:
        cert = json.loads(Path(certificate_json).read_text(encoding="utf-8"))
        params = cert.get("parameters") or {}
    except (OSError, ValueError):
        return [f"the certificate is INCONCLUSIVE: conformity not shown for every parameter ({certificate_json})"]
    not_eval = [n for n, p in params.items() if p.get("verdict") == "NOT EVALUATED" and p.get("limit") is not None]
    undecided = [n for n, p in params.items() if p.get("verdict") == "UNDECIDED"]
    out = ["the certificate is INCONCLUSIVE — this is not a failure: no parameter failed its limit, but "
           "conformity could not be shown for all of them."]  # fmt: skip
    if not_eval:
        sizes = [n for n in not_eval if n.startswith("r_")]
        if sizes and spins is False:
            out.append(
                f"  {', '.join(sizes)}: the size effect (the accelerometers' offsets from the rotation centre) "
                "needs the unit to spin; this procedure has no spin steps (a static record), so it cannot see it."
            )
            out.append(
                "  To calibrate it, run a procedure with fast spins: tablebench run --procedure ten-step-fast-spin"
            )
        elif sizes:
            out.append(
                f"  {', '.join(sizes)}: the size effect (the accelerometers' offsets from the rotation centre) "
                "cannot be identified by this procedure: its spins are too slow (at the published 1.6 °/s the "
                "effect is a few µg, below the unit's bias stability)."
            )
            out.append(
                "  To calibrate it as well, run the procedure with fast spins: "
                "tablebench run --procedure ten-step-fast-spin"
            )
        others = [n for n in not_eval if not n.startswith("r_")]
        if others:
            out.append(f"  {', '.join(others)}: not identified by this procedure (see the plan's warnings).")
    if undecided:
        out.append(
            f"  {', '.join(undecided)}: the expanded uncertainty U straddles the limit (undecided); a longer or "
            "better-conditioned procedure reduces U."
        )
    return out
