#!/usr/bin/env bash
# Install tablebench into the project environment .venv (created with the system python3 on first use,
# reused afterwards; nothing is installed outside this folder) and run the main job: the ten-step
# calibration on the simulated bench, leaving a recording, calibration.json and a certificate PDF in the
# run folder it prints. Extra arguments go to 'tablebench run' (e.g. --procedure ten-step-fast-spin --seed 3).
set -euo pipefail
cd "$(dirname "$0")/.."
TABLEBENCH_EXTRAS=""
. scripts/venv.sh
exec "$VENV_DIR/bin/tablebench" run "$@"
