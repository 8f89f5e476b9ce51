"""Helpers to run real procedures on (variants of) the shipped simulated bench, for end-to-end tests."""

from __future__ import annotations

import io
import re
import subprocess
import sys
import time
from pathlib import Path

from benches.session import execute, prepare
from procedures.paths import resolve_bench
from tests import REPO_ROOT

SIM = resolve_bench("sim")

CLI = [sys.executable, "-m", "benches.cli"]
"""``tablebench`` as a separate process (what a technician runs; signals reach it as they would)."""


def short_ten_step(*, hold_s: float, warmup_s: float, name: str | None = None) -> str:
    """The text of the published ten-step sequence shortened so a run takes seconds: the same steps with holds of
    ``hold_s``, a warm-up of ``warmup_s``, settling of 1 s and spins at 30 °/s; renamed ``name`` if given."""
    text = (REPO_ROOT / "procedures" / "ten-step.yaml").read_text(encoding="utf-8")
    subs = [
        ("settle_s: 5", "settle_s: 1"),
        ("hold_s: 60", f"hold_s: {hold_s:g}"),
        ("spin_settle_s: 10", "spin_settle_s: 1"),
        ("duration_s: 900", f"duration_s: {warmup_s:g}"),
        ("rate_dps: 1.6", "rate_dps: 30"),
    ]
    if name is not None:
        subs.append(("name: ten-step", f"name: {name}"))
    for old, new in subs:
        assert old in text, f"short_ten_step: {old!r} not in ten-step.yaml"
        text = text.replace(old, new)
    return text


def start_cli(args: list[str], cwd: Path) -> subprocess.Popen:
    """Start ``tablebench ARGS`` in its own session (so a signal sent to it reaches only it)."""
    return subprocess.Popen(
        CLI + args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )


def wait_for_step(proc: subprocess.Popen, marker: str, timeout: float = 120.0) -> None:
    """Read the run's plain progress lines until step ``marker`` starts (AssertionError if it never does)."""
    t0 = time.monotonic()
    assert proc.stderr is not None
    for line in proc.stderr:
        if line.startswith(f"step {marker}"):
            return
        if time.monotonic() - t0 > timeout:
            break
    raise AssertionError(f"step {marker} never started")


def bench_variant(
    tmp_path: Path, *, rate: float | None = None, name: str = "bench.yaml", source: str = "sim.yaml", **subs: str
) -> Path:
    """A copy of the shipped simulated bench ``source`` (default benches/sim.yaml) with the unit's sample rate (and
    anti-alias corner and latency) changed, plus raw ``old=new`` text substitutions given as keyword pairs
    ``key=("old", "new")``."""
    text = (SIM.parent / source).read_text(encoding="utf-8")
    if rate is not None:
        text = re.sub(r"sample_rate_hz: [0-9.]+", f"sample_rate_hz: {rate}", text)
        text = re.sub(r"anti_alias_hz: [0-9.]+", f"anti_alias_hz: {rate / 4}", text)
        # the 2nd-order Butterworth at fs/4 has a DC group delay of 1/√2 sample
        text = re.sub(r"latency_ms: [0-9.]+", f"latency_ms: {1e3 / (2**0.5 * rate):.6g}", text)
    for old, new in subs.values():
        assert old in text, f"bench_variant: {old!r} not in {source}"
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
