#!/usr/bin/env bash
# Install tablebench with its test dependencies into the project environment .venv (created with the system
# python3 on first use, reused afterwards; nothing is installed outside this folder, nothing on the system
# changes) and run ruff and the test suite. Extra arguments go to pytest (e.g. -m slow for the longer
# Monte Carlo tests). CI runs exactly this (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."
TABLEBENCH_EXTRAS="test"
. scripts/venv.sh
"$VENV_PY" -m ruff check .
exec "$VENV_PY" -m pytest "$@"
