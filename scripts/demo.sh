#!/usr/bin/env bash
# Quick start, command 1: install, build, and run the main job on the bundled demo.
# The demo scan is not stored in git: it is rendered deterministically (seed 1) from the
# bundled synthetic "equipment" scene — a plant room with an open cabinet, pipes and a motor
# with six planted hot spots — then validated, summarised and reconstructed into a coloured
# 3D model with a calibrated surface temperature on every vertex, whose hot and cold spots are
# then found, measured and drawn. Until the report exists, these are the stages that run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
heatwave=build/cli/heatwave
out=build/demo/equipment
echo
echo "== heatwave synth: render the demo scan (640x480 depth + colour, 320x240 thermal, 1 s)"
"$heatwave" synth --scene equipment --size full --duration 1 --seed 1 --out "$out" --overwrite
echo
echo "== heatwave scan-info: validate it, decoding every frame"
"$heatwave" scan-info "$out" --check-frames
echo
echo "== heatwave reconstruct: track the depth stream, fuse and mesh a coloured model, lay temperature on it"
"$heatwave" reconstruct "$out" --out build/demo/reconstruction --overwrite
echo
echo "== heatwave analyze: find and measure hot and cold spots, render the four views"
"$heatwave" analyze build/demo/reconstruction/model.ply --config scripts/demo_analyze.yaml \
  --out build/demo/analysis --overwrite
echo
echo "Demo scan: $out  (ground truth in $out/truth/: scene.ply, hotspots.yaml)"
echo "Model:     build/demo/reconstruction/model.ply (MeshLab, CloudCompare; per-vertex temperature_c, temperature_confidence, ...), trajectory.txt, reconstruct.json"
echo "Analysis:  build/demo/analysis/analyze.json, images/*.png (thermal, colour, IH mapping, highlighting) and *.exr"
