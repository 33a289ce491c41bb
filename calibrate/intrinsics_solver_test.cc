#include "calibrate/intrinsics_solver.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "calibrate/synthetic_views.h"
#include "core/camera.h"
#include "core/cameramodel_io.h"
#include "core/rig.h"
#include "core/transform.h"

namespace hw::calibrate {
namespace {

constexpr double kNoisePx = 0.3;  // per-coordinate Gaussian noise of the synthetic corners

core::Target Chessboard() {  // 9 x 6 inner corners = 54, 4 cm squares
  core::Target target;
  target.type = core::TargetType::kChessboard;
  target.rows = 6;
  target.cols = 9;
  target.square_m = 0.04;
  return target;
}

core::CameraModel TruthCamera() { return test::SyntheticCamera(); }

std::vector<core::Rigid3d> RandomPoses(int count, bool fronto_parallel, unsigned seed,
                                       const core::Target& target = Chessboard()) {
  return test::RandomTargetPoses(TruthCamera(), target, count, fronto_parallel, seed);
}

// χ² of a solution's 9 intrinsics against the truth under its own covariance.
double Chi2AgainstTruth(const IntrinsicsResult& r) {
  const Eigen::VectorXd error = r.camera.Params() - TruthCamera().Params();
  return error.dot(r.intrinsics_covariance.ldlt().solve(error));
}

// The solution with the target shape estimated (the default) and ignored.
std::pair<IntrinsicsResult, IntrinsicsResult> SolveWithAndWithoutShape(const core::Target& target,
                                                                      const std::vector<ViewObservation>& views) {
  IntrinsicsOptions ignore;
  ignore.estimate_target_shape = false;
  return {SolveIntrinsics(target, 640, 480, views), SolveIntrinsics(target, 640, 480, views, ignore)};
}

std::vector<ViewObservation> Observe(const std::vector<core::Rigid3d>& poses, double noise_px,
                                     unsigned seed, const core::Target& target = Chessboard(),
                                     double keep_fraction = 1) {
  return test::ObserveTarget(TruthCamera(), target, poses, noise_px, seed, keep_fraction);
}

TEST(SolveIntrinsics, MatchesTruthWithinItsCovariance) {
  const std::vector<core::Rigid3d> poses = RandomPoses(20, false, 1);
  const IntrinsicsResult result =
      SolveIntrinsics(Chessboard(), 640, 480, Observe(poses, kNoisePx, 2));
  std::printf(
      "20 views x 54 corners, opencv5: solved in %.3f s, rms %.4f px, sigma %.4f px, "
      "%d outliers\n",
      result.solve_seconds, result.rms_px, result.observation_sigma_px, result.outliers);
  EXPECT_LT(result.solve_seconds, 1.0);
  ASSERT_EQ(result.mrcal_lensmodel, "LENSMODEL_OPENCV5");
  ASSERT_EQ(result.mrcal_intrinsics.size(), 9u);
  ASSERT_EQ(result.intrinsics_covariance.rows(), 9);
  const Eigen::VectorXd truth = TruthCamera().Params();
  const Eigen::VectorXd solved = result.camera.Params();
  const Eigen::VectorXd error = solved - truth;
  for (int i = 0; i < 9; ++i) {
    const double sigma = std::sqrt(result.intrinsics_covariance(i, i));
    std::printf("  param %d: truth %.6g solved %.6g error %.3g = %.2f sigma\n", i, truth(i),
                solved(i), error(i), error(i) / sigma);
    EXPECT_LT(std::abs(error(i)), 4 * sigma) << "param " << i;  // 4 sigma: p = 6e-5 each
  }
  // Mahalanobis distance: chi-square with 9 degrees of freedom, p = 0.001 at 27.9.
  const double chi2 = error.dot(result.intrinsics_covariance.ldlt().solve(error));
  std::printf("  chi2 (9 dof) of the intrinsics error: %.2f\n", chi2);
  EXPECT_LT(chi2, 27.9);
  // The noise estimate: 2160 measurements give it to ~1.5 % (1 sigma).
  EXPECT_NEAR(result.observation_sigma_px, kNoisePx, 0.05 * kNoisePx);
  // RMS residual norm = sigma sqrt(2 (1 - Nstate / Nmeas)), Nstate = 9 + 6 * 20 = 129.
  const double expected_rms = kNoisePx * std::sqrt(2.0 * (1.0 - 129.0 / 2160.0));
  EXPECT_NEAR(result.rms_px, expected_rms, 0.05 * expected_rms);
  EXPECT_GT(result.worst_px, result.rms_px);
  EXPECT_LT(result.outliers, 5);  // 3x the RMS norm: exp(-9) of Gaussian corners, ~0.1 expected
  ASSERT_EQ(result.camera_from_target.size(), 20u);
  // Every pose within its covariance (rt difference, first order): chi-square with 6 degrees
  // of freedom, p = 1e-4 at 27.9 (20 poses: 0.2 % chance of a false failure).
  for (size_t i = 0; i < poses.size(); ++i) {
    Eigen::Matrix<double, 6, 1> rt_error;
    rt_error << core::RodriguesFromQuaternion(result.camera_from_target[i].rotation) -
                    core::RodriguesFromQuaternion(poses[i].rotation),
        result.camera_from_target[i].translation - poses[i].translation;
    const int at = 9 + 6 * static_cast<int>(i);
    const Eigen::Matrix<double, 6, 6> pose_covariance = result.state_covariance.block<6, 6>(at, at);
    EXPECT_LT(rt_error.dot(pose_covariance.ldlt().solve(rt_error)), 27.9) << "view " << i;
  }
  ASSERT_EQ(result.residuals_px.size(), 20u);
  EXPECT_EQ(result.residuals_px[0].size(), 54u);
  EXPECT_EQ(result.view_rms_px.size(), 20u);
}

// A square_grid target (4 corners per hole: not the regular lattice of mrcal's chessboard
// observations) with 20 % of the corners missing in every view.
TEST(SolveIntrinsics, SquareGridWithMissingCorners) {
  const core::Target target = test::SquareGridTarget(4, 5, 0.03, 0.06);
  const std::vector<core::Rigid3d> poses = RandomPoses(15, false, 21, target);
  const std::vector<ViewObservation> views = Observe(poses, kNoisePx, 22, target, 0.8);
  const IntrinsicsResult result = SolveIntrinsics(target, 640, 480, views);
  const double chi2 = Chi2AgainstTruth(result);
  std::printf("  square_grid, 15 views, 80 %% of 80 corners: chi2 %.2f, sigma %.4f px\n", chi2,
              result.observation_sigma_px);
  EXPECT_LT(chi2, 27.9);  // chi-square, 9 degrees of freedom, p = 0.001
  EXPECT_NEAR(result.observation_sigma_px, kNoisePx, 0.07 * kNoisePx);  // ~1900 measurements
  EXPECT_EQ(result.residuals_px[0].size(), views[0].corner_ids.size());
}

// A heated mask whose holes the detector sees shifted as mrcal_problem.h's TargetShapeModel
// describes: every edge F(u) = -0.4 mm + 1.5 mm max(0, u) outwards (shrunk by bleeding, and
// by a side wall where it faces the camera). Estimated, the intrinsics are within their
// covariance and F is recovered at the knots (up to the linear part the poses absorb);
// ignored, the same data bias the intrinsics far beyond it.
TEST(SolveIntrinsics, EstimatesTheTargetShapeOfAHeatedMask) {
  const core::Target target = test::SquareGridTarget(5, 7, 0.02, 0.035);
  const auto F = [](double u) { return -0.0004 + 0.0015 * std::max(0.0, u); };
  const std::vector<core::Rigid3d> poses = RandomPoses(20, false, 31, target);
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  std::mt19937 rng(32);
  std::normal_distribution<double> noise(0, kNoisePx);
  std::vector<ViewObservation> views;
  for (const core::Rigid3d& pose : poses) {
    const Eigen::Vector3d c = pose.Inverse().translation;  // the camera centre, target frame
    ViewObservation view;
    for (size_t id = 0; id < corners.size(); ++id) {
      const size_t first = id / 4 * 4;
      const Eigen::Vector3d centre =
          0.25 * (corners[first] + corners[first + 1] + corners[first + 2] + corners[first + 3]);
      const double sx = corners[id].x() > centre.x() ? 1 : -1, sy = corners[id].y() > centre.y() ? 1 : -1;
      const double ux = -sx * (c.x() - corners[id].x()) / -c.z(), uy = -sy * (c.y() - corners[id].y()) / -c.z();
      const Eigen::Vector3d seen = corners[id] + Eigen::Vector3d(sx * F(ux), sy * F(uy), 0);
      view.corner_ids.push_back(static_cast<int>(id));
      view.pixels.push_back(TruthCamera().Project(pose * seen) + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    views.push_back(std::move(view));
  }
  const auto [estimated, ignored] = SolveWithAndWithoutShape(target, views);
  std::printf("  heated mask with walls: chi2 %.1f estimated (rms %.3f px), %.1f ignored (rms %.3f px)\n",
              Chi2AgainstTruth(estimated), estimated.rms_px, Chi2AgainstTruth(ignored), ignored.rms_px);
  EXPECT_LT(Chi2AgainstTruth(estimated), 27.9);  // chi-square, 9 degrees of freedom, p = 0.001
  EXPECT_GT(Chi2AgainstTruth(ignored), 40.0);  // p = 4e-6 for an unbiased solution
  // F at the knots the views reach (|u| <= 0.5 here), relative to F(0), up to the linear
  // part α u the poses absorb (mrcal_problem.h): the difference to the truth, less its best
  // line through 0, is noise. (F's constant trades with the shift in the image: at one
  // distance a metre on the target is nearly a fixed number of pixels.)
  const std::vector<double>& u = estimated.edge_shift_knots_u;
  ASSERT_EQ(estimated.edge_shift_m.size(), u.size());
  const size_t zero = static_cast<size_t>(std::find(u.begin(), u.end(), 0.0) - u.begin());
  ASSERT_LT(zero, u.size());
  const auto relative = [&](size_t j) { return estimated.edge_shift_m[j] - estimated.edge_shift_m[zero]; };
  double num = 0, den = 0;
  for (size_t j = 0; j < u.size(); ++j) {
    if (std::abs(u[j]) > 0.5) continue;
    num += u[j] * (relative(j) - (F(u[j]) - F(0)));
    den += u[j] * u[j];
  }
  ASSERT_GT(den, 0);
  for (size_t j = 0; j < u.size(); ++j) {
    if (std::abs(u[j]) > 0.5 || j == zero) continue;
    const double expected = F(u[j]) - F(0) + num / den * u[j];
    // σ of a difference of two correlated knots: at most the sum of their σ.
    const double sigma = estimated.edge_shift_sigma_m[j] + estimated.edge_shift_sigma_m[zero];
    std::printf("  F(%+.2f) - F(0): %.3f mm, expected %.3f, sigma <= %.3f\n", u[j], 1e3 * relative(j), 1e3 * expected,
                1e3 * sigma);
    EXPECT_NEAR(relative(j), expected, 3 * sigma) << "knot " << j;
  }
  // No shift in the image was put in (it trades with F's constant: 3 sigma, loose).
  EXPECT_LT(std::abs(estimated.edge_shift_px), 3 * estimated.edge_shift_sigma_px + 0.05);
}

// An aprilgrid whose tags the detector sees grown by 0.3 px in the image and shrunk by
// 0.4 mm on the target (libapriltag's bias changes with the tags' size in pixels; a print's
// ink spread is one in metres). Estimated, the intrinsics are within their covariance and
// both shifts are recovered within 3 sigma; ignored, the intrinsics are biased far beyond it.
TEST(SolveIntrinsics, EstimatesAnAprilGridsShiftInTheImageAndOnTheTarget) {
  core::Target target;
  target.type = core::TargetType::kAprilGrid;
  target.rows = 6;
  target.cols = 6;
  target.square_m = 0.03;
  target.pitch_m = 0.039;
  target.family = "tag36h11";
  constexpr double kImageShiftPx = 0.3, kTargetShiftM = -0.0004;
  const std::vector<core::Rigid3d> poses = RandomPoses(20, false, 51, target);
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  std::mt19937 rng(52);
  std::normal_distribution<double> noise(0, 0.1);  // the fixtures' aprilgrid residuals: 0.11 px RMS
  std::vector<ViewObservation> views;
  for (const core::Rigid3d& pose : poses) {
    ViewObservation view;
    for (size_t id = 0; id < corners.size(); ++id) {
      const size_t first = id / 4 * 4;
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (size_t j = first; j < first + 4; ++j) centre += 0.25 * corners[j];
      const double sx = corners[id].x() > centre.x() ? 1 : -1, sy = corners[id].y() > centre.y() ? 1 : -1;
      const Eigen::Vector3d grown = corners[id] + Eigen::Vector3d(sx, sy, 0) * kTargetShiftM;
      const Eigen::Vector2d q = TruthCamera().Project(pose * grown);
      // The two edges through the corner, moved kImageShiftPx along their outward image
      // normals: the corner moves by d with n_x·d = n_y·d = shift.
      const Eigen::Vector2d along_x = TruthCamera().Project(pose * (grown - Eigen::Vector3d(sx * 0.01, 0, 0))) - q;
      const Eigen::Vector2d along_y = TruthCamera().Project(pose * (grown - Eigen::Vector3d(0, sy * 0.01, 0))) - q;
      // The edge along x has the y-side outward normal, and vice versa.
      Eigen::Vector2d n_edge_x(-along_x.y(), along_x.x()), n_edge_y(-along_y.y(), along_y.x());
      n_edge_x.normalize();
      n_edge_y.normalize();
      if (n_edge_x.dot(-along_y) < 0) n_edge_x = -n_edge_x;  // outward: away from the tag's inside
      if (n_edge_y.dot(-along_x) < 0) n_edge_y = -n_edge_y;
      Eigen::Matrix2d N;
      N << n_edge_x.transpose(), n_edge_y.transpose();
      const Eigen::Vector2d d = N.inverse() * Eigen::Vector2d(kImageShiftPx, kImageShiftPx);
      view.corner_ids.push_back(static_cast<int>(id));
      view.pixels.push_back(q + d + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    views.push_back(std::move(view));
  }
  const auto [estimated, ignored] = SolveWithAndWithoutShape(target, views);
  ASSERT_EQ(estimated.edge_shift_m.size(), 1u);
  std::printf("  aprilgrid: chi2 %.1f estimated, %.1f ignored; image shift %.3f +- %.3f px (true %.3f), "
              "target shift %.3f +- %.3f mm (true %.3f)\n",
              Chi2AgainstTruth(estimated), Chi2AgainstTruth(ignored), estimated.edge_shift_px, estimated.edge_shift_sigma_px, kImageShiftPx,
              1e3 * estimated.edge_shift_m[0], 1e3 * estimated.edge_shift_sigma_m[0], 1e3 * kTargetShiftM);
  EXPECT_LT(Chi2AgainstTruth(estimated), 27.9);  // chi-square, 9 degrees of freedom, p = 0.001
  EXPECT_GT(Chi2AgainstTruth(ignored), 40.0);
  EXPECT_NEAR(estimated.edge_shift_px, kImageShiftPx, 3 * estimated.edge_shift_sigma_px);
  EXPECT_NEAR(estimated.edge_shift_m[0], kTargetShiftM, 3 * estimated.edge_shift_sigma_m[0]);
}

// The smallest masks still solve with the target shape estimated: 2 x 2 holes (16 corners a
// view), 6 views. Knots no edge reaches are held by the prior's gauge row alone; the
// solution must not be worse than with the shape ignored by more than the noise.
TEST(SolveIntrinsics, TinyMaskSolvesWithTheTargetShape) {
  const core::Target target = test::SquareGridTarget(2, 2, 0.04, 0.07);
  const std::vector<core::Rigid3d> poses = RandomPoses(6, false, 41, target);
  const std::vector<ViewObservation> views = Observe(poses, kNoisePx, 42, target);
  const auto [estimated, ignored] = SolveWithAndWithoutShape(target, views);
  std::printf("  2 x 2 mask, 6 views: chi2 %.1f estimated, %.1f ignored; sigma fx %.2f vs %.2f px\n",
              Chi2AgainstTruth(estimated), Chi2AgainstTruth(ignored), std::sqrt(estimated.intrinsics_covariance(0, 0)),
              std::sqrt(ignored.intrinsics_covariance(0, 0)));
  EXPECT_LT(Chi2AgainstTruth(estimated), 27.9);
  EXPECT_TRUE(std::isfinite(estimated.edge_shift_px));
  for (double sigma : estimated.edge_shift_sigma_m) EXPECT_TRUE(std::isfinite(sigma));
}

TEST(SolveIntrinsics, StagedAndUnstagedAgree) {
  const std::vector<ViewObservation> views = Observe(RandomPoses(15, false, 3), kNoisePx, 4);
  IntrinsicsOptions options;
  const IntrinsicsResult staged = SolveIntrinsics(Chessboard(), 640, 480, views, options);
  options.staged = false;
  const IntrinsicsResult direct = SolveIntrinsics(Chessboard(), 640, 480, views, options);
  for (size_t i = 0; i < staged.mrcal_intrinsics.size(); ++i) {
    const double sigma =
        std::sqrt(staged.intrinsics_covariance(static_cast<int>(i), static_cast<int>(i)));
    EXPECT_NEAR(staged.mrcal_intrinsics[i], direct.mrcal_intrinsics[i], 1e-3 * sigma);
  }
}

TEST(SolveIntrinsics, FlagsAPlantedOutlier) {
  std::vector<ViewObservation> views = Observe(RandomPoses(15, false, 5), kNoisePx, 6);
  views[3].pixels[10] += Eigen::Vector2d(3, 4);  // 5 px
  const IntrinsicsResult result = SolveIntrinsics(Chessboard(), 640, 480, views);
  EXPECT_TRUE(result.outlier[3][10]);
  EXPECT_NEAR(result.residuals_px[3][10].norm(), 5, 1.5);
  EXPECT_GE(result.outliers, 1);
  EXPECT_LT(result.outliers, 5);
  EXPECT_LT(result.worst_px, 5 * kNoisePx * std::sqrt(2.0));  // the outlier is not an inlier
}

TEST(SolveIntrinsics, OpenCv8Fits) {
  const std::vector<ViewObservation> views = Observe(RandomPoses(20, false, 7), kNoisePx, 8);
  IntrinsicsOptions options;
  options.model = LensModel::kOpenCv8;
  const IntrinsicsResult result = SolveIntrinsics(Chessboard(), 640, 480, views, options);
  EXPECT_EQ(result.mrcal_lensmodel, "LENSMODEL_OPENCV8");
  EXPECT_EQ(result.camera.distortion.size(), 8u);
  EXPECT_NEAR(result.observation_sigma_px, kNoisePx, 0.05 * kNoisePx);
  // The extra coefficients trade off against each other and against the poses, so compare
  // projections as ProjectionUncertaintyMap defines them: a point at 1 m on the truth's ray
  // of q, fixed in the targets' frames (truth poses), seen through the solved poses (mean)
  // and intrinsics, lands within 4 predicted sigmas (worst direction) of q.
  const std::vector<core::Rigid3d> poses = RandomPoses(20, false, 7);
  const core::CameraModel truth = TruthCamera();
  const std::vector<double> sigma_px = ProjectionUncertaintyMap(result, 5, 5, 1.0);
  for (int row = 0; row < 5; ++row) {
    for (int col = 0; col < 5; ++col) {
      const Eigen::Vector2d q(col * 639.0 / 4, row * 479.0 / 4);
      const Eigen::Vector3d p_cam = truth.Unproject(q)->normalized();
      Eigen::Vector3d p_cam_solved = Eigen::Vector3d::Zero();
      for (size_t i = 0; i < poses.size(); ++i) {
        p_cam_solved += result.camera_from_target[i] * (poses[i].Inverse() * p_cam) / 20.0;
      }
      const double error_px = (result.camera.Project(p_cam_solved) - q).norm();
      EXPECT_LT(error_px, 4 * sigma_px[static_cast<size_t>(5 * row + col)]) << q.transpose();
    }
  }
}

// Monte-Carlo: 40 noisy copies of the same poses, re-solved; the spread of the projection of
// a point fixed in the targets' frames (as ProjectionUncertaintyMap defines it) against the
// prediction from one solve.
TEST(ProjectionUncertaintyMap, AgreesWithMonteCarlo) {
  const std::vector<core::Rigid3d> poses = RandomPoses(15, false, 9);
  const core::CameraModel truth = TruthCamera();
  constexpr int kCols = 3, kRows = 3, kSamples = 40;
  constexpr double kRangeM = 1.0;
  std::vector<IntrinsicsResult> solutions;
  for (int k = 0; k < kSamples; ++k) {
    solutions.push_back(SolveIntrinsics(Chessboard(), 640, 480, Observe(poses, kNoisePx, 100 + k)));
  }
  // The prediction depends on the solution it is computed at (strongly so in the image
  // corners, extrapolated beyond the observed corners): the expected variance is the mean of
  // the solutions' predicted variances.
  std::vector<double> predicted(kCols * kRows, 0.0);
  for (const IntrinsicsResult& solution : solutions) {
    const std::vector<double> map = ProjectionUncertaintyMap(solution, kCols, kRows, kRangeM);
    ASSERT_EQ(map.size(), predicted.size());
    for (size_t i = 0; i < map.size(); ++i) predicted[i] += map[i] * map[i] / kSamples;
  }
  for (double& value : predicted) value = std::sqrt(value);
  for (int row = 0; row < kRows; ++row) {
    for (int col = 0; col < kCols; ++col) {
      const Eigen::Vector2d q(col * 639.0 / (kCols - 1), row * 479.0 / (kRows - 1));
      const Eigen::Vector3d p_cam = kRangeM * truth.Unproject(q)->normalized();
      std::vector<Eigen::Vector2d> projected;
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (const IntrinsicsResult& solution : solutions) {
        Eigen::Vector3d p_cam_solved = Eigen::Vector3d::Zero();
        for (size_t i = 0; i < poses.size(); ++i) {
          p_cam_solved += solution.camera_from_target[i] * (poses[i].Inverse() * p_cam);
        }
        projected.push_back(
            solution.camera.Project(p_cam_solved / static_cast<double>(poses.size())));
        mean += projected.back() / kSamples;
      }
      Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
      for (const Eigen::Vector2d& p : projected)
        cov += (p - mean) * (p - mean).transpose() / (kSamples - 1);
      const double empirical =
          std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(1));
      const double prediction = predicted[static_cast<size_t>(row * kCols + col)];
      std::printf("  q (%.0f, %.0f): predicted %.4f px, Monte-Carlo %.4f px (%+.0f %%)\n", q.x(),
                  q.y(), prediction, empirical, 100 * (empirical / prediction - 1));
      // 40 samples give a standard deviation to ~11 % (1 sigma): 30 % is ~2.7 sigma. The image
      // corners lie beyond every observed target corner, where the linearisation is least
      // accurate and the four corners move together (one draw, not four): 45 % there.
      const bool image_corner = (row == 0 || row == kRows - 1) && (col == 0 || col == kCols - 1);
      EXPECT_NEAR(empirical, prediction, (image_corner ? 0.45 : 0.3) * prediction) << q.transpose();
    }
  }
}

TEST(ProjectionUncertaintyMap, IsSmallestWhereTheTargetWasSeen) {
  const IntrinsicsResult result =
      SolveIntrinsics(Chessboard(), 640, 480, Observe(RandomPoses(15, false, 11), kNoisePx, 12));
  const std::vector<double> map = ProjectionUncertaintyMap(result, 5, 5, 1.0);
  ASSERT_EQ(map.size(), 25u);
  for (double value : map) EXPECT_TRUE(std::isfinite(value) && value > 0);
  EXPECT_LT(map[12], map[0]);  // centre vs corner: the corners are extrapolated
  EXPECT_LT(map[12], map[24]);
  EXPECT_THROW(ProjectionUncertaintyMap(result, 0, 5, 1.0), std::invalid_argument);
  EXPECT_THROW(ProjectionUncertaintyMap(result, 5, 5, 0.0), std::invalid_argument);
  EXPECT_THROW(ProjectionUncertaintyMap(IntrinsicsResult{}, 5, 5, 1.0), std::invalid_argument);
}

std::string ErrorOf(const std::vector<ViewObservation>& views,
                    const IntrinsicsOptions& options = {}) {
  try {
    SolveIntrinsics(Chessboard(), 640, 480, views, options);
  } catch (const std::invalid_argument& error) {
    return error.what();
  }
  return "";
}

TEST(SolveIntrinsics, RefusesTooFewViews) {
  const std::vector<ViewObservation> views = Observe(RandomPoses(2, false, 13), kNoisePx, 14);
  EXPECT_NE(ErrorOf(views).find("2 views given, at least 3"), std::string::npos) << ErrorOf(views);
}

TEST(SolveIntrinsics, RefusesFrontoParallelViews) {
  const std::vector<ViewObservation> views = Observe(RandomPoses(10, true, 15), kNoisePx, 16);
  EXPECT_NE(ErrorOf(views).find("fronto-parallel"), std::string::npos) << ErrorOf(views);
  const std::vector<ViewObservation> exact = Observe(RandomPoses(10, true, 17), 0, 18);
  EXPECT_NE(ErrorOf(exact).find("fronto-parallel"), std::string::npos) << ErrorOf(exact);
}

TEST(SolveIntrinsics, RefusesBadInputs) {
  std::vector<ViewObservation> views = Observe(RandomPoses(3, false, 19), kNoisePx, 20);
  IntrinsicsOptions options;
  options.outlier_sigmas = 1;
  EXPECT_EQ(ErrorOf(views, options),
            "intrinsics options: outlier_sigmas: must be in (1, 100], got 1");
  views[1].corner_ids[5] = 54;
  EXPECT_NE(ErrorOf(views).find("view 1: corner id 54 is outside"), std::string::npos);
  views[1].corner_ids[5] = 4;
  EXPECT_NE(ErrorOf(views).find("view 1: corner id 4 appears twice"), std::string::npos);
  views[1].corner_ids.resize(3);
  EXPECT_NE(ErrorOf(views).find("view 1: 3 corner ids but 54 pixels"), std::string::npos);
}

}  // namespace
}  // namespace hw::calibrate
