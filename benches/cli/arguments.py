"""Command-line values shared by several commands, turned into typed values at the boundary.

Each helper raises :class:`core.errors.UsageError` (or, as an argparse ``type=``, ``ArgumentTypeError``,
which argparse reports as ``argument --NAME: …`` with exit code 2) naming the argument and what is allowed.
"""

from __future__ import annotations

import argparse
import math

from core.errors import UsageError
from core.seeds import MAX_SEED


def parse_overrides(items: list[str]) -> dict[str, float]:
    """``["duration_s=60", ...]`` (repeated ``--set``) → ``{"duration_s": 60.0}``; UsageError if malformed."""
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not sep or not name.strip() or not math.isfinite(v):
            raise UsageError(f"--set {item!r}: expected NAME=NUMBER, e.g. --set duration_s=60")
        out[name.strip()] = v
    return out


def check_seed(value: int | None) -> None:
    """``--seed`` (run, table; parsed as an int): None or a whole number in [0, 2⁶³ − 1], the range of the bench
    file's ``simulation.seed``; UsageError naming the option otherwise (one line, before anything is created)."""
    if value is not None and not 0 <= value <= MAX_SEED:
        raise UsageError(f"--seed {value}: must be a whole number from 0 to 2**63 - 1 ({MAX_SEED})")


def bounded(low: float, high: float, *, integer: bool = False, low_open: bool = False):
    """argparse ``type=`` for a finite number in [low, high] (``low_open``: (low, high]); whole numbers with
    ``integer``. The message states the allowed range; argparse names the option and exits with code 2."""
    kind = "a whole number" if integer else "a number"
    lo_br = "(" if low_open else "["
    allowed = f"{kind} in {lo_br}{low:g}, {high:g}]"

    def parse(text: str) -> float | int:
        try:
            value: float | int = int(text, 10) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}") from None
        ok = math.isfinite(value) and (value > low if low_open else value >= low) and value <= high
        if not ok:
            raise argparse.ArgumentTypeError(f"{text} is out of range; allowed: {allowed}")
        return value

    parse.__name__ = "integer" if integer else "number"
    return parse


def add_bench_argument(p: argparse.ArgumentParser) -> None:
    """``--bench FILE`` (check, plan, run, table): a bench file or a shipped bench's name."""
    p.add_argument(
        "--bench",
        metavar="FILE",
        default=None,
        help="bench YAML file or shipped name (default: benches/sim.yaml here, else the shipped sim bench)",
    )


def add_procedure_arguments(p: argparse.ArgumentParser, *, positional: bool = False) -> None:
    """The procedure (``--procedure FILE``, or the positional ``FILE`` of ``check``) and its ``--set`` overrides
    (parsed by :func:`parse_overrides`), for check, plan and run."""
    if positional:
        p.add_argument("procedure", metavar="FILE", help="procedure YAML file, or a shipped name like ten-step")
    else:
        p.add_argument(
            "--procedure", metavar="FILE", default=None, help="procedure YAML file or shipped name (default: ten-step)"
        )
    p.add_argument(
        "--set",
        metavar="NAME=VALUE",
        action="append",
        default=[],
        help="override a procedure parameter (from its parameters: block), e.g. --set duration_s=60; repeatable",
    )


def add_registry_arguments(p: argparse.ArgumentParser) -> None:
    """``--registry URL|PATH|off`` and ``--operator NAME``: where results are also recorded (the calibration
    registry, ``docs/registry.md``) and who is recorded as the operator."""
    p.add_argument(
        "--registry",
        default=None,
        metavar="URL",
        help="calibration registry to record into: postgresql://USER@HOST/DB, sqlite:///FILE, a file path, or "
        "'off' (default: $TABLEBENCH_REGISTRY, else registry.sqlite in the runs folder)",
    )
    p.add_argument(
        "--operator",
        default=None,
        metavar="NAME",
        help="operator recorded in the registry (default: $TABLEBENCH_OPERATOR, else the login name)",
    )


def sink_options(args: argparse.Namespace) -> dict[str, object]:
    """The result-sink options of a command's arguments (:func:`benches.results.sinks_for_run`)."""
    return {"registry": getattr(args, "registry", None), "operator": getattr(args, "operator", None)}
