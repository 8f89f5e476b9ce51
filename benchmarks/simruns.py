"""Run shipped procedures on variants of the simulated bench, for benchmarks."""

from __future__ import annotations

import io
import re
import tempfile
import time
from pathlib import Path

from benches.identify import LiveIdentifier
from benches.session import execute, prepare
from procedures.paths import resolve_bench


def bench_at_rate(folder: Path, rate: float) -> Path:
    """benches/sim.yaml with the unit's sample rate, anti-alias corner (fs/4) and latency adapted."""
    text = resolve_bench("sim").read_text(encoding="utf-8")
    text = re.sub(r"sample_rate_hz: [0-9.]+", f"sample_rate_hz: {rate}", text)
    text = re.sub(r"anti_alias_hz: [0-9.]+", f"anti_alias_hz: {rate / 4}", text)
    text = re.sub(r"latency_ms: [0-9.]+", f"latency_ms: {1e3 / (2**0.5 * rate):.6g}", text)
    p = folder / f"sim-{int(rate)}Hz.yaml"
    p.write_text(text, encoding="utf-8")
    return p


def timed_run(
    bench: Path, procedure: str, *, seed: int, transport: str | None = None, live: bool = False
) -> tuple[Path, float, float]:
    """Run a procedure; return (run folder, wall s, bench s). Folder lives in a fresh temp dir."""
    prep = prepare(bench, procedure)
    folder = Path(tempfile.mkdtemp(prefix="tb-bench-")) / "run"
    folder.mkdir(parents=True)
    observers = (lambda progress: [LiveIdentifier(prep.config)]) if live else None
    t0 = time.perf_counter()
    result = execute(
        prep, folder, seed=seed, transport=transport, live=False, stream=io.StringIO(), observers=observers
    )
    wall = time.perf_counter() - t0
    if result.status != "complete":
        raise RuntimeError(f"benchmark run failed: {result.reason}")
    return folder, wall, result.bench_seconds
