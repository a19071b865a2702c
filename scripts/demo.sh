#!/usr/bin/env bash
# The whole odocal pipeline on synthetic data with known truth.
# Usage: scripts/demo.sh [OUT_DIR]   (run through `make demo`)
# All 131 runs of the experiment are rendered as 1280x720 ceiling videos and
# tracked with the calibrated camera into the dataset (DEMO_RUNS changes the
# number of runs, e.g. DEMO_RUNS=12 for a quick look).
set -euo pipefail
out=${1:-demo-out}
odocal=${ODOCAL:-target/release/odocal}
runs=${DEMO_RUNS:-131}
rm -rf "$out"
mkdir -p "$out/logs"
start=$SECONDS
stage() { printf '\n== %s ==\n' "$1"; }
# run NAME CMD...: runs a stage, keeps its output in logs/NAME.txt, and times it.
run() {
  local name=$1 t0=$SECONDS; shift
  "$@" 2>&1 | tee "$out/logs/$name.txt"
  echo "$name $(( SECONDS - t0 ))" >> "$out/logs/times.txt"
}

stage "1/8 calibration views from a known camera (synth calib)"
run synth-calib "$odocal" synth calib --out "$out/calib" --seed 1
stage "2/8 Zhang calibration and floor plane (calibrate), and its error against the truth"
run calibrate "$odocal" calibrate "$out"/calib/view_*.png --board 9x6 --square 0.05 \
  --floor "$out"/calib/floor_*.png --out "$out/camera.json" \
  --yaml-opencv "$out/camera-opencv.yaml" --yaml-ros "$out/camera-ros.yaml"
run check-calib "$odocal" synth check-calib --camera "$out/camera.json" --truth "$out/calib/truth.json"

stage "3/8 ground truth: a 1280x720 ceiling video of the robot, tracked with the calibrated camera"
run synth-track "$odocal" synth track --out "$out/track" --seed 1
run track "$odocal" track "$out/track/video.avi" --camera "$out/camera.json" \
  --out "$out/track/traj.csv" --tum "$out/track/traj.tum" --report "$out/track/report.json" \
  --truth "$out/track/frames.csv" --condition "the demo's video (default scene: 4 ms exposure, global shutter)"

stage "4/8 the odometry experiment: $runs straight runs at 0.2/0.5/0.7 m/s, each a 1280x720 ceiling video and a 200 ms log"
run synth-experiment "$odocal" synth experiment --out "$out/experiment" --runs "$runs" --seed 1 \
  --frames video --no-calib-views

stage "5/8 dataset.json: the $runs videos tracked with the calibrated camera, aligned with the logs"
run dataset "$odocal" dataset --manifest "$out/experiment/manifest.json" --camera "$out/camera.json" \
  --out "$out/dataset.json" --csv "$out/dataset.csv" --truth "$out/experiment/truth/oracle.json"

stage "6/8 the corrector: sweep k = 6..12 (Tables 1 and 2), train k = 8, correct a new log"
run sweep "$odocal" train "$out/dataset.json" --sweep 6..12 --restarts 10 --folds 5 \
  --oracle "$out/experiment/truth/oracle.json" --report "$out/train"
run train "$odocal" train "$out/dataset.json" --out "$out/model.json" --hidden 8
"$odocal" synth experiment --out "$out/heldout" --runs 3 --seed 99 --frames none > /dev/null
run correct "$odocal" correct --model "$out/model.json" "$out/heldout/runs/run002.odometry.csv" \
  --out "$out/heldout/run002.corrected.csv"

stage "7/8 laser positioning among 30 reflectors (synth lrf, lrf localize)"
run synth-lrf "$odocal" synth lrf --out "$out/lrf" --seed 1
run lrf "$odocal" lrf localize --map "$out/lrf/map.json" "$out/lrf/scans.csv" \
  --out "$out/lrf/poses.csv" --truth "$out/lrf/truth.csv"

stage "8/8 report"
run report "$odocal" report --demo-dir "$out" --out "$out/report.html" --svg-dir "$out/plots"

stage "summary"
pick() { grep -h -E "$2" "$out/logs/$1.txt" | head -n "${3:-1}" | sed 's/^ */  /'; }
echo "calibration (truth: synth calib):"
pick check-calib "calibration error|floor mapping" 2
echo "ground truth from the ceiling camera (tracked video vs renderer's truth):"
pick track "RMS|position" 2
echo "dataset from $runs tracked videos (targets: real end points from the camera; truth: the simulator):"
pick dataset "^dataset:|rejected|raw odometry|against the truth" 8
echo "corrector and baselines (cross-validated on the samples of dataset.json):"
echo "  Table 2 (cross-validated, 5 folds): method | MSE m² | MSE cm² | relative error % | RMS end error cm | samples | distance m"
grep -h -E "^\| (raw odometry|mean end point|kinematic calibration|linear regression|kernel ridge|perceptron|oracle)" "$out/train/report.md" | head -n 7 | sed 's/^/  /'
grep -h "Verdict" "$out/train/report.md" | sed 's/^/  /'
echo "a held-out log, corrected:"
pick correct "corrected|raw" 2
echo "laser positioning:"
pick lrf "vs truth|lrf localize" 2
echo
echo "time per stage (s): $(tr '\n' ' ' < "$out/logs/times.txt")"
if [ -n "${DEMO_BUILD_S:-}" ]; then
  echo "build (cargo build --release): $DEMO_BUILD_S s; stages: $(( SECONDS - start )) s; total: $(( DEMO_BUILD_S + SECONDS - start )) s"
else
  echo "total: $(( SECONDS - start )) s (build not included)"
fi
echo "report: $out/report.html (plots also in $out/plots/)"
