#!/usr/bin/env bash
# Regenerate the embedded default dataset from the rig simulator (deterministic: same files every time).
# The station's effects (reference_solutions/stations/default.yaml: Coulomb friction, sensor
# quantisation, position noise) are recorded in truth.json beside the manifest.
set -euo pipefail
cd "$(dirname "$0")/.."
grader simulate --station default --seed 2026 --overwrite -o reference_solutions/datasets/default
