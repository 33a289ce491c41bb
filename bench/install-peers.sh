#!/usr/bin/env bash
# Installs the Debian 12 packages the peer harnesses of bench/reconstruct_peers.sh need:
# Open3D 0.16 (bench/open3d_reconstruct.cc) and /usr/bin/time (peak memory of each run).
# The OpenCV-contrib peer (bench/opencv_kinfu_reconstruct.cc) needs nothing more than
# scripts/install-deps.sh already installs (libopencv-contrib-dev has the rgbd module).
# Optional peers, not dependencies of heatwave: CI does not call this script.
# Idempotent and non-interactive: packages already present are left alone.
set -euo pipefail

packages=(
  # Open3D's C++ library and its CMake config (pulls fmt, GLEW, GLFW headers it includes)
  libopen3d-dev
  # GNU time: peak resident memory (-v) of each method's run
  time
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-peers: all ${#packages[@]} packages already installed"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-peers: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
