"""tablebench's tests, mirroring the packages (``tests/analysis/noise`` tests ``analysis/noise``, ...)."""

from pathlib import Path
from typing import NoReturn

REPO_ROOT = Path(__file__).resolve().parents[1]

NOTES: list[str] = []
"""Lines printed at the end of the test run (``tests/conftest.py``): tests that could not run here say so
visibly (e.g. no browser, no PostgreSQL server) instead of passing silently."""


def not_run_here(line: str) -> NoReturn:
    """THE one way a test may skip: a real component users have (a browser, a PostgreSQL server) is missing on
    this machine. ``line`` says what did not run and how to get it; it is printed at the end of the run."""
    import pytest

    NOTES.append(line)
    pytest.skip(line)


def line_of(text: str, needle: str) -> int:
    """The 1-based number of the first line of ``text`` containing ``needle`` (where an error must point)."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)
