#!/usr/bin/env bash
# Two settings of `heatwave reconstruct` side by side in one run: every scan is reconstructed
# alternately with the options A and B, ROUNDS times each, from the first frame's groundtruth
# pose. Prints per run frames/s, the frames integrated, the model casts and their mean time,
# the thermal raycast's mean time per fused thermal frame (scans with thermal), the ATE and
# the surface error (world frame and registered shape, medians); then the medians of
# frames/s and of the cast time, and their ratios A / B.
#   bench/ab_reconstruct.sh --a "ARGS" --b "ARGS" [--build DIR] [--out DIR] [--rounds N]
#                           --scans "SCAN ..." [--rig RIG] [--args "ARGS FOR BOTH"]
#                           [--a-bin HEATWAVE] [--b-bin HEATWAVE]
# --a-bin / --b-bin run that side with another build's heatwave (copied first, so a rebuild
# during the run does not change it): two builds side by side, e.g. stop 60's allocation
# against stop 59's build (README, Allocating from pixels half a block apart):
#   bench/ab_reconstruct.sh --scans "EQ10 BD10" --rig ORACLE --args --no-thermal \
#     --a "" --b "" --a-bin STOP59/heatwave
# E.g. the integration cadence (ReconstructionOptions::integrate_max_motion_m / _deg) on the
# 10 s full-size renders with their true depth field:
#   bench/ab_reconstruct.sh --scans "EQ10 BD10" --rig ORACLE --args --no-thermal \
#     --a "" --b "--integrate-max-motion 0.06 --integrate-max-motion-deg 3.75"
# or rays stepped by the blocks' bands against the fixed truncation (RaycastOptions::band_steps):
#   ... --a "" --b "--raycast-band-steps false"
set -euo pipefail
out=build/bench-results/ab-reconstruct
extra=""
usage=2,21
a_args=""
b_args=""
a_bin=""
b_bin=""
rest=()
while [ $# -gt 0 ]; do  # --a / --b here, the shared options in alternate_common.sh
  case "$1" in
    --a) a_args=$2; shift 2 ;;
    --b) b_args=$2; shift 2 ;;
    --a-bin) a_bin=$2; shift 2 ;;
    --b-bin) b_bin=$2; shift 2 ;;
    *) rest+=("$1"); shift ;;
  esac
done
set -- "${rest[@]}"
# shellcheck source=bench/alternate_common.sh
source "$(dirname "$0")/alternate_common.sh"
declare -A binary=([a]="$heatwave" [b]="$heatwave")
for mode in a b; do
  bin=$a_bin
  [ $mode = b ] && bin=$b_bin
  [ -z "$bin" ] && continue
  [ -x "$bin" ] || { echo "--$mode-bin $bin: not an executable" >&2; exit 2; }
  cp "$bin" "$out/heatwave-$mode"
  binary[$mode]=$out/heatwave-$mode
done
# reconstruct.json → "fps integrated casts cast_ms thermal_cast_ms ate_mm surface_mm shape_mm"
figures() {
  python3 - "$1" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
frames = j["frames"]
g = j.get("groundtruth_evaluation", {})
s = g.get("surface_to_truth", {})
mm = lambda v: "nan" if v is None else f"{1e3 * v:.2f}"
casts = [f["raycast_ms"] for f in frames if f.get("raycast_ms", 0) > 0]
thermal = j.get("thermal", {}).get("timings", {}).get("mean_raycast_ms", float("nan"))
print(f'{j["timings"]["frames_per_s"]:.2f} {sum(f["integrated"] for f in frames)} {len(casts)} '
      f'{sum(casts) / max(1, len(casts)):.1f} {thermal:.1f} {mm(g.get("ate_m", {}).get("rmse"))} '
      f'{mm(s.get("median_m"))} {mm(s.get("registered", {}).get("median_m"))}')
PY
}
for scan in $scans; do
  name=$(basename "$scan")
  scan_rig=${rig:-$scan/rig.yaml}
  declare -A fps=([a]="" [b]="") cast=([a]="" [b]="")
  for round in $(seq 1 "$rounds"); do
    for mode in a b; do
      args=$a_args
      [ $mode = b ] && args=$b_args
      run="$out/$name-$mode"
      # shellcheck disable=SC2086
      "${binary[$mode]}" reconstruct "$scan" --rig "$scan_rig" --out "$run" --overwrite --start-at-groundtruth $extra $args \
        > /dev/null 2>&1
      read -r f n c cms tms ate surface shape <<< "$(figures "$run/reconstruct.json")"
      printf "%-10s round %d %s %6s frames/s  %3s integrated  %3s casts %6s ms  thermal cast %6s ms  ATE %s mm  surface %s mm  shape %s mm\n" \
        "$name" "$round" "$mode" "$f" "$n" "$c" "$cms" "$tms" "$ate" "$surface" "$shape"
      fps[$mode]="${fps[$mode]} $f"
      cast[$mode]="${cast[$mode]} $cms"
    done
  done
  fa=$(echo "${fps[a]}" | median); fb=$(echo "${fps[b]}" | median)
  ca=$(echo "${cast[a]}" | median); cb=$(echo "${cast[b]}" | median)
  printf "%-10s median frames/s a %s, b %s (ratio a/b %.3f); model cast a %s, b %s ms (ratio a/b %.3f)\n" \
    "$name" "$fa" "$fb" "$(awk -v a="$fa" -v b="$fb" 'BEGIN {print a / b}')" \
    "$ca" "$cb" "$(awk -v a="$ca" -v b="$cb" 'BEGIN {print a / b}')"
done
