"""Shared pytest configuration."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")


def pytest_terminal_summary(terminalreporter) -> None:  # noqa: ANN001 - pytest's hook signature
    """Print the visible notes of tests that could not run here (one line each)."""
    from tests import NOTES

    for line in dict.fromkeys(NOTES):
        terminalreporter.write_line(line, yellow=True, bold=True)
