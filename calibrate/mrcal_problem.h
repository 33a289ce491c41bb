#pragma once

// The intrinsics problem as libmrcal 2.2 sees it (internal to SolveIntrinsics and
// ProjectionUncertaintyMap). mrcal's chessboard observations need a regular grid of
// corners, which square_grid and aprilgrid targets are not; so the target frame is mrcal's
// reference frame, every corner a fixed discrete point in it, and every view one camera pose
// (an mrcal "extrinsics", rt camera_from_target) sharing the one set of intrinsics.

#include <Eigen/Core>
#include <array>
#include <vector>

#include "calibrate/intrinsics_solver.h"
#include "core/mrcal_c.h"

namespace hw::calibrate {

// Projection of a camera-frame point with mrcal (pixels) and its Jacobians: dq/dp_cam 2x3
// and dq/dintrinsics 2xN (may be null).
Eigen::Vector2d MrcalProject(const mrcal_lensmodel_t& lensmodel,
                             const std::vector<double>& intrinsics, const Eigen::Vector3d& p_cam,
                             Eigen::Matrix<double, 2, 3>* dq_dp, Eigen::MatrixXd* dq_dintrinsics);

// p_cam = camera_from_target(rt) p_target and dp_cam/drt, 3x6 (may be null).
Eigen::Vector3d MrcalTransform(const mrcal_pose_t& rt, const Eigen::Vector3d& p_target,
                               Eigen::Matrix<double, 3, 6>* dp_drt);

class MrcalProblem {
 public:
  // `lensmodel`: LENSMODEL_OPENCV5, LENSMODEL_OPENCV8 or a configured
  // LENSMODEL_SPLINED_STEREOGRAPHIC (core::MrcalLensModel).
  MrcalProblem(const mrcal_lensmodel_t& lensmodel, int width_px, int height_px,
               const std::vector<Eigen::Vector3d>& corners_target,
               const std::vector<ViewObservation>& views);

  int NumIntrinsics() const;
  int NumState() const;  // intrinsics + 6 per view
  int NumObservations() const { return static_cast<int>(observations_.size()); }

  // mrcal_optimize from the current intrinsics and poses, all poses free, the core and the
  // distortion free as asked, mrcal's regularisation on, no mrcal outlier rejection; the
  // known outliers are left out. Throws std::runtime_error when mrcal fails.
  void Optimize(bool optimize_core, bool optimize_distortion);

  // Marks as outliers the inlier corners whose residual norm exceeds `sigmas` times the RMS
  // residual norm of the inliers. Returns how many were marked.
  int MarkOutliers(double sigmas);

  // The result at the current state, with its covariance (throws std::runtime_error when
  // J^T J is singular, e.g. more unknowns than inlier measurements). core_free = false: the
  // core (fx fy cx cy) was held fixed (splined models), so it has zero covariance and does
  // not count as an unknown.
  IntrinsicsResult Result(bool core_free = true) const;

  std::vector<double> intrinsics;   // mrcal order: fx fy cx cy k... (or spline controls)
  std::vector<mrcal_pose_t> poses;  // rt camera_from_target per view

 private:
  // observed - projected of every observation; with J, d(projected)/d(state) stacked 2 rows
  // per observation (outliers included).
  std::vector<Eigen::Vector2d> Residuals(Eigen::MatrixXd* J) const;
  // Jacobian of mrcal's regularisation measurements with respect to the intrinsics (they
  // depend on nothing else), from mrcal_optimizer_callback's measurement vector.
  Eigen::MatrixXd RegularizationJacobian() const;

  mrcal_lensmodel_t lensmodel_{};
  std::array<int, 2> imagersize_{};
  std::vector<mrcal_point3_t> points_;
  std::vector<mrcal_observation_point_t> observations_;  // view-major; px.z < 0: outlier
  std::vector<int> view_begin_;  // index of each view's first observation, plus the end
};

}  // namespace hw::calibrate
