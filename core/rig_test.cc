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
#include "core/rig_test_support.h"
#include "core/splined_test_support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using hw::test::LineOf;
using hw::test::Replace;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using namespace rig_test;

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

// The heatwave extension rolling_shutter_s (the colour camera's readout): written only when
// not 0, read back bit for bit, checked against its range and its camera.
TEST(RigTest, RollingShutterRoundTripsAndIsChecked) {
  Rig rig = MakeRig(true, true);
  EXPECT_EQ(FormatRig(rig).find("rolling_shutter_s"), std::string::npos);
  rig.rgb_readout_s = 0.0271234;
  const std::string text = FormatRig(rig);
  EXPECT_THAT(text, HasSubstr("rolling_shutter_s:"));
  EXPECT_THAT(text, HasSubstr("  rgb: 0.0271234\n"));
  ExpectSameRig(rig, ParseRig(text, "rig.yaml"));

  const std::string full = kFullRig;
  EXPECT_THAT(RigError(full + "rolling_shutter_s:\n  rgb: 0.2\n"),
              HasSubstr("rolling_shutter_s.rgb: must be in [0, 0.1] s, got 0.2"));
  EXPECT_THAT(RigError(full + "rolling_shutter_s:\n  rgb: -0.01\n"),
              HasSubstr("rolling_shutter_s.rgb: must be in [0, 0.1] s, got -0.01"));
  EXPECT_THAT(RigError(full + "rolling_shutter_s:\n  thermal: 0.01\n"), HasSubstr("rolling_shutter_s: unknown key 'thermal'"));
  EXPECT_THAT(RigError(FormatRig(MakeRig(false, true)) + "rolling_shutter_s:\n  rgb: 0.02\n"),
              HasSubstr("rolling_shutter_s.rgb: given but cameras.rgb is absent"));
  EXPECT_EQ(ParseRig(full + "rolling_shutter_s:\n  rgb: 0.1\n", "rig.yaml").rgb_readout_s, 0.1);

  rig.rgb_readout_s = std::nan("");
  EXPECT_THAT(rig.Check(), HasSubstr("rolling_shutter_s.rgb: must be in [0, 0.1] s"));
  Rig no_rgb = MakeRig(false, true);
  no_rgb.rgb_readout_s = 0.02;
  EXPECT_THAT(no_rgb.Check(), HasSubstr("rolling_shutter_s.rgb: must be 0 when cameras.rgb is absent"));
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


// ---------------------------------------------------------------------------------------
// Splined cameras (mrcal LENSMODEL_SPLINED_STEREOGRAPHIC; beyond scan-format.md).

namespace splined {

Rig SplinedRig() {
  Rig rig = MakeRig(true, true);
  rig.thermal = test::SplinedTestCamera(640, 512, 554, {2, 10, 9, 66}, -0.12);
  rig.thermal->distortion[5] = 1.0 / 3.0 * 1e-3;  // all 17 digits
  rig.thermal->distortion[6] = 5e-324;
  return rig;
}

TEST(RigSplinedTest, RoundTripsBitForBit) {
  const Rig rig = SplinedRig();
  const std::string text = FormatRig(rig);
  EXPECT_THAT(text, HasSubstr("    model: splined"));
  EXPECT_THAT(text, HasSubstr("    splined: { order: 2, nx: 10, ny: 9, fov_x_deg: 66 }"));
  const Rig back = ParseRig(text, "rig.yaml");
  ExpectSameRig(rig, back);
  EXPECT_TRUE(*back.thermal == *rig.thermal);
  EXPECT_EQ(FormatRig(back), text);
}

// The thermal camera of SplinedRig's text with `from` replaced by `to`: the InputError.
std::string SplinedError(const std::string& from, const std::string& to) {
  const std::string text = FormatRig(SplinedRig());
  EXPECT_NE(text.find(from), std::string::npos) << from;
  return RigError(Replace(text, from, to));
}

TEST(RigSplinedTest, BadConfigsAreRefusedNamingTheKey) {
  EXPECT_THAT(SplinedError("order: 2", "order: 4"),
              HasSubstr("cameras.thermal.splined.order: must be 2 or 3, got 4"));
  EXPECT_THAT(SplinedError("nx: 10", "nx: 3"),
              HasSubstr("cameras.thermal.splined.nx: must be in [4, 64], got 3"));
  EXPECT_THAT(SplinedError("ny: 9", "ny: 65"),
              HasSubstr("cameras.thermal.splined.ny: must be in [4, 64], got 65"));
  EXPECT_THAT(SplinedError("fov_x_deg: 66", "fov_x_deg: 180"),
              HasSubstr("cameras.thermal.splined.fov_x_deg: must be in [1, 179] degrees, got 180"));
  EXPECT_THAT(SplinedError("fov_x_deg: 66", "fov_x_deg: 66.5"),
              HasSubstr("cameras.thermal.splined.fov_x_deg"));
  EXPECT_THAT(SplinedError("nx: 10", "nx: 11"),
              HasSubstr("cameras.thermal.distortion: splined with nx = 11, ny = 9 needs 2 nx ny "
                        "= 198 control values, got 180"));
  EXPECT_THAT(SplinedError(", fov_x_deg: 66", ""),
              HasSubstr("cameras.thermal.splined.fov_x_deg: missing required key"));
  EXPECT_THAT(SplinedError(" }   # mrcal", ", knots: 3 }   # mrcal"),
              HasSubstr("cameras.thermal.splined: unknown key 'knots'"));
  // The block belongs to splined cameras only, and they need it.
  EXPECT_THAT(SplinedError("    splined: { order: 2", "    splined: { order: 2"),
              HasSubstr("<no error>"));
  EXPECT_THAT(SplinedError("model: splined", "model: opencv"),
              HasSubstr("cameras.thermal.splined: only a splined camera has this block"));
  const std::string text = FormatRig(SplinedRig());
  const size_t begin = text.find("    splined: {");
  const std::string without_block = text.substr(0, begin) + text.substr(text.find('\n', begin) + 1);
  EXPECT_THAT(RigError(without_block), HasSubstr("cameras.thermal.splined: missing required key"));
}

}  // namespace splined

}  // namespace
}  // namespace hw::core
