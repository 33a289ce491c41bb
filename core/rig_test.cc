#include "core/rig.h"

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

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using hw::test::LineOf;
using hw::test::Replace;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// ---------------------------------------------------------------------------------------
// Fixtures.

// Numbers chosen to need all 17 digits (1/3, 0.1 + 0.2, ...) or to be at the edges of
// what a careless writer loses (1e-17, 5e-324, 1e300).
CameraModel MakeCamera(CameraModelType type, int num_distortion, double seed) {
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

Rigid3d MakeTransform(double seed) {
  const Eigen::Quaterniond q(0.9 + seed, -0.1 / 3.0, 0.2 * seed, 1e-17);
  return Rigid3d(q, Eigen::Vector3d(0.03 + seed, -1.0 / 3.0, 1e-9));
}

ThermalSettings MakeThermalSettings() {
  ThermalSettings s;
  s.raw_scale = 0.01;
  s.raw_offset = -273.15;
  s.spectral_band_um = {7.5, 13.999999999999998};
  s.netd_k = 0.045;
  s.emissivity = 0.95;
  s.reflected_c = 21.0 / 3.0;
  return s;
}

Rig MakeRig(bool with_rgb, bool with_thermal, int rgb_distortion = 5, int thermal_distortion = 8) {
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
void ExpectSameCamera(const CameraModel& a, const CameraModel& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.distortion, b.distortion);
}

void ExpectSameTransform(const Rigid3d& a, const Rigid3d& b) {
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a.rotation.coeffs()[i], b.rotation.coeffs()[i]) << i;
  for (int i = 0; i < 3; ++i) EXPECT_EQ(a.translation[i], b.translation[i]) << i;
}

void ExpectSameRig(const Rig& a, const Rig& b) {
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
std::string RigError(const std::string& text) {
  try {
    ParseRig(text, "rig.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

// A full rig with distinct values in every line, so that each line can be edited alone.
const char* const kFullRig = R"(version: 1
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

const char* const kRgbBlock = R"(  rgb:
    width: 1280
    height: 720
    model: opencv
    fx: 910.25
    fy: 911.5
    cx: 639.75
    cy: 359.25
    distortion: [0.1, -0.25, 0.001, -0.002, 0.05]
)";

const char* const kThermalCameraBlock = R"(  thermal:
    width: 160
    height: 120
    model: opencv
    fx: 180.5
    fy: 181.5
    cx: 79.5
    cy: 59.5
    distortion: [-0.3, 0.12, 0.0005, 0.0007]
)";

const char* const kThermalBlock = R"(thermal:
  raw_scale: 0.01
  raw_offset: -273.15
  spectral_band_um: [7.5, 14.0]
  netd_k: 0.04
  emissivity: 0.95
  reflected_c: 20.0
)";

// ---------------------------------------------------------------------------------------
// Round trips.

TEST(RigTest, RoundTripsEveryCombinationOfCamerasBitForBit) {
  for (const bool with_rgb : {false, true}) {
    for (const bool with_thermal : {false, true}) {
      for (const int rgb_distortion : {4, 5, 8}) {
        for (const int thermal_distortion : {4, 5, 8}) {
          SCOPED_TRACE(::testing::Message()
                       << "rgb " << with_rgb << " thermal " << with_thermal << " k "
                       << rgb_distortion << "/" << thermal_distortion);
          const Rig rig = MakeRig(with_rgb, with_thermal, rgb_distortion, thermal_distortion);
          ASSERT_EQ(rig.Check(), "");
          const std::string text = FormatRig(rig);
          const Rig back = ParseRig(text, "rig.yaml");
          ExpectSameRig(rig, back);
          // Formatting is a fixed point: the same rig gives the same text.
          EXPECT_EQ(FormatRig(back), text);
          // Blocks of absent cameras are not written at all.
          EXPECT_EQ(text.find("rgb") != std::string::npos, with_rgb) << text;
          EXPECT_EQ(text.find("thermal") != std::string::npos, with_thermal) << text;
        }
      }
    }
  }
}

TEST(RigTest, RoundTripsPinholeColourAndThermalCameras) {
  Rig rig = MakeRig(true, true);
  rig.rgb = MakeCamera(CameraModelType::kPinhole, 0, 3);
  rig.thermal = MakeCamera(CameraModelType::kPinhole, 0, 4);
  ExpectSameRig(rig, ParseRig(FormatRig(rig), "rig.yaml"));
}

TEST(RigTest, RoundTripsRandomRotationsBitForBit) {
  // Quaternions as Rigid3d keeps them (normalised) must come back with every bit.
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  Rig rig = MakeRig(true, false);
  for (int i = 0; i < 300; ++i) {
    rig.depth_from_rgb =
        Rigid3d(Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)),
                Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
    const Rig back = ParseRig(FormatRig(rig), "rig.yaml");
    ExpectSameTransform(rig.depth_from_rgb, back.depth_from_rgb);
  }
}

TEST(RigTest, WriteAndReadThroughAFile) {
  const fs::path dir = hw::test::TestFolder();
  const Rig rig = MakeRig(true, true);
  WriteRig(dir / "scan" / "rig.yaml", rig);
  ExpectSameRig(rig, ReadRig(dir / "scan" / "rig.yaml"));
  // Only the file itself: the temporary was renamed, not left behind.
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir / "scan")) {
    EXPECT_EQ(entry.path().filename(), "rig.yaml");
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(RigTest, FormatUsesTheSpecLayoutAndPlainFloats) {
  const std::string text = FormatRig(MakeRig(true, true));
  EXPECT_THAT(text, StartsWith("version: 1\ndepth_scale: 5000.0"));
  EXPECT_THAT(text, HasSubstr("\ncameras:\n  depth:\n    width: 640\n    height: 480\n"
                              "    model: pinhole"));
  EXPECT_THAT(text, HasSubstr("\nextrinsics:"));
  EXPECT_THAT(text, HasSubstr("\n  depth_from_rgb: { q_xyzw: ["));
  EXPECT_THAT(text, HasSubstr("\ntime_offset_s:"));
  EXPECT_THAT(text, HasSubstr("\n  thermal: -0.04\n"));
  EXPECT_THAT(text, HasSubstr("\n  raw_offset: -273.15\n"));
  // Floats always have a '.', also with an exponent, as YAML 1.1 readers need.
  EXPECT_THAT(text, HasSubstr("1.0e-17"));
  EXPECT_THAT(text, HasSubstr("    fy: 524.3333333333334\n"));
  EXPECT_THAT(text, HasSubstr("    distortion: []"));
}

TEST(RigTest, ReadsTheSpecExample) {
  // scan-format.md's rig.yaml verbatim, its "..." blocks filled in.
  const std::string text = R"(version: 1
depth_scale: 1000.0          # raw depth units per metre (TUM uses 5000)
cameras:
  depth:
    width: 640
    height: 480
    model: pinhole           # pinhole | opencv   (opencv = OpenCV's k1 k2 p1 p2 [k3 [k4 k5 k6]])
    fx: 525.0
    fy: 525.0
    cx: 319.5
    cy: 239.5
    distortion: []           # OpenCV order; empty for pinhole
  rgb:                       # same keys; optional when there is no colour stream
    width: 640
    height: 480
    model: opencv
    fx: 517.3
    fy: 516.5
    cx: 318.6
    cy: 255.3
    distortion: [0.2624, -0.9531, -0.0054, 0.0026, 1.1633]
  thermal:                   # same keys; optional when there is no thermal stream
    width: 160
    height: 120
    model: pinhole
    fx: 150.0
    fy: 150.0
    cx: 79.5
    cy: 59.5
    distortion: []
extrinsics:                  # each maps points from the named camera into the depth camera
  depth_from_rgb:     { q_xyzw: [0, 0, 0, 1], t_m: [0.0, 0.0, 0.0] }
  depth_from_thermal: { q_xyzw: [0, 0, 0, 1], t_m: [0.03, 0.0, 0.0] }
time_offset_s:               # per stream, see Conventions; depth is 0 by definition
  rgb: 0.0
  thermal: 0.0
thermal:
  raw_scale: 0.01            # apparent °C = raw * raw_scale + raw_offset
  raw_offset: -273.15        #   (0.01 / -273.15 is centikelvin, as FLIR radiometric Lepton/Boson)
  spectral_band_um: [7.5, 14.0]
  netd_k: 0.04               # noise-equivalent temperature difference of one frame
  emissivity: 0.95           # default surface emissivity for the whole scene
  reflected_c: 20.0          # reflected apparent temperature
)";
  const Rig rig = ParseRig(text, "rig.yaml");
  EXPECT_EQ(rig.depth_scale, 1000.0);
  CameraModel depth = CameraModel::Pinhole(640, 480, 525.0, 525.0);
  ExpectSameCamera(rig.depth, depth);
  ASSERT_TRUE(rig.rgb.has_value());
  EXPECT_EQ(rig.rgb->type, CameraModelType::kOpenCV);
  EXPECT_EQ(rig.rgb->fx, 517.3);
  EXPECT_EQ(rig.rgb->cy, 255.3);
  EXPECT_EQ(rig.rgb->distortion, (std::vector<double>{0.2624, -0.9531, -0.0054, 0.0026, 1.1633}));
  ASSERT_TRUE(rig.thermal.has_value());
  ExpectSameCamera(*rig.thermal, CameraModel::Pinhole(160, 120, 150.0, 150.0));
  ExpectSameTransform(rig.depth_from_rgb, Rigid3d());
  ExpectSameTransform(rig.depth_from_thermal,
                      Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0, 0)));
  EXPECT_EQ(rig.rgb_time_offset_s, 0.0);
  EXPECT_EQ(rig.thermal_time_offset_s, 0.0);
  ASSERT_TRUE(rig.thermal_settings.has_value());
  EXPECT_EQ(rig.thermal_settings->raw_scale, 0.01);
  EXPECT_EQ(rig.thermal_settings->raw_offset, -273.15);
  EXPECT_EQ(rig.thermal_settings->spectral_band_um, (std::array<double, 2>{7.5, 14.0}));
  EXPECT_EQ(rig.thermal_settings->netd_k, 0.04);
  EXPECT_EQ(rig.thermal_settings->emissivity, 0.95);
  EXPECT_EQ(rig.thermal_settings->reflected_c, 20.0);
  // 30000 raw counts of centikelvin are 26.85 °C apparent.
  EXPECT_NEAR(rig.thermal_settings->ApparentFromRaw(30000), 26.85, 1e-12);
}

TEST(RigTest, ReadsTheFullTestRigAndOptionalForms) {
  const Rig rig = ParseRig(kFullRig, "rig.yaml");
  ASSERT_TRUE(rig.thermal.has_value());
  EXPECT_EQ(rig.thermal->distortion, (std::vector<double>{-0.3, 0.12, 0.0005, 0.0007}));
  EXPECT_EQ(rig.thermal_time_offset_s, -0.04);
  const Eigen::Vector4d q_xyzw(0, 0, 0.6, 0.8);
  EXPECT_LE((rig.depth_from_thermal.rotation.coeffs() - q_xyzw).norm(), 1e-16);

  // Depth only: extrinsics and time_offset_s may be absent, or present and empty; the
  // depth clock's own offset may be given as 0; '+' signs and exponents are numbers.
  const std::string depth_only =
      "version: 1\ndepth_scale: +5e3\ncameras:\n  depth:\n"
      "    {width: 64, height: 48, model: pinhole, fx: 50, fy: 50,"
      " cx: 31.5, cy: 23.5, distortion: []}\n";
  EXPECT_EQ(ParseRig(depth_only, "rig.yaml").depth_scale, 5000.0);
  EXPECT_FALSE(ParseRig(depth_only + "extrinsics: {}\ntime_offset_s: {depth: 0}\n", "rig.yaml")
                   .rgb.has_value());

  // A quaternion off unit by less than 1e-6 is accepted and normalised.
  const Rig slightly_off =
      ParseRig(Replace(kFullRig, "[0.0, 0.0, 0.6, 0.8]", "[0.0, 0.0, 0.6, 0.8000005]"), "rig.yaml");
  EXPECT_NEAR(slightly_off.depth_from_thermal.rotation.norm(), 1.0, 1e-15);
  // Boundary values that are allowed.
  EXPECT_EQ(RigError(Replace(kFullRig, "emissivity: 0.95", "emissivity: 1")), "<no error>");
  EXPECT_EQ(RigError(Replace(kFullRig, "netd_k: 0.04", "netd_k: 0")), "<no error>");
  EXPECT_EQ(RigError(Replace(kFullRig, "raw_scale: 0.01", "raw_scale: -0.01")), "<no error>");
}

// ---------------------------------------------------------------------------------------
// Ranges (rig.h, camera.h): values that parse as numbers but cannot describe a rig.

TEST(RigTest, AbsurdValuesAreRefusedWithKeyValueRangeAndLine) {
  const std::string full = kFullRig;
  struct Case {
    std::string from, to, expected;  // expected: what() up to " (line N)"
  };
  const std::vector<Case> cases = {
      // The values of the review: each loaded before, making depth, temperature or a
      // projection inf or meaningless.
      {"depth_scale: 1000.0", "depth_scale: 1e-300",
       "depth_scale: must be in [1, 1e6] raw units per metre, got 1e-300"},
      {"raw_scale: 0.01", "raw_scale: 1e300",
       "thermal.raw_scale: |raw_scale| must be in [1e-6, 10] °C per count (either sign), got "
       "1e300"},
      {"fx: 525.0", "fx: 1e-320", "cameras.depth.fx: must be in [1, 1e6] px, got 1e-320"},
      {"t_m: [-0.025, 0.0, 0.0]", "t_m: [1e300, 0, 0]",
       "extrinsics.depth_from_rgb.t_m: must be at most 10 m long, got [1e300, 0, 0]"},
      {"thermal: -0.04", "thermal: 1e300",
       "time_offset_s.thermal: must be in [-1e10, 1e10] s, got 1e300"},
      {"width: 640", "width: 1000000000",
       "cameras.depth.width: must be in [1, 16384] px, got 1000000000"},
      // One beyond each other bound.
      {"depth_scale: 1000.0", "depth_scale: 0.5",
       "depth_scale: must be in [1, 1e6] raw units per metre, got 0.5"},
      {"depth_scale: 1000.0", "depth_scale: 2e6",
       "depth_scale: must be in [1, 1e6] raw units per metre, got 2e6"},
      {"height: 120", "height: 16385",
       "cameras.thermal.height: must be in [1, 16384] px, got 16385"},
      {"fy: 911.5", "fy: 1.5e6", "cameras.rgb.fy: must be in [1, 1e6] px, got 1500000"},
      {"fx: 180.5", "fx: 0.5", "cameras.thermal.fx: must be in [1, 1e6] px, got 0.5"},
      {"cx: 639.75", "cx: 2561",
       "cameras.rgb.cx: must be in [-width, 2 width] = [-1280, 2560] px, got 2561"},
      {"cy: 59.5", "cy: -121",
       "cameras.thermal.cy: must be in [-height, 2 height] = [-120, 240] px, got -121"},
      {"[-0.3, 0.12, 0.0005, 0.0007]", "[-0.3, 1.5e4, 0.0005, 0.0007]",
       "cameras.thermal.distortion[1]: must be in [-10000, 10000], got 15000"},
      {"t_m: [0.03, 0.01, -0.002]", "t_m: [6, 8, 0.1]",
       "extrinsics.depth_from_thermal.t_m: must be at most 10 m long, got [6, 8, 0.1]"},
      {"rgb: 0.0", "rgb: -2e10", "time_offset_s.rgb: must be in [-1e10, 1e10] s, got -2e10"},
      {"raw_scale: 0.01", "raw_scale: 1e-7",
       "thermal.raw_scale: |raw_scale| must be in [1e-6, 10] °C per count (either sign), got "
       "1e-7"},
      {"raw_scale: 0.01", "raw_scale: -11",
       "thermal.raw_scale: |raw_scale| must be in [1e-6, 10] °C per count (either sign), got -11"},
      {"raw_offset: -273.15", "raw_offset: -1e4",
       "thermal.raw_offset: must be in [-1000, 1000] °C, got -10000"},
      {"[7.5, 14.0]", "[0.05, 14.0]",
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [0.05, "
       "14]"},
      {"[7.5, 14.0]", "[7.5, 1e300]",
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [7.5, "
       "1e300]"},
      {"netd_k: 0.04", "netd_k: 11", "thermal.netd_k: must be in [0, 10] K, got 11"},
      {"emissivity: 0.95", "emissivity: 1e-300",
       "thermal.emissivity: must be in [0.01, 1], got 1e-300"},
      {"reflected_c: 20.0", "reflected_c: 3001",
       "thermal.reflected_c: must be in (-273.15, 3000] °C (above absolute zero), got 3001"},
      {"reflected_c: 20.0", "reflected_c: -273.15",
       "thermal.reflected_c: must be in (-273.15, 3000] °C (above absolute zero), got -273.15"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.to);
    EXPECT_EQ(RigError(Replace(full, c.from, c.to)),
              "rig.yaml: " + c.expected + " (line " + std::to_string(LineOf(full, c.from)) + ")");
  }
}

TEST(RigTest, ValuesAtTheEdgesOfTheirRangesAreAccepted) {
  const std::string full = kFullRig;
  const std::vector<std::pair<std::string, std::string>> edges = {
      {"depth_scale: 1000.0", "depth_scale: 1"},
      {"depth_scale: 1000.0", "depth_scale: 1e6"},
      {"width: 640", "width: 16384"},
      {"fx: 525.0", "fx: 1"},
      {"fy: 911.5", "fy: 1e6"},
      {"cx: 639.75", "cx: -1280"},
      {"cy: 359.25", "cy: 1440"},
      {"[-0.3, 0.12, 0.0005, 0.0007]", "[-1e4, 1e4, 5e-324, 0]"},
      {"t_m: [0.03, 0.01, -0.002]", "t_m: [6, 8, 0]"},
      // A thermal camera counting from boot, depth on Unix time: 1.7e9 s apart.
      {"thermal: -0.04", "thermal: 1.7e9"},
      {"rgb: 0.0", "rgb: -1e10"},
      {"raw_scale: 0.01", "raw_scale: -1e-6"},
      {"raw_scale: 0.01", "raw_scale: 10"},
      {"raw_offset: -273.15", "raw_offset: 1000"},
      {"[7.5, 14.0]", "[0.1, 1000]"},
      {"netd_k: 0.04", "netd_k: 10"},
      {"emissivity: 0.95", "emissivity: 0.01"},
      {"reflected_c: 20.0", "reflected_c: 3000"},
      {"reflected_c: 20.0", "reflected_c: -273.14"},
  };
  for (const auto& [from, to] : edges) {
    SCOPED_TRACE(to);
    const std::string text = Replace(full, from, to);
    EXPECT_EQ(RigError(text), "<no error>");
    // And what is accepted is written back and read again unchanged.
    const Rig rig = ParseRig(text, "rig.yaml");
    ExpectSameRig(rig, ParseRig(FormatRig(rig), "rig.yaml"));
  }
}

TEST(RigTest, CheckHoldsTheRangesForRigsBuiltInCode) {
  // The same ranges without a file: WriteRig asserts them, so nothing out of range is written.
  const std::vector<std::pair<std::function<void(Rig&)>, std::string>> cases = {
      {[](Rig& r) { r.depth_scale = 1e-300; },
       "depth_scale: must be in [1, 1e6] raw units per metre, got 1e-300"},
      {[](Rig& r) { r.depth_scale = INFINITY; }, "depth_scale: must be finite, got inf"},
      {[](Rig& r) { r.depth.fx = 1e-320; }, "cameras.depth.fx: must be in [1, 1e6] px, got 1e-320"},
      {[](Rig& r) { r.thermal->width = 1000000000; },
       "cameras.thermal.width: must be in [1, 16384] px, got 1000000000"},
      {[](Rig& r) { r.depth_from_rgb.translation.x() = 1e300; },
       "extrinsics.depth_from_rgb.t_m: must be at most 10 m long, got [1e300, -0.3333333333333333, "
       "1e-9]"},
      {[](Rig& r) { r.depth_from_thermal.translation = Eigen::Vector3d(0.03, 0, NAN); },
       "extrinsics.depth_from_thermal.t_m: must be at most 10 m long, got [0.03, 0, nan]"},
      {[](Rig& r) { r.thermal_time_offset_s = 1e300; },
       "time_offset_s.thermal: must be in [-1e10, 1e10] s, got 1e300"},
      {[](Rig& r) { r.rgb_time_offset_s = -INFINITY; },
       "time_offset_s.rgb: must be finite, got -inf"},
      {[](Rig& r) { r.thermal_settings->raw_scale = 1e300; },
       "thermal.raw_scale: |raw_scale| must be in [1e-6, 10] °C per count (either sign), got "
       "1e300"},
      {[](Rig& r) { r.thermal_settings->raw_offset = NAN; },
       "thermal.raw_offset: must be finite, got nan"},
      {[](Rig& r) { r.thermal_settings->emissivity = 1e-300; },
       "thermal.emissivity: must be in [0.01, 1], got 1e-300"},
  };
  for (const auto& [mutate, expected] : cases) {
    Rig rig = MakeRig(true, true);
    ASSERT_EQ(rig.Check(), "");
    mutate(rig);
    EXPECT_EQ(rig.Check(), expected);
  }
  EXPECT_EQ(ThermalSettings().Check(), "");
  ThermalSettings settings;
  settings.netd_k = -1;
  EXPECT_EQ(settings.Check(), "netd_k: must be in [0, 10] K, got -1");
  // Writing what could not be read back is a bug, asserted.
  Rig absurd = MakeRig(true, true);
  absurd.depth.fx = 1e-320;
  EXPECT_DEATH(FormatRig(absurd), "Check");
  EXPECT_EQ(CheckExtrinsicTranslation(Eigen::Vector3d(0, 0, 10)), "");
  EXPECT_EQ(CheckExtrinsicTranslation(Eigen::Vector3d(0, 0, 10.000001)),
            "must be at most 10 m long, got [0, 0, 10.000001]");
}

// ---------------------------------------------------------------------------------------
// Malformed rig.yaml.

struct BadRig {
  std::string name;
  std::string text;
  std::string expected;  // substring of what()
};

std::vector<BadRig> BadRigs() {
  const std::string full = kFullRig;
  const std::string no_rgb = Replace(full, kRgbBlock, "");
  const std::string no_thermal_camera = Replace(full, kThermalCameraBlock, "");
  return {
      // Values out of range.
      {"negative focal", Replace(full, "fx: 180.5", "fx: -3"),
       "cameras.thermal.fx: must be in [1, 1e6] px, got -3"},
      {"zero focal", Replace(full, "fy: 526.0", "fy: 0"),
       "cameras.depth.fy: must be in [1, 1e6] px, got 0"},
      {"zero width", Replace(full, "width: 640", "width: 0"),
       "cameras.depth.width: must be in [1, 16384] px, got 0"},
      {"negative height", Replace(full, "height: 720", "height: -720"),
       "cameras.rgb.height: must be in [1, 16384] px, got -720"},
      {"non-unit quaternion", Replace(full, "[0, 0, 0, 1]", "[0, 0, 0, 1.2]"),
       "extrinsics.depth_from_rgb.q_xyzw: not a unit quaternion (norm 1.2)"},
      {"quaternion off by 2e-6",
       Replace(full, "[0.0, 0.0, 0.6, 0.8]", "[0.0, 0.0, 0.6, 0.8000016]"),
       "extrinsics.depth_from_thermal.q_xyzw: not a unit quaternion (norm 1.00000128)"},
      {"zero quaternion", Replace(full, "[0.0, 0.0, 0.6, 0.8]", "[0, 0, 0, 0]"),
       "extrinsics.depth_from_thermal.q_xyzw: not a unit quaternion (norm 0)"},
      {"unknown model", Replace(full, "model: pinhole", "model: fisheye"),
       "cameras.depth.model: must be pinhole or opencv, got 'fisheye'"},
      {"opencv with 3 coefficients",
       Replace(full, "[0.1, -0.25, 0.001, -0.002, 0.05]", "[0.1, 0, 0]"),
       "cameras.rgb.distortion: opencv needs 4, 5 or 8 coefficients, got 3"},
      {"opencv with none", Replace(full, "[-0.3, 0.12, 0.0005, 0.0007]", "[]"),
       "cameras.thermal.distortion: opencv needs 4, 5 or 8 coefficients, got 0"},
      {"pinhole with coefficients", Replace(full, "distortion: []", "distortion: [0.1, 0, 0, 0]"),
       "cameras.depth.distortion: pinhole needs 0 coefficients, got 4"},
      {"band decreasing", Replace(full, "[7.5, 14.0]", "[14.0, 7.5]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [14, 7.5]"},
      {"band from zero", Replace(full, "[7.5, 14.0]", "[0, 14.0]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [0, 14]"},
      {"band negative", Replace(full, "[7.5, 14.0]", "[-8, -7.5]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [-8, -7.5]"},
      {"band equal", Replace(full, "[7.5, 14.0]", "[7.5, 7.5]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [7.5, 7.5]"},
      {"emissivity 0", Replace(full, "emissivity: 0.95", "emissivity: 0"),
       "thermal.emissivity: must be in [0.01, 1], got 0"},
      {"emissivity above 1", Replace(full, "emissivity: 0.95", "emissivity: 1.01"),
       "thermal.emissivity: must be in [0.01, 1], got 1.01"},
      {"negative netd", Replace(full, "netd_k: 0.04", "netd_k: -0.01"),
       "thermal.netd_k: must be in [0, 10] K, got -0.01"},
      {"zero raw scale", Replace(full, "raw_scale: 0.01", "raw_scale: 0"),
       "thermal.raw_scale: |raw_scale| must be in [1e-6, 10] °C per count (either sign), got 0"},
      {"reflected below absolute zero", Replace(full, "reflected_c: 20.0", "reflected_c: -300"),
       "thermal.reflected_c: must be in (-273.15, 3000] °C (above absolute zero), got -300"},
      {"zero depth scale", Replace(full, "depth_scale: 1000.0", "depth_scale: 0"),
       "depth_scale: must be in [1, 1e6] raw units per metre, got 0"},
      {"negative depth scale", Replace(full, "depth_scale: 1000.0", "depth_scale: -1000"),
       "depth_scale: must be in [1, 1e6] raw units per metre, got -1000"},
      {"depth clock offset", Replace(full, "  rgb: 0.0\n", "  rgb: 0.0\n  depth: 0.1\n"),
       "time_offset_s.depth: must be 0 (depth is the reference clock), got 0.1"},
      {"version 2", Replace(full, "version: 1", "version: 2"), "version: unsupported version 2"},
      {"version 2 with new keys", Replace(full, "version: 1", "version: 2\nnew_key: 3"),
       "version: unsupported version 2"},
      {"version 0", Replace(full, "version: 1", "version: 0"), "version: unsupported version 0"},
      {"version float", Replace(full, "version: 1", "version: 1.0"),
       "version: must be an integer, got '1.0'"},
      {"version quoted", Replace(full, "version: 1", "version: \"1\""),
       "version: must be an integer, got string \"1\""},

      // Unknown keys at every level.
      {"unknown top key", full + "colour: red\n", "top level: unknown key 'colour'"},
      {"unknown camera key", Replace(full, "    fx: 525.0\n", "    fx: 525.0\n    fxx: 525.0\n"),
       "cameras.depth: unknown key 'fxx'"},
      {"misspelt camera key", Replace(full, "    fx: 910.25\n", "    f_x: 910.25\n"),
       "cameras.rgb: unknown key 'f_x'"},
      {"unknown camera", Replace(full, "cameras:\n", "cameras:\n  ir:\n    width: 1\n"),
       "cameras: unknown key 'ir'"},
      {"unknown extrinsics", Replace(full, "extrinsics:\n", "extrinsics:\n  depth_from_ir: {}\n"),
       "extrinsics: unknown key 'depth_from_ir'"},
      {"unknown transform key", Replace(full, "t_m: [-0.025", "scale: 1, t_m: [-0.025"),
       "extrinsics.depth_from_rgb: unknown key 'scale'"},
      {"unknown time offset", Replace(full, "  rgb: 0.0\n", "  rgb: 0.0\n  ir: 0.1\n"),
       "time_offset_s: unknown key 'ir'"},
      {"unknown thermal key", Replace(full, "  netd_k: 0.04\n", "  netd_k: 0.04\n  gain: 2\n"),
       "thermal: unknown key 'gain'"},
      {"duplicate key", Replace(full, "    fx: 525.0\n", "    fx: 525.0\n    fx: 530.0\n"),
       "cameras.depth: duplicate key 'fx'"},
      {"duplicate top key", full + "version: 1\n", "top level: duplicate key 'version'"},
      {"duplicate flow key",
       Replace(full, "t_m: [-0.025, 0.0, 0.0]", "t_m: [1, 2, 3], t_m: [1, 2, 3]"),
       "extrinsics.depth_from_rgb: duplicate key 't_m'"},
      {"non-scalar key", full + "? [a, b]\n: 1\n", "top level: keys must be plain names"},

      // Missing keys.
      {"missing version", Replace(full, "version: 1\n", ""), "version: missing required key"},
      {"missing depth scale", Replace(full, "depth_scale: 1000.0\n", ""),
       "depth_scale: missing required key"},
      {"missing fy", Replace(full, "    fy: 911.5\n", ""), "cameras.rgb.fy: missing required key"},
      {"missing model", Replace(full, "    model: pinhole\n", ""),
       "cameras.depth.model: missing required key"},
      {"missing distortion", Replace(full, "    distortion: []\n", ""),
       "cameras.depth.distortion: missing required key"},
      {"missing depth camera",
       Replace(full,
               "  depth:\n    width: 640\n    height: 480\n    model: pinhole\n"
               "    fx: 525.0\n    fy: 526.0\n    cx: 319.5\n    cy: 239.5\n"
               "    distortion: []\n",
               ""),
       "cameras.depth: missing required key"},
      {"missing cameras", "version: 1\ndepth_scale: 1000\n", "cameras: missing required key"},
      {"missing netd", Replace(full, "  netd_k: 0.04\n", ""),
       "thermal.netd_k: missing required key"},
      {"missing thermal block", Replace(full, kThermalBlock, ""), "thermal: missing required key"},
      {"missing thermal offset", Replace(full, "  thermal: -0.04\n", ""),
       "time_offset_s.thermal: missing required key"},
      {"missing time offsets", Replace(full, "time_offset_s:\n  rgb: 0.0\n  thermal: -0.04\n", ""),
       "time_offset_s.rgb: missing required key"},
      {"missing rgb extrinsics",
       Replace(full, "  depth_from_rgb: { q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }\n", ""),
       "extrinsics.depth_from_rgb: missing required key"},
      {"missing t_m", Replace(full, ", t_m: [-0.025, 0.0, 0.0]", ""),
       "extrinsics.depth_from_rgb.t_m: missing required key"},

      // Blocks for cameras that are absent.
      {"rgb extrinsics without rgb", no_rgb,
       "extrinsics.depth_from_rgb: given but cameras.rgb is absent"},
      {"rgb offset without rgb",
       Replace(no_rgb, "  depth_from_rgb: { q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }\n", ""),
       "time_offset_s.rgb: given but cameras.rgb is absent"},
      {"thermal extrinsics without thermal", no_thermal_camera,
       "extrinsics.depth_from_thermal: given but cameras.thermal is absent"},
      {"thermal block without thermal",
       Replace(Replace(no_thermal_camera,
                       "  depth_from_thermal: { q_xyzw: [0.0, 0.0, 0.6, 0.8], t_m: [0.03, 0.01, "
                       "-0.002] }\n",
                       ""),
               "  thermal: -0.04\n", ""),
       "thermal: given but cameras.thermal is absent"},

      // Wrong types.
      {"quoted number", Replace(full, "fx: 525.0", "fx: \"525.0\""),
       "cameras.depth.fx: must be a number, got string \"525.0\""},
      {"word for number", Replace(full, "fx: 525.0", "fx: five"),
       "cameras.depth.fx: must be a number, got 'five'"},
      {"number with unit", Replace(full, "cx: 319.5", "cx: 319.5px"),
       "cameras.depth.cx: must be a number, got '319.5px'"},
      {"list for number", Replace(full, "fx: 525.0", "fx: [525.0]"),
       "cameras.depth.fx: must be a number, got a list"},
      {"mapping for number", Replace(full, "fx: 525.0", "fx: {value: 525.0}"),
       "cameras.depth.fx: must be a number, got a mapping"},
      {"nothing for number", Replace(full, "fx: 525.0", "fx:"),
       "cameras.depth.fx: must be a number, got nothing"},
      {"infinite number", Replace(full, "cy: 239.5", "cy: .inf"),
       "cameras.depth.cy: must be finite, got '.inf'"},
      {"nan", Replace(full, "cy: 239.5", "cy: nan"), "cameras.depth.cy: must be finite, got 'nan'"},
      {"overflowing number", Replace(full, "depth_scale: 1000.0", "depth_scale: 1e999"),
       "depth_scale: number out of range"},
      {"double sign", Replace(full, "fx: 525.0", "fx: +-525.0"),
       "cameras.depth.fx: must be a number, got '+-525.0'"},
      {"fractional width", Replace(full, "width: 640", "width: 640.5"),
       "cameras.depth.width: must be an integer, got '640.5'"},
      {"huge width", Replace(full, "width: 640", "width: 99999999999"),
       "cameras.depth.width: integer out of range"},
      {"list for model", Replace(full, "model: pinhole", "model: [pinhole]"),
       "cameras.depth.model: must be a name, got a list"},
      {"scalar distortion", Replace(full, "distortion: []", "distortion: 0"),
       "cameras.depth.distortion: must be a list of numbers, got '0'"},
      {"word in distortion", Replace(full, "[0.1, -0.25, 0.001, -0.002, 0.05]", "[0.1, x, 0, 0]"),
       "cameras.rgb.distortion[1]: must be a number, got 'x'"},
      {"short quaternion", Replace(full, "[0, 0, 0, 1]", "[0, 0, 1]"),
       "extrinsics.depth_from_rgb.q_xyzw: must be a list of 4 numbers, got 3"},
      {"long translation", Replace(full, "[0.03, 0.01, -0.002]", "[0.03, 0.01, -0.002, 1]"),
       "extrinsics.depth_from_thermal.t_m: must be a list of 3 numbers, got 4"},
      {"short band", Replace(full, "[7.5, 14.0]", "[7.5]"),
       "thermal.spectral_band_um: must be a list of 2 numbers, got 1"},
      {"scalar transform",
       Replace(full, "{ q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }", "identity"),
       "extrinsics.depth_from_rgb: must be a mapping of keys, got 'identity'"},
      {"list for cameras", "version: 1\ndepth_scale: 1000\ncameras: [depth]\n",
       "cameras: must be a mapping of keys, got a list"},
      {"empty camera", Replace(full, kThermalCameraBlock, "  thermal:\n"),
       "cameras.thermal: must be a mapping of keys, got nothing"},

      // Not YAML, or not one mapping.
      {"empty", "", "rig.yaml: empty file"},
      {"only comments", "# nothing here\n\n", "rig.yaml: empty file"},
      {"empty document", "---\n...\n", "rig.yaml: empty file"},
      {"top-level list", "- version\n- 1\n",
       "expected a mapping of keys at the top level, got a list"},
      {"top-level scalar", "rig", "expected a mapping of keys at the top level, got 'rig'"},
      {"two documents", full + "---\nversion: 1\n",
       "more than one YAML document (the second starts on line 44)"},
      {"two empty documents", "---\n---\n", "more than one YAML document"},
      // yaml-cpp 0.7's LoadAll would loop, allocating without bound, on these.
      {"leading comma", "," + full, "rig.yaml: line 1: YAML syntax error: unexpected ','"},
      {"lone comma", ",", "rig.yaml: line 1: YAML syntax error: unexpected ','"},
      {"comma after document end", "...\n,\n",
       "rig.yaml: line 2: YAML syntax error: unexpected ','"},
      {"second document a comma", full + "---\n,\n", "more than one YAML document"},
      {"syntax error in a second document", full + "---\n[\n",
       "rig.yaml: line 46: YAML syntax error"},
      {"deep nesting", "version: " + std::string(3000, '[') + std::string(3000, ']') + "\n",
       "rig.yaml: line 1: YAML nesting deeper than 32 levels"},
      {"unclosed flow list", Replace(full, "[7.5, 14.0]", "[7.5, 14.0"), "YAML syntax error"},
      {"bad indentation", Replace(full, "    fy: 526.0\n", "   fy: 526.0\n"), "YAML syntax error"},
      {"tab indentation", Replace(full, "    fy: 526.0\n", "\tfy: 526.0\n"), "YAML syntax error"},
      // yaml-cpp reads an unclosed quote to the end of the file: caught all the same.
      {"unclosed quote", Replace(full, "model: pinhole", "model: \"pinhole"),
       "cameras.depth.model: must be pinhole or opencv, got string \"pinhole fx: 525.0 fy: 526.0 "
       "cx: 319.5 cy...\""},
      {"multi-line name", Replace(full, "model: pinhole", "model: |\n      pin\n      hole"),
       "cameras.depth.model: must be pinhole or opencv, got string \"pin\\nhole\\n\""},
      {"negative infinity", Replace(full, "cy: 239.5", "cy: -.Inf"),
       "cameras.depth.cy: must be finite"},
  };
}

TEST(RigTest, EveryMalformedRigThrowsOneClearInputError) {
  for (const BadRig& bad : BadRigs()) {
    SCOPED_TRACE(bad.name);
    const std::string error = RigError(bad.text);
    EXPECT_THAT(error, StartsWith("rig.yaml: "));
    EXPECT_THAT(error, HasSubstr(bad.expected));
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  }
}

TEST(RigTest, ErrorsGiveTheLineNumber) {
  const std::string full = kFullRig;
  EXPECT_EQ(RigError(Replace(full, "fx: 180.5", "fx: -3")),
            "rig.yaml: cameras.thermal.fx: must be in [1, 1e6] px, got -3 (line " +
                std::to_string(LineOf(full, "fx: 180.5")) + ")");
  EXPECT_EQ(RigError(Replace(full, "    fx: 525.0\n", "    fxx: 525.0\n")),
            "rig.yaml: cameras.depth: unknown key 'fxx' (line " +
                std::to_string(LineOf(full, "fx: 525.0")) + ")");
  EXPECT_EQ(RigError(Replace(full, "[0, 0, 0, 1]", "[0, 0, 0, 1.2]")),
            "rig.yaml: extrinsics.depth_from_rgb.q_xyzw: not a unit quaternion (norm 1.2) (line " +
                std::to_string(LineOf(full, "[0, 0, 0, 1]")) + ")");
  // A missing key points at the mapping it is missing from.
  EXPECT_EQ(RigError(Replace(full, "  netd_k: 0.04\n", "")),
            "rig.yaml: thermal.netd_k: missing required key (line " +
                std::to_string(LineOf(full, "raw_scale")) + ")");
  EXPECT_THAT(RigError(Replace(full, "[7.5, 14.0]", "[7.5, 14.0")), StartsWith("rig.yaml: line "));
  const std::string syntax = RigError(Replace(full, "    fy: 526.0\n", "   fy: 526.0\n"));
  EXPECT_THAT(syntax, StartsWith("rig.yaml: line " + std::to_string(LineOf(full, "fy: 526.0")) +
                                 ": YAML syntax error: "));
}

TEST(RigTest, MissingFileIsAnInputError) {
  const fs::path dir = hw::test::TestFolder();
  EXPECT_THROW(ReadRig(dir / "rig.yaml"), InputError);
  EXPECT_THROW(ReadRig(dir), InputError);  // a folder
  WriteFileAtomically(dir / "rig.yaml", "version: 1\n");
  try {
    ReadRig(dir / "rig.yaml");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), dir / "rig.yaml");
    EXPECT_EQ(e.reason(), "depth_scale: missing required key (line 1)");
  }
}

// Returns or throws InputError on every input; when it returns, the rig is valid and
// survives a round trip.
void ExpectParsesOrInputError(const std::string& text, int* accepted) {
  try {
    const Rig rig = ParseRig(text, "rig.yaml");
    ASSERT_EQ(rig.Check(), "");
    ExpectSameRig(rig, ParseRig(FormatRig(rig), "rig.yaml"));
    ++*accepted;
  } catch (const InputError& e) {
    ASSERT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    FAIL() << "unexpected exception " << e.what() << " on:\n" << text;
  }
}

TEST(RigTest, FuzzTruncationsMutationsAndDeletions) {
  const std::string full = kFullRig;
  int cases = 0, accepted = 0;
  // Every prefix.
  for (size_t n = 0; n <= full.size(); ++n, ++cases) {
    ExpectParsesOrInputError(full.substr(0, n), &accepted);
  }
  // Random byte edits: overwrite, insert or delete, 1-3 per case, biased to YAML syntax.
  std::mt19937 rng(12345);
  const std::string specials = ":-[]{},#'\"&*!|>?%@` \n\t0123456789.eE+";
  for (int i = 0; i < 2000; ++i, ++cases) {
    std::string text = full;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits && !text.empty(); ++e) {
      const size_t at = rng() % text.size();
      const char c =
          (rng() % 4 == 0) ? static_cast<char>(rng() % 256) : specials[rng() % specials.size()];
      switch (rng() % 3) {
        case 0:
          text[at] = c;
          break;
        case 1:
          text.insert(text.begin() + static_cast<std::ptrdiff_t>(at), c);
          break;
        default:
          text.erase(at, 1);
          break;
      }
    }
    ExpectParsesOrInputError(text, &accepted);
  }
  // Deleting lines (keys, whole blocks' headers), one and several at a time.
  std::vector<std::string> lines;
  for (size_t start = 0; start < full.size();) {
    const size_t end = full.find('\n', start);
    lines.push_back(full.substr(start, end - start + 1));
    start = end + 1;
  }
  for (int i = 0; i < 400; ++i, ++cases) {
    std::vector<std::string> kept = lines;
    const int deletions = i < static_cast<int>(lines.size()) ? 1 : 1 + static_cast<int>(rng() % 4);
    for (int d = 0; d < deletions && !kept.empty(); ++d) {
      const size_t at =
          i < static_cast<int>(lines.size()) ? static_cast<size_t>(i) : rng() % kept.size();
      kept.erase(kept.begin() + static_cast<std::ptrdiff_t>(at));
    }
    std::string text;
    for (const std::string& line : kept) text += line;
    ExpectParsesOrInputError(text, &accepted);
  }
  // The fuzz must reach both outcomes, or it tested nothing.
  EXPECT_GT(accepted, 10);
  EXPECT_LT(accepted, cases / 2);
  RecordProperty("cases", cases);
  RecordProperty("accepted", accepted);
}

// ---------------------------------------------------------------------------------------
// Rig::Check on rigs built in code.

TEST(RigTest, CheckNamesTheBadField) {
  EXPECT_EQ(MakeRig(true, true).Check(), "");
  EXPECT_EQ(Rig().Check(), "cameras.depth.width: must be in [1, 16384] px, got 0");

  Rig rig = MakeRig(true, true);
  rig.depth_scale = 0;
  EXPECT_EQ(rig.Check(), "depth_scale: must be in [1, 1e6] raw units per metre, got 0");

  rig = MakeRig(true, true);
  rig.rgb->fx = -1;
  EXPECT_EQ(rig.Check(), "cameras.rgb.fx: must be in [1, 1e6] px, got -1");

  rig = MakeRig(true, true);
  rig.depth_from_thermal.rotation.coeffs() << 0, 0, 0, 2;
  EXPECT_EQ(rig.Check(), "extrinsics.depth_from_thermal.q_xyzw: not a unit quaternion (norm 2)");

  rig = MakeRig(true, true);
  rig.rgb_time_offset_s = NAN;
  EXPECT_THAT(rig.Check(), StartsWith("time_offset_s.rgb: must be finite"));

  rig = MakeRig(true, true);
  rig.thermal_settings->emissivity = 0;
  EXPECT_EQ(rig.Check(), "thermal.emissivity: must be in [0.01, 1], got 0");

  rig = MakeRig(true, true);
  rig.thermal_settings.reset();
  EXPECT_EQ(rig.Check(), "thermal: required when cameras.thermal is present");

  // What rig.yaml cannot hold for an absent camera must not be set.
  rig = MakeRig(false, false);
  rig.thermal_settings = ThermalSettings();
  EXPECT_EQ(rig.Check(), "thermal: must be absent when cameras.thermal is absent");
  rig = MakeRig(false, false);
  rig.depth_from_rgb = MakeTransform(0.1);
  EXPECT_EQ(rig.Check(), "extrinsics.depth_from_rgb: must be identity when cameras.rgb is absent");
  rig = MakeRig(false, false);
  rig.thermal_time_offset_s = 0.5;
  EXPECT_EQ(rig.Check(),
            "time_offset_s.thermal: must be 0 when cameras.thermal is absent, got 0.5");
}

}  // namespace
}  // namespace hw::core
