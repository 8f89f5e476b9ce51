#!/usr/bin/env bash
# Install tablebench with its test dependencies (and poppler's pdftoppm for the certificate page
# rendering test, where apt is available) and run the test suite. Extra arguments go to pytest
# (e.g. -m slow for the longer Monte Carlo tests).
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e ".[test]"
if ! command -v pdftoppm >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    (apt-get update -qq && apt-get install -y -qq poppler-utils >/dev/null) || echo "note: could not install poppler-utils; the page-rendering test will be skipped"
fi
python3 -m ruff check .
python3 -m pytest "$@"
