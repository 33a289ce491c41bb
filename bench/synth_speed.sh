#!/usr/bin/env bash
# Benchmark: what the realism of synthetic scans costs (not part of the test suite).
# Renders every scene twice in one run, side by side on the same machine: with the realistic
# defaults, and "plain" — every switchable realism effect off (--no-noise and the --no-*
# flags below) — and prints frames, wall time, frames/s and the ratio realistic / plain.
# What "plain" keeps (it cannot be switched from the CLI): free aiming, the adaptive truth
# mesh and observed areas, motion blur, optics. Then times the full calibration sessions.
# Usage: bench/synth_speed.sh [BUILD_DIR=build] [DURATION_S=1] [SCENES="equipment building large"]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
duration=${2:-1}
scenes=${3:-"equipment building large"}
heatwave="$build/cli/heatwave"
out=$(mktemp -d /tmp/heatwave-bench.XXXXXX)
trap 'rm -rf "$out"' EXIT
plain=(--no-noise --no-rolling-shutter --no-specular --no-shadows --no-auto-exposure
       --no-reflections --no-depth-artefacts --reflected-error 0)
printf '%-24s %8s %9s %9s %9s\n' item frames wall_s frames/s ratio
last_s=0
run() {
  local name=$1; shift
  local start end frames
  start=$(date +%s.%N)
  "$heatwave" synth "$@" --out "$out/$name" --quiet
  end=$(date +%s.%N)
  frames=$(cat "$out/$name"/depth.txt "$out/$name"/rgb.txt "$out/$name"/thermal.txt 2>/dev/null |
           grep -vc '^#' || true)
  last_s=$(awk -v s="$start" -v e="$end" 'BEGIN { print e - s }')
  awk -v n="$name" -v f="$frames" -v w="$last_s" -v r="${ratio_to:-}" \
      'BEGIN { printf "%-24s %8d %9.1f %9.2f", n, f, w, f / w;
               if (r != "") printf " %9.2f", w / r; printf "\n" }'
  rm -rf "${out:?}/$name"
}
for scene in $scenes; do
  ratio_to="" run "$scene-plain" --scene "$scene" --size full --duration "$duration" "${plain[@]}"
  ratio_to=$last_s run "$scene" --scene "$scene" --size full --duration "$duration"
done
for session in intrinsics-thermal intrinsics-chessboard intrinsics-aprilgrid; do
  ratio_to="" run "$session" --session "$session" --size full
done
