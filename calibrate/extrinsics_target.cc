#include "calibrate/extrinsics_target.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <Eigen/Geometry>
#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "calibrate/hole_corner.h"
#include "core/error.h"
#include "core/option_check.h"
#include "core/strings.h"

namespace hw::calibrate {

std::string TargetExtrinsicsOptions::Check() const {
  using core::OptionFail;
  if (const std::string e = grid.Check(); !e.empty()) return "grid." + e;
  if (!(min_stills >= 3 && min_stills <= 10000)) return OptionFail("min_stills", min_stills, "in [3, 10000]");
  if (!(min_corners >= 4 && min_corners <= 10000)) return OptionFail("min_corners", min_corners, "in [4, 10000]");
  if (!(min_plane_points >= 10 && min_plane_points <= 1000000)) {
    return OptionFail("min_plane_points", min_plane_points, "in [10, 1e6]");
  }
  if (!(depth_stride_px >= 0 && depth_stride_px <= 64)) return OptionFail("depth_stride_px", depth_stride_px, "in [0, 64]");
  if (!(hole_margin_m >= 0 && hole_margin_m <= 0.05)) return OptionFail("hole_margin_m", hole_margin_m, "in [0, 0.05] m");
  if (!(plate_border_m >= 0 && plate_border_m <= 0.5)) return OptionFail("plate_border_m", plate_border_m, "in [0, 0.5] m");
  if (!(plane_cell_m >= 0.005 && plane_cell_m <= 0.5)) return OptionFail("plane_cell_m", plane_cell_m, "in [0.005, 0.5] m");
  if (!(plane_gate_m > 0 && plane_gate_m <= 1)) return OptionFail("plane_gate_m", plane_gate_m, "in (0, 1] m");
  if (!(ransac_threshold_m > 0 && ransac_threshold_m <= 0.2)) {
    return OptionFail("ransac_threshold_m", ransac_threshold_m, "in (0, 0.2] m");
  }
  if (!(ransac_iterations >= 1 && ransac_iterations <= 100000)) {
    return OptionFail("ransac_iterations", ransac_iterations, "in [1, 100000]");
  }
  if (!(huber_sigmas >= 0.5 && huber_sigmas <= 100)) return OptionFail("huber_sigmas", huber_sigmas, "in [0.5, 100]");
  if (!(reweight_iterations >= 0 && reweight_iterations <= 20)) {
    return OptionFail("reweight_iterations", reweight_iterations, "in [0, 20]");
  }
  if (!(depth_affine_sigma_per_m == 0 ||
        (depth_affine_sigma_per_m >= kMinDepthAffineSigmaPerM && depth_affine_sigma_per_m <= 0.1))) {
    return OptionFail("depth_affine_sigma_per_m", depth_affine_sigma_per_m, "0 (automatic) or in [1e-5, 0.1] /m");
  }
  return "";
}

namespace {

using core::StringPrintf;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

// A pose as 6 parameters about a reference (R0, t0): (Exp(ω) R0, t0 + δt), p = [ω; δt] —
// calibrate/extrinsics.h's parameterisation, used for every pose of the problem.
struct PoseRef {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  explicit PoseRef(const core::Rigid3d& pose)
      : rotation(pose.rotation.toRotationMatrix()), translation(pose.translation) {}
  core::Rigid3d Apply(const double* p) const {
    const Eigen::Vector3d w(p[0], p[1], p[2]);
    const Eigen::Quaterniond turn =
        w.norm() > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w.normalized())) : Eigen::Quaterniond::Identity();
    return core::Rigid3d(turn * Eigen::Quaterniond(rotation), translation + Eigen::Vector3d(p[3], p[4], p[5]));
  }
};

// camera.Project with its analytic Jacobian, for use inside an autodiff functor.
class ProjectCost : public ceres::SizedCostFunction<2, 3> {
 public:
  explicit ProjectCost(const core::CameraModel& camera) : camera_(camera) {}
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Eigen::Vector3d p(parameters[0][0], parameters[0][1], parameters[0][2]);
    if (!(p.z() > 1e-6)) return false;
    Eigen::Matrix<double, 2, 3> J;
    const Eigen::Vector2d px = camera_.Project(p, jacobians ? &J : nullptr);
    residuals[0] = px.x();
    residuals[1] = px.y();
    if (jacobians && jacobians[0]) {
      for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 3; ++c) jacobians[0][3 * r + c] = J(r, c);
    }
    return true;
  }

 private:
  const core::CameraModel& camera_;
};

// Reprojection of a target corner: (projected − observed) / σ, px / px. The corner moves
// out of its hole by the camera's apparent edge shift (m, in the target plane: `outward` is
// the corner's direction from its hole's centre, (±1, ±1, 0)), then to where the camera
// sees it through a plate of thickness_m (calibrate/hole_corner.h: the camera centre in
// the target frame picks the visible edges).
struct CornerResidual {
  CornerResidual(const core::CameraModel& camera, const Eigen::Vector3d& corner_in_target, const Eigen::Vector3d& outward,
                 double thickness_m, const Eigen::Vector2d& observed, const PoseRef& still, const PoseRef& extrinsic,
                 double sigma_px)
      : project(new ProjectCost(camera)),
        corner(corner_in_target),
        outward(outward),
        thickness_m(thickness_m),
        still_R0(still.rotation),
        still_t(still.translation),
        extrinsic_R0t(extrinsic.rotation.transpose()),
        extrinsic_t(extrinsic.translation),
        observed(observed),
        sigma_px(sigma_px) {}

  template <typename T>
  bool operator()(const T* extrinsic, const T* still, const T* edge_shift, T* residual) const {
    T shifted[2] = {corner.x() + edge_shift[0] * outward.x(), corner.y() + edge_shift[0] * outward.y()};
    T xy[2] = {shifted[0], shifted[1]};
    if (thickness_m > 0) {
      // The camera centre (the extrinsic's translation, depth frame) in the target frame:
      // R0ᵀ · R(−ω) · (c − t_still).
      T c[3];
      for (int i = 0; i < 3; ++i) c[i] = extrinsic_t[i] + extrinsic[3 + i] - still_t[i] - still[3 + i];
      const T minus_w[3] = {-still[0], -still[1], -still[2]};
      T turned[3];
      ceres::AngleAxisRotatePoint(minus_w, c, turned);
      T camera_in_target[3];
      for (int r = 0; r < 3; ++r) {
        camera_in_target[r] = still_R0(0, r) * turned[0] + still_R0(1, r) * turned[1] + still_R0(2, r) * turned[2];
      }
      if (!(camera_in_target[2] < T(0))) return false;  // behind the plate: not a view of it
      const double out[2] = {outward.x(), outward.y()};
      VisibleHoleCorner(shifted, out, thickness_m, camera_in_target, xy);
    }
    T rotated[3];
    for (int r = 0; r < 3; ++r) rotated[r] = still_R0(r, 0) * xy[0] + still_R0(r, 1) * xy[1];
    T in_depth[3];
    ceres::AngleAxisRotatePoint(still, rotated, in_depth);
    for (int i = 0; i < 3; ++i) in_depth[i] += still_t[i] + still[3 + i] - extrinsic_t[i] - extrinsic[3 + i];
    const T minus_w[3] = {-extrinsic[0], -extrinsic[1], -extrinsic[2]};
    T turned[3];
    ceres::AngleAxisRotatePoint(minus_w, in_depth, turned);
    T in_camera[3];
    for (int r = 0; r < 3; ++r) {
      in_camera[r] = extrinsic_R0t(r, 0) * turned[0] + extrinsic_R0t(r, 1) * turned[1] + extrinsic_R0t(r, 2) * turned[2];
    }
    T pixel[2];
    if (!project(in_camera, pixel)) return false;
    residual[0] = (pixel[0] - observed.x()) / sigma_px;
    residual[1] = (pixel[1] - observed.y()) / sigma_px;
    return true;
  }

  ceres::CostFunctionToFunctor<2, 3> project;
  Eigen::Vector3d corner, outward;  // target frame, corner.z() = 0
  double thickness_m;
  Eigen::Matrix3d still_R0;
  Eigen::Vector3d still_t;
  Eigen::Matrix3d extrinsic_R0t;
  Eigen::Vector3d extrinsic_t;
  Eigen::Vector2d observed;
  double sigma_px;
};

// Signed distance of the mean depth point of a cell of the plate to the plate's plane
// z = 0 of the target frame, / σ of a cell's mean. Cells rather than points: the depth
// error is spatially correlated (the correlator's window, a device-fixed low-frequency
// disparity distortion), so points of a cell are not independent; their mean's σ is
// sqrt(σ_white² / n + σ_cell²), both estimated from the residuals.
// The depth points are corrected by the depth model [a, b, c_x, c_y] (1/m):
// z' = z + z² (a + b r² + c_x x + c_y y), (x, y) the pixel's ray on the z = 1 plane and
// r² = x² + y² — a disparity offset, a radial bowl and a tilt of disparity error (Smisek et
// al. 2011, Herrera et al. 2012) to first order in inverse depth (1/z' ≈ 1/z − δ), which
// structured-light depth cameras carry and which would otherwise tilt and shift the planes.
struct PlaneResidual {
  PlaneResidual(std::vector<Eigen::Vector3d> points_in_depth, const PoseRef& still, double sigma_m)
      : points(std::move(points_in_depth)), normal0(still.rotation.col(2)), still_t(still.translation), sigma_m(sigma_m) {
    for (const Eigen::Vector3d& q : points) {
      mean += q / static_cast<double>(points.size());
      mean_z += q * q.z() / static_cast<double>(points.size());
      mean_bowl += q * q.z() * (q.x() * q.x() + q.y() * q.y()) / (q.z() * q.z()) / static_cast<double>(points.size());
      mean_x += q * q.x() / static_cast<double>(points.size());
      mean_y += q * q.y() / static_cast<double>(points.size());
    }
  }
  // The cell's mean point (the depth model is linear in its parameters: the mean of the
  // corrected points is mean + a · mean(q z) + b · mean(q z r²) + c_x · mean(q X) + c_y · mean(q Y)).
  // still_error: the still's depth plane error [offset m, tilt about target y, about target
  // x (rad)] at the cell's centre (centre_m, target plane, from the plate's centre).
  template <typename T>
  bool operator()(const T* still, const T* depth_model, const T* still_error, const T* common_offset,
                  T* residual) const {
    const T n0[3] = {T(normal0.x()), T(normal0.y()), T(normal0.z())};
    T n[3];
    ceres::AngleAxisRotatePoint(still, n0, n);
    T d = T(0);
    for (int i = 0; i < 3; ++i) {
      d += n[i] * (mean[i] + depth_model[0] * mean_z[i] + depth_model[1] * mean_bowl[i] + depth_model[2] * mean_x[i] +
                   depth_model[3] * mean_y[i] - still_t[i] - still[3 + i]);
    }
    d -= common_offset[0] + still_error[0] + still_error[1] * centre_m.x() + still_error[2] * centre_m.y();
    residual[0] = d / sigma_m;
    return true;
  }
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector3d> points;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), mean_z = Eigen::Vector3d::Zero(), mean_bowl = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_x = Eigen::Vector3d::Zero(), mean_y = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal0, still_t;
  double sigma_m;
};

// Prior of a still's depth plane error: N(0, σ) per component.
struct StillErrorPrior {
  double sigma_offset_m, sigma_tilt_rad;
  template <typename T>
  bool operator()(const T* e, T* residual) const {
    residual[0] = e[0] / sigma_offset_m;
    residual[1] = e[1] / sigma_tilt_rad;
    residual[2] = e[2] / sigma_tilt_rad;
    return true;
  }
};

// Prior of the depth model's affine part (a, c_x, c_y): N(0, σ) each, 1/m.
struct AffinePrior {
  double sigma_per_m;
  template <typename T>
  bool operator()(const T* m, T* residual) const {
    residual[0] = m[0] / sigma_per_m;
    residual[1] = m[2] / sigma_per_m;
    residual[2] = m[3] / sigma_per_m;
    return true;
  }
};

struct OffsetPrior {
  double sigma_m;
  template <typename T>
  bool operator()(const T* offset, T* residual) const {
    residual[0] = offset[0] / sigma_m;
    return true;
  }
};

// The depth point corrected by the depth model (PlaneResidual).
Eigen::Vector3d CorrectDepth(const Eigen::Vector3d& q, const double* depth_model) {
  const double r2 = (q.x() * q.x() + q.y() * q.y()) / (q.z() * q.z());
  return q * (1 + q.z() * (depth_model[0] + depth_model[1] * r2 + depth_model[2] * q.x() / q.z() +
                           depth_model[3] * q.y() / q.z()));
}

struct CameraObservations {
  std::vector<int> ids;
  std::vector<Eigen::Vector2d> pixels;
  bool Usable(int min_corners) const { return static_cast<int>(ids.size()) >= min_corners; }
};

struct StillData {
  CameraObservations thermal, rgb;
  std::vector<Eigen::Vector3d> plane_points;   // in the depth frame, m
  std::vector<Eigen::Vector2d> plane_pixels;   // their depth pixels
  std::vector<std::vector<int>> cells;         // plate points grouped by cell of the target plane
  std::vector<Eigen::Vector2d> cell_centres;   // the cells' centres, target plane from the holes' centre, m
  double still_error[3] = {0, 0, 0};           // depth plane error: offset m, tilts rad
  core::Rigid3d depth_from_target;
  double params[6] = {0, 0, 0, 0, 0, 0};
};

// camera_from_target by PnP on the undistorted corners (IPPE, then iterative refinement).
std::optional<core::Rigid3d> SolvePnP(const core::CameraModel& camera, const std::vector<Eigen::Vector3d>& corners,
                                      const CameraObservations& obs) {
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  for (size_t i = 0; i < obs.ids.size(); ++i) {
    const std::optional<Eigen::Vector3d> ray = camera.Unproject(obs.pixels[i]);
    if (!ray) continue;
    const Eigen::Vector3d& c = corners[obs.ids[i]];
    object.emplace_back(c.x(), c.y(), c.z());
    image.emplace_back(ray->x(), ray->y());
  }
  if (object.size() < 4) return std::nullopt;
  cv::Mat rvec, tvec;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  if (!cv::solvePnP(object, image, K, cv::noArray(), rvec, tvec, false, cv::SOLVEPNP_IPPE)) return std::nullopt;
  cv::solvePnP(object, image, K, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
  const Eigen::Vector3d w(rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2));
  const Eigen::Quaterniond q = w.norm() > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w.normalized()))
                                            : Eigen::Quaterniond::Identity();
  const core::Rigid3d pose(q, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
  if (!(pose.translation.z() > 0)) return std::nullopt;
  return pose;
}

// Whether (x, y) of the target plane is on the plate, at least margin from a hole and
// inside the holes' extent grown by border.
bool OnPlate(const core::Target& target, double x, double y, double margin, double border) {
  const double p = target.pitch_m, s = target.square_m;
  const double width = (target.cols - 1) * p + s, height = (target.rows - 1) * p + s;
  if (x < -border + margin || y < -border + margin || x > width + border - margin || y > height + border - margin) {
    return false;
  }
  // The nearest hole's column and row: holes at [c p, c p + s].
  const auto in_hole_band = [&](double v, int n) {
    const int k = std::clamp(static_cast<int>(std::floor(v / p)), 0, n - 1);
    for (int j = std::max(0, k - 1); j <= std::min(n - 1, k + 1); ++j) {
      if (v > j * p - margin && v < j * p + s + margin) return true;
    }
    return false;
  };
  return !(in_hole_band(x, target.cols) && in_hole_band(y, target.rows));
}

// The plate's points in a depth frame given a guess of depth_from_target: sampled pixels on
// the plate region near the plane, then a RANSAC plane among them. Empty when too few.
void SelectPlatePoints(const cv::Mat& depth_m, const core::CameraModel& depth_camera, const core::Target& target,
                       const core::Rigid3d& depth_from_target, const TargetExtrinsicsOptions& o, int stride,
                       uint64_t seed, StillData& still) {
  still.plane_points.clear();
  still.plane_pixels.clear();
  still.cells.clear();
  const core::Rigid3d target_from_depth = depth_from_target.Inverse();
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> pixels;
  for (int v = stride / 2; v < depth_m.rows; v += stride) {
    for (int u = stride / 2; u < depth_m.cols; u += stride) {
      const float z = depth_m.at<float>(v, u);
      if (!(z > 0)) continue;
      const std::optional<Eigen::Vector3d> ray = depth_camera.Unproject(Eigen::Vector2d(u, v));
      if (!ray) continue;
      const Eigen::Vector3d q = *ray * static_cast<double>(z);
      const Eigen::Vector3d x = target_from_depth * q;
      if (std::abs(x.z()) > o.plane_gate_m) continue;
      if (!OnPlate(target, x.x(), x.y(), o.hole_margin_m, o.plate_border_m)) continue;
      points.push_back(q);
      pixels.emplace_back(u, v);
    }
  }
  if (static_cast<int>(points.size()) < o.min_plane_points) return;
  // RANSAC: the plane of three random points with the most points within the threshold.
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<size_t> pick(0, points.size() - 1);
  int best = -1;
  Eigen::Vector3d best_n = Eigen::Vector3d::UnitZ();
  double best_d = 0;
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const Eigen::Vector3d& a = points[pick(rng)];
    const Eigen::Vector3d& b = points[pick(rng)];
    const Eigen::Vector3d& c = points[pick(rng)];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-9) continue;
    n.normalize();
    const double d = n.dot(a);
    int count = 0;
    for (const Eigen::Vector3d& q : points) count += std::abs(n.dot(q) - d) < o.ransac_threshold_m;
    if (count > best) {
      best = count;
      best_n = n;
      best_d = d;
    }
  }
  if (best < o.min_plane_points) return;
  std::map<std::pair<int, int>, std::vector<int>> cells;
  for (size_t i = 0; i < points.size(); ++i) {
    if (std::abs(best_n.dot(points[i]) - best_d) < o.ransac_threshold_m) {
      const Eigen::Vector3d x = target_from_depth * points[i];
      cells[{static_cast<int>(std::floor(x.x() / o.plane_cell_m)), static_cast<int>(std::floor(x.y() / o.plane_cell_m))}]
          .push_back(static_cast<int>(still.plane_points.size()));
      still.plane_points.push_back(points[i]);
      still.plane_pixels.push_back(pixels[i]);
    }
  }
  still.cells.clear();
  still.cell_centres.clear();
  const double p = target.pitch_m, s = target.square_m;
  const Eigen::Vector2d holes_centre(((target.cols - 1) * p + s) / 2, ((target.rows - 1) * p + s) / 2);
  for (auto& [key, members] : cells) {
    if (members.size() < 3) continue;
    still.cells.push_back(std::move(members));
    still.cell_centres.push_back(o.plane_cell_m * Eigen::Vector2d(key.first + 0.5, key.second + 0.5) - holes_centre);
  }
}

// A robust RMS: the RMS of the values within 3 σ_MAD (σ_MAD = 1.4826 · median |v|).
double RobustRms(std::vector<double> values) {
  if (values.empty()) return 0;
  std::vector<double> a(values.size());
  for (size_t i = 0; i < values.size(); ++i) a[i] = std::abs(values[i]);
  std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
  const double mad_sigma = 1.4826 * a[a.size() / 2];
  double sum = 0;
  int n = 0;
  for (double v : values) {
    if (std::abs(v) <= 3 * mad_sigma) {
      sum += v * v;
      ++n;
    }
  }
  // The RMS of a Gaussian truncated at 3σ is 0.986 σ.
  return n > 0 ? std::sqrt(sum / n) / 0.986 : mad_sigma;
}

}  // namespace

TargetExtrinsicsResult EstimateTargetExtrinsics(const core::Scan& scan, const core::Target& target,
                                                const TargetExtrinsicsOptions& o,
                                                const TargetExtrinsicsProgressFn& progress) {
  assert(o.Check().empty());
  const std::string where = scan.folder().string();
  const core::Rig& rig = scan.rig();
  if (!rig.thermal || !rig.rgb) {
    throw core::InputError(scan.rig_path(), "the rig needs a thermal and an rgb camera for the target-based extrinsics");
  }
  if (scan.NumFrames(core::Stream::kThermal) == 0 || scan.NumFrames(core::Stream::kRgb) == 0) {
    throw core::InputError(where, "the scan needs thermal and rgb frames for the target-based extrinsics (it has " +
                                      std::to_string(scan.NumFrames(core::Stream::kThermal)) + " thermal, " +
                                      std::to_string(scan.NumFrames(core::Stream::kRgb)) + " rgb)");
  }
  if (target.type != core::TargetType::kSquareGrid || !target.Check().empty()) {
    throw core::InputError(where, "the target must be a valid square_grid (heated mask), got " +
                                      core::TargetTypeName(target.type));
  }
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  const int stride =
      o.depth_stride_px > 0 ? o.depth_stride_px : std::max(1, static_cast<int>(std::lround(4.0 * rig.depth.width / 640.0)));

  TargetExtrinsicsResult result;
  const auto detect_start = Clock::now();
  const int n_depth = scan.NumFrames(core::Stream::kDepth);
  std::vector<StillData> data;
  std::vector<cv::Mat> depth_images;
  const cv::Mat depth_offsets =
      rig.depth_correction ? core::DepthOffsetMap(*rig.depth_correction, rig.depth) : cv::Mat();
  for (int i = 0; i < n_depth; ++i) {
    TargetExtrinsicsStill still;
    still.depth_frame = i;
    still.thermal_frame = scan.AssociatedFrame(i, core::Stream::kThermal).value_or(-1);
    still.rgb_frame = scan.AssociatedFrame(i, core::Stream::kRgb).value_or(-1);
    StillData d;
    const auto detect = [&](const cv::Mat& image, const std::string& name, CameraObservations& obs) {
      const Detection det = DetectSquareGrid(image, target, o.grid, name);
      if (det.accepted) {
        obs.ids = det.corner_ids;
        obs.pixels = det.pixels;
      }
    };
    if (still.thermal_frame >= 0) {
      detect(scan.LoadThermal(still.thermal_frame), "thermal frame " + std::to_string(still.thermal_frame), d.thermal);
    }
    if (still.rgb_frame >= 0) {
      cv::Mat grey;
      cv::cvtColor(scan.LoadRgb(still.rgb_frame), grey, cv::COLOR_RGB2GRAY);
      detect(grey, "rgb frame " + std::to_string(still.rgb_frame), d.rgb);
    }
    if (d.thermal.Usable(o.min_corners)) still.thermal_corners = static_cast<int>(d.thermal.ids.size());
    if (d.rgb.Usable(o.min_corners)) still.rgb_corners = static_cast<int>(d.rgb.ids.size());
    // The first pose: the PnP of the camera with more corners, through the rig's extrinsics.
    std::optional<core::Rigid3d> pose;
    if (still.rgb_corners >= still.thermal_corners && still.rgb_corners > 0) {
      if (auto p = SolvePnP(*rig.rgb, corners, d.rgb)) pose = rig.depth_from_rgb * *p;
    }
    if (!pose && still.thermal_corners > 0) {
      if (auto p = SolvePnP(*rig.thermal, corners, d.thermal)) pose = rig.depth_from_thermal * *p;
    }
    cv::Mat depth;
    if (!pose) {
      still.reason = "no grid in thermal or colour";
    } else {
      d.depth_from_target = *pose;
      depth = scan.LoadDepth(i);
      // The rig's depth calibration (calibrate depth), when it has one: the plate's plane is
      // then measured without the sensor's disparity distortion.
      if (!depth_offsets.empty()) core::CorrectDepth(depth_offsets, &depth);
      SelectPlatePoints(depth, rig.depth, target, *pose, o, stride, static_cast<uint64_t>(i) + 1, d);
      still.plane_points = static_cast<int>(d.plane_points.size());
      if (d.plane_points.empty()) still.reason = "too few plate points in depth";
      else still.used = true;
    }
    if (!still.used) {
      d.thermal = {};
      d.rgb = {};
    }
    if (still.thermal_corners == 0) d.thermal = {};
    if (still.rgb_corners == 0) d.rgb = {};
    result.stills.push_back(still);
    data.push_back(std::move(d));
    depth_images.push_back(depth);
    if (progress) progress(i + 1, n_depth);
  }
  result.detect_seconds = Seconds(detect_start);
  int thermal_stills = 0, rgb_stills = 0;
  for (const TargetExtrinsicsStill& s : result.stills) {
    result.stills_used += s.used;
    thermal_stills += s.used && s.thermal_corners > 0;
    rgb_stills += s.used && s.rgb_corners > 0;
  }
  if (thermal_stills < o.min_stills || rgb_stills < o.min_stills) {
    throw core::InputError(where, StringPrintf("too few stills for the target-based extrinsics: %d of %d depth frames "
                                               "have the grid in thermal and the plate in depth, %d in colour; at "
                                               "least %d each are needed",
                                               thermal_stills, n_depth, rgb_stills, o.min_stills));
  }

  // The joint solve.
  const auto solve_start = Clock::now();
  const PoseRef thermal_ref(rig.depth_from_thermal), rgb_ref(rig.depth_from_rgb);
  double thermal_params[6] = {0, 0, 0, 0, 0, 0}, rgb_params[6] = {0, 0, 0, 0, 0, 0};
  double depth_model[4] = {0, 0, 0, 0};  // [a, b, c_x, c_y], 1/m: PlaneResidual
  // The affine part is estimated only with a calibrated field; its prior σ is given, or the
  // field's RMS over its nodes (a device's affine error, which no wall shows, taken as large
  // as the rest of its field).
  const bool estimate_affine = o.depth_affine && rig.depth_correction.has_value();
  const double affine_sigma =
      !estimate_affine                   ? 0
      : o.depth_affine_sigma_per_m > 0 ? o.depth_affine_sigma_per_m
                                       : std::max(rig.depth_correction->RmsPerM(),
                                                  TargetExtrinsicsOptions::kMinDepthAffineSigmaPerM);
  double thermal_shift[1] = {0}, rgb_shift[1] = {0};
  double common_offset[1] = {0};
  // Direction of each corner from its hole's centre (TL, TR, BR, BL: core::TargetCorners).
  const auto outward = [](int id) {
    static const double sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1};
    return Eigen::Vector3d(sx[id % 4], sy[id % 4], 0);
  };
  std::vector<PoseRef> still_refs;
  for (StillData& d : data) still_refs.emplace_back(d.depth_from_target);
  // First guesses, refined below: corners σ px, plate points' white σ and cells' correlated σ, m.
  double sigma_thermal = 0.3, sigma_rgb = 0.3, sigma_plane = 0.005, sigma_cell = 0.001;
  // The stills' depth plane errors: σ of the offset (m) and of the tilts (rad), estimated
  // from the stills (random effects, EM: E[e²] = ê² + Var(ê)).
  double sigma_still_offset = 0.002, sigma_still_tilt = 0.005;
  const int rounds = o.reweight_iterations + 1;
  std::unique_ptr<ceres::Problem> problem;
  for (int round = 0; round <= rounds; ++round) {
    // Round 1 re-selects the plate points with the poses of round 0.
    if (round == 1) {
      for (size_t k = 0; k < data.size(); ++k) {
        if (!result.stills[k].used) continue;
        const core::Rigid3d pose = still_refs[k].Apply(data[k].params);
        SelectPlatePoints(depth_images[k], rig.depth, target, pose, o, stride, k + 1, data[k]);
        result.stills[k].plane_points = static_cast<int>(data[k].plane_points.size());
      }
    }
    problem = std::make_unique<ceres::Problem>();
    problem->AddParameterBlock(depth_model, 4);
    // Which of [a, b, c_x, c_y] are free: none in the first round (the poses are rough, and
    // a free depth scale lets that solve wander); then the bowl b with depth_model, and the
    // affine part (a, c_x, c_y) under its prior when estimate_affine.
    std::vector<int> fixed;
    if (!(o.depth_model && round > 0)) fixed.push_back(1);
    if (!(estimate_affine && round > 0)) fixed.insert(fixed.end(), {0, 2, 3});
    if (fixed.size() == 4) {
      problem->SetParameterBlockConstant(depth_model);
    } else if (!fixed.empty()) {
      std::sort(fixed.begin(), fixed.end());
      problem->SetManifold(depth_model, new ceres::SubsetManifold(4, fixed));
    }
    if (estimate_affine && round > 0) {
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<AffinePrior, 3, 4>(new AffinePrior{affine_sigma}),
                                nullptr, depth_model);
    }
    ceres::LossFunction* loss = new ceres::HuberLoss(o.huber_sigmas);
    for (size_t k = 0; k < data.size(); ++k) {
      if (!result.stills[k].used) continue;
      StillData& d = data[k];
      for (const auto& [obs, camera, ref, params, sigma, shift] :
           {std::tuple{&d.thermal, &*rig.thermal, &thermal_ref, thermal_params, sigma_thermal, thermal_shift},
            std::tuple{&d.rgb, &*rig.rgb, &rgb_ref, rgb_params, sigma_rgb, rgb_shift}}) {
        for (size_t i = 0; i < obs->ids.size(); ++i) {
          problem->AddResidualBlock(new ceres::AutoDiffCostFunction<CornerResidual, 2, 6, 6, 1>(
                                        new CornerResidual(*camera, corners[obs->ids[i]], outward(obs->ids[i]),
                                                           target.thickness_m, obs->pixels[i], still_refs[k], *ref,
                                                           sigma)),
                                    loss, params, d.params, shift);
        }
      }
      for (const std::vector<int>& cell : d.cells) {
        std::vector<Eigen::Vector3d> points;
        for (int i : cell) points.push_back(d.plane_points[i]);
        const double n = static_cast<double>(points.size());
        const double sigma = std::sqrt(sigma_plane * sigma_plane / n + sigma_cell * sigma_cell);
        auto* residual = new PlaneResidual(std::move(points), still_refs[k], sigma);
        residual->centre_m = d.cell_centres[&cell - d.cells.data()];
        problem->AddResidualBlock(new ceres::AutoDiffCostFunction<PlaneResidual, 1, 6, 4, 3, 1>(residual), loss,
                                  d.params, depth_model, d.still_error, common_offset);
      }
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<StillErrorPrior, 3, 3>(
                                    new StillErrorPrior{sigma_still_offset, sigma_still_tilt}),
                                nullptr, d.still_error);
      if (!o.still_errors) problem->SetParameterBlockConstant(d.still_error);
    }
    // The depth's range bias common to all stills: not separable from the extrinsics'
    // translation along the view axes, so it gets a prior: the depth's correlated error
    // (a cell's σ_cell, or the stills' scatter if larger) has no known mean — a device
    // whose plate points err together by σ is not trusted to be unbiased to better than σ.
    problem->AddResidualBlock(new ceres::AutoDiffCostFunction<OffsetPrior, 1, 1>(
                                  new OffsetPrior{std::max(sigma_cell, sigma_still_offset)}),
                              nullptr, common_offset);
    if (!o.still_errors) problem->SetParameterBlockConstant(common_offset);
    for (double* shift : {thermal_shift, rgb_shift}) {
      if (problem->HasParameterBlock(shift) && !o.edge_shift) problem->SetParameterBlockConstant(shift);
    }
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::SPARSE_SCHUR;
    solver.max_num_iterations = 100;
    solver.num_threads = 2;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, problem.get(), &summary);
    if (!summary.IsSolutionUsable()) {
      throw core::InputError(where, "the target-based extrinsic solve failed: " + summary.message);
    }
    // Residuals (unwhitened) of each type, for the σ estimates and the diagnostics.
    result.thermal_residuals.clear();
    result.rgb_residuals.clear();
    result.plane_residuals.clear();
    std::vector<double> thermal_values, rgb_values, plane_values;
    // Per cell: the dof of the residuals about the cell's mean, and the mean's square minus
    // the white noise's share (for σ_cell).
    double within_dof = 0, cell_excess = 0;
    int cells = 0, cell_dof_lost = 0;
    std::vector<std::pair<double, int>> cell_means;
    for (size_t k = 0; k < data.size(); ++k) {
      if (!result.stills[k].used) continue;
      const StillData& d = data[k];
      const core::Rigid3d depth_from_target = still_refs[k].Apply(d.params);
      for (const auto& [obs, camera, ref, params, values, samples, shift] :
           {std::tuple{&d.thermal, &*rig.thermal, &thermal_ref, thermal_params, &thermal_values,
                       &result.thermal_residuals, thermal_shift},
            std::tuple{&d.rgb, &*rig.rgb, &rgb_ref, rgb_params, &rgb_values, &result.rgb_residuals, rgb_shift}}) {
        for (size_t i = 0; i < obs->ids.size(); ++i) {
          // The solver's own residual at σ = 1 px: projected − observed, px.
          const CornerResidual corner(*camera, corners[obs->ids[i]], outward(obs->ids[i]), target.thickness_m,
                                      obs->pixels[i], still_refs[k], *ref, 1.0);
          Eigen::Vector2d r;
          if (!corner(params, d.params, shift, r.data())) continue;  // the camera behind the plate
          values->push_back(r.x());
          values->push_back(r.y());
          samples->push_back({static_cast<int>(k), obs->pixels[i], r});
        }
      }
      const core::Rigid3d target_from_depth = depth_from_target.Inverse();
      std::vector<double> r(d.plane_points.size());
      for (size_t i = 0; i < d.plane_points.size(); ++i) {
        const Eigen::Vector3d x = target_from_depth * CorrectDepth(d.plane_points[i], depth_model);
        r[i] = x.z();  // the diagnostics' distance to the plate (the still's plane error not removed)
        result.plane_residuals.push_back({static_cast<int>(k), d.plane_pixels[i], Eigen::Vector2d(r[i], 0)});
      }
      for (const std::vector<int>& cell : d.cells) {
        double mean = 0;
        for (int i : cell) mean += r[i] / static_cast<double>(cell.size());
        for (int i : cell) plane_values.push_back(r[i] - mean);
        within_dof += static_cast<double>(cell.size()) - 1;
        cell_means.emplace_back(mean, static_cast<int>(cell.size()));
        ++cells;
      }
      cell_dof_lost += 3;  // the still's plane absorbs 3 dof of its cells' means
    }
    if (round == rounds) break;
    sigma_thermal = std::max(RobustRms(thermal_values), 1e-3);
    sigma_rgb = std::max(RobustRms(rgb_values), 1e-3);
    // White σ: robust RMS of the residuals about their cell means, corrected for the dof the
    // means take. Cell σ: the cells' mean residuals beyond the white share.
    const double dof_factor = within_dof > 0 ? std::sqrt((within_dof + cells) / within_dof) : 1.0;
    sigma_plane = std::max(RobustRms(plane_values) * dof_factor, 1e-5);
    for (const auto& [mean, n] : cell_means) cell_excess += mean * mean - sigma_plane * sigma_plane / n;
    sigma_cell = std::sqrt(std::max(cell_excess, 0.0) / std::max(cells - cell_dof_lost, 1));
    sigma_cell = std::max(sigma_cell, 1e-5);
    if (o.still_errors) {
      // EM step for the stills' plane error σ: E[e²] = ê² + posterior variance.
      ceres::Covariance::Options em_options;
      em_options.algorithm_type = ceres::SPARSE_QR;
      ceres::Covariance em(em_options);
      std::vector<std::pair<const double*, const double*>> em_blocks;
      for (size_t k = 0; k < data.size(); ++k) {
        if (result.stills[k].used) em_blocks.emplace_back(data[k].still_error, data[k].still_error);
      }
      if (em.Compute(em_blocks, problem.get())) {
        double off = 0, tilt = 0;
        int n = 0;
        for (const auto& [block, unused] : em_blocks) {
          double c[9];
          em.GetCovarianceBlock(block, block, c);
          off += block[0] * block[0] + c[0];
          tilt += 0.5 * (block[1] * block[1] + c[4] + block[2] * block[2] + c[8]);
          ++n;
        }
        sigma_still_offset = std::max(std::sqrt(off / n), 1e-5);
        sigma_still_tilt = std::max(std::sqrt(tilt / n), 1e-6);
      }
    }
  }
  result.sigma_thermal_px = sigma_thermal;
  result.sigma_rgb_px = sigma_rgb;
  result.sigma_plane_m = sigma_plane;
  result.sigma_cell_m = sigma_cell;
  result.sigma_still_offset_m = sigma_still_offset;
  result.sigma_still_tilt_rad = sigma_still_tilt;
  result.depth_model = Eigen::Vector4d(depth_model[0], depth_model[1], depth_model[2], depth_model[3]);
  result.depth_affine_sigma_per_m = affine_sigma;
  result.target_thickness_m = target.thickness_m;
  result.thermal_edge_shift_m = thermal_shift[0];
  result.rgb_edge_shift_m = rgb_shift[0];

  // Covariance of the two extrinsics, the still poses marginalised (the last problem's
  // residuals are whitened by the σ it was built with).
  ceres::Covariance::Options cov_options;
  // Sparse QR: the same numbers as a dense SVD here (full-size sessions: to every printed
  // digit), the whole solve 1.4 s instead of 2.4; a rank-deficient Jacobian makes Compute fail.
  cov_options.algorithm_type = ceres::SPARSE_QR;
  cov_options.num_threads = 2;
  ceres::Covariance covariance(cov_options);
  std::vector<std::pair<const double*, const double*>> blocks = {{thermal_params, thermal_params},
                                                                  {rgb_params, rgb_params}};
  // The depth model's, where the last round left part of it free.
  const bool depth_model_free = o.depth_model || estimate_affine;
  if (depth_model_free) blocks.emplace_back(depth_model, depth_model);
  if (!covariance.Compute(blocks, problem.get())) {
    throw core::InputError(where, "the target-based extrinsics are not determined by these stills (degenerate "
                                  "configuration: vary the target's orientation and position)");
  }
  const auto fill = [&](ExtrinsicsEstimate& e, const char* camera, const PoseRef& ref, const double* params,
                        const std::vector<ResidualSample>& samples) {
    e.camera = camera;
    e.depth_from_camera = ref.Apply(params);
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
    covariance.GetCovarianceBlock(params, params, c.data());
    e.covariance = c;
    e.observations = 2 * static_cast<int>(samples.size());
    double sum = 0;
    for (const ResidualSample& s : samples) sum += s.residual.squaredNorm();
    e.rms_residual = samples.empty() ? 0 : std::sqrt(sum / (2.0 * samples.size()));
    e.residual_unit = "px";
  };
  if (depth_model_free) {
    Eigen::Matrix<double, 4, 4, Eigen::RowMajor> c;
    covariance.GetCovarianceBlock(depth_model, depth_model, c.data());
    result.depth_model_covariance = c;
  }
  fill(result.thermal, "thermal", thermal_ref, thermal_params, result.thermal_residuals);
  fill(result.rgb, "rgb", rgb_ref, rgb_params, result.rgb_residuals);
  // A σ of centimetres or degrees is no calibration: the stills leave a direction free and
  // the factorisation only did not notice (a legitimate one is millimetres, 0.1°).
  for (const ExtrinsicsEstimate* e : {&result.thermal, &result.rgb}) {
    const double sigma_mm = e->TranslationSigmaMm().maxCoeff(), sigma_deg = e->RotationSigmaDeg().maxCoeff();
    if (!(sigma_mm <= 50 && sigma_deg <= 5)) {
      char what[160];
      std::snprintf(what, sizeof(what), "%s 1-sigma %.0f mm, %.1f deg", e->camera.c_str(), sigma_mm, sigma_deg);
      throw core::InputError(where, "the target-based extrinsics are not determined by these stills (degenerate "
                                    "configuration: " + std::string(what) +
                                    "; vary the target's orientation and position)");
    }
  }
  double sum = 0;
  for (const ResidualSample& s : result.plane_residuals) sum += s.residual.x() * s.residual.x();
  result.plane_points = static_cast<int>(result.plane_residuals.size());
  result.plane_rms_m = result.plane_points > 0 ? std::sqrt(sum / result.plane_points) : 0;
  result.solve_seconds = Seconds(solve_start);
  return result;
}

}  // namespace hw::calibrate
