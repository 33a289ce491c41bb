// ProjectionUncertaintyMap (declared in intrinsics_solver.h): mrcal's projection uncertainty
// with the "mean of frames" reference, propagated through the full state covariance.

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "calibrate/intrinsics_solver.h"
#include "calibrate/mrcal_problem.h"
#include "core/cameramodel_io.h"

namespace hw::calibrate {

std::vector<double> ProjectionUncertaintyMap(const IntrinsicsResult& result, int grid_cols,
                                             int grid_rows, double range_m) {
  if (grid_cols < 1 || grid_cols > 1000 || grid_rows < 1 || grid_rows > 1000) {
    throw std::invalid_argument("projection uncertainty: the grid " + std::to_string(grid_cols) +
                                " x " + std::to_string(grid_rows) + " is outside [1, 1000]^2");
  }
  if (!(std::isfinite(range_m) && range_m > 0)) {
    throw std::invalid_argument("projection uncertainty: range_m must be finite and > 0, got " +
                                std::to_string(range_m));
  }
  mrcal_lensmodel_t lensmodel{};
  const int n_intrinsics = static_cast<int>(result.mrcal_intrinsics.size());
  const int n_views = static_cast<int>(result.camera_from_target.size());
  const int n_state = n_intrinsics + 6 * n_views;
  if (!mrcal_lensmodel_from_name(&lensmodel, result.mrcal_lensmodel.c_str()) ||
      mrcal_lensmodel_num_params(&lensmodel) != n_intrinsics || n_views == 0 ||
      result.state_covariance.rows() != n_state || result.state_covariance.cols() != n_state ||
      !result.camera.Check().empty() || result.camera.NumParams() != n_intrinsics ||
      result.camera.Params() !=
          Eigen::Map<const Eigen::VectorXd>(result.mrcal_intrinsics.data(), n_intrinsics)) {
    throw std::invalid_argument(
        "projection uncertainty: the result has no consistent "
        "lens model, intrinsics, poses and state_covariance");
  }
  std::vector<mrcal_pose_t> poses;
  for (const core::Rigid3d& pose : result.camera_from_target) {
    const Eigen::Vector3d r = core::RodriguesFromQuaternion(pose.rotation);
    poses.push_back({{{r.x(), r.y(), r.z()}},
                     {{pose.translation.x(), pose.translation.y(), pose.translation.z()}}});
  }

  std::vector<double> map;
  map.reserve(static_cast<size_t>(grid_cols * grid_rows));
  const int width = result.camera.width, height = result.camera.height;
  Eigen::Matrix<double, 2, 3> dq_dp;
  Eigen::MatrixXd dq_di;
  Eigen::Matrix<double, 3, 6> dp_drt;
  Eigen::MatrixXd G(2, n_state);
  for (int row = 0; row < grid_rows; ++row) {
    for (int col = 0; col < grid_cols; ++col) {
      const Eigen::Vector2d q(
          grid_cols > 1 ? col * (width - 1.0) / (grid_cols - 1) : (width - 1) / 2.0,
          grid_rows > 1 ? row * (height - 1.0) / (grid_rows - 1) : (height - 1) / 2.0);
      // The camera is mrcal's model (same intrinsics); its Newton unprojection also converges
      // where mrcal_unproject's solver gives up, e.g. a splined model's extrapolated edge.
      const Eigen::Vector3d ray = result.camera.Unproject(q).value_or(
          Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
      if (!ray.allFinite() || !(ray.norm() > 0)) {
        map.push_back(std::numeric_limits<double>::quiet_NaN());
        continue;
      }
      const Eigen::Vector3d p_cam = range_m * ray.normalized();
      MrcalProject(lensmodel, result.mrcal_intrinsics, p_cam, &dq_dp, &dq_di);
      G.leftCols(n_intrinsics) = dq_di;
      // The point is fixed in every view's target frame; the camera-frame point is the mean
      // of its images through the (perturbed) poses, each pose contributing 1 / n_views.
      for (int i = 0; i < n_views; ++i) {
        const core::Rigid3d& camera_from_target = result.camera_from_target[static_cast<size_t>(i)];
        const Eigen::Vector3d p_target = camera_from_target.Inverse() * p_cam;
        MrcalTransform(poses[static_cast<size_t>(i)], p_target, &dp_drt);
        G.block(0, n_intrinsics + 6 * i, 2, 6) = dq_dp * dp_drt / n_views;
      }
      const Eigen::Matrix2d cov = G * result.state_covariance * G.transpose();
      const double mean = 0.5 * (cov(0, 0) + cov(1, 1));
      const double half_diff = 0.5 * (cov(0, 0) - cov(1, 1));
      const double largest = mean + std::sqrt(half_diff * half_diff + cov(0, 1) * cov(0, 1));
      map.push_back(std::sqrt(std::max(largest, 0.0)));
    }
  }
  return map;
}

}  // namespace hw::calibrate
