#!/usr/bin/env bash
# Quick start, command 1: install, build, and run the main job on the bundled demo.
# `heatwave demo` renders the bundled synthetic scan deterministically (seed 1) from the
# "equipment" scene — a plant room with an open cabinet, pipes and a motor with planted hot
# spots, ground truth in build/demo/scan/truth/ — and audits it end to end: reconstruct
# with temperature, find and measure hot and cold spots, write report.html and report.pdf.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
build/cli/heatwave demo --out build/demo --overwrite
