// Frame decoding, side by side on the same files in one run: heatwave's checked decoder
// (core/image_io.h: ReadFile + header check + libpng / OpenImageIO) against the peer it
// replaced, cv::imread. Prints per-format time per frame and the ratio heatwave / OpenCV.
//
//   build/bench/bench_decode_speed SCAN_FOLDER [repeats]
//
// Render a full-size scan first, e.g.
//   build/cli/heatwave synth --scene equipment --size full --duration 1 --out /tmp/bench-scan
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "core/image_io.h"

namespace fs = std::filesystem;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SCAN_FOLDER [repeats]\n", argv[0]);
    return 2;
  }
  const int repeats = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  std::map<std::string, std::vector<fs::path>> files;  // "depth .png" -> frames
  for (const std::string stream : {"depth", "rgb", "thermal"}) {
    const fs::path dir = fs::path(argv[1]) / stream;
    if (!fs::is_directory(dir)) continue;
    for (const auto& entry : fs::directory_iterator(dir)) {
      files[stream + " " + entry.path().extension().string()].push_back(entry.path());
    }
  }
  if (files.empty()) {
    std::fprintf(stderr, "no frames under %s\n", argv[1]);
    return 1;
  }
  using Clock = std::chrono::steady_clock;
  std::printf("%-14s %7s %14s %14s %8s\n", "frames", "count", "heatwave ms", "cv::imread ms",
              "ratio");
  for (const auto& [kind, paths] : files) {
    double ours_s = 0, peer_s = 0;
    size_t checksum = 0;
    for (int r = 0; r < repeats; ++r) {
      // Alternate the order so neither side always gets the warmer page cache.
      for (int side = 0; side < 2; ++side) {
        const bool ours = (r + side) % 2 == 0;
        const auto start = Clock::now();
        for (const fs::path& path : paths) {
          const cv::Mat image =
              ours ? hw::core::ReadImage(path) : cv::imread(path.string(), cv::IMREAD_UNCHANGED);
          checksum += image.total();
        }
        const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
        (ours ? ours_s : peer_s) += seconds;
      }
    }
    const double n = static_cast<double>(paths.size()) * repeats;
    std::printf("%-14s %7zu %14.3f %14.3f %8.2f\n", kind.c_str(), paths.size(), 1e3 * ours_s / n,
                1e3 * peer_s / n, ours_s / peer_s);
    if (checksum == 0) return 1;
  }
  return 0;
}
