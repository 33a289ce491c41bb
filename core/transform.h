#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hw::core {

// A rigid transform named target_from_source (scan-format.md): it maps a point given in
// frame `source` into frame `target`, p_target = rotation * p_source + translation.
// Compose by matching frames: world_from_thermal = world_from_depth * depth_from_thermal.
// The rotation is kept a unit quaternion (Hamilton convention, as Eigen and TUM).
struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // metres

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& q, const Eigen::Vector3d& t)
      : rotation(q.normalized()), translation(t) {}

  static Rigid3d Identity() { return Rigid3d(); }
  // From a 3x4 [R|t] matrix (pass m.topRows<3>() for a 4x4); R is projected to the nearest
  // rotation. Does not validate: parsers must reject non-rotations themselves.
  static Rigid3d FromMatrix(const Eigen::Matrix<double, 3, 4>& Rt);
  Eigen::Matrix<double, 3, 4> ToMatrix3x4() const;
  Eigen::Matrix4d ToMatrix4() const;

  Eigen::Vector3d operator*(const Eigen::Vector3d& point_in_source) const {
    return rotation * point_in_source + translation;
  }
  // a_from_b * b_from_c = a_from_c
  Rigid3d operator*(const Rigid3d& b_from_c) const {
    return Rigid3d(rotation * b_from_c.rotation, rotation * b_from_c.translation + translation);
  }
  Rigid3d Inverse() const {
    const Eigen::Quaterniond q_inv = rotation.conjugate();
    return Rigid3d(q_inv, -(q_inv * translation));
  }

  // SE(3) exponential and logarithm with tangent xi = [omega (rad, axis-angle); v (m)],
  // rotation first (Sophus/Lie-group convention: Exp(xi) = exp of the 4x4 twist matrix).
  static Rigid3d Exp(const Eigen::Matrix<double, 6, 1>& xi);
  Eigen::Matrix<double, 6, 1> Log() const;

  // Rotation angle (rad) and translation norm (m): the size of a (relative) motion.
  double RotationAngle() const;
  double TranslationNorm() const { return translation.norm(); }
};

// Interpolates between two poses: slerp on the rotation, linear on the translation;
// s = 0 gives a, s = 1 gives b (s outside [0, 1] extrapolates linearly / by slerp).
Rigid3d Interpolate(const Rigid3d& a, const Rigid3d& b, double s);

// Largest difference between two transforms: rotation angle of a^-1 b (rad) and
// translation distance (m).
struct PoseError {
  double rotation_rad = 0;
  double translation_m = 0;
};
PoseError ComparePoses(const Rigid3d& a, const Rigid3d& b);

}  // namespace hw::core
