"""tablebench's tests, mirroring the packages (``tests/analysis/noise`` tests ``analysis/noise``, ...)."""

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
