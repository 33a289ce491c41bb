#!/usr/bin/env bash
# What marching rays by each block's narrowest fused band buys (RaycastOptions::band_steps,
# `--raycast-band-steps`), side by side in one run: every scan is reconstructed alternately
# with band steps (the default) and with steps of the fixed truncation, ROUNDS times each,
# from the first frame's groundtruth pose. Prints per run frames/s, the model raycasts'
# count and mean time, the thermal raycast's mean time (scans with thermal frames) and the
# ATE; then the medians' ratios. The trajectories differ (the crossings are refined from
# other brackets: the same surfaces to < 1 mm, reconstruct/raycast_test), so tracking's
# chaotic part moves the ATE by a few tenths of a millimetre either way.
#   bench/band_steps.sh [--build DIR] [--out DIR] [--rounds N] --scans "SCAN ..." [--rig RIG]
#                       [--args "EXTRA RECONSTRUCT ARGS"]
# RIG: a rig.yaml for every scan (e.g. bench_depth_oracle_rig's true depth field), default
# each scan's own. Scans: e.g. the 10 s full-size renders `heatwave synth --scene
# equipment|building --size full --duration 10 --no-thermal --seed 1` (13 and 21 min on 2
# cores): the bands widen beyond 2.1 m, so the far `building` sweep gains most.
set -euo pipefail
out=build/bench-results/band-steps
extra=""
usage=2,15
# shellcheck source=bench/alternate_common.sh
source "$(dirname "$0")/alternate_common.sh"
# reconstruct.json → "fps raycasts raycast_ms thermal_raycast_ms ate_mm"
figures() {
  python3 - "$1" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
frames = [f for f in j["frames"] if f.get("raycast_ms", 0) > 0]
cast = sum(f["raycast_ms"] for f in frames) / max(1, len(frames))
t = j.get("thermal", {}).get("timings", {})
ate = j.get("groundtruth_evaluation", {}).get("ate_m", {}).get("rmse")
print(f'{j["timings"]["frames_per_s"]:.2f} {len(frames)} {cast:.1f} {t.get("mean_raycast_ms", float("nan")):.1f} '
      f'{1e3 * ate if ate is not None else float("nan"):.2f}')
PY
}
for scan in $scans; do
  name=$(basename "$scan")
  scan_rig=${rig:-$scan/rig.yaml}
  declare -A fps=([true]="" [false]="") cast=([true]="" [false]="")
  for round in $(seq 1 "$rounds"); do
    for mode in true false; do
      run="$out/$name-$mode"
      # shellcheck disable=SC2086
      "$heatwave" reconstruct "$scan" --rig "$scan_rig" --out "$run" --overwrite --start-at-groundtruth \
        --raycast-band-steps "$mode" $extra > /dev/null 2>&1
      read -r f n c tc ate <<< "$(figures "$run/reconstruct.json")"
      printf "%-10s round %d band-steps %-5s %6s frames/s  %3s raycasts %6s ms  thermal raycast %6s ms  ATE %s mm\n" \
        "$name" "$round" "$mode" "$f" "$n" "$c" "$tc" "$ate"
      fps[$mode]="${fps[$mode]} $f"
      cast[$mode]="${cast[$mode]} $c"
    done
  done
  ft=$(echo "${fps[true]}" | median); ff=$(echo "${fps[false]}" | median)
  ct=$(echo "${cast[true]}" | median); cf=$(echo "${cast[false]}" | median)
  printf "%-10s median frames/s %s vs %s (ratio %.3f); model raycast %s vs %s ms (ratio %.3f)\n" "$name" "$ft" "$ff" \
    "$(awk -v a="$ft" -v b="$ff" 'BEGIN {print a / b}')" "$ct" "$cf" "$(awk -v a="$ct" -v b="$cf" 'BEGIN {print a / b}')"
done
