#!/usr/bin/env bash
# Benchmark: temperature on the model, every fusion method side by side on the same run (not
# part of the test suite). The command behind the README's thermal table:
#
#   cmake --build build --target heatwave && bench/thermal_fusion.sh
#
# For each scan it renders (once; cached under DATA_DIR, default BUILD_DIR/bench-data) a
# full-size fixture scan with thermal (`heatwave synth --size full --duration 4
# --reflected-error 0`: 640x480 depth + colour, 320x240 thermal with the standard camera's
# NETD, vignetting, fixed-pattern noise and ±1-2 K / 2 % calibration error; ~25 min of both
# cores each), then runs on it, one after the other:
#   no-thermal   heatwave reconstruct --no-thermal: the reconstruction alone (frames/s)
#   rig          heatwave reconstruct: thermal fusion with rig.yaml's one emissivity (0.95)
#   truth        ... with each surface's true emissivity (--emissivity-from-truth) and the
#                camera's true vignetting (--thermal-vignetting 0.05): a characterised camera
#   gt-poses     as truth, fused along groundtruth.txt (--poses) instead of tracking: the
#                fusion's own error, without the tracker's drift misplacing the thermal rays
#   gt-no-conf   as gt-poses, every confidence power 0 (C_R = 1: plain rays)
#   gt-no-edge   as gt-poses, without the silhouette rule (--thermal-edge-radius 0) and the
#                view cap (--thermal-max-views 0): the fusion as the table's first run had it
#   NAME-iS      any of the above with --thermal-frame-interval S: only the most confident
#                thermal frame of each S seconds fused (e.g. rig-i0 every frame, gt-poses-i0.3)
#   NAME-b0      any of the above with --no-thermal-background: each fused frame's shading and
#                splatting inline instead of beside the depth pipeline (e.g. rig-b0)
#   NAME-r0      any of the above with --thermal-reflections false: the whole reflection taken
#                as the uniform reflected temperature, no mirror rays traced (e.g. gt-poses-r0)
#   NAME-o       any of the above with the depth sensor's true error field (the oracle rig
#                that build/bench/bench_depth_oracle_rig writes beside the scan, once): the
#                temperature without the depth calibration's residual error (e.g. truth-o)
# With --baseline BIN (an earlier build's heatwave), each config also runs with BIN right
# before this build's run, as NAME@base: the two builds side by side on the same input, in
# one run (a -b0 config runs only with this build).
# All runs start at the groundtruth pose (the model is in the truth's frame). heatwave
# reconstruct samples every method (latest, mean, capped-mean, online, offline) at the model's
# vertices and scores it against truth/scene.ply (reconstruct/thermal_eval.h): RMSE, p95 and
# bias over vertices within 1 cm of the true surface away from model boundaries, on the
# uniform subset (away from hot-spot borders and low-emissivity patches), after removing the
# best camera gain and offset, on the resolved subset (the uniform one less what a thermal
# pixel mixes across a step: the truth uniform within 2 pixel footprints) after the same map,
# and on low-emissivity patches. The table lists them per scan,
# configuration and method, with frames/s of the whole pipeline beside the reconstruction
# alone; OUT_DIR/summary.tsv holds the same rows.
#
# Usage: bench/thermal_fusion.sh [--build DIR] [--data DIR] [--out DIR] [--scans "A B"]
#                                [--configs "A B"]  (default: all six above) [--baseline BIN]
#   scans: eqT4 (equipment, smooth), bdT4 (building, smooth), eqJ4 (equipment, jerky)
set -euo pipefail
cd "$(dirname "$0")/.."

build=build
data=""
out=""
scans="eqT4 bdT4 eqJ4"
configs="no-thermal rig truth gt-poses gt-no-conf gt-no-edge"
baseline=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --data) data=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scans) scans=$2; shift 2 ;;
    --configs) configs=$2; shift 2 ;;
    --baseline) baseline=$2; shift 2 ;;
    -h|--help) sed -n '2,46p' "$0"; exit 0 ;;
    *) echo "unknown option: $1" >&2; exit 2 ;;
  esac
done
data=${data:-$build/bench-data}
out=${out:-$build/bench-results/thermal-fusion}
[[ -x $build/cli/heatwave ]] || { echo "build heatwave first: cmake --build $build --target heatwave" >&2; exit 2; }
mkdir -p "$data" "$out"
# A copy, so that a rebuild during the (long) run does not pull the binary away.
heatwave=$out/heatwave
cp "$build/cli/heatwave" "$heatwave"
if [[ -n $baseline ]]; then
  [[ -x $baseline ]] || { echo "--baseline $baseline: not an executable" >&2; exit 2; }
  cp "$baseline" "$out/heatwave-base"
  baseline=$out/heatwave-base
fi

synth_args() {
  case "$1" in
    eqT4) echo "--scene equipment" ;;
    bdT4) echo "--scene building" ;;
    eqJ4) echo "--scene equipment --trajectory jerky" ;;
    *) echo "unknown scan $1 (eqT4 bdT4 eqJ4)" >&2; exit 2 ;;
  esac
}

summary=$out/summary.tsv
printf "scan\tconfig\tmethod\tfps\tthermal_ms\trmse\tp95\tbias\trmse_uniform\tp95_uniform\trmse_affine\tp95_affine\trmse_resolved\tp95_resolved\trmse_low_e\tbias_low_e\tcompared\tworst_third\tmiddle\tbest_third\n" > "$summary"
for scan in $scans; do
  if [[ ! -f $data/$scan/thermal.txt ]]; then
    echo "== rendering $scan (minutes)" >&2
    # shellcheck disable=SC2046
    "$heatwave" synth $(synth_args "$scan") --size full --duration 4 --seed 1 --reflected-error 0 \
      --out "$data/$scan" --overwrite -q
  fi
  for config in $configs; do
    args=(--start-at-groundtruth --overwrite -q)
    base=$config
    background=1
    if [[ $base =~ ^(.*)-r0$ ]]; then
      base=${BASH_REMATCH[1]}
      args+=(--thermal-reflections false)
    fi
    if [[ $base =~ ^(.*)-o$ ]]; then
      base=${BASH_REMATCH[1]}
      oracle=$data/$scan/oracle-rig.yaml
      if [[ ! -f $oracle ]]; then
        [[ -x $build/bench/bench_depth_oracle_rig ]] ||
          { echo "build bench_depth_oracle_rig first: cmake --build $build --target bench_depth_oracle_rig" >&2; exit 2; }
        "$build/bench/bench_depth_oracle_rig" "$data/$scan/rig.yaml" "$oracle"
      fi
      args+=(--rig "$oracle")
    fi
    if [[ $base =~ ^(.*)-b0$ ]]; then
      base=${BASH_REMATCH[1]}
      background=0
      args+=(--no-thermal-background)
    fi
    if [[ $base =~ ^(.*)-i([0-9.]+)$ ]]; then
      base=${BASH_REMATCH[1]}
      args+=(--thermal-frame-interval "${BASH_REMATCH[2]}")
    fi
    case $base in
      no-thermal) args+=(--no-thermal) ;;
      truth) args+=(--emissivity-from-truth --thermal-vignetting 0.05) ;;
      gt-poses) args+=(--emissivity-from-truth --thermal-vignetting 0.05 --poses "$data/$scan/groundtruth.txt") ;;
      gt-no-conf) args+=(--emissivity-from-truth --thermal-vignetting 0.05 --poses "$data/$scan/groundtruth.txt"
                         --confidence-powers 0,0,0,0,0) ;;
      gt-no-edge) args+=(--emissivity-from-truth --thermal-vignetting 0.05 --poses "$data/$scan/groundtruth.txt"
                         --thermal-edge-radius 0 --thermal-max-views 0) ;;
      rig) ;;
      *) echo "unknown config $config" >&2; exit 2 ;;
    esac
    runs=("$config:$heatwave")
    [[ -n $baseline && $background == 1 ]] && runs=("$config@base:$baseline" "${runs[@]}")
    for run in "${runs[@]}"; do
      name=${run%%:*}
      binary=${run#*:}
      echo "== $scan $name" >&2
      "$binary" reconstruct "$data/$scan" --out "$out/$scan-$name" "${args[@]}"
      python3 - "$out/$scan-$name/reconstruct.json" "$scan" "$name" >> "$summary" <<'EOF'
import json, sys
d = json.load(open(sys.argv[1]))
fps = d["timings"]["frames_per_s"]
frames = max(1, len(d["frames"]))
t = d.get("thermal")
if t is None:
    print(f"{sys.argv[2]}\t{sys.argv[3]}\t-\t{fps:.2f}\t0" + "\t-" * 15)
    sys.exit()
# Frames/s of the whole pipeline: the caller's time in depth processing, thermal fusion (the
# stage beside it, ThermalFusionOptions::background, counts where the caller waits for it)
# and the offline estimate, per depth frame; decoding the frames excluded.
total_s = d["timings"]["process_s"] + t["timings"]["fusion_s"] + t["timings"]["offline_s"]
fps_all = frames / total_s
ms = t["timings"]["mean_raycast_ms"] + t["timings"]["mean_fuse_ms"]
for m in t.get("truth_evaluation", []):
    f = lambda k: "nan" if m[k] is None else f"{m[k]:.3f}"
    print("\t".join([sys.argv[2], sys.argv[3], m["method"], f"{fps_all:.2f}", f"{ms:.0f}",
                     f("rmse_k"), f("p95_abs_k"), f("mean_k"), f("rmse_uniform_k"), f("p95_abs_uniform_k"),
                     f("rmse_affine_k"), f("p95_abs_affine_k"), f("rmse_resolved_affine_k"),
                     f("p95_abs_resolved_affine_k"), f("rmse_low_emissivity_k"),
                     f("mean_low_emissivity_k"), str(m["compared"])] +
                    # RMSE after gain/offset per third of the views' mean confidence (worst first)
                    [("nan" if c["rmse_affine_k"] is None else f'{c["rmse_affine_k"]:.3f}')
                     for c in m.get("by_view_quality", [])]))
EOF
    done
  done
done
echo
column -t -s $'\t' "$summary"
echo "(K; fps: depth frames per second of processing, thermal fusion included; thermal_ms per thermal frame;"
echo " worst_third / middle / best_third: uniform subset after gain/offset, split at the terciles of the mean"
echo " confidence of each region's views)"
