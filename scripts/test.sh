#!/usr/bin/env bash
# Install tablebench with its test dependencies and run the test suite (fast tests; add -m slow for more).
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e ".[test]"
python3 -m ruff check .
python3 -m pytest "$@"
