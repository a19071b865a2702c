#!/usr/bin/env bash
# The whole odocal pipeline on synthetic data with known truth.
# Usage: scripts/demo.sh [OUT_DIR]   (run through `make demo`)
set -euo pipefail
out=${1:-demo-out}
odocal=${ODOCAL:-target/release/odocal}
mkdir -p "$out"
stage() { printf '\n== %s ==\n' "$*"; }
timed() { local t0=$SECONDS; "$@"; echo "   ($(( SECONDS - t0 )) s)"; }

stage "1. calibration views from a known camera (synth calib)"
timed "$odocal" synth calib --out "$out/calib" --seed 1
stage "2. Zhang calibration and floor plane (calibrate)"
timed "$odocal" calibrate "$out"/calib/view_*.png --board 9x6 --square 0.05 \
  --floor "$out"/calib/floor_*.png --out "$out/camera.json" \
  --yaml-opencv "$out/camera-opencv.yaml" --yaml-ros "$out/camera-ros.yaml"
stage "calibration against the truth"
"$odocal" synth check-calib --camera "$out/camera.json" --truth "$out/calib/truth.json"
