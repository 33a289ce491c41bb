#include "calibrate/extrinsics.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>

namespace hw::calibrate {
namespace {

core::Rigid3d Truth() {
  return core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(1, 2, 3).normalized())),
                       Eigen::Vector3d(0.05, -0.02, 0.01));
}

// Perturbs `x` by [ω; δt] in the header's parameterisation.
core::Rigid3d Perturb(const core::Rigid3d& x, const Vector6d& e) {
  const double angle = e.head<3>().norm();
  const Eigen::Quaterniond dq =
      angle > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, e.head<3>() / angle)) : Eigen::Quaterniond::Identity();
  return core::Rigid3d(dq * x.rotation, x.translation + e.tail<3>());
}

TEST(Extrinsics, ErrorInvertsThePerturbation) {
  Vector6d e;
  e << 0.002, -0.001, 0.003, 0.004, 0.001, -0.002;
  const core::Rigid3d estimate = Truth();
  const core::Rigid3d truth = Perturb(estimate, e);
  EXPECT_LT((ExtrinsicsError(estimate, truth) - e).norm(), 1e-12);
  EXPECT_NEAR(RotationErrorDeg(estimate, truth), e.head<3>().norm() * 180 / M_PI, 1e-9);
  EXPECT_NEAR(TranslationErrorMm(estimate, truth), e.tail<3>().norm() * 1e3, 1e-9);
}

TEST(Extrinsics, SigmasAreChiDistributedUnderTheirCovariance) {
  // Draw errors from a correlated covariance; the mean χ² per block must be 3 (dof).
  Matrix6d a = Matrix6d::Random();
  const Matrix6d cov = 1e-6 * (a * a.transpose() + Matrix6d::Identity());
  const Matrix6d l = cov.llt().matrixL();
  std::mt19937 rng(3);
  std::normal_distribution<double> n01;
  ExtrinsicsEstimate est;
  est.depth_from_camera = Truth();
  est.covariance = cov;
  double sum_r = 0, sum_t = 0;
  const int kDraws = 4000;
  for (int i = 0; i < kDraws; ++i) {
    Vector6d z;
    for (int k = 0; k < 6; ++k) z[k] = n01(rng);
    const ExtrinsicsSigmas s = ErrorInSigmas(est, Perturb(est.depth_from_camera, l * z));
    sum_r += s.rotation * s.rotation;
    sum_t += s.translation * s.translation;
  }
  // Mean of χ²(3) over 4000 draws: 3 ± sqrt(6/4000) = 3 ± 0.04; 5σ band.
  EXPECT_NEAR(sum_r / kDraws, 3.0, 0.2);
  EXPECT_NEAR(sum_t / kDraws, 3.0, 0.2);
}

TEST(Extrinsics, SigmasInDegreesAndMillimetres) {
  ExtrinsicsEstimate est;
  est.covariance.diagonal() << std::pow(M_PI / 180, 2), 4 * std::pow(M_PI / 180, 2), 0, 1e-6, 4e-6, 9e-6;
  EXPECT_NEAR(est.RotationSigmaDeg()[0], 1, 1e-12);
  EXPECT_NEAR(est.RotationSigmaDeg()[1], 2, 1e-12);
  EXPECT_NEAR(est.TranslationSigmaMm()[2], 3, 1e-12);
  // A singular block: the truth is infinitely many sigmas away unless exact.
  EXPECT_TRUE(std::isinf(ErrorInSigmas(est, Perturb(Truth(), Vector6d::Constant(1e-3))).rotation));
  const std::string json = ExtrinsicsJson(est, &est.depth_from_camera);
  EXPECT_NE(json.find("\"rotation_deg\""), std::string::npos);
  EXPECT_NE(json.find("\"error\""), std::string::npos);
}

}  // namespace
}  // namespace hw::calibrate
