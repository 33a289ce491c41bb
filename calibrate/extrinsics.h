#pragma once

// What the extrinsic solvers share (issue 13): an estimate of one camera's pose in the
// depth camera's frame with its 6-DoF covariance, its comparison with a true rig, and its
// JSON form. The target-based solve (heated square_grid seen by thermal, colour and depth)
// and the targetless one (3D lines of depth vs 2D lines of thermal) both return it.
//
// Parameterisation of the covariance (both solvers use it, the reports print it):
//   depth_from_camera = (R, t);  the true one = (Exp(ω) · R, t + δt)
//   ω   rotation vector (rad) about the DEPTH frame's axes, applied on the left;
//   δt  translation offset (m) in the depth frame, additive.
// so the translation's σ is the σ of t itself in mm, independent of the rotation, and the
// rotation's σ is about the depth camera's x (right), y (down), z (forward) axes.

#include <Eigen/Core>
#include <string>

#include "core/transform.h"

namespace hw::calibrate {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

struct ExtrinsicsEstimate {
  std::string camera;               // the camera whose pose this is: "thermal" or "rgb"
  core::Rigid3d depth_from_camera;  // the estimate
  // Covariance of [ω (rad); δt (m)] (see above), 1σ² units rad², m². Zero: not estimated.
  Matrix6d covariance = Matrix6d::Zero();
  int observations = 0;        // residuals (scalar) in the solve
  double rms_residual = 0;     // RMS of those residuals, in residual_unit
  std::string residual_unit;   // "px" (reprojection), "m" (point to plane), ...

  // 1σ of the rotation about the depth frame's x, y, z axes, degrees.
  Eigen::Vector3d RotationSigmaDeg() const;
  // 1σ of the translation along the depth frame's x, y, z axes, millimetres.
  Eigen::Vector3d TranslationSigmaMm() const;
};

// The error of `estimate` against `truth` in the parameterisation above: truth =
// (Exp(ω) · R_est, t_est + δt) → [ω (rad); δt (m)].
Vector6d ExtrinsicsError(const core::Rigid3d& estimate, const core::Rigid3d& truth);

// Rotation angle of the error, degrees, and translation distance, millimetres.
double RotationErrorDeg(const core::Rigid3d& estimate, const core::Rigid3d& truth);
double TranslationErrorMm(const core::Rigid3d& estimate, const core::Rigid3d& truth);

// How many sigmas the truth is from the estimate, per block: sqrt(eᵀ Σ⁻¹ e) of the
// rotation (3 dof) and translation (3 dof) parts of ExtrinsicsError, each with its own 3x3
// block of the covariance. A χ with 3 dof: below 2.8 in 95 %, 3.4 in 99 % of runs when the
// covariance is right. Infinity when the block is singular.
struct ExtrinsicsSigmas {
  double rotation = 0;
  double translation = 0;
};
ExtrinsicsSigmas ErrorInSigmas(const ExtrinsicsEstimate& estimate, const core::Rigid3d& truth);

// The estimate as a JSON object: camera, depth_from_camera {quaternion_wxyz, translation_m,
// rpy_deg}, sigma {rotation_deg[3], translation_mm[3]}, covariance (6x6, rows), observations,
// rms_residual, residual_unit. With a truth: also error {rotation_deg, translation_mm,
// rotation_sigmas, translation_sigmas}.
std::string ExtrinsicsJson(const ExtrinsicsEstimate& estimate, const core::Rigid3d* truth = nullptr);

}  // namespace hw::calibrate
