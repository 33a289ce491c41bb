#!/usr/bin/env bash
# Global relocalisation from keyframes, side by side in one run on the same scan: the scan,
# then the lens covered for GAP s and the rig back where it was from START to START + DUR s
# of the scan (the same frames again with later stamps, groundtruth.txt extended with their
# true poses), reconstructed with keyframes (the default) and without
# (--relocalisation-candidates 0), both along the sensor's true depth field (an oracle rig:
# the drift is then tracking's, not the sensor's). Prints per run the frames lost and
# recovered, the returning frames' error from the truth and the ATE of the whole run.
#   bench/relocalisation.sh [--build DIR] [--out DIR] [--scan SCAN] [--gap S] [--start S] [--dur S]
# Default scan, rendered once into --out when absent: the 3 s `equipment` sweep (`heatwave
# synth --scene equipment --size full --duration 3 --no-thermal`, ~6 min on 2 cores).
set -euo pipefail
build=build
out=build/bench-results/relocalisation
scan=""
gap=1.0
start=0.3
dur=1.0
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --scan) scan=$2; shift 2 ;;
    --gap) gap=$2; shift 2 ;;
    --start) start=$2; shift 2 ;;
    --dur) dur=$2; shift 2 ;;
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
scan=$(cd "$scan" && pwd)
ret="$out/returning"
rm -rf "$ret"
mkdir -p "$ret"
for f in "$scan"/*; do
  case "$(basename "$f")" in depth.txt|rgb.txt|groundtruth.txt) ;; *) ln -s "$f" "$ret/" ;; esac
done
python3 - "$scan" "$ret" "$gap" "$start" "$dur" <<'PY'
import bisect, math, os, sys
src, dst, gap, start_s, dur_s = sys.argv[1], sys.argv[2], *map(float, sys.argv[3:6])
def entries(p):
    head, rows = [], []
    if not os.path.exists(p): return None, None
    for l in open(p):
        (head if l.startswith('#') or not l.strip() else rows).append(l)
    return head, rows
gh, grows = entries(os.path.join(src, 'groundtruth.txt'))
gt = [(float(r.split()[0]), [float(x) for x in r.split()[1:8]]) for r in grows]
stamps = [g[0] for g in gt]
def pose_at(t):  # positions linear, quaternions normalised linear (poses 1 ms apart)
    i = min(max(bisect.bisect_left(stamps, t), 1), len(gt) - 1)
    (ta, a), (tb, b) = gt[i - 1], gt[i]
    s = (t - ta) / (tb - ta)
    if sum(x * y for x, y in zip(a[3:], b[3:])) < 0: b = b[:3] + [-x for x in b[3:]]
    p = [a[k] + s * (b[k] - a[k]) for k in range(7)]
    n = math.sqrt(sum(x * x for x in p[3:]))
    return p[:3] + [x / n for x in p[3:]]
_, drows = entries(os.path.join(src, 'depth.txt'))
t0, t_end = float(drows[0].split()[0]), float(drows[-1].split()[0])
shift = t_end + gap - (t0 + start_s)
extra = []
for name in ('depth.txt', 'rgb.txt'):
    head, rows = entries(os.path.join(src, name))
    if rows is None: continue
    lines = head + rows
    for r in rows:
        t = float(r.split()[0])
        if t0 + start_s <= t < t0 + start_s + dur_s:
            lines.append("%.6f %s\n" % (t + shift, r.split()[1]))
            if name == 'depth.txt': extra.append((t + shift, pose_at(t)))
    open(os.path.join(dst, name), 'w').writelines(lines)
open(os.path.join(dst, 'groundtruth.txt'), 'w').writelines(
    gh + grows + ["%.6f %s\n" % (t, " ".join("%.9f" % x for x in p)) for t, p in extra])
open(os.path.join(dst, 'returning_from_s'), 'w').write("%.6f\n" % (t_end + gap - 1e-3))
print("== %d frames return after a %.1f s gap to %.1f-%.1f s of %s" % (len(extra), gap, start_s, start_s + dur_s, src))
PY
"$oracle" "$scan/rig.yaml" "$out/rig-oracle.yaml" >/dev/null
from=$(cat "$ret/returning_from_s")
for candidates in 3 0; do
  run="$out/run-candidates-$candidates"
  "$heatwave" reconstruct "$ret" --rig "$out/rig-oracle.yaml" --out "$run" --overwrite --start-at-groundtruth \
    --no-thermal --relocalisation-candidates "$candidates" > "$run.log" 2>&1 || { cat "$run.log"; exit 1; }
  python3 - "$run/trajectory.txt" "$ret/groundtruth.txt" "$from" "$candidates" <<'PY'
import sys, math
est_p, gt_p, t_from, c = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
def rows(p): return [[float(x) for x in l.split()[:4]] for l in open(p) if l.strip() and not l.startswith('#')]
gt = rows(gt_p)
err = []
for t, x, y, z in rows(est_p):
    if t < t_from: continue
    g = min(gt, key=lambda r: abs(r[0] - t))
    err.append(1000 * math.dist(g[1:], (x, y, z)))
err.sort()
what = "median %.1f mm, max %.1f mm" % (err[len(err) // 2], err[-1]) if err else "none"
print("candidates %s: returning frames fused %d, their error from the truth (no alignment) %s" % (c, len(err), what))
PY
  grep -E "^(Frames|Tracking   [0-9]+ of|Accuracy)" "$run.log" | sed 's/^/    /'
done
