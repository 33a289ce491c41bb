#include "calibrate/line_alignment.h"

#include <random>

#include <gtest/gtest.h>

namespace hw::calibrate {
namespace {

constexpr double kDeg = M_PI / 180.0;

core::CameraModel Camera() {
  core::CameraModel k = core::CameraModel::Pinhole(320, 240, 300, 300);
  k.cx = 159.5;
  k.cy = 119.5;
  return k;
}

core::Rigid3d TruePose() {
  return core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d(1, -0.7, 0.3).normalized())),
                       Eigen::Vector3d(0.045, -0.028, 0.004));
}

core::Rigid3d Perturbed(const core::Rigid3d& pose, double deg, double m) {
  return core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(deg * kDeg, Eigen::Vector3d(0.3, 1, -0.5).normalized())) *
                           pose.rotation,
                       pose.translation + m * Eigen::Vector3d(1, -1, 1).normalized());
}

// Frames of random 3D segments 1–3 m in front of the thermal camera, each seen as its exact
// projection plus Gaussian noise of noise_px on the 2D endpoints. `direction` fixes every
// segment's direction (degenerate); zero: random directions.
std::vector<LineFrame> Frames(int frames, int lines, double noise_px, const Eigen::Vector3d& direction, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(-1, 1);
  std::normal_distribution<double> noise(0, noise_px);
  const core::CameraModel k = Camera();
  const core::Rigid3d pose = TruePose();
  std::vector<LineFrame> out;
  for (int f = 0; f < frames; ++f) {
    LineFrame frame;
    frame.thermal_index = f;
    while (static_cast<int>(frame.lines_3d.size()) < lines) {
      const Eigen::Vector3d centre_th(0.6 * uni(rng), 0.45 * uni(rng), 2.0 + uni(rng));
      Eigen::Vector3d dir = direction.norm() > 0 ? direction.normalized()
                                                 : Eigen::Vector3d(uni(rng), uni(rng), 0.3 * uni(rng)).normalized();
      const double half = 0.15 + 0.1 * uni(rng);
      Segment3d s;
      s.a = pose * (centre_th - half * dir);
      s.b = pose * (centre_th + half * dir);
      Eigen::Vector2d a, b;
      if (!ProjectSegment(s, pose, k, &a, &b) || !k.IsInImage(a) || !k.IsInImage(b)) continue;
      frame.lines_3d.push_back(s);
      frame.lines_2d.push_back({a + Eigen::Vector2d(noise(rng), noise(rng)), b + Eigen::Vector2d(noise(rng), noise(rng))});
    }
    out.push_back(frame);
  }
  return out;
}

// Exact lines: the alignment converges from 1°/1 cm off to the truth (noise-free data; the
// bound is the convergence tolerance, 1e-3° / 1e-3 mm, with margin).
TEST(LineAlignment, RecoversTheTruthFromExactLines) {
  const auto frames = Frames(10, 8, 0.0, Eigen::Vector3d::Zero(), 1);
  const LineAlignmentResult r = AlignLines(frames, Camera(), Perturbed(TruePose(), 1.0, 0.01), {});
  ASSERT_EQ(r.failure, "");
  EXPECT_LT(RotationErrorDeg(r.estimate.depth_from_camera, TruePose()), 0.01);
  EXPECT_LT(TranslationErrorMm(r.estimate.depth_from_camera, TruePose()), 0.1);
  EXPECT_EQ(r.matches.size(), 80u);
}

// Noisy endpoints (0.3 px): over seeds, the error stays within the reported covariance
// (χ with 3 dof: 99 % below 3.4; 3 seeds, so 4 allows for one unlucky draw) and the σ is
// small (thousands of residuals).
TEST(LineAlignment, CovarianceCoversTheErrorOnNoisyLines) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const auto frames = Frames(40, 8, 0.3, Eigen::Vector3d::Zero(), seed);
    const LineAlignmentResult r = AlignLines(frames, Camera(), Perturbed(TruePose(), 1.0, 0.01), {});
    ASSERT_EQ(r.failure, "") << "seed " << seed;
    const ExtrinsicsSigmas s = ErrorInSigmas(r.estimate, TruePose());
    EXPECT_LT(s.rotation, 4.0) << "seed " << seed;
    EXPECT_LT(s.translation, 4.0) << "seed " << seed;
    EXPECT_LT(RotationErrorDeg(r.estimate.depth_from_camera, TruePose()), 0.1) << "seed " << seed;
    EXPECT_LT(TranslationErrorMm(r.estimate.depth_from_camera, TruePose()), 5) << "seed " << seed;
  }
}

// Every line parallel to the depth frame's x axis: the translation along x is unobservable
// (moving along a line keeps it on itself) — a failure naming that direction, no number.
// (With noisy 2D lines the information is not exactly singular; the σ bound
// max_sigma_mm catches that case.)
TEST(LineAlignment, AllLinesParallelFailNamingTheDirection) {
  const core::Rigid3d pose = TruePose();
  const Eigen::Vector3d x_in_thermal = pose.rotation.conjugate() * Eigen::Vector3d::UnitX();
  const auto frames = Frames(10, 8, 0.0, x_in_thermal, 4);
  const LineAlignmentResult r = AlignLines(frames, Camera(), pose, {});
  EXPECT_NE(r.failure.find("translation along the depth frame's direction [1.00, 0.00, 0.00]"), std::string::npos)
      << r.failure;
  EXPECT_TRUE(r.estimate.covariance.isZero()) << r.estimate.covariance;
}

TEST(LineAlignment, TooFewLinesFail) {
  const auto frames = Frames(1, 3, 0.0, Eigen::Vector3d::Zero(), 5);
  const LineAlignmentResult r = AlignLines(frames, Camera(), TruePose(), {});
  EXPECT_NE(r.failure.find("too few line matches: 3"), std::string::npos) << r.failure;
}

TEST(LineAlignment, OptionsCheckNamesTheField) {
  LineAlignmentOptions o;
  EXPECT_EQ(o.Check(), "");
  o.final_gate_mrad = 100;
  EXPECT_NE(o.Check().find("final_gate_mrad"), std::string::npos);
  o = {};
  o.cluster_frames = 0;
  EXPECT_NE(o.Check().find("cluster_frames"), std::string::npos);
}

}  // namespace
}  // namespace hw::calibrate
