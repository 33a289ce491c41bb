#!/usr/bin/env bash
# What `heatwave calibrate depth` buys tracking, side by side in one run on the same scan:
# the scan reconstructed with its depth uncorrected, corrected with the field calibrated
# from a depth-wall recording of the same device, with that field plus the depth scale
# `calibrate extrinsics` measures on its plate (folded into rig.yaml; reconstruct then also
# widens ICP's gate by default), and corrected with the fixtures' true field (an oracle:
# whole, its affine part recorded as measured so that the gate widens as for the plate-
# calibrated rig, and without its affine part, which no wall recording can see).
# Prints the calibrations' figures, then each run's ATE, surface error and ratio to the
# uncorrected ATE.
#   bench/depth_correction.sh [--build DIR] [--out DIR] [--scan SCAN] [--wall WALL] [--plate PLATE]
# Default inputs, rendered once into --out when absent: the full `depth-wall` session, the
# full `extrinsics-target` session (seed 1, ~2 min) and the 3 s `equipment` scan (`heatwave
# synth --scene equipment --size full --duration 3 --no-thermal`, ~6 min on 2 cores).
set -euo pipefail
build=build
out=build/bench-results/depth-correction
scan=""
wall=""
plate=""
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scan) scan=$2; shift 2 ;;
    --wall) wall=$2; shift 2 ;;
    --plate) plate=$2; shift 2 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
heatwave="$build/cli/heatwave"
oracle="$build/bench/bench_depth_oracle_rig"
mkdir -p "$out"
if [ -z "$scan" ]; then
  scan="$out/eq3"
  [ -f "$scan/depth.txt" ] || "$heatwave" synth --scene equipment --size full --duration 3 --no-thermal -q --overwrite --out "$scan"
fi
if [ -z "$wall" ]; then
  wall="$out/wall"
  [ -f "$wall/depth.txt" ] || "$heatwave" synth --session depth-wall --size full -q --overwrite --out "$wall"
fi

echo "== calibrate depth on $wall (through the scan's depth camera)"
"$heatwave" calibrate depth --scan "$wall" --rig "$scan/rig.yaml" --out "$out/calibration" --overwrite --max-sigma-mm 5 2>/dev/null |
  grep -E "^(Planes|Residual|Field|QA|Wrote)"
if [ -z "$plate" ]; then
  plate="$out/plate"
  [ -f "$plate/depth.txt" ] || "$heatwave" synth --session extrinsics-target --size full --seed 1 -q --overwrite --out "$plate"
fi
# The bench's order: intrinsics first (here the plate session's true ones, truth/rig.yaml:
# through its nominal rig, 1-2 % off in focal length, the extrinsics fail QA and the scale is
# not measured, so nothing is folded), the wall through them, then the plate through that
# correction.
echo "== calibrate depth on $wall, then extrinsics on $plate (through that correction)"
"$heatwave" calibrate depth --scan "$wall" --rig "$plate/truth/rig.yaml" --out "$out/calibration-for-plate" \
  --overwrite --max-sigma-mm 5 -q
"$heatwave" calibrate extrinsics --scan "$plate" --rig "$out/calibration-for-plate/rig.yaml" \
  --out "$out/calibration-plate" --overwrite 2>/dev/null | grep -E "^(Stills|Depth|QA|Wrote)"
"$oracle" "$scan/rig.yaml" "$out/rig-oracle.yaml" >/dev/null
"$oracle" "$scan/rig.yaml" "$out/rig-oracle-no-affine.yaml" --no-affine >/dev/null

ate() {  # trajectory → ATE rmse in mm
  "$heatwave" eval-trajectory "$1" "$scan/groundtruth.txt" | awk '/^ATE/ {print $4}'
}
declare -A rigs=([uncorrected]="$scan/rig.yaml" [calibrated]="$out/calibration/rig.yaml"
                 [calibrated+plate]="$out/calibration-plate/rig.yaml"
                 [oracle]="$out/rig-oracle.yaml" [oracle-no-affine]="$out/rig-oracle-no-affine.yaml")
base=""
printf "%-18s %10s %8s %14s %12s %10s\n" run "ATE (mm)" ratio "surface (mm)" "shape (mm)" "seconds"
for name in uncorrected calibrated calibrated+plate oracle oracle-no-affine; do
  start=$(date +%s.%N)
  # The surface error (model to truth/scene.ply, median) from the summary, when the scan has truth.
  # And after registering the model onto the truth (the summary's Shape line: the shape's own error).
  summary=$("$heatwave" reconstruct "$scan" --rig "${rigs[$name]}" --out "$out/reconstruct-$name" --overwrite \
    --start-at-groundtruth 2>/dev/null)
  surface=$(echo "$summary" | awk '/^Surface/ {print $6}')
  shape=$(echo "$summary" | sed -n 's/^Shape .*: median \([0-9.]*\) mm.*/\1/p')
  seconds=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN {print b - a}')
  a=$(ate "$out/reconstruct-$name/trajectory.txt")
  [ -n "$base" ] || base=$a
  printf "%-18s %10.3f %8.3f %14s %12s %10.1f\n" "$name" "$a" "$(awk -v a="$a" -v b="$base" 'BEGIN {print a / b}')" \
    "${surface:--}" "${shape:--}" "$seconds"
done
