#!/usr/bin/env bash
# Benchmark: how memory and time per frame grow with the mapped area, on the `large` scene
# (a multi-room building walk) at full size, with the peers' fusion beside heatwave's on the
# same poses (not part of the test suite). The command behind the README's *Scale* figures:
#
#   bench/install-peers.sh && cmake --build build --target heatwave bench_open3d_reconstruct \
#       bench_opencv_kinfu_reconstruct && bench/scale.sh
#
# It renders (once; cached under DATA_DIR, default BUILD_DIR/bench-data) `heatwave synth
# --scene large --size full --duration S --no-rgb --no-thermal` (640x480 depth only: the
# scene's colour renders at 0.1-0.3 frames/s, its depth at ~2.5; ~4 min for 20 s), then, at
# each voxel size, fuses it along its groundtruth.txt (no tracking: the walk's first stretch
# runs along a wall only the colour term holds, README *Scale*), each run under GNU time:
#   heatwave          heatwave reconstruct --poses: every frame integrated, and the model
#                     raycast as often as the dynamic mask needs it (the default)
#   heatwave-fusion   the same with the dynamic mask off (--dynamic-margin 0
#                     --dynamic-fraction 0): integration alone, as the peers below
#   open3d            bench_open3d_reconstruct --poses: Open3D 0.16 VoxelBlockGrid integration
#                     (tsdf + weight, 16^3 blocks), OMP_WAIT_POLICY=PASSIVE
#   opencv-kinfu      bench_opencv_kinfu_reconstruct --poses: OpenCV-contrib kinfu HashTSDF
# all with the same voxel size, truncation (4 voxels) and depth range (0.3-5 m). It prints a
# row per WINDOW seconds of the walk from the heatwave run — the blocks allocated by then,
# the volume's memory (blocks x the bytes per block reconstruct.json reports), the mean
# integration and raycast time per frame over the window — and then every method's
# frames/s (processing, decoding excluded) and peak RSS, with heatwave-fusion / peer ratios.
# heatwave's peak includes meshing the model and scoring it against truth/scene.ply, and its
# voxels carry colour (12 bytes); the peers' do neither. A peer whose program was not built
# (bench/install-peers.sh) is skipped. OUT_DIR/summary.tsv holds the window rows,
# OUT_DIR/methods.tsv the method rows.
#
# Usage: bench/scale.sh [--build DIR] [--data DIR] [--out DIR] [--duration S]
#                       [--voxel-sizes "0.01 0.005"] [--window S]
set -euo pipefail

build=build
data=""
out=""
duration=20
voxels="0.01 0.005"
window=2
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --data) data=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --duration) duration=$2; shift 2 ;;
    --voxel-sizes) voxels=$2; shift 2 ;;
    --window) window=$2; shift 2 ;;
    *) echo "scale.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
data=${data:-$build/bench-data}
out=${out:-$build/bench-results/scale}
heatwave="$build/cli/heatwave"
if [ ! -x "$heatwave" ]; then
  echo "scale.sh: $heatwave not built (cmake --build $build --target heatwave)" >&2
  exit 1
fi
if ! /usr/bin/time -v true >/dev/null 2>&1; then
  echo "scale.sh: needs GNU time (/usr/bin/time, Debian package time) for the peak memory" >&2
  exit 1
fi
mkdir -p "$data" "$out"

scan="$data/large-full-${duration}s-depth"
# A complete render has depth.txt and no .heatwave-run marker (core/output_folder.h).
if [ ! -f "$scan/depth.txt" ] || [ -e "$scan/.heatwave-run" ]; then
  echo "rendering large (full size, $duration s, depth only) into $scan: takes minutes" >&2
  args=(synth --scene large --size full --duration "$duration" --no-rgb --no-thermal --out "$scan" --quiet)
  [ -d "$scan" ] && args+=(--overwrite)
  "$heatwave" "${args[@]}"
fi

summary="$out/summary.tsv"
methods="$out/methods.tsv"
printf 'voxel_m\tuntil_s\tblocks\tvolume_mb\tintegrate_ms\traycast_ms\n' > "$summary"
printf 'voxel_m\tmethod\tfps\tpeak_mb\n' > "$methods"
# Peak RSS (MB) from a GNU time -v file.
peak_mb() { awk -F': ' '/Maximum resident set size/ { printf "%.0f", $2 / 1024 }' "$1"; }

for voxel in $voxels; do
  truncation=$(python3 -c "print(4 * $voxel)")
  for method in heatwave heatwave-fusion open3d opencv-kinfu; do
    run="$out/$method-$voxel"
    case $method in
      heatwave|heatwave-fusion)
        echo "== $method, voxel $voxel m" >&2
        args=(reconstruct "$scan" --out "$run" --overwrite --no-thermal --poses "$scan/groundtruth.txt"
              --start-at-groundtruth --voxel-size "$voxel" --truncation "$truncation" --max-depth 5)
        if [ "$method" = heatwave-fusion ]; then args+=(--dynamic-margin 0 --dynamic-fraction 0); fi
        /usr/bin/time -v -o "$run.time" "$heatwave" "${args[@]}" >&2
        fps=$(python3 -c "import json, sys; print('%.2f' % json.load(open(sys.argv[1]))['timings']['frames_per_s'])" \
              "$run/reconstruct.json")
        ;;
      open3d|opencv-kinfu)
        bin="$build/bench/bench_open3d_reconstruct"
        if [ "$method" = opencv-kinfu ]; then bin="$build/bench/bench_opencv_kinfu_reconstruct"; fi
        if [ ! -x "$bin" ]; then
          echo "scale.sh: $bin not built: $method skipped" >&2
          continue
        fi
        echo "== $method, voxel $voxel m" >&2
        OMP_WAIT_POLICY=PASSIVE /usr/bin/time -v -o "$run.time" "$bin" "$scan" --out "$run-trajectory.txt" \
          --summary "$run.json" --poses "$scan/groundtruth.txt" --voxel-size "$voxel" --truncation "$truncation" \
          --max-depth 5 >&2
        fps=$(python3 -c "import json, sys; print('%.2f' % json.load(open(sys.argv[1]))['fps'])" "$run.json")
        ;;
    esac
    printf '%s\t%s\t%s\t%s\n' "$voxel" "$method" "$fps" "$(peak_mb "$run.time")" >> "$methods"
  done

  python3 - "$out/heatwave-$voxel/reconstruct.json" "$voxel" "$window" "$summary" "$methods" <<'EOF'
import csv, json, sys
d = json.load(open(sys.argv[1]))
voxel, window = float(sys.argv[2]), float(sys.argv[3])
mem = d["memory"]
bytes_per_block = mem["volume_bytes"] / max(1, mem["blocks"])
frames = d["frames"]
t0 = frames[0]["timestamp_s"]
rows, window_frames, end = [], [], t0 + window

def flush(until):
    if not window_frames:
        return
    n = len(window_frames)
    rows.append((until - t0, window_frames[-1]["blocks"], window_frames[-1]["blocks"] * bytes_per_block / 2**20,
                 sum(f["integrate_ms"] for f in window_frames) / n, sum(f["raycast_ms"] for f in window_frames) / n))
    window_frames.clear()

for f in frames:
    while f["timestamp_s"] >= end:
        flush(end)
        end += window
    window_frames.append(f)
flush(frames[-1]["timestamp_s"])
with open(sys.argv[4], "a") as out:
    for r in rows:
        out.write(f"{voxel}\t{r[0]:.1f}\t{r[1]}\t{r[2]:.1f}\t{r[3]:.1f}\t{r[4]:.1f}\n")
print(f"voxel {voxel} m: {'until s':>8} {'blocks':>8} {'volume MB':>10} {'integrate ms':>13} {'raycast ms':>11}")
for r in rows:
    print(f"{'':14}{r[0]:8.1f} {r[1]:8d} {r[2]:10.1f} {r[3]:13.1f} {r[4]:11.1f}")
area = d["mesh"]["area_m2"]
print(f"  volume {mem['volume_bytes'] / 2**20:.0f} MB in {mem['blocks']} blocks ({bytes_per_block / 1024:.1f} KB each), "
      f"model {area:.1f} m2: {mem['volume_bytes'] / 2**20 / area:.1f} MB of volume per m2 mapped")

methods = [r for r in csv.DictReader(open(sys.argv[5]), delimiter="\t") if float(r["voxel_m"]) == voxel]
base = next((r for r in methods if r["method"] == "heatwave-fusion"), None)
print(f"  {'method':<16} {'frames/s':>9} {'peak MB':>8}   heatwave-fusion / method: frames/s, peak")
for r in methods:
    ratio = ""
    if base is not None and r["method"] in ("open3d", "opencv-kinfu"):
        ratio = f"{float(base['fps']) / float(r['fps']):.2f}x  {float(base['peak_mb']) / float(r['peak_mb']):.2f}x"
    print(f"  {r['method']:<16} {float(r['fps']):9.2f} {float(r['peak_mb']):8.0f}   {ratio}")
EOF
done
