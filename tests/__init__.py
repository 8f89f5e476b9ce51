"""tablebench's tests, mirroring the packages (``tests/analysis/noise`` tests ``analysis/noise``, ...)."""

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def line_of(text: str, needle: str) -> int:
    """The 1-based number of the first line of ``text`` containing ``needle`` (where an error must point)."""
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)
