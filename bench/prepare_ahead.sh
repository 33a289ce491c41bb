#!/usr/bin/env bash
# What preparing each depth frame beside the previous one's processing buys
# (ScanReconstructionOptions::prepare_ahead), side by side in one run: every scan is
# reconstructed alternately with it (the default) and without (--no-prepare-ahead), ROUNDS
# times each, from the first frame's groundtruth pose. Prints frames/s and the per-frame
# stages of every run, the ratio of the medians, and whether the two trajectories are
# byte-identical (they must be).
#   bench/prepare_ahead.sh [--build DIR] [--out DIR] [--rounds N] --scans "SCAN ..."
#                          [--rig RIG] [--args "EXTRA RECONSTRUCT ARGS"]
# RIG: a rig.yaml for every scan (e.g. bench_depth_oracle_rig's true depth field), default
# each scan's own. Scans: e.g. the 10 s full-size renders `heatwave synth --scene
# equipment|building --size full --duration 10 --no-thermal --seed 1` (13 and 21 min on 2 cores).
set -euo pipefail
out=build/bench-results/prepare-ahead
extra="--no-thermal"
usage=2,12
# shellcheck source=bench/alternate_common.sh
source "$(dirname "$0")/alternate_common.sh"
for scan in $scans; do
  name=$(basename "$scan")
  scan_rig=${rig:-$scan/rig.yaml}
  fps_ahead=""
  fps_serial=""
  for round in $(seq 1 "$rounds"); do
    for mode in ahead serial; do
      flag=""
      [ $mode = serial ] && flag="--no-prepare-ahead"
      run="$out/$name-$mode"
      # shellcheck disable=SC2086
      speed=$("$heatwave" reconstruct "$scan" --rig "$scan_rig" --out "$run" --overwrite --start-at-groundtruth \
        $extra $flag 2>/dev/null | sed -n 's/^Speed      //p')
      fps=$(echo "$speed" | awk '{print $1}')
      printf "%-10s round %d %-6s %s\n" "$name" "$round" "$mode" "$speed"
      if [ $mode = ahead ]; then fps_ahead="$fps_ahead $fps"; else fps_serial="$fps_serial $fps"; fi
    done
  done
  a=$(echo "$fps_ahead" | median)
  s=$(echo "$fps_serial" | median)
  same="byte-identical"
  cmp -s "$out/$name-ahead/trajectory.txt" "$out/$name-serial/trajectory.txt" || same="DIFFERENT"
  printf "%-10s median frames/s: prepared ahead %s, serial %s, ratio %.3f; trajectories %s\n" "$name" "$a" "$s" \
    "$(awk -v a="$a" -v s="$s" 'BEGIN {print a / s}')" "$same"
done
