#!/usr/bin/env bash
# Benchmark: full-size synthetic scans and calibration sessions (not part of the test suite).
# Renders every scene for DURATION seconds of recording and every calibration session at its
# full preset, and prints frames, wall time and frames/s per item.
# Usage: bench/synth_speed.sh [BUILD_DIR=build] [DURATION_S=2]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
duration=${2:-2}
heatwave="$build/cli/heatwave"
out=$(mktemp -d /tmp/heatwave-bench.XXXXXX)
trap 'rm -rf "$out"' EXIT
printf '%-24s %8s %9s %9s\n' item frames wall_s frames/s
run() {
  local name=$1; shift
  local start end frames
  start=$(date +%s.%N)
  "$heatwave" synth "$@" --out "$out/$name" --quiet
  end=$(date +%s.%N)
  frames=$(cat "$out/$name"/depth.txt "$out/$name"/rgb.txt "$out/$name"/thermal.txt 2>/dev/null |
           grep -vc '^#' || true)
  awk -v n="$name" -v f="$frames" -v s="$start" -v e="$end" \
      'BEGIN { printf "%-24s %8d %9.1f %9.2f\n", n, f, e - s, f / (e - s) }'
}
for scene in equipment building large; do
  run "$scene" --scene "$scene" --size full --duration "$duration"
done
for session in intrinsics-thermal intrinsics-chessboard intrinsics-aprilgrid; do
  run "$session" --session "$session" --size full
done
