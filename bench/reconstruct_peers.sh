#!/usr/bin/env bash
# Benchmark: heatwave reconstruct side by side with its peers, on the same frames with the same
# voxel size in one run (not part of the test suite). The command behind the README figures:
#
#   bench/install-peers.sh && cmake --build build --target heatwave bench_open3d_reconstruct \
#       bench_opencv_kinfu_reconstruct && bench/reconstruct_peers.sh
#
# For each scene it renders (once; cached under DATA_DIR, default BUILD_DIR/bench-data) a
# full-size fixture scan, `heatwave synth --scene SCENE --size full` (640x480, 10 s; minutes
# to render), then runs, one after the other on that scan:
#   heatwave       heatwave reconstruct SCAN --out DIR (frame-to-model, track+integrate+raycast)
#   open3d         bench_open3d_reconstruct: Open3D 0.16 tensor VoxelBlockGrid frame-to-model,
#                  run with OMP_WAIT_POLICY=PASSIVE (spinning OpenMP waits collapse on 2 cores)
#   opencv-kinfu   bench_opencv_kinfu_reconstruct: OpenCV-contrib FastICPOdometry frame to
#                  frame + kinfu HashTSDF volume
# evaluates each trajectory against the scan's groundtruth.txt with `heatwave eval-trajectory
# --json` (ATE RMSE after SE(3) alignment), measures wall time and peak memory (/usr/bin/time
# -v when present, else each program's own figure), and prints a table: method, frames/s,
# ATE RMSE mm, peak MB, wall and CPU seconds of the whole run (CPU time tells how loaded a
# shared machine was), and heatwave / peer ratios of frames/s and ATE. The same figures go to
# OUT_DIR/summary.json. frames/s is frames over processing time, decoding excluded, as each
# program reports it (heatwave: reconstruct.json; falls back to frames over wall time).
# A peer whose program was not built (Open3D missing: bench/install-peers.sh) is skipped.
#
# Usage: bench/reconstruct_peers.sh [options]
#   --build DIR        build folder (default build)
#   --data DIR         cache of rendered scans (default BUILD_DIR/bench-data)
#   --out DIR          results: per-method outputs and summary.json
#                      (default BUILD_DIR/bench-results/reconstruct-peers)
#   --scenes "A B"     scenes to render and run (default "equipment building")
#   --voxel-size M     voxel size of every method, m (default 0.005, heatwave's default)
#   --duration S       scan length, s (default: the preset's, full 10 s)
#   --size full|small  synth preset (default full; small: 80x60 1 s, a quick check of the
#                      script only, too small for the peers to track)
#   --methods "A B"    subset of "heatwave open3d opencv-kinfu" (default all three)
set -euo pipefail
cd "$(dirname "$0")/.."

build=build
data=""
out=""
scenes="equipment building"
voxel=0.005
duration=""
size=full
methods="heatwave open3d opencv-kinfu"
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --data) data=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scenes) scenes=$2; shift 2 ;;
    --voxel-size) voxel=$2; shift 2 ;;
    --duration) duration=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --methods) methods=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) echo "reconstruct_peers: unknown option $1 (--help lists them)" >&2; exit 2 ;;
  esac
done
data=${data:-$build/bench-data}
out=${out:-$build/bench-results/reconstruct-peers}
heatwave="$build/cli/heatwave"
open3d_bin="$build/bench/bench_open3d_reconstruct"
opencv_bin="$build/bench/bench_opencv_kinfu_reconstruct"
if [ ! -x "$heatwave" ]; then
  echo "reconstruct_peers: $heatwave not built (cmake --build $build --target heatwave)" >&2
  exit 1
fi
gnu_time=""
if [ -x /usr/bin/time ] && /usr/bin/time -v true >/dev/null 2>&1; then gnu_time=/usr/bin/time; fi
mkdir -p "$data" "$out"
rows="$out/rows.jsonl"
: > "$rows"

# Renders SCENE into the cache unless a complete render is there (depth.txt written and no
# .heatwave-run marker: core/output_folder.h). Prints the scan folder.
render() {
  local scene=$1 scan
  scan="$data/$scene-$size${duration:+-${duration}s}"
  if [ -f "$scan/depth.txt" ] && [ ! -e "$scan/.heatwave-run" ]; then
    echo "$scan"; return
  fi
  echo "rendering $scene ($size size${duration:+, $duration s}) into $scan: takes minutes" >&2
  # No thermal stream: reconstruction does not read it, and it is a third of the render.
  local args=(synth --scene "$scene" --size "$size" --no-thermal --out "$scan" --quiet)
  [ -n "$duration" ] && args+=(--duration "$duration")
  [ -d "$scan" ] && args+=(--overwrite)
  "$heatwave" "${args[@]}" >&2
  echo "$scan"
}

# Runs a command under GNU time when present and returns its exit status; leaves
# "wall_s [peak_mb cpu_s]" in $run_dir/time.txt (the last two only with GNU time).
timed() {
  local run_dir=$1; shift
  local start end rc=0
  start=$(date +%s.%N)
  if [ -n "$gnu_time" ]; then
    "$gnu_time" -v -o "$run_dir/gnu-time.txt" "$@" || rc=$?
  else
    "$@" || rc=$?
  fi
  end=$(date +%s.%N)
  local peak="" cpu=""
  if [ -n "$gnu_time" ]; then
    peak=$(awk -F': ' '/Maximum resident set size/ { printf "%.1f", $2 / 1024 }' \
           "$run_dir/gnu-time.txt")
    cpu=$(awk -F': ' '/User time|System time/ { s += $2 } END { printf "%.2f", s }' \
          "$run_dir/gnu-time.txt")
  fi
  awk -v s="$start" -v e="$end" -v p="$peak" -v c="$cpu" \
      'BEGIN { printf "%.3f %s %s\n", e - s, p, c }' > "$run_dir/time.txt"
  return "$rc"
}

# Collects one method's figures into a JSON row (python3: JSON in, JSON out).
collect() {
  local scene=$1 method=$2 run_dir=$3 scan=$4 status=$5
  python3 - "$scene" "$method" "$run_dir" "$scan" "$status" "$voxel" >> "$rows" <<'EOF'
import json, os, sys
scene, method, run_dir, scan, status, voxel = sys.argv[1:7]
row = {"scene": scene, "method": method, "scan": scan, "voxel_size_m": float(voxel),
       "status": status, "fps": None, "fps_source": None, "ate_rmse_mm": None,
       "peak_mb": None, "wall_s": None, "cpu_s": None, "frames": None, "output": run_dir}

def load(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None

def find(node, want, path=""):
    """(path, value) of numbers whose lower-cased key path contains every word of `want`."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield from find(v, want, path + "/" + str(k).lower())
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        if all(w in path for w in want):
            yield path, float(node)

if status != "ok":  # a failed or skipped run has no figures
    print(json.dumps(row))
    sys.exit(0)

try:
    wall, *rest = open(os.path.join(run_dir, "time.txt")).read().split()
    row["wall_s"] = float(wall)
    if len(rest) == 2:  # GNU time: peak resident MB, user + system CPU seconds
        row["peak_mb"], row["cpu_s"] = float(rest[0]), float(rest[1])
except OSError:
    pass

if method == "heatwave":
    info = load(os.path.join(run_dir, "out", "reconstruct.json"))
    if info is not None:
        fps = [v for p, v in find(info, ["fps"])] + \
              [v for p, v in find(info, ["frames_per_s"])]
        if fps:
            row["fps"], row["fps_source"] = fps[0], "reconstruct.json"
        # "frames" is the per-frame list of heatwave's report.
        if isinstance(info.get("frames"), list):
            row["frames"] = len(info["frames"])
        if row["peak_mb"] is None and "memory" in info:
            row["peak_mb"] = info["memory"]["peak_rss_bytes"] / 2**20
    if row["fps"] is None and row["wall_s"]:
        try:
            with open(os.path.join(scan, "depth.txt")) as f:
                n = sum(1 for l in f if l.strip() and not l.startswith("#"))
            row["frames"] = row["frames"] or n
            row["fps"], row["fps_source"] = n / row["wall_s"], "frames / wall time"
        except OSError:
            pass
else:
    info = load(os.path.join(run_dir, "summary.json"))
    if info is not None:
        row["fps"], row["fps_source"] = info["fps"], "harness loop timer"
        row["frames"] = info["frames"]
        if row["peak_mb"] is None:
            row["peak_mb"] = info["peak_rss_mb"]

ate = load(os.path.join(run_dir, "eval.json"))
if ate is not None:
    # heatwave eval-trajectory --json: the first number under a key path naming both "ate"
    # and "rmse"; metres unless the key says mm.
    for p, v in find(ate, ["ate", "rmse"]):
        row["ate_rmse_mm"] = v if p.endswith("mm") else v * 1000
        break
print(json.dumps(row))
EOF
}

echo "reconstruct_peers: voxel size $voxel m; results in $out"
for scene in $scenes; do
  scan=$(render "$scene")
  if [ ! -f "$scan/groundtruth.txt" ]; then
    echo "reconstruct_peers: $scan has no groundtruth.txt" >&2; exit 1
  fi
  for method in $methods; do
    run_dir="$out/$scene/$method"
    rm -rf "$run_dir"; mkdir -p "$run_dir"
    status=ok
    case "$method" in
      heatwave)
        # The peers' depth range (0.3–4 m, bench/peer_common.h) and voxel size.
        vargs=(--voxel-size "$voxel" --max-depth 4 --min-depth 0.3)
        # Its own fresh --out folder: run_dir already holds this script's files.
        timed "$run_dir" "$heatwave" reconstruct "$scan" --out "$run_dir/out" "${vargs[@]}" \
            > "$run_dir/log.txt" 2>&1 || status=failed
        trajectory="$run_dir/out/trajectory.txt"
        ;;
      open3d|opencv-kinfu)
        bin=$open3d_bin; [ "$method" = opencv-kinfu ] && bin=$opencv_bin
        if [ ! -x "$bin" ]; then
          echo "reconstruct_peers: $bin not built: $method skipped" >&2
          collect "$scene" "$method" "$run_dir" "$scan" "not built"
          continue
        fi
        timed "$run_dir" env OMP_WAIT_POLICY=PASSIVE "$bin" "$scan" \
            --out "$run_dir/trajectory.txt" --summary "$run_dir/summary.json" \
            --voxel-size "$voxel" > "$run_dir/log.txt" 2>&1 || status=failed
        trajectory="$run_dir/trajectory.txt"
        ;;
      *) echo "reconstruct_peers: unknown method $method" >&2; exit 2 ;;
    esac
    if [ "$status" = ok ] && [ -f "$trajectory" ]; then
      "$heatwave" eval-trajectory "$trajectory" "$scan/groundtruth.txt" --json \
          > "$run_dir/eval.json" 2> "$run_dir/eval.log" ||
        echo "reconstruct_peers: eval-trajectory failed on $method: $(head -1 "$run_dir/eval.log")" >&2
    else
      echo "reconstruct_peers: $method failed on $scene: $(tail -1 "$run_dir/log.txt")" >&2
    fi
    collect "$scene" "$method" "$run_dir" "$scan" "$status"
  done
done

# Table and summary.json, with heatwave / peer ratios per scene.
python3 - "$rows" "$out/summary.json" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1]) if l.strip()]
def fmt(v, spec):
    return format(v, spec) if v is not None else "n/a"
def ratio(a, b):
    return a / b if a is not None and b not in (None, 0) else None
print("%-10s %-13s %7s %9s %12s %9s %9s %9s %12s %12s  %s" % (
    "scene", "method", "frames", "frames/s", "ATE RMSE mm", "peak MB", "wall s", "CPU s",
    "fps hw/peer", "ATE hw/peer", "status"))
for r in rows:
    hw = next((x for x in rows if x["scene"] == r["scene"] and x["method"] == "heatwave"), None)
    if r["method"] != "heatwave" and hw is not None:
        r["fps_ratio_heatwave_over_peer"] = ratio(hw["fps"], r["fps"])
        r["ate_ratio_heatwave_over_peer"] = ratio(hw["ate_rmse_mm"], r["ate_rmse_mm"])
    print("%-10s %-13s %7s %9s %12s %9s %9s %9s %12s %12s  %s" % (
        r["scene"], r["method"], fmt(r["frames"], "d"), fmt(r["fps"], ".2f"),
        fmt(r["ate_rmse_mm"], ".2f"), fmt(r["peak_mb"], ".0f"), fmt(r["wall_s"], ".1f"),
        fmt(r["cpu_s"], ".1f"),
        fmt(r.get("fps_ratio_heatwave_over_peer"), ".2f"),
        fmt(r.get("ate_ratio_heatwave_over_peer"), ".2f"), r["status"]))
with open(sys.argv[2], "w") as f:
    json.dump({"rows": rows}, f, indent=2)
    f.write("\n")
print("summary:", sys.argv[2])
EOF
