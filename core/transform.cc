#include "core/transform.h"

#include <Eigen/SVD>
#include <cassert>
#include <cmath>

namespace hw::core {

namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Below this angle (rad) the closed forms below divide ~0 by ~0 and lose precision; their
// Taylor series are used instead. Each series is summed to well below 1 ulp there.
constexpr double kSmallAngle = 1e-4;
// (theta - sin theta) / theta^3 cancels catastrophically much earlier (relative error
// ~6 eps / theta^2), so its series is used up to this angle (rad).
constexpr double kSeriesAngleB = 0.5;
// (1 - (theta/2) cot(theta/2)) / theta^2: same, relative error ~12 eps / theta^2.
constexpr double kSeriesAngleD = 0.25;

// Unit quaternion of the rotation vector omega (rad): [cos(theta/2), sin(theta/2) omega/theta].
Eigen::Quaterniond QuaternionExp(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  const double half = 0.5 * theta;
  double sin_half_over_theta;  // sin(theta/2) / theta
  if (theta < kSmallAngle) {
    sin_half_over_theta = 0.5 - theta_sq / 48.0 + theta_sq * theta_sq / 3840.0;
  } else {
    sin_half_over_theta = std::sin(half) / theta;
  }
  const Eigen::Vector3d xyz = sin_half_over_theta * omega;
  return Eigen::Quaterniond(std::cos(half), xyz.x(), xyz.y(), xyz.z()).normalized();
}

// Rotation vector (rad, angle in [0, pi]) of a unit quaternion. Works from the quaternion
// rather than the matrix so that it stays exact near pi, where acos/trace methods fail.
// Optionally returns the coefficient D = (1 - (theta/2) cot(theta/2)) / theta^2 of the
// inverse left Jacobian, which Log() needs and which is cheapest to get from (w, |xyz|).
Eigen::Vector3d QuaternionLog(const Eigen::Quaterniond& q_in, double* d_out) {
  Eigen::Quaterniond q = q_in.normalized();
  // q and -q are the same rotation: pick w >= 0 so that the angle is in [0, pi].
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  const double n = q.vec().norm();  // sin(theta/2)
  const double w = q.w();           // cos(theta/2)
  const double theta = 2.0 * std::atan2(n, w);
  double theta_over_n;  // theta / sin(theta/2)
  if (n < kSmallAngle) {
    // atan(x)/x = 1 - x^2/3 + x^4/5 with x = n/w (w ~ 1 here).
    const double x_sq = (n * n) / (w * w);
    theta_over_n = 2.0 / w * (1.0 - x_sq / 3.0 + x_sq * x_sq / 5.0);
  } else {
    theta_over_n = theta / n;
  }
  if (d_out != nullptr) {
    const double theta_sq = theta * theta;
    if (theta < kSeriesAngleD) {
      // 1 - x cot x = sum |B_2k| (2x)^2k / (2k)!, x = theta/2 (B: Bernoulli numbers).
      constexpr double kCoeff[] = {1.0 / 12.0,          1.0 / 720.0,
                                   1.0 / 30240.0,       1.0 / 1209600.0,
                                   1.0 / 47900160.0,    691.0 / 2730.0 / 479001600.0};
      double d = 0, power = 1;
      for (const double c : kCoeff) {
        d += c * power;
        power *= theta_sq;
      }
      *d_out = d;
    } else {
      // (theta/2) cot(theta/2) = (theta/2) w / n; n > 0 here.
      *d_out = (1.0 - 0.5 * theta * w / n) / theta_sq;
    }
  }
  return theta_over_n * q.vec();
}

}  // namespace

Rigid3d Rigid3d::FromMatrix(const Eigen::Matrix<double, 3, 4>& Rt) {
  // Nearest rotation (Frobenius norm) to the 3x3 block: U V^T, with the sign fixed so
  // that it is a rotation. Callers that must reject non-rotations check R themselves.
  const Eigen::Matrix3d m = Rt.leftCols<3>();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  if ((u * v.transpose()).determinant() < 0) u.col(2) = -u.col(2);
  const Eigen::Matrix3d r = u * v.transpose();
  return Rigid3d(Eigen::Quaterniond(r), Rt.col(3));
}

Eigen::Matrix<double, 3, 4> Rigid3d::ToMatrix3x4() const {
  Eigen::Matrix<double, 3, 4> rt;
  rt.leftCols<3>() = rotation.toRotationMatrix();
  rt.col(3) = translation;
  return rt;
}

Eigen::Matrix4d Rigid3d::ToMatrix4() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topRows<3>() = ToMatrix3x4();
  return m;
}

// Exp([omega; v]) = (R, V v) with R = exp(omega^) and the left Jacobian
// V = I + A W + B W^2, W = omega^, A = (1 - cos theta)/theta^2, B = (theta - sin theta)/theta^3.
Rigid3d Rigid3d::Exp(const Vector6d& xi) {
  const Eigen::Vector3d omega = xi.head<3>();
  const Eigen::Vector3d v = xi.tail<3>();
  const double theta_sq = omega.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  double a, b;
  if (theta < kSmallAngle) {
    a = 0.5 - theta_sq / 24.0 + theta_sq * theta_sq / 720.0;
  } else {
    // 1 - cos = 2 sin^2(theta/2): no cancellation.
    const double s = std::sin(0.5 * theta);
    a = 2.0 * s * s / theta_sq;
  }
  if (theta < kSeriesAngleB) {
    // sum_k (-1)^k theta^2k / (2k+3)!
    b = 0;
    double term = 1.0 / 6.0;
    for (int k = 0; k < 8; ++k) {
      b += term;
      term *= -theta_sq / ((2.0 * k + 4.0) * (2.0 * k + 5.0));
    }
  } else {
    b = (theta - std::sin(theta)) / (theta_sq * theta);
  }
  const Eigen::Vector3d w_v = omega.cross(v);
  const Eigen::Vector3d t = v + a * w_v + b * omega.cross(w_v);
  Rigid3d result;
  result.rotation = QuaternionExp(omega);
  result.translation = t;
  return result;
}

// Log = [omega; V^-1 t] with V^-1 = I - W/2 + D W^2 (D as in QuaternionLog).
Vector6d Rigid3d::Log() const {
  double d = 0;
  const Eigen::Vector3d omega = QuaternionLog(rotation, &d);
  const Eigen::Vector3d w_t = omega.cross(translation);
  Vector6d xi;
  xi.head<3>() = omega;
  xi.tail<3>() = translation - 0.5 * w_t + d * omega.cross(w_t);
  return xi;
}

double Rigid3d::RotationAngle() const {
  const Eigen::Quaterniond q = rotation.normalized();
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

Rigid3d Interpolate(const Rigid3d& a, const Rigid3d& b, double s) {
  // a_rot * exp(s * log(a_rot^-1 b_rot)); log picks the angle in [0, pi], i.e. the shorter
  // arc. Exact at s = 0 (multiplying by the identity quaternion) and valid for any s.
  const Eigen::Quaterniond delta = a.rotation.conjugate() * b.rotation;
  const Eigen::Vector3d omega = QuaternionLog(delta, nullptr);
  Rigid3d result;
  result.rotation = (a.rotation * QuaternionExp(s * omega)).normalized();
  // Exact endpoints (the product above is exact only to an ulp).
  if (s == 0) result.rotation = a.rotation;
  if (s == 1) result.rotation = b.rotation;
  result.translation = (1.0 - s) * a.translation + s * b.translation;
  return result;
}

PoseError ComparePoses(const Rigid3d& a, const Rigid3d& b) {
  PoseError error;
  // Angle of a^-1 b from its quaternion: atan2 keeps full precision for tiny angles,
  // unlike acos of the matrix trace.
  const Eigen::Quaterniond delta = (a.rotation.conjugate() * b.rotation).normalized();
  error.rotation_rad = 2.0 * std::atan2(delta.vec().norm(), std::abs(delta.w()));
  // |translation of a^-1 b| = |R_a^T (t_b - t_a)| = |t_b - t_a|.
  error.translation_m = (b.translation - a.translation).norm();
  return error;
}

}  // namespace hw::core
