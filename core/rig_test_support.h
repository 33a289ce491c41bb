#pragma once

// Rigs, cameras and rig.yaml texts shared by the rig tests.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>
#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"

#include "core/rig.h"

namespace hw::core::rig_test {

// ---------------------------------------------------------------------------------------
// Fixtures.

// Numbers chosen to need all 17 digits (1/3, 0.1 + 0.2, ...) or to be at the edges of
// what a careless writer loses (1e-17, 5e-324, 1e300).
inline CameraModel MakeCamera(CameraModelType type, int num_distortion, double seed) {
  CameraModel camera;
  camera.width = 640 + static_cast<int>(seed);
  camera.height = 480;
  camera.type = type;
  camera.fx = 525.1234567890123 + seed;
  camera.fy = 524.0 + 1.0 / 3.0;
  camera.cx = 319.5 + 0.1 + 0.2;
  camera.cy = 239.49999999999997;
  const std::vector<double> coefficients = {
      0.1 + seed * 1e-3, -0.25 / 3.0, 1e-17, -2e-4, 5e-324, 1e-300, -0.5, 2.0 / 7.0};
  camera.distortion.assign(coefficients.begin(), coefficients.begin() + num_distortion);
  return camera;
}

inline Rigid3d MakeTransform(double seed) {
  const Eigen::Quaterniond q(0.9 + seed, -0.1 / 3.0, 0.2 * seed, 1e-17);
  return Rigid3d(q, Eigen::Vector3d(0.03 + seed, -1.0 / 3.0, 1e-9));
}

inline ThermalSettings MakeThermalSettings() {
  ThermalSettings s;
  s.raw_scale = 0.01;
  s.raw_offset = -273.15;
  s.spectral_band_um = {7.5, 13.999999999999998};
  s.netd_k = 0.045;
  s.emissivity = 0.95;
  s.reflected_c = 21.0 / 3.0;
  return s;
}

inline Rig MakeRig(bool with_rgb, bool with_thermal, int rgb_distortion = 5, int thermal_distortion = 8) {
  Rig rig;
  rig.depth_scale = 5000.0;
  rig.depth = MakeCamera(CameraModelType::kPinhole, 0, 0);
  if (with_rgb) {
    rig.rgb = MakeCamera(CameraModelType::kOpenCV, rgb_distortion, 1);
    rig.depth_from_rgb = MakeTransform(0.01);
    rig.rgb_time_offset_s = 1.0 / 30.0;
  }
  if (with_thermal) {
    rig.thermal = MakeCamera(CameraModelType::kOpenCV, thermal_distortion, 2);
    rig.depth_from_thermal = MakeTransform(-0.3);
    rig.thermal_time_offset_s = -0.04;
    rig.thermal_settings = MakeThermalSettings();
  }
  return rig;
}

// Exact: FormatRig writes shortest round-trip numbers, so nothing may change at all.
inline void ExpectSameCamera(const CameraModel& a, const CameraModel& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.distortion, b.distortion);
  if (a.type == CameraModelType::kSplined) {
    EXPECT_EQ(a.splined, b.splined);
  }
}

inline void ExpectSameTransform(const Rigid3d& a, const Rigid3d& b) {
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a.rotation.coeffs()[i], b.rotation.coeffs()[i]) << i;
  for (int i = 0; i < 3; ++i) EXPECT_EQ(a.translation[i], b.translation[i]) << i;
}

inline void ExpectSameRig(const Rig& a, const Rig& b) {
  EXPECT_EQ(a.depth_scale, b.depth_scale);
  ExpectSameCamera(a.depth, b.depth);
  ASSERT_EQ(a.rgb.has_value(), b.rgb.has_value());
  if (a.rgb) ExpectSameCamera(*a.rgb, *b.rgb);
  ASSERT_EQ(a.thermal.has_value(), b.thermal.has_value());
  if (a.thermal) ExpectSameCamera(*a.thermal, *b.thermal);
  ExpectSameTransform(a.depth_from_rgb, b.depth_from_rgb);
  ExpectSameTransform(a.depth_from_thermal, b.depth_from_thermal);
  EXPECT_EQ(a.rgb_time_offset_s, b.rgb_time_offset_s);
  EXPECT_EQ(a.thermal_time_offset_s, b.thermal_time_offset_s);
  EXPECT_EQ(a.rgb_readout_s, b.rgb_readout_s);
  ASSERT_EQ(a.thermal_settings.has_value(), b.thermal_settings.has_value());
  if (a.thermal_settings) {
    const ThermalSettings& s = *a.thermal_settings;
    const ThermalSettings& t = *b.thermal_settings;
    EXPECT_EQ(s.raw_scale, t.raw_scale);
    EXPECT_EQ(s.raw_offset, t.raw_offset);
    EXPECT_EQ(s.spectral_band_um, t.spectral_band_um);
    EXPECT_EQ(s.netd_k, t.netd_k);
    EXPECT_EQ(s.emissivity, t.emissivity);
    EXPECT_EQ(s.reflected_c, t.reflected_c);
  }
}

// The what() of the InputError that ParseRig throws on `text`, or "<no error>".
inline std::string RigError(const std::string& text) {
  try {
    ParseRig(text, "rig.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

// A full rig with distinct values in every line, so that each line can be edited alone.
inline const char* const kFullRig = R"(version: 1
depth_scale: 1000.0
cameras:
  depth:
    width: 640
    height: 480
    model: pinhole
    fx: 525.0
    fy: 526.0
    cx: 319.5
    cy: 239.5
    distortion: []
  rgb:
    width: 1280
    height: 720
    model: opencv
    fx: 910.25
    fy: 911.5
    cx: 639.75
    cy: 359.25
    distortion: [0.1, -0.25, 0.001, -0.002, 0.05]
  thermal:
    width: 160
    height: 120
    model: opencv
    fx: 180.5
    fy: 181.5
    cx: 79.5
    cy: 59.5
    distortion: [-0.3, 0.12, 0.0005, 0.0007]
extrinsics:
  depth_from_rgb: { q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }
  depth_from_thermal: { q_xyzw: [0.0, 0.0, 0.6, 0.8], t_m: [0.03, 0.01, -0.002] }
time_offset_s:
  rgb: 0.0
  thermal: -0.04
thermal:
  raw_scale: 0.01
  raw_offset: -273.15
  spectral_band_um: [7.5, 14.0]
  netd_k: 0.04
  emissivity: 0.95
  reflected_c: 20.0
)";

inline const char* const kRgbBlock = R"(  rgb:
    width: 1280
    height: 720
    model: opencv
    fx: 910.25
    fy: 911.5
    cx: 639.75
    cy: 359.25
    distortion: [0.1, -0.25, 0.001, -0.002, 0.05]
)";

inline const char* const kThermalCameraBlock = R"(  thermal:
    width: 160
    height: 120
    model: opencv
    fx: 180.5
    fy: 181.5
    cx: 79.5
    cy: 59.5
    distortion: [-0.3, 0.12, 0.0005, 0.0007]
)";

inline const char* const kThermalBlock = R"(thermal:
  raw_scale: 0.01
  raw_offset: -273.15
  spectral_band_um: [7.5, 14.0]
  netd_k: 0.04
  emissivity: 0.95
  reflected_c: 20.0
)";

}  // namespace hw::core::rig_test
