"""A technician's run, end to end: load and check, plan, open the bench, run, record, identify, certify.

This module wires the pieces together; every piece lives elsewhere (bench files: ``bench_config``;
procedures: ``procedures``; drivers: ``factory``; the run: ``runner``; the file: ``recording``).
Nothing moves until the bench file and the procedure have been loaded, compiled and checked against the
table's limits.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import shutil
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import h5py

from core.errors import UserError
from core.provenance import software_version

from .progress import ProgressDisplay
from .recording import Hdf5Recorder, open_recording, read_steps
from .runner import Runner, RunResult, SampleObserver

DEFAULT_PROCEDURE = "ten-step"


class SessionError(UserError, RuntimeError):
    """A run cannot start or resume; the message says why and what to do."""


@dataclass
class Prepared:
    """A bench and a procedure loaded, compiled and checked (nothing has moved)."""

    bench_path: Path
    procedure_path: Path
    config: object  # benches.bench_config.BenchConfig
    compiled: object  # procedures.steps.CompiledProcedure
    estimated_s: float
    overrides: dict[str, float]


def prepare(
    bench: str | Path | None, procedure: str | Path | None, overrides: dict[str, float] | None = None
) -> Prepared:
    """Load the bench and the procedure (with parameter overrides), compile and check; ConfigError if wrong."""
    from benches.bench_config import load_bench
    from procedures.compiler import compile_procedure
    from procedures.loader import load_procedure
    from procedures.paths import default_bench_path, resolve_bench, resolve_procedure

    bench_path = resolve_bench(bench) if bench else default_bench_path()
    procedure_path = resolve_procedure(procedure or DEFAULT_PROCEDURE)
    config = load_bench(bench_path)
    proc = load_procedure(procedure_path, overrides or None)
    compiled = compile_procedure(proc, limits=config.turntable.limits, mounting=config.unit.mounting)
    return Prepared(
        bench_path,
        procedure_path,
        config,
        compiled,
        compiled.estimated_duration(config.turntable.limits),
        dict(overrides or {}),
    )


def recorded_overrides(folder: Path) -> dict[str, float]:
    """The procedure parameter overrides a run was started with (stored in its recording)."""
    with open_recording(folder / "recording.h5") as f:
        text = f.attrs.get("procedure_overrides", "{}")
    return {str(k): float(v) for k, v in json.loads(text).items()}


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
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


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
) -> RunResult:
    """Open the bench, run the procedure into ``folder/recording.h5`` and close everything.

    With ``resume``, the recording is continued after its last complete step: a simulated bench replays the
    completed steps (deterministic, not recorded); a real bench skips them.
    """
    from benches.factory import open_bench

    stream = stream or sys.stderr
    config = prep.config
    compiled = prep.compiled
    rec_path = folder / "recording.h5"
    steps = list(compiled.steps)
    replay: list[int] = []
    start_sample = 0
    if resume:
        with open_recording(rec_path) as f:
            done = [s for s in read_steps(f) if s.status == "complete"]
            if f.attrs.get("status") == "complete":
                raise SessionError(f"{folder}: the run is already complete; nothing to resume")
            if f.attrs.get("procedure_sha256") != compiled.sha256:
                raise SessionError(f"{folder}: the procedure text differs from the recorded one; cannot resume")
            seed = int(f.attrs.get("seed", -1))
            seed = None if seed < 0 else seed
        start_sample = done[-1].end_sample if done else 0
        done_idx = [s.index for s in done]
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
            attrs = {
                "software_version": software_version(),
                "seed": -1 if seed is None else int(seed),
                "bench_name": config.name,
                "bench_file": str(prep.bench_path),
                "procedure_name": compiled.name,
                "procedure_file": str(prep.procedure_path),
                "procedure_sha256": compiled.sha256,
                "procedure_overrides": json.dumps(prep.overrides, sort_keys=True),
                "bench_sha256": _sha256(config.text),
                "sample_rate_hz": float(config.unit.sample_rate),
                "simulated": world is not None,
                "transport": bench.transport,
                "site_g": float(config.site.g),
                "site_g_source": config.site.g_source,
            }
            recorder = Hdf5Recorder(
                rec_path, attrs=attrs, bench_text=config.text, procedure_text=compiled.text, truth=truth
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


def copy_inputs(prep: Prepared, folder: Path) -> None:
    """Keep copies of the bench and procedure files next to the recording (provenance, resume)."""
    for src, name in ((prep.bench_path, "bench.yaml"), (prep.procedure_path, "procedure.yaml")):
        dst = folder / name
        if not dst.exists():
            shutil.copyfile(src, dst)


def recording_status(path: Path) -> dict[str, object]:
    """Summary of one recording for ``tablebench runs``."""
    try:
        with h5py.File(path, "r") as f:
            steps = read_steps(f)
            rate = float(f.attrs.get("sample_rate_hz", 0.0)) or 1.0
            return {
                "path": str(path.parent),
                "status": str(f.attrs.get("status", "?")),
                "procedure": str(f.attrs.get("procedure_name", "?")),
                "bench": str(f.attrs.get("bench_name", "?")),
                "created": str(f.attrs.get("created_utc", "?")),
                "steps_done": sum(s.status == "complete" for s in steps),
                "bench_s": f["imu/time"].shape[0] / rate,
            }
    except (OSError, KeyError) as exc:
        return {"path": str(path.parent), "status": f"unreadable ({exc.__class__.__name__})"}


__all__ = [
    "Prepared",
    "SessionError",
    "copy_inputs",
    "execute",
    "new_run_folder",
    "prepare",
    "recording_status",
]
