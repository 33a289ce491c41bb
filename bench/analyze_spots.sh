#!/usr/bin/env bash
# Scores `heatwave analyze` against the planted spots of synthetic scans: on each scan's truth
# mesh (truth/scene.ply: every planted spot, closed-form areas and lengths) and on any
# reconstructed model given (--model MODEL.ply SCAN: only the spots the scan observed, areas
# against observed_area_m2). Prints one summary per model; details in each analyze.json.
#   bench/analyze_spots.sh [--build DIR] [--out DIR] SCAN... [--model MODEL.ply SCAN]...
# Render scans first, e.g. `heatwave synth --scene equipment --size full --duration 4
# --out build/bench-data/eqT4`, reconstruct them with `heatwave reconstruct --start-at-groundtruth`.
set -euo pipefail
build=build
out=build/bench-results/analyze-spots
truth_scans=()
models=()
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --model) models+=("$2|$3"); shift 3 ;;
    *) truth_scans+=("$1"); shift ;;
  esac
done
heatwave="$build/cli/heatwave"
mkdir -p "$out"
run() {  # name model truth-yaml [extra args]
  local name=$1 model=$2 truth=$3
  shift 3
  echo "== $name ($model)"
  "$heatwave" analyze "$model" --out "$out/$name" --truth "$truth" --no-images --overwrite "$@" |
    grep -E "spots:|truth:|thresholds|warning: [0-9]+ weaker" || true
}
for scan in "${truth_scans[@]}"; do
  run "$(basename "$scan")-truth" "$scan/truth/scene.ply" "$scan/truth/hotspots.yaml"
done
for pair in "${models[@]}"; do
  model=${pair%%|*}
  scan=${pair#*|}
  run "$(basename "$(dirname "$model")")" "$model" "$scan/truth/hotspots.yaml" --truth-observed-only
done
