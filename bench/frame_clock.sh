#!/usr/bin/env bash
# What reading each stream at exposure times fitted to its frame clock buys tracking
# (core/frame_clock.h), side by side in one run: every scan is reconstructed with the stamps
# as indexed (--keep-stamps) and with the fitted times (the default), through each rig given,
# from the first frame's groundtruth pose. Prints ATE and surface error (median, world frame
# and after registering the model onto the truth: the summary's Surface and Shape lines) for
# both and their ratio, and the fitted clocks.
#   bench/frame_clock.sh [--build DIR] [--out DIR] --scans "SCAN ..." [--rigs "NAME=RIG ..."]
#                        [--args "EXTRA RECONSTRUCT ARGS"]
# RIG "scan" is each scan's own rig.yaml; bench/depth_correction.sh writes calibrated ones and
# bench_depth_oracle_rig the sensor's true depth field (an oracle). Scans: e.g. the 10 s
# full-size renders `heatwave synth --scene equipment|building --size full --duration 10
# --no-thermal --seed 1` (13 and 21 min on 2 cores).
set -euo pipefail
build=build
out=build/bench-results/frame-clock
scans=""
rigs="rig=scan"
extra="--no-thermal"
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scans) scans=$2; shift 2 ;;
    --rigs) rigs=$2; shift 2 ;;
    --args) extra=$2; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
[ -n "$scans" ] || { echo "--scans is required" >&2; exit 2; }
heatwave="$build/cli/heatwave"
mkdir -p "$out"
printf "%-10s %-16s %11s %11s %6s %13s %13s %13s %13s\n" scan rig "ATE stamps" "ATE fitted" ratio "surf. stamps" "surf. fitted" \
  "shape stamps" "shape fitted"
for scan in $scans; do
  name=$(basename "$scan")
  for entry in $rigs; do
    rig_name=${entry%%=*}
    rig=${entry#*=}
    [ "$rig" = scan ] && rig="$scan/rig.yaml"
    declare -A ate surface shape
    for mode in stamps fitted; do
      flag=""
      [ $mode = stamps ] && flag="--keep-stamps"
      run="$out/$name-$rig_name-$mode"
      # shellcheck disable=SC2086
      summary=$("$heatwave" reconstruct "$scan" --rig "$rig" --out "$run" --overwrite --start-at-groundtruth \
        $extra $flag 2>/dev/null)
      ate[$mode]=$(echo "$summary" | awk '/^Accuracy/ {print $6}')
      surface[$mode]=$(echo "$summary" | awk '/^Surface/ {print $6}')
      shape[$mode]=$(echo "$summary" | sed -n 's/^Shape .*: median \([0-9.]*\) mm.*/\1/p')
      [ $mode = fitted ] && clocks=$(echo "$summary" | sed -n 's/^Stamps     //p')
    done
    printf "%-10s %-16s %11s %11s %6.3f %13s %13s %13s %13s\n" "$name" "$rig_name" "${ate[stamps]}" "${ate[fitted]}" \
      "$(awk -v a="${ate[fitted]}" -v b="${ate[stamps]}" 'BEGIN {print a / b}')" "${surface[stamps]:--}" \
      "${surface[fitted]:--}" "${shape[stamps]:--}" "${shape[fitted]:--}"
  done
  echo "           clocks: $clocks"
done
