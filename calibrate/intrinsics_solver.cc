#include "calibrate/intrinsics_solver.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "calibrate/mrcal_problem.h"
#include "core/camera_mrcal.h"
#include "core/cameramodel_io.h"
#include "core/option_check.h"

namespace hw::calibrate {
namespace {

constexpr int kMinViews = 3;
constexpr int kMinCornersPerView = 4;
constexpr int kMaxOutlierIterations = 20;
constexpr int kMaxShapeSteps = 10;
// Largest relative standard error of the homography focal estimate accepted as a seed: 10 %
// in f is well within mrcal's convergence basin; fronto-parallel views give 100 % or more.
constexpr double kMaxSeedFocalRelativeError = 0.1;

void CheckInputs(int width_px, int height_px, const std::vector<ViewObservation>& views,
                 const IntrinsicsOptions& options, int num_corners) {
  if (const std::string problem = options.Check(); !problem.empty()) {
    throw std::invalid_argument("intrinsics options: " + problem);
  }
  if (width_px < 1 || width_px > core::CameraModel::kMaxSidePx || height_px < 1 ||
      height_px > core::CameraModel::kMaxSidePx) {
    throw std::invalid_argument("intrinsics: the image size " + std::to_string(width_px) + " x " +
                                std::to_string(height_px) + " px is outside [1, 16384]");
  }
  if (static_cast<int>(views.size()) < kMinViews) {
    throw std::invalid_argument("intrinsics: " + std::to_string(views.size()) +
                                " views given, at least 3 are needed (with the target tilted "
                                "differently in each) to solve a camera's intrinsics");
  }
  for (size_t v = 0; v < views.size(); ++v) {
    const ViewObservation& view = views[v];
    const std::string name = "intrinsics: view " + std::to_string(v) + ": ";
    if (view.corner_ids.size() != view.pixels.size()) {
      throw std::invalid_argument(name + std::to_string(view.corner_ids.size()) +
                                  " corner ids but " + std::to_string(view.pixels.size()) +
                                  " pixels");
    }
    if (static_cast<int>(view.corner_ids.size()) < kMinCornersPerView) {
      throw std::invalid_argument(name + std::to_string(view.corner_ids.size()) +
                                  " corners, at least 4 are needed for its pose");
    }
    std::vector<bool> seen(static_cast<size_t>(num_corners), false);
    for (size_t k = 0; k < view.corner_ids.size(); ++k) {
      const int id = view.corner_ids[k];
      if (id < 0 || id >= num_corners) {
        throw std::invalid_argument(name + "corner id " + std::to_string(id) +
                                    " is outside the target's [0, " + std::to_string(num_corners) +
                                    ")");
      }
      if (seen[static_cast<size_t>(id)]) {
        throw std::invalid_argument(name + "corner id " + std::to_string(id) + " appears twice");
      }
      seen[static_cast<size_t>(id)] = true;
      if (!view.pixels[k].allFinite()) {
        throw std::invalid_argument(name + "the pixel of corner " + std::to_string(id) +
                                    " is not finite");
      }
    }
  }
}

// Focal length (pixels, fx = fy) from the views' homographies, principal point at the
// centre: with H ~ K [r1 r2 t] (pixels shifted to the centre and scaled by 1 / s), the
// orthonormality of r1, r2 gives per view two equations linear in a = 1 / f^2 (Zhang 2000,
// with K's only unknown f). A view parallel to the image plane makes both right-hand sides
// zero (its homography carries no perspective), so a set of such views leaves a at 0 +/-
// noise: the estimate is refused when a <= 0 or its relative standard error is too large.
double SeedFocalPx(const std::vector<Eigen::Vector3d>& corners_target, int width_px, int height_px,
                   const std::vector<ViewObservation>& views) {
  const double cx = (width_px - 1) / 2.0, cy = (height_px - 1) / 2.0;
  const double scale = 1.0 / std::max(width_px, height_px);  // keeps a near 1
  Eigen::MatrixXd A(2 * static_cast<int>(views.size()), 1);
  Eigen::VectorXd b(A.rows());
  for (size_t v = 0; v < views.size(); ++v) {
    std::vector<cv::Point2d> object, image;
    for (size_t k = 0; k < views[v].corner_ids.size(); ++k) {
      const Eigen::Vector3d& p = corners_target[static_cast<size_t>(views[v].corner_ids[k])];
      object.emplace_back(p.x(), p.y());
      image.emplace_back((views[v].pixels[k].x() - cx) * scale,
                         (views[v].pixels[k].y() - cy) * scale);
    }
    const cv::Mat H_cv = cv::findHomography(object, image, 0);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    if (!H_cv.empty()) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) H(r, c) = H_cv.at<double>(r, c);
      }
      H /= H.norm();
    }
    const Eigen::Vector3d h1 = H.col(0), h2 = H.col(1);
    const int row = 2 * static_cast<int>(v);
    A(row, 0) = h1.x() * h2.x() + h1.y() * h2.y();
    b(row) = -h1.z() * h2.z();
    A(row + 1, 0) = h1.x() * h1.x() - h2.x() * h2.x() + h1.y() * h1.y() - h2.y() * h2.y();
    b(row + 1) = -(h1.z() * h1.z() - h2.z() * h2.z());
  }
  const double ata = A.squaredNorm();
  const double a = ata > 0 ? A.col(0).dot(b) / ata : 0;
  const double dof = static_cast<double>(A.rows() - 1);
  const double a_std = std::sqrt((b - A * a).squaredNorm() / dof / ata);
  // f = 1 / sqrt(a): its relative error is half that of a.
  if (!(a > 0) || !(0.5 * a_std / a <= kMaxSeedFocalRelativeError)) {
    throw std::invalid_argument(
        "intrinsics: the views do not constrain the focal length — the target is (nearly) "
        "fronto-parallel in all of them, or too few views disagree too much through the lens's "
        "distortion (homography focal estimate: 1/f^2 = " +
        std::to_string(a) + " +/- " + std::to_string(a_std) +
        " in units of the image size); tilt the target 20-40 degrees about different axes "
        "in several views, and add views");
  }
  return 1.0 / std::sqrt(a) / scale;
}

// camera_from_target of every view by PnP on the seed pinhole camera (planar IPPE).
std::vector<mrcal_pose_t> SeedPoses(const std::vector<Eigen::Vector3d>& corners_target, double f_px,
                                    int width_px, int height_px,
                                    const std::vector<ViewObservation>& views) {
  const cv::Matx33d K(f_px, 0, (width_px - 1) / 2.0, 0, f_px, (height_px - 1) / 2.0, 0, 0, 1);
  std::vector<mrcal_pose_t> poses;
  for (size_t v = 0; v < views.size(); ++v) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (size_t k = 0; k < views[v].corner_ids.size(); ++k) {
      const Eigen::Vector3d& p = corners_target[static_cast<size_t>(views[v].corner_ids[k])];
      object.emplace_back(p.x(), p.y(), p.z());
      image.emplace_back(views[v].pixels[k].x(), views[v].pixels[k].y());
    }
    cv::Vec3d rvec, tvec;
    if (!cv::solvePnP(object, image, K, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE) ||
        !(tvec[2] > 0)) {
      throw std::invalid_argument("intrinsics: view " + std::to_string(v) +
                                  ": no pose of the target fits its corners (PnP failed)");
    }
    poses.push_back({{{rvec[0], rvec[1], rvec[2]}}, {{tvec[0], tvec[1], tvec[2]}}});
  }
  return poses;
}

mrcal_lensmodel_t ParametricLensModel(LensModel model) {
  mrcal_lensmodel_t lensmodel{};
  // A splined solve starts from opencv8, the richest parametric model (mrcal's workflow).
  lensmodel.type = model == LensModel::kOpenCv5 ? MRCAL_LENSMODEL_OPENCV5 : MRCAL_LENSMODEL_OPENCV8;
  return lensmodel;
}

void CheckOverdetermined(const MrcalProblem& problem, const std::string& hint) {
  if (2 * problem.NumObservations() <= problem.NumState()) {
    throw std::invalid_argument("intrinsics: " + std::to_string(problem.NumObservations()) +
                                " corners give " + std::to_string(2 * problem.NumObservations()) +
                                " measurements for " + std::to_string(problem.NumState()) +
                                " unknowns (intrinsics and 6 per view): more corners are needed" +
                                hint);
  }
}

// The seeded problem solved: staged as asked (the poses alone, then with the core), then
// everything, then the outlier loop. core_free = false keeps the core as seeded throughout.
void SolveSeeded(MrcalProblem& problem, const IntrinsicsOptions& options, bool core_free) {
  if (options.staged) {
    problem.Optimize(/*core=*/false, /*distortion=*/false);
    if (core_free) problem.Optimize(true, false);
  }
  // Everything free; the target's shape parameters (if any) in turn with the rest until
  // their step is below a micrometre (2-3 steps: the residuals are nearly linear in them).
  const auto optimize_all = [&] {
    problem.Optimize(core_free, true);
    for (int step = 0; step < kMaxShapeSteps; ++step) {
      if (problem.EstimateShapeStep() < 1e-6) break;
      problem.Optimize(core_free, true);
    }
  };
  optimize_all();
  for (int iteration = 0; iteration < kMaxOutlierIterations; ++iteration) {
    if (problem.MarkOutliers(options.outlier_sigmas) == 0) break;
    optimize_all();
  }
}

// The target shape parameters estimated for `target` (mrcal_problem.h, TargetShapeModel):
// square_grid (a heated mask) a shift in the image and F(u) on knots tan = -1 ... 1 every
// 0.25 (u's range in practice: views tilted up to 45 degrees; the spacing resolves the bled
// background's parallax, which saturates within |u| ~ 0.2 on the fixtures' masks);
// aprilgrid the shift in the image and a constant F (metres on the target: together a
// shift linear in the tags' size in pixels, and the print's ink spread); chessboards nothing.
TargetShapeModel ShapeModel(const core::Target& target, const IntrinsicsOptions& options) {
  TargetShapeModel shape;
  if (!options.estimate_target_shape || target.type == core::TargetType::kChessboard) return shape;
  shape.pixel_offset = true;
  if (target.type == core::TargetType::kSquareGrid) shape.knots_u = {-1, -0.75, -0.5, -0.25, 0, 0.25, 0.5, 0.75, 1};
  if (target.type == core::TargetType::kAprilGrid) shape.knots_u = {0};
  return shape;
}

}  // namespace

std::string IntrinsicsOptions::Check() const {
  if (!(outlier_sigmas > 1 && outlier_sigmas <= 100)) {
    return core::OptionFail("outlier_sigmas", outlier_sigmas, "in (1, 100]");
  }
  if (spline_order != 2 && spline_order != 3) {
    return core::OptionFail("spline_order", spline_order, "2 or 3");
  }
  if (spline_nx != 0 && (spline_nx < 4 || spline_nx > 64)) {
    return core::OptionFail("spline_nx", spline_nx, "0 (automatic) or in [4, 64]");
  }
  if (spline_ny != 0 && (spline_ny < 4 || spline_ny > 64)) {
    return core::OptionFail("spline_ny", spline_ny, "0 (automatic) or in [4, 64]");
  }
  if (spline_fov_x_deg != 0 && (spline_fov_x_deg < 1 || spline_fov_x_deg > 179)) {
    return core::OptionFail("spline_fov_x_deg", spline_fov_x_deg,
                            "0 (automatic) or in [1, 179] degrees");
  }
  return "";
}

IntrinsicsResult SolveIntrinsics(const core::Target& target, int width_px, int height_px,
                                 const std::vector<ViewObservation>& views,
                                 const IntrinsicsOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (const std::string problem = target.Check(); !problem.empty()) {
    throw std::invalid_argument("intrinsics: target: " + problem);
  }
  const std::vector<Eigen::Vector3d> corners_target = core::TargetCorners(target);
  CheckInputs(width_px, height_px, views, options, static_cast<int>(corners_target.size()));

  MrcalProblem problem(ParametricLensModel(options.model), width_px, height_px, corners_target,
                       views, ShapeModel(target, options));
  CheckOverdetermined(problem, "");
  const double f_px = SeedFocalPx(corners_target, width_px, height_px, views);
  problem.intrinsics.assign(static_cast<size_t>(problem.NumIntrinsics()), 0.0);
  problem.intrinsics[0] = problem.intrinsics[1] = f_px;
  problem.intrinsics[2] = (width_px - 1) / 2.0;
  problem.intrinsics[3] = (height_px - 1) / 2.0;
  problem.poses = SeedPoses(corners_target, f_px, width_px, height_px, views);
  problem.UpdatePoints();
  SolveSeeded(problem, options, /*core_free=*/true);

  IntrinsicsResult result;
  if (options.model != LensModel::kSplined) {
    result = problem.Result();
  } else {
    const core::CameraModel parametric = problem.Result().camera;
    const core::SplinedConfig config = ChooseSplinedConfig(options, parametric);
    const core::CameraModel seed = SplinedApproximation(parametric, config);
    MrcalProblem splined(core::MrcalLensModel(seed), width_px, height_px, corners_target, views,
                         ShapeModel(target, options));
    CheckOverdetermined(splined, " (or fewer spline knots: " + std::to_string(config.nx) + " x " +
                                     std::to_string(config.ny) + " now)");
    const Eigen::VectorXd params = seed.Params();
    splined.intrinsics.assign(params.data(), params.data() + params.size());
    splined.poses = problem.poses;
    splined.shape_params = problem.shape_params;
    splined.UpdatePoints();
    // The core stays the opencv8 fit's: it is (nearly) redundant with the spline, which
    // can shift and scale u as well, so solving both leaves J^T J (nearly) singular; mrcal
    // locks it for its splined models likewise.
    SolveSeeded(splined, options, /*core_free=*/false);
    result = splined.Result(/*core_free=*/false);
    result.parametric_camera = parametric;
  }
  result.solve_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hw::calibrate
