#!/usr/bin/env bash
# Install tablebench and run the main job: the ten-step calibration on the simulated bench, leaving a
# recording, calibration.json and a certificate PDF in the run folder it prints. Extra arguments go to
# 'tablebench run' (e.g. --procedure ten-step-fast-spin --seed 3 --transport loopback).
set -euo pipefail
cd "$(dirname "$0")/.."
python3 -m pip install --quiet --disable-pip-version-check -e .
exec tablebench run "$@"
