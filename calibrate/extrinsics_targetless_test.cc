// The targetless extrinsics on the fixtures' `extrinsics-targetless` sessions against their
// truth, several seeds; and its failures.

#include "calibrate/extrinsics_targetless.h"

#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/rig.h"
#include "fixtures/cached_test_data.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;
using fixtures::CalibrationSessionKind;
using fixtures::CalibrationSessionOptions;

// The small session made longer and sparser: 3 s of the hand-held path at 10 Hz depth and
// 9 Hz thermal (as many frames to render as 1 s at 30/27 Hz, three times the viewpoints;
// consecutive frames at 27 Hz see nearly the same lines and add little).
fs::path Session(uint64_t seed) {
  CalibrationSessionOptions o = CalibrationSessionOptions::Preset(CalibrationSessionKind::kTargetlessExtrinsics, true, seed);
  o.targetless.duration_s = 3.0;
  o.targetless.depth_rate_hz = 10;
  o.targetless.thermal_rate_hz = 9;
  return fixtures::test::CachedSession("targetless-3s-seed" + std::to_string(seed), o, "thermal.txt");
}

// As on the bench: the true rig's intrinsics and clock offsets (calibrated before), the
// nominal rig's depth_from_thermal (1°/1 cm off) as the start.
core::Scan OpenWithBenchRig(const fs::path& session, core::Rig* truth) {
  *truth = core::ReadRig(session / "truth" / "rig.yaml");
  core::Rig start = *truth;
  start.depth_from_thermal = core::ReadRig(session / "rig.yaml").depth_from_thermal;
  const fs::path rig_path = session.parent_path() / (session.filename().string() + "-bench-rig.yaml");
  core::WriteRig(rig_path, start);
  core::ScanOptions options;
  options.rig_path = rig_path;
  return core::Scan::Open(session, options);
}

struct Run {
  double rotation_deg = 0, translation_mm = 0;
  ExtrinsicsSigmas sigmas;
};

// With the groundtruth trajectory. Bounds on the SMALL session (160×120 thermal, f 148 px:
// one pixel is 0.39°; ~27 frames): rotation 0.5° (the target) and translation 2 cm
// (twice the 1 cm: the small images' lines, ~1 m long at 2 m, constrain the
// translation along the viewing direction weakly; the full-size session, measured with
// bench_targetless_speed, meets 1 cm); the error within 4σ per block (3 dof: 99.6 % below
// 3.7 when the covariance is right; the small session's ~30 frames are few clusters for the
// sandwich).
void CheckSeeds(uint64_t first, uint64_t last) {
  for (uint64_t seed = first; seed <= last; ++seed) {
    core::Rig truth;
    const core::Scan scan = OpenWithBenchRig(Session(seed), &truth);
    TargetlessOptions options;
    const TargetlessResult r = EstimateTargetlessExtrinsics(scan, scan.groundtruth(), options);
    const double rot = RotationErrorDeg(r.estimate.depth_from_camera, truth.depth_from_thermal);
    const double tra = TranslationErrorMm(r.estimate.depth_from_camera, truth.depth_from_thermal);
    const ExtrinsicsSigmas s = ErrorInSigmas(r.estimate, truth.depth_from_thermal);
    std::printf("seed %lu: %zu frames, %d matches, error %.3f deg %.2f mm, %.2f / %.2f sigmas, edge %.2f px\n", seed,
                r.frames.size(), r.matches, rot, tra, s.rotation, s.translation, r.edge_offset_px);
    EXPECT_LT(rot, 0.5) << "seed " << seed;
    EXPECT_LT(tra, 20.0) << "seed " << seed;
    EXPECT_LT(s.rotation, 4.0) << "seed " << seed;
    EXPECT_LT(s.translation, 4.0) << "seed " << seed;
    EXPECT_EQ(r.estimate.camera, "thermal");
    EXPECT_GT(r.estimate.observations, 0);
    // The diagnostic image draws.
    const cv::Mat diagnostic = DrawTargetlessDiagnostic(scan, r, 0, options, 2);
    EXPECT_EQ(diagnostic.cols, 2 * truth.thermal->width);
  }
}

TEST(TargetlessExtrinsics, RecoversTheTruthOnSmallSessions) { CheckSeeds(1, 3); }

// More seeds than the suite renders (each ~20 s to render once): run with
// --gtest_also_run_disabled_tests to check the bounds are not tuned to seeds 1–3.
TEST(TargetlessExtrinsics, DISABLED_RecoversTheTruthOnMoreSeeds) { CheckSeeds(4, 8); }

// Without a trajectory only frame pairs within 10 ms are used and the motion in between is
// not compensated: either an estimate (reported, not bounded beyond sanity) or a clear
// InputError naming the folder — never a crash.
TEST(TargetlessExtrinsics, WithoutTrajectoryEstimatesOrFailsClearly) {
  core::Rig truth;
  const fs::path session = Session(1);
  const core::Scan scan = OpenWithBenchRig(session, &truth);
  try {
    const TargetlessResult r = EstimateTargetlessExtrinsics(scan, std::nullopt, TargetlessOptions{});
    std::printf("no trajectory: %zu frames, error %.3f deg %.2f mm\n", r.frames.size(),
                RotationErrorDeg(r.estimate.depth_from_camera, truth.depth_from_thermal),
                TranslationErrorMm(r.estimate.depth_from_camera, truth.depth_from_thermal));
    EXPECT_LT(RotationErrorDeg(r.estimate.depth_from_camera, truth.depth_from_thermal), 3.0);
  } catch (const core::InputError& e) {
    std::printf("no trajectory: %s\n", e.what());
    EXPECT_EQ(e.path(), session);
  }
}

// Too few lines: a single frame cannot determine the pose → InputError naming the folder.
TEST(TargetlessExtrinsics, TooFewFramesFailWithTheFolder) {
  core::Rig truth;
  const fs::path session = Session(1);
  const core::Scan scan = OpenWithBenchRig(session, &truth);
  TargetlessOptions options;
  options.max_frames = 1;
  try {
    EstimateTargetlessExtrinsics(scan, scan.groundtruth(), options);
    FAIL() << "no error";
  } catch (const core::InputError& e) {
    EXPECT_EQ(e.path(), session);
    EXPECT_NE(std::string(e.what()).find("targetless extrinsics"), std::string::npos) << e.what();
  }
}

TEST(TargetlessExtrinsics, OptionsCheckNamesTheSubStruct) {
  TargetlessOptions o;
  EXPECT_EQ(o.Check(), "");
  o.image_lines.lsd_scale = 2;
  EXPECT_NE(o.Check().find("image_lines.lsd_scale"), std::string::npos) << o.Check();
  o = {};
  o.max_pair_dt_s = 0;
  EXPECT_NE(o.Check().find("max_pair_dt_s"), std::string::npos);
}

}  // namespace
}  // namespace hw::calibrate
