"""Shared pytest configuration."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")
# The calibration registry (docs/registry.md) is off for the suite, so that a test issuing a certificate does
# not also build a database in its runs folder; the registry's own tests (tests/benches/registry) name one.
os.environ.setdefault("TABLEBENCH_REGISTRY", "off")


def pytest_terminal_summary(terminalreporter) -> None:  # noqa: ANN001 - pytest's hook signature
    """Print the visible notes of tests that could not run here (one line each)."""
    from tests import NOTES

    for line in dict.fromkeys(NOTES):
        terminalreporter.write_line(line, yellow=True, bold=True)
