#include "calibrate/extrinsics.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <vector>

#include "core/json.h"

namespace hw::calibrate {
namespace {

constexpr double kDegPerRad = 180.0 / M_PI;

std::string VectorJson(const Eigen::VectorXd& v) {
  std::string s = "[";
  for (int i = 0; i < v.size(); ++i) s += (i ? ", " : "") + core::JsonNumber(v[i]);
  return s + "]";
}

// sqrt(eᵀ C⁻¹ e) with a 3x3 covariance block; infinity when C is not positive definite.
double Chi(const Eigen::Vector3d& e, const Eigen::Matrix3d& c) {
  const Eigen::LLT<Eigen::Matrix3d> llt(c);
  if (llt.info() != Eigen::Success || c.diagonal().minCoeff() <= 0) {
    return std::numeric_limits<double>::infinity();
  }
  return std::sqrt(e.dot(llt.solve(e)));
}

}  // namespace

Eigen::Vector3d ExtrinsicsEstimate::RotationSigmaDeg() const {
  return covariance.diagonal().head<3>().cwiseMax(0).cwiseSqrt() * kDegPerRad;
}

Eigen::Vector3d ExtrinsicsEstimate::TranslationSigmaMm() const {
  return covariance.diagonal().tail<3>().cwiseMax(0).cwiseSqrt() * 1e3;
}

Vector6d ExtrinsicsError(const core::Rigid3d& estimate, const core::Rigid3d& truth) {
  const Eigen::AngleAxisd aa(truth.rotation * estimate.rotation.conjugate());
  Vector6d e;
  e.head<3>() = aa.angle() * aa.axis();
  e.tail<3>() = truth.translation - estimate.translation;
  return e;
}

double RotationErrorDeg(const core::Rigid3d& estimate, const core::Rigid3d& truth) {
  return ExtrinsicsError(estimate, truth).head<3>().norm() * kDegPerRad;
}

double TranslationErrorMm(const core::Rigid3d& estimate, const core::Rigid3d& truth) {
  return (truth.translation - estimate.translation).norm() * 1e3;
}

ExtrinsicsSigmas ErrorInSigmas(const ExtrinsicsEstimate& estimate, const core::Rigid3d& truth) {
  const Vector6d e = ExtrinsicsError(estimate.depth_from_camera, truth);
  return {Chi(e.head<3>(), estimate.covariance.topLeftCorner<3, 3>()),
          Chi(e.tail<3>(), estimate.covariance.bottomRightCorner<3, 3>())};
}

std::string ExtrinsicsJson(const ExtrinsicsEstimate& estimate, const core::Rigid3d* truth) {
  const core::Rigid3d& x = estimate.depth_from_camera;
  const Eigen::Quaterniond& q = x.rotation;
  // Roll-pitch-yaw of the rotation matrix as R = Rz(yaw) Ry(pitch) Rx(roll), degrees.
  const Eigen::Vector3d zyx = q.toRotationMatrix().eulerAngles(2, 1, 0) * kDegPerRad;
  std::vector<std::string> rows;
  for (int r = 0; r < 6; ++r) rows.push_back(VectorJson(estimate.covariance.row(r).transpose()));
  core::JsonObject o;
  o.String("camera", estimate.camera)
      .Add("depth_from_camera",
           core::JsonObject()
               .Add("quaternion_wxyz", VectorJson(Eigen::Vector4d(q.w(), q.x(), q.y(), q.z())))
               .Add("translation_m", VectorJson(x.translation))
               .Add("rpy_deg", VectorJson(Eigen::Vector3d(zyx[2], zyx[1], zyx[0])))
               .str())
      .Add("sigma", core::JsonObject()
                        .Add("rotation_deg", VectorJson(estimate.RotationSigmaDeg()))
                        .Add("translation_mm", VectorJson(estimate.TranslationSigmaMm()))
                        .str())
      .Add("covariance", core::JsonArray(rows, "    "))
      .String("covariance_parameters", "rotation vector rad (depth frame, left), translation m")
      .Int("observations", estimate.observations)
      .Number("rms_residual", estimate.rms_residual)
      .String("residual_unit", estimate.residual_unit);
  if (truth != nullptr) {
    const ExtrinsicsSigmas s = ErrorInSigmas(estimate, *truth);
    o.Add("error", core::JsonObject()
                       .Number("rotation_deg", RotationErrorDeg(x, *truth))
                       .Number("translation_mm", TranslationErrorMm(x, *truth))
                       .Number("rotation_sigmas", s.rotation)
                       .Number("translation_sigmas", s.translation)
                       .str());
  }
  return o.str();
}

}  // namespace hw::calibrate
