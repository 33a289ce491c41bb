#!/usr/bin/env bash
# Installs every Debian 12 package heatwave needs to build, test and run.
# Idempotent and non-interactive: packages already present are left alone.
# The README's "Dependencies" section says why each one is here.
set -euo pipefail

packages=(
  # toolchain; lld: LLVM's linker, 4–6× faster than GNU ld on our test executables
  build-essential cmake pkg-config ninja-build lld
  # core
  libeigen3-dev libyaml-cpp-dev libopencv-dev libopencv-contrib-dev libcli11-dev libpng-dev
  # calibrate
  libceres-dev libmrcal-dev libapriltag-dev
  # calibrate: mrcal's sparse Jacobian is a CHOLMOD matrix (also pulled in by libmrcal-dev)
  libsuitesparse-dev
  # analyze / fixtures; core decodes JPEG and TIFF frames with OpenImageIO
  libembree-dev libtbb-dev libopenimageio-dev
  # analyze: k-d trees for nearest-point queries (spot surroundings, before/after alignment)
  libnanoflann-dev
  # Debian's OpenImageIO CMake config names these files; find_package fails without them
  openimageio-tools python3-imath
  # capture
  libopenni2-dev libusb-1.0-0-dev libuvc-dev
  # reconstruct: the TSDF's block hash (absl::flat_hash_map)
  libabsl-dev
  # report: PDF and images (Cairo + Pango), analyze.json / reconstruct.json reading,
  # decimation of the model embedded in the HTML report's 3D view
  libcairo2-dev libpango1.0-dev nlohmann-json3-dev libmeshoptimizer-dev zlib1g-dev
  # report: the PDF's typeface (embedded as a subset)
  fonts-dejavu-core
  # tests
  libgtest-dev libgmock-dev
  # report tests: the PDF checked with pdftotext / pdffonts / pdfinfo, the HTML opened in
  # headless Chromium
  poppler-utils chromium
  # calibration tests: OpenCV's sample chessboard images (left01..14.jpg), real camera data
  opencv-doc
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed"
else
  echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# report: three.js and esbuild for the HTML report's 3D view, pinned by
# report/viewer/package-lock.json; the build bundles them offline from node_modules.
if ! command -v npm >/dev/null 2>&1; then
  echo "install-deps: npm not found: installing Debian's nodejs and npm"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends nodejs npm
fi
viewer_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/report/viewer"
if [ ! -d "$viewer_dir/node_modules" ] || [ "$viewer_dir/package-lock.json" -nt "$viewer_dir/node_modules" ]; then
  echo "install-deps: npm ci in report/viewer"
  (cd "$viewer_dir" && npm ci --no-audit --no-fund)
  touch "$viewer_dir/node_modules"
else
  echo "install-deps: report/viewer/node_modules is up to date"
fi
