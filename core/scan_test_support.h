#pragma once

// Test helpers shared by core/scan_test.cc and core/frame_clock_test.cc: a small rig and scan
// folders that hold indexes only.

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "core/atomic_file.h"
#include "core/rig.h"

namespace hw::core::test {

// 32×24 depth and colour, 16×12 thermal; every extrinsic set.
inline Rig TestRig() {
  Rig rig;
  rig.depth_scale = 1000.0;
  rig.depth = CameraModel::Pinhole(32, 24, 30.0, 30.0);
  rig.rgb = CameraModel::Pinhole(32, 24, 31.0, 31.0);
  rig.depth_from_rgb = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.025, 0, 0));
  rig.thermal = CameraModel::Pinhole(16, 12, 15.0, 15.0);
  // Baseline |(0.03, 0.04, 0)| = 0.05 m, rotated 10 degrees about the optical axis.
  rig.depth_from_thermal =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(0.03, 0.04, 0));
  rig.thermal_settings = ThermalSettings{};
  return rig;
}

inline void WriteText(const std::filesystem::path& path, const std::string& text) { WriteFileAtomically(path, text); }

inline std::string Stamp(double t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", t);
  return buf;
}

// "t <stream>/t.png" lines.
inline std::string IndexText(const std::string& stream, const std::vector<double>& times,
                             const std::string& extension = ".png") {
  std::string text = "# " + stream + "\n";
  for (const double t : times) text += Stamp(t) + " " + stream + "/" + Stamp(t) + extension + "\n";
  return text;
}

inline std::vector<double> Times(int n, double start_s, double period_s) {
  std::vector<double> times;
  for (int i = 0; i < n; ++i) times.push_back(start_s + i * period_s);
  return times;
}

// A scan with indexes only (frame files missing: warnings, which these tests do not load).
inline void WriteIndexOnlyScan(const std::filesystem::path& folder, const Rig& rig, const std::vector<double>& depth,
                               const std::vector<double>& rgb, const std::vector<double>& thermal) {
  WriteRig(folder / "rig.yaml", rig);
  WriteText(folder / "depth.txt", IndexText("depth", depth));
  if (!rgb.empty()) WriteText(folder / "rgb.txt", IndexText("rgb", rgb));
  if (!thermal.empty()) WriteText(folder / "thermal.txt", IndexText("thermal", thermal));
}

}  // namespace hw::core::test
