#include "core/transform.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <unsupported/Eigen/MatrixFunctions>
#include <vector>

namespace hw::core {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix4ld = Eigen::Matrix<long double, 4, 4>;
constexpr double kPi = std::numbers::pi;

// Independent reference: the matrix exponential of the 4x4 twist [omega^ v; 0 0], in long
// double so that its own rounding (~1e-19) is far below the tolerances checked here.
Matrix4ld TwistExpReference(const Vector6d& xi) {
  Matrix4ld twist = Matrix4ld::Zero();
  const long double wx = xi[0], wy = xi[1], wz = xi[2];
  twist(0, 1) = -wz;
  twist(0, 2) = wy;
  twist(1, 0) = wz;
  twist(1, 2) = -wx;
  twist(2, 0) = -wy;
  twist(2, 1) = wx;
  twist(0, 3) = xi[3];
  twist(1, 3) = xi[4];
  twist(2, 3) = xi[5];
  return twist.exp();
}

double MaxAbsDiff(const Eigen::Matrix4d& a, const Matrix4ld& b) {
  return (a.cast<long double>() - b).cwiseAbs().maxCoeff();
}

Vector6d Twist(const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& v) {
  Vector6d xi;
  xi << axis.normalized() * angle, v;
  return xi;
}

Rigid3d RandomPose(std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return Rigid3d(q, Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
}

// Angles that exercise every branch of Exp/Log: zero, the Taylor regions, both sides of
// each series/closed-form switch (1e-4, 0.25, 0.5 rad) and the neighbourhood of pi.
const std::vector<double> kAngles = {0.0,    1e-15,  1e-12,         1e-8,          9.9e-5,
                                     1.01e-4, 1e-3,  0.0999,        0.2499,        0.2501,
                                     0.4999, 0.5001, 1.0,           2.0,           3.0,
                                     kPi - 1e-4,     kPi - 1e-7,    kPi - 1e-10};

TEST(TransformTest, ExpMatchesMatrixExponentialOfTwist) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  double worst = 0;
  for (const double angle : kAngles) {
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
      const Eigen::Vector3d v(normal(rng), normal(rng), normal(rng));
      const Vector6d xi = Twist(axis, angle, v);
      const double error = MaxAbsDiff(Rigid3d::Exp(xi).ToMatrix4(), TwistExpReference(xi));
      worst = std::max(worst, error);
      // Entries are O(|v|) ~ 1-3: a few ulps of that.
      ASSERT_LT(error, 4e-15) << "angle " << angle << " trial " << trial;
    }
  }
  std::printf("Exp vs long-double expm: max abs error %.3g\n", worst);
}

TEST(TransformTest, ExpOfZeroIsExactlyIdentity) {
  const Rigid3d t = Rigid3d::Exp(Vector6d::Zero());
  EXPECT_EQ(t.rotation.coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_EQ(t.translation, Eigen::Vector3d::Zero());
  EXPECT_EQ(Rigid3d::Identity().Log(), Vector6d::Zero());
}

TEST(TransformTest, PureTranslationAndPureRotation) {
  Vector6d xi;
  xi << 0, 0, 0, 1.5, -2, 0.25;
  const Rigid3d t = Rigid3d::Exp(xi);
  EXPECT_EQ(t.translation, Eigen::Vector3d(1.5, -2, 0.25));
  EXPECT_DOUBLE_EQ(t.RotationAngle(), 0.0);
  // Rotation by 90 degrees about z maps x to y.
  xi << 0, 0, kPi / 2, 0, 0, 0;
  const Eigen::Vector3d y = Rigid3d::Exp(xi) * Eigen::Vector3d::UnitX();
  EXPECT_NEAR((y - Eigen::Vector3d::UnitY()).norm(), 0.0, 1e-15);
  // Screw motion: half a turn about z with v along x moves the origin to (0, 2/pi, 0) * ...
  // Exp([0 0 pi; 1 0 0]) translation = V v, V x = (sin pi/pi, (1-cos pi)/pi, 0) = (0, 2/pi, 0).
  xi << 0, 0, kPi, 1, 0, 0;
  EXPECT_NEAR((Rigid3d::Exp(xi).translation - Eigen::Vector3d(0, 2 / kPi, 0)).norm(), 0.0,
              1e-15);
}

TEST(TransformTest, LogInvertsExpAtAllAngles) {
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  double worst = 0;
  for (const double angle : kAngles) {
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
      const Vector6d xi = Twist(axis, angle, Eigen::Vector3d(normal(rng), normal(rng),
                                                             normal(rng)));
      const Vector6d back = Rigid3d::Exp(xi).Log();
      const double error = (back - xi).cwiseAbs().maxCoeff();
      worst = std::max(worst, error);
      // Near pi the inverse left Jacobian has entries ~ 1/pi^2 * |W^2| ~ 1 and the
      // quaternion carries 1 ulp: a few 1e-15 in absolute terms.
      ASSERT_LT(error, 1e-14) << "angle " << angle << " trial " << trial;
    }
  }
  std::printf("Log(Exp(xi)) - xi: max abs error %.3g\n", worst);
}

TEST(TransformTest, TinyAngleLogKeepsRelativePrecision) {
  // At 1e-12 rad an absolute tolerance says nothing: check the relative error.
  for (const double angle : {1e-15, 1e-12, 1e-9, 1e-6}) {
    const Vector6d xi = Twist(Eigen::Vector3d(1, 2, 3), angle, Eigen::Vector3d(0.1, 0, 0));
    const Vector6d back = Rigid3d::Exp(xi).Log();
    EXPECT_LT((back.head<3>() - xi.head<3>()).norm(), 1e-15 * angle) << angle;
    EXPECT_NEAR(Rigid3d::Exp(xi).RotationAngle(), angle, 1e-15 * angle);
  }
}

TEST(TransformTest, LogAtExactlyPi) {
  // Rotation by pi about (1, 1, 0)/sqrt2: the quaternion has w = 0 (and either sign).
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 1, 0).normalized();
  for (const double sign : {1.0, -1.0}) {
    Eigen::Quaterniond q(0.0, sign * axis.x(), sign * axis.y(), sign * axis.z());
    const Rigid3d t(q, Eigen::Vector3d(0.5, -1, 2));
    const Vector6d xi = t.Log();
    EXPECT_NEAR(xi.head<3>().norm(), kPi, 1e-15);
    EXPECT_NEAR(std::abs(xi.head<3>().normalized().dot(axis)), 1.0, 1e-15);
    const Rigid3d back = Rigid3d::Exp(xi);
    const PoseError e = ComparePoses(back, t);
    EXPECT_LT(e.rotation_rad, 1e-15);
    EXPECT_LT(e.translation_m, 1e-15);
  }
}

TEST(TransformTest, ExpOfLogRoundTripsRandomPoses) {
  std::mt19937 rng(3);
  double worst = 0;
  for (int trial = 0; trial < 1000; ++trial) {
    const Rigid3d t = RandomPose(rng);
    const Rigid3d back = Rigid3d::Exp(t.Log());
    const PoseError e = ComparePoses(t, back);
    worst = std::max({worst, e.rotation_rad, e.translation_m});
    // Log angle is always in [0, pi].
    ASSERT_LE(t.Log().head<3>().norm(), kPi + 1e-15);
  }
  EXPECT_LT(worst, 1e-14);
  std::printf("Exp(Log(T)) vs T: max error %.3g\n", worst);
}

TEST(TransformTest, OneParameterSubgroup) {
  // Exp(s xi) Exp(u xi) = Exp((s + u) xi): a consequence of Exp being the twist exponential.
  const Vector6d xi = Twist(Eigen::Vector3d(0.3, -1, 0.2), 0.9, Eigen::Vector3d(1, 2, -0.5));
  for (const double s : {-1.3, 0.0, 0.25, 1.0}) {
    for (const double u : {-0.7, 0.5, 2.0}) {
      const PoseError e =
          ComparePoses(Rigid3d::Exp(s * xi) * Rigid3d::Exp(u * xi), Rigid3d::Exp((s + u) * xi));
      EXPECT_LT(e.rotation_rad, 1e-14);
      EXPECT_LT(e.translation_m, 1e-14);
    }
  }
}

TEST(TransformTest, CompositionAndInverseIdentities) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    const Rigid3d a = RandomPose(rng), b = RandomPose(rng), c = RandomPose(rng);
    const Eigen::Vector3d p(0.3, -0.2, 1.7);
    // Associativity, and agreement with the matrices.
    PoseError e = ComparePoses((a * b) * c, a * (b * c));
    EXPECT_LT(e.rotation_rad, 1e-14);
    EXPECT_LT(e.translation_m, 1e-14);
    const Eigen::Vector4d ph(p.x(), p.y(), p.z(), 1.0);
    EXPECT_LT(((a * b) * p - (a.ToMatrix4() * b.ToMatrix4() * ph).head<3>()).norm(), 1e-14);
    // Inverse.
    e = ComparePoses(a * a.Inverse(), Rigid3d::Identity());
    EXPECT_LT(e.rotation_rad, 1e-15);
    EXPECT_LT(e.translation_m, 1e-14);
    e = ComparePoses((a * b).Inverse(), b.Inverse() * a.Inverse());
    EXPECT_LT(e.rotation_rad, 1e-14);
    EXPECT_LT(e.translation_m, 1e-14);
    EXPECT_LT((a.Inverse() * (a * p) - p).norm(), 1e-14);
    // Log of the inverse is minus the log (away from pi, where the sign of omega is free).
    if (a.RotationAngle() < 3.0) {
      EXPECT_LT((a.Inverse().Log() + a.Log()).cwiseAbs().maxCoeff(), 1e-13);
    }
  }
}

TEST(TransformTest, MatrixRoundTrip) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 100; ++trial) {
    const Rigid3d a = RandomPose(rng);
    const Eigen::Matrix4d m = a.ToMatrix4();
    EXPECT_EQ(m.row(3), Eigen::RowVector4d(0, 0, 0, 1));
    EXPECT_EQ(m.topRows<3>(), a.ToMatrix3x4());
    const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
    EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-15 * 10);
    EXPECT_NEAR(r.determinant(), 1.0, 1e-15 * 10);
    const PoseError e = ComparePoses(Rigid3d::FromMatrix(a.ToMatrix3x4()), a);
    EXPECT_LT(e.rotation_rad, 1e-15 * 10);
    EXPECT_EQ(e.translation_m, 0.0);
  }
}

TEST(TransformTest, FromMatrixProjectsToNearestRotation) {
  // A rotation scaled by 1.01 and with 1e-3 noise: the result is still a unit quaternion
  // close to the rotation. Exactly scaled R gives exactly R back (same singular vectors).
  const Rigid3d truth(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3)
                                                                    .normalized())),
                      Eigen::Vector3d(1, 2, 3));
  Eigen::Matrix<double, 3, 4> rt = truth.ToMatrix3x4();
  rt.leftCols<3>() *= 1.01;
  Rigid3d back = Rigid3d::FromMatrix(rt);
  EXPECT_NEAR(back.rotation.norm(), 1.0, 1e-15);
  EXPECT_LT(ComparePoses(back, truth).rotation_rad, 1e-14);
  rt(0, 1) += 1e-3;
  back = Rigid3d::FromMatrix(rt);
  EXPECT_NEAR(back.rotation.norm(), 1.0, 1e-15);
  EXPECT_LT(ComparePoses(back, truth).rotation_rad, 1e-3);
  EXPECT_GT(ComparePoses(back, truth).rotation_rad, 1e-5);  // the noise did something
}

TEST(TransformTest, RotationAngleAndComparePoses) {
  const Rigid3d a(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())),
                  Eigen::Vector3d(1, 0, 0));
  const Rigid3d b(Eigen::Quaterniond(Eigen::AngleAxisd(0.3 + 1e-7, Eigen::Vector3d::UnitX())),
                  Eigen::Vector3d(1, 0.003, 0.004));
  EXPECT_NEAR(a.RotationAngle(), 0.3, 1e-16);
  const PoseError e = ComparePoses(a, b);
  EXPECT_NEAR(e.rotation_rad, 1e-7, 1e-16);
  EXPECT_NEAR(e.translation_m, 0.005, 1e-16);
  // The sign of the quaternion does not matter.
  Rigid3d minus_a = a;
  minus_a.rotation.coeffs() = -a.rotation.coeffs();
  EXPECT_NEAR(minus_a.RotationAngle(), 0.3, 1e-16);
  EXPECT_EQ(ComparePoses(a, minus_a).rotation_rad, 0.0);
}

TEST(TransformTest, InterpolateEndpointsAreExact) {
  std::mt19937 rng(13);
  for (int trial = 0; trial < 100; ++trial) {
    const Rigid3d a = RandomPose(rng), b = RandomPose(rng);
    const Rigid3d at0 = Interpolate(a, b, 0.0), at1 = Interpolate(a, b, 1.0);
    EXPECT_EQ(at0.rotation.coeffs(), a.rotation.coeffs());
    EXPECT_EQ(at0.translation, a.translation);
    EXPECT_EQ(at1.rotation.coeffs(), b.rotation.coeffs());
    EXPECT_EQ(at1.translation, b.translation);
  }
}

TEST(TransformTest, InterpolateMidpointOfKnownRotation) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, -1, 2).normalized();
  const Rigid3d a(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, axis)), Eigen::Vector3d(0, 0, 0));
  const Rigid3d b(Eigen::Quaterniond(Eigen::AngleAxisd(1.4, axis)), Eigen::Vector3d(2, 4, -6));
  const Rigid3d mid = Interpolate(a, b, 0.5);
  const Rigid3d expected(Eigen::Quaterniond(Eigen::AngleAxisd(0.8, axis)),
                         Eigen::Vector3d(1, 2, -3));
  const PoseError e = ComparePoses(mid, expected);
  EXPECT_LT(e.rotation_rad, 1e-15);
  EXPECT_LT(e.translation_m, 1e-15);
}

TEST(TransformTest, InterpolateTakesShorterArc) {
  // b is a rotation of 270 degrees about z, i.e. -90 degrees: the midpoint is -45 degrees,
  // whichever sign b's quaternion is stored with.
  const Rigid3d a;
  Rigid3d b(Eigen::Quaterniond(Eigen::AngleAxisd(1.5 * kPi, Eigen::Vector3d::UnitZ())),
            Eigen::Vector3d::Zero());
  const Rigid3d expected(
      Eigen::Quaterniond(Eigen::AngleAxisd(-0.25 * kPi, Eigen::Vector3d::UnitZ())),
      Eigen::Vector3d::Zero());
  EXPECT_LT(ComparePoses(Interpolate(a, b, 0.5), expected).rotation_rad, 1e-15);
  b.rotation.coeffs() = -b.rotation.coeffs();
  EXPECT_LT(ComparePoses(Interpolate(a, b, 0.5), expected).rotation_rad, 1e-15);
  // Relative angle along the way never exceeds 90 degrees.
  for (double s = 0; s <= 1.0; s += 0.125) {
    EXPECT_LE(ComparePoses(a, Interpolate(a, b, s)).rotation_rad, 0.5 * kPi + 1e-15);
  }
}

TEST(TransformTest, InterpolateHasConstantAngularVelocity) {
  std::mt19937 rng(17);
  for (int trial = 0; trial < 50; ++trial) {
    const Rigid3d a = RandomPose(rng), b = RandomPose(rng);
    const double total = ComparePoses(a, b).rotation_rad;
    const int steps = 10;
    for (int i = 0; i < steps; ++i) {
      const Rigid3d p = Interpolate(a, b, static_cast<double>(i) / steps);
      const Rigid3d q = Interpolate(a, b, static_cast<double>(i + 1) / steps);
      // Equal steps in angle, and the angle from a grows linearly in s.
      EXPECT_NEAR(ComparePoses(p, q).rotation_rad, total / steps, 1e-13);
      EXPECT_NEAR(ComparePoses(a, q).rotation_rad, total * (i + 1) / steps, 1e-13);
    }
    // Extrapolation continues at the same rate (while the angle stays below pi).
    if (total < 1.0) {
      EXPECT_NEAR(ComparePoses(a, Interpolate(a, b, 2.0)).rotation_rad, 2 * total, 1e-13);
      EXPECT_NEAR(ComparePoses(a, Interpolate(a, b, -1.0)).rotation_rad, total, 1e-13);
    }
  }
}

}  // namespace
}  // namespace hw::core
