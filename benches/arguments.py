"""Command-line values shared by several commands, turned into typed values at the boundary.

Each helper raises :class:`core.errors.UsageError` (or, as an argparse ``type=``, ``ArgumentTypeError``,
which argparse reports as ``argument --NAME: …`` with exit code 2) naming the argument and what is allowed.
"""

from __future__ import annotations

import argparse
import math

from core.errors import UsageError

MAX_SEED = 2**63 - 1
"""Largest simulator seed (the bench file's ``simulation.seed`` has the same range)."""


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


def seed(text: str) -> int:
    """argparse ``type=`` for ``--seed``: a whole number in [0, 2⁶³ − 1]."""
    try:
        value = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number in [0, {MAX_SEED}], got {text!r}") from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"{text} is out of range; allowed 0 … {MAX_SEED} (2**63 - 1)")
    return value
