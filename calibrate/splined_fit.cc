// The splined model's helpers (declared in intrinsics_solver.h): its configuration, its
// seed from a parametric fit, and the projection difference of two models.

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <vector>

#include "calibrate/intrinsics_solver.h"

namespace hw::calibrate {
namespace {

constexpr double kDegPerRad = 180 / std::numbers::pi;
constexpr double kMargin = 1.05;  // 5 % beyond the image: the spline must span all of it

// mrcal's stereographic projection of the normalised point xy: |u| = 2 tan(theta / 2).
Eigen::Vector2d Stereographic(const Eigen::Vector2d& xy) {
  return xy * (2 / (1 + std::sqrt(1 + xy.squaredNorm())));
}

// Pixels every `step` px over the image, edges included.
std::vector<Eigen::Vector2d> ImageGrid(const core::CameraModel& camera, double step) {
  std::vector<Eigen::Vector2d> pixels;
  const double right = camera.width - 0.5, bottom = camera.height - 0.5;
  for (double y = -0.5;; y = std::min(y + step, bottom)) {
    for (double x = -0.5;; x = std::min(x + step, right)) {
      pixels.emplace_back(x, y);
      if (x == right) break;
    }
    if (y == bottom) break;
  }
  return pixels;
}

}  // namespace

core::SplinedConfig ChooseSplinedConfig(const IntrinsicsOptions& options,
                                        const core::CameraModel& parametric) {
  // The image's extent in u: its border unprojected (the extremes lie on it for any lens
  // that is one-to-one over the image). Where the parametric model cannot unproject (a fold
  // past a corner), the pinhole extent through fx, fy stands in.
  double ux_max = 0, uy_max = 0;
  for (const Eigen::Vector2d& pixel : ImageGrid(parametric, 2)) {
    const bool border = pixel.x() == -0.5 || pixel.y() == -0.5 ||
                        pixel.x() == parametric.width - 0.5 || pixel.y() == parametric.height - 0.5;
    if (!border) continue;
    const std::optional<Eigen::Vector3d> ray = parametric.Unproject(pixel);
    const Eigen::Vector2d xy =
        ray ? Eigen::Vector2d(ray->head<2>())
            : Eigen::Vector2d((pixel.x() - parametric.cx) / parametric.fx,
                              (pixel.y() - parametric.cy) / parametric.fy);
    const Eigen::Vector2d u = Stereographic(xy);
    ux_max = std::max(ux_max, std::abs(u.x()));
    uy_max = std::max(uy_max, std::abs(u.y()));
  }
  core::SplinedConfig config;
  config.order = options.spline_order;
  // |u| = 2 tan(theta / 2): the full horizontal angle is 4 atan(u_x / 2).
  config.fov_x_deg = options.spline_fov_x_deg > 0
                         ? options.spline_fov_x_deg
                         : std::clamp(static_cast<int>(std::ceil(
                                          4 * std::atan(kMargin * ux_max / 2) * kDegPerRad)),
                                      1, 179);
  config.nx = options.spline_nx > 0
                  ? options.spline_nx
                  : std::clamp(static_cast<int>(std::lround(parametric.width / 40.0)), 8, 30);
  if (options.spline_ny > 0) {
    config.ny = options.spline_ny;
  } else {
    // mrcal spaces the knots equally in x and y; the spline is valid over nx - order
    // segments across (spanning fov_x_deg), likewise ny - order down.
    const double u_edge = 2 * std::tan(config.fov_x_deg / kDegPerRad / 4);
    const double spacing = 2 * u_edge / (config.nx - config.order);
    config.ny = std::clamp(
        config.order + static_cast<int>(std::ceil(2 * kMargin * uy_max / spacing)), 4, 64);
  }
  return config;
}

core::CameraModel SplinedApproximation(const core::CameraModel& parametric,
                                       const core::SplinedConfig& config) {
  core::CameraModel splined;
  splined.width = parametric.width;
  splined.height = parametric.height;
  splined.type = core::CameraModelType::kSplined;
  splined.fx = parametric.fx;
  splined.fy = parametric.fy;
  splined.cx = parametric.cx;
  splined.cy = parametric.cy;
  splined.splined = config;
  const int n = config.NumControls();
  splined.distortion.assign(static_cast<size_t>(n), 0.0);
  // Same core: the pixels agree when u + spline(u) equals the parametric model's distorted
  // normalised point (q - c) / f. The spline is linear in its controls, so with all
  // controls 0 Distort gives u and J_dist the B-spline basis: A controls = d - u.
  Eigen::MatrixXd AtA = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd Atb = Eigen::VectorXd::Zero(n);
  const double step = std::max(parametric.width, parametric.height) / 40.0;
  Eigen::Matrix<double, 2, Eigen::Dynamic> basis;
  for (const Eigen::Vector2d& pixel : ImageGrid(parametric, step)) {
    const std::optional<Eigen::Vector3d> ray = parametric.Unproject(pixel);
    if (!ray) continue;
    const Eigen::Vector2d u = splined.Distort(ray->head<2>(), nullptr, &basis);
    const Eigen::Vector2d d((pixel.x() - parametric.cx) / parametric.fx,
                            (pixel.y() - parametric.cy) / parametric.fy);
    AtA += basis.transpose() * basis;
    Atb += basis.transpose() * (d - u);
  }
  // A ridge far below the data's weight: it only decides the controls no pixel reaches.
  const double ridge = 1e-6 * std::max(AtA.diagonal().maxCoeff(), 1e-12);
  AtA.diagonal().array() += ridge;
  const Eigen::VectorXd controls = AtA.ldlt().solve(Atb);
  for (int i = 0; i < n; ++i) splined.distortion[static_cast<size_t>(i)] = controls[i];
  return splined;
}

ModelDifference ProjectionDifference(const core::CameraModel& from, const core::CameraModel& to,
                                     const std::vector<Eigen::Vector2d>& pixels) {
  std::vector<Eigen::Vector3d> rays;
  std::vector<Eigen::Vector2d> targets;
  for (const Eigen::Vector2d& pixel : pixels) {
    if (const std::optional<Eigen::Vector3d> ray = from.Unproject(pixel)) {
      rays.push_back(ray->normalized());
      targets.push_back(pixel);
    }
  }
  // Gauss-Newton on the rotation R (left perturbation, d(R v)/dw = -[R v]x), from R = I:
  // the frames of two fits to the same data differ by a small rotation at most.
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  auto residuals = [&](const Eigen::Matrix3d& rotation, Eigen::Matrix3d* JtJ, Eigen::Vector3d* Jtr,
                       std::vector<double>* norms) {
    Eigen::Matrix<double, 2, 3> J_point;
    for (size_t i = 0; i < rays.size(); ++i) {
      const Eigen::Vector3d p = rotation * rays[i];
      if (!(p.z() > 0)) continue;
      const Eigen::Vector2d r = to.Project(p, &J_point) - targets[i];
      if (!r.allFinite()) continue;
      if (norms != nullptr) norms->push_back(r.norm());
      if (JtJ != nullptr) {
        Eigen::Matrix3d skew;
        skew << 0, -p.z(), p.y(), p.z(), 0, -p.x(), -p.y(), p.x(), 0;
        const Eigen::Matrix<double, 2, 3> J = -J_point * skew;
        *JtJ += J.transpose() * J;
        *Jtr += J.transpose() * r;
      }
    }
  };
  for (int iteration = 0; iteration < 10 && !rays.empty(); ++iteration) {
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Jtr = Eigen::Vector3d::Zero();
    residuals(R, &JtJ, &Jtr, nullptr);
    const Eigen::Vector3d w = -JtJ.ldlt().solve(Jtr);
    if (!w.allFinite()) break;
    const double angle = w.norm();
    if (angle > 0) R = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix() * R;
    if (angle < 1e-12) break;
  }
  std::vector<double> norms;
  residuals(R, nullptr, nullptr, &norms);
  ModelDifference difference;
  difference.points = static_cast<int>(norms.size());
  double sum_squared = 0;
  for (const double norm : norms) {
    sum_squared += norm * norm;
    difference.worst_px = std::max(difference.worst_px, norm);
  }
  difference.rms_px = norms.empty() ? 0 : std::sqrt(sum_squared / static_cast<double>(norms.size()));
  difference.rotation_rad = Eigen::AngleAxisd(R).angle();
  return difference;
}

}  // namespace hw::calibrate
