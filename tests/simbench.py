"""Helpers to run real procedures on (variants of) the shipped simulated bench, for end-to-end tests."""

from __future__ import annotations

import io
import re
from pathlib import Path

from benches.session import execute, prepare
from procedures.paths import resolve_bench

SIM = resolve_bench("sim")


def bench_variant(tmp_path: Path, *, rate: float | None = None, name: str = "bench.yaml", **subs: str) -> Path:
    """A copy of benches/sim.yaml with the unit's sample rate (and anti-alias corner) changed, plus raw
    ``old=new`` text substitutions given as keyword pairs ``key=("old", "new")``."""
    text = SIM.read_text(encoding="utf-8")
    if rate is not None:
        text = re.sub(r"sample_rate_hz: [0-9.]+", f"sample_rate_hz: {rate}", text)
        text = re.sub(r"anti_alias_hz: [0-9.]+", f"anti_alias_hz: {rate / 4}", text)
        # the 2nd-order Butterworth at fs/4 has a DC group delay of 1/√2 sample
        text = re.sub(r"latency_ms: [0-9.]+", f"latency_ms: {1e3 / (2**0.5 * rate):.6g}", text)
    for old, new in subs.values():
        assert old in text, f"bench_variant: {old!r} not in sim.yaml"
        text = text.replace(old, new)
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def run_procedure(
    tmp_path: Path,
    bench: Path,
    procedure: str,
    *,
    seed: int,
    out: str = "run",
    transport: str | None = None,
    overrides: dict[str, float] | None = None,
    observers: list | None = None,
) -> Path:
    """Run ``procedure`` on ``bench``; return the run folder. ``observers`` (e.g. a LiveIdentifier) see it."""
    prep = prepare(bench, procedure, overrides)
    folder = tmp_path / out
    folder.mkdir(parents=True, exist_ok=True)
    result = execute(
        prep,
        folder,
        seed=seed,
        transport=transport,
        live=False,
        stream=io.StringIO(),
        observers=(lambda _progress: observers) if observers else None,
    )
    assert result.status == "complete", result.reason
    return folder
