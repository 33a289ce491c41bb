#include "reconstruct/thermal_confidence.h"

#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace hw::reconstruct {
namespace {

using ::testing::HasSubstr;

constexpr double kDeg = M_PI / 180.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(ThermalConfidenceTest, DefaultOptionsAreValid) {
  EXPECT_EQ(ThermalConfidenceOptions().Check(), "");
}

TEST(ThermalConfidenceTest, CheckNamesTheBadField) {
  struct Case {
    const char* field;
    std::function<void(ThermalConfidenceOptions&)> spoil;
  };
  const std::vector<Case> cases = {
      {"motion_power", [](auto& o) { o.motion_power = -0.1; }},
      {"distortion_power", [](auto& o) { o.distortion_power = 10.5; }},
      {"angle_power", [](auto& o) { o.angle_power = kNaN; }},
      {"distance_power", [](auto& o) { o.distance_power = 11; }},
      {"operating_power", [](auto& o) { o.operating_power = -1; }},
      {"integration_time_s", [](auto& o) { o.integration_time_s = 1.5; }},
      {"motion_blur_px", [](auto& o) { o.motion_blur_px = 0; }},
      {"distortion_px", [](auto& o) { o.distortion_px = -1; }},
      {"max_angle_deg", [](auto& o) { o.max_angle_deg = 90.5; }},
      {"max_angle_deg", [](auto& o) { o.max_angle_deg = 0; }},
      {"reference_distance_m", [](auto& o) { o.reference_distance_m = 0; }},
      {"ffc_settle_s", [](auto& o) { o.ffc_settle_s = -0.1; }},
      {"ffc_ramp_s", [](auto& o) { o.ffc_ramp_s = kNaN; }},
      {"drift_onset_s", [](auto& o) { o.drift_onset_s = -1; }},
      {"drift_time_s", [](auto& o) { o.drift_time_s = 0; }},
  };
  for (const Case& c : cases) {
    ThermalConfidenceOptions o;
    c.spoil(o);
    EXPECT_THAT(o.Check(), HasSubstr(c.field)) << c.field;
  }
  ThermalConfidenceOptions edges;  // the ends of the ranges are valid
  edges.motion_power = 0;
  edges.distortion_power = 10;
  edges.integration_time_s = 0;
  edges.max_angle_deg = 90;
  edges.ffc_settle_s = edges.ffc_ramp_s = edges.drift_onset_s = 0;
  EXPECT_EQ(edges.Check(), "");
}

// The pinhole projection of a point in the camera frame, px (principal point irrelevant).
Eigen::Vector2d Project(const Eigen::Vector3d& p, double fx, double fy) {
  return {fx * p.x() / p.z(), fy * p.y() / p.z()};
}

// The static point seen at time t by a camera moving with constant body velocities (v, ω)
// from its pose at t = 0: P(t) = R(t)ᵀ (P − v t), R(t) the rotation by ω t. Its image
// velocity at 0 by a central difference (the O(t²) terms of the exact screw motion cancel).
double FiniteDifferenceSpeed(const Eigen::Vector3d& p, const Eigen::Vector3d& v,
                             const Eigen::Vector3d& w, double fx, double fy, double dt) {
  const auto at = [&](double t) {
    const double angle = w.norm() * t;
    const Eigen::Matrix3d r =
        angle == 0 ? Eigen::Matrix3d::Identity()
                   : Eigen::AngleAxisd(angle, w.normalized()).toRotationMatrix();
    return Project(r.transpose() * (p - v * t), fx, fy);
  };
  return ((at(dt) - at(-dt)) / (2 * dt)).norm();
}

TEST(ThermalConfidenceTest, ImageSpeedMatchesFiniteDifferenceOfProjection) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1, 1), depth(0.3, 5);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3d p(unit(rng) * 2, unit(rng) * 2, depth(rng));
    const Eigen::Vector3d v(unit(rng), unit(rng), unit(rng));                // ≤ 1.7 m/s
    const Eigen::Vector3d w = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 3;  // rad/s
    const double fx = 200 + 300 * (unit(rng) + 1), fy = fx * (1 + 0.05 * unit(rng));
    const double speed = ImageSpeedPxPerS(p, v, w, fx, fy);
    const double expected = FiniteDifferenceSpeed(p, v, w, fx, fy, 1e-5);
    EXPECT_NEAR(speed, expected, 1e-5 * expected) << "trial " << trial;
  }
}

TEST(ThermalConfidenceTest, ImageSpeedHandCases) {
  // Sideways at 1 m/s, a point 2 m ahead on the axis: du/dt = −fx · 1 / 2.
  EXPECT_NEAR(ImageSpeedPxPerS({0, 0, 2}, {1, 0, 0}, {0, 0, 0}, 300, 300), 150, 1e-12);
  // Forward motion does not move the point on the axis.
  EXPECT_NEAR(ImageSpeedPxPerS({0, 0, 2}, {0, 0, 1}, {0, 0, 0}, 300, 300), 0, 1e-12);
  // A pan of ω about y moves the axis point by fx · ω whatever its depth.
  EXPECT_NEAR(ImageSpeedPxPerS({0, 0, 7}, {0, 0, 0}, {0, 0.5, 0}, 300, 300), 150, 1e-12);
  EXPECT_TRUE(std::isnan(ImageSpeedPxPerS({0, 0, 0}, {1, 0, 0}, {0, 0, 0}, 300, 300)));
  EXPECT_TRUE(std::isnan(ImageSpeedPxPerS({0, 0, -1}, {1, 0, 0}, {0, 0, 0}, 300, 300)));
}

TEST(ThermalConfidenceTest, FastRotationBlursMoreThanSlow) {
  const ThermalConfidenceOptions o;  // τ = 10 ms, 1 px scale
  const Eigen::Vector3d p(0.3, -0.2, 2.0);
  const double fx = 300;
  const auto c1 = [&](double deg_per_s) {
    const double speed = ImageSpeedPxPerS(p, Eigen::Vector3d::Zero(),
                                          Eigen::Vector3d(0, deg_per_s * kDeg, 0), fx, fx);
    return MotionConfidence(speed * o.integration_time_s, o);
  };
  // 90°/s: ~4.8 px of smear, c1 ≈ e^(−11.5); 5°/s: ~0.27 px, c1 ≈ 0.97.
  EXPECT_LT(c1(90), 1e-4);
  EXPECT_GT(c1(5), 0.95);
  EXPECT_LT(c1(90), c1(30));
  EXPECT_LT(c1(30), c1(5));
  EXPECT_EQ(c1(0), 1);
}

TEST(ThermalConfidenceTest, MotionAndDistortionAreGaussians) {
  const ThermalConfidenceOptions o;
  EXPECT_EQ(MotionConfidence(0, o), 1);
  EXPECT_NEAR(MotionConfidence(1, o), std::exp(-0.5), 1e-15);
  EXPECT_NEAR(MotionConfidence(2, o), std::exp(-2.0), 1e-15);
  EXPECT_EQ(MotionConfidence(kNaN, o), 0);
  EXPECT_EQ(DistortionConfidence(0, o), 1);
  EXPECT_NEAR(DistortionConfidence(20, o), std::exp(-0.5), 1e-15);
  EXPECT_NEAR(DistortionConfidence(10, o), std::exp(-0.125), 1e-15);
  EXPECT_EQ(DistortionConfidence(kNaN, o), 0);
}

TEST(ThermalConfidenceTest, GrazingViewTrustedLessThanFrontal) {
  const ThermalConfidenceOptions o;  // max 80°
  const auto c3 = [&](double deg) { return AngleConfidence(std::cos(deg * kDeg), o); };
  EXPECT_EQ(c3(0), 1);
  EXPECT_NEAR(c3(60), 0.5, 1e-12);
  EXPECT_NEAR(c3(75), std::cos(75 * kDeg), 1e-15);
  EXPECT_LT(c3(75), c3(30));
  EXPECT_EQ(c3(81), 0);  // beyond max_angle_deg
  EXPECT_EQ(c3(95), 0);  // facing away
  EXPECT_EQ(AngleConfidence(-1, o), 0);
  EXPECT_EQ(AngleConfidence(kNaN, o), 0);
  ThermalConfidenceOptions narrow = o;  // options that change between calls are honoured
  narrow.max_angle_deg = 60;
  EXPECT_EQ(AngleConfidence(std::cos(70 * kDeg), narrow), 0);
  EXPECT_NEAR(AngleConfidence(std::cos(70 * kDeg), o), std::cos(70 * kDeg), 1e-15);
  EXPECT_EQ(AngleConfidence(std::cos(70 * kDeg), narrow), 0);
  ThermalConfidenceOptions all = o;
  all.max_angle_deg = 90;
  EXPECT_NEAR(AngleConfidence(std::cos(89 * kDeg), all), std::cos(89 * kDeg), 1e-15);
}

TEST(ThermalConfidenceTest, DistanceFallsAsOneOverD) {
  const ThermalConfidenceOptions o;  // 1 m
  EXPECT_EQ(DistanceConfidence(0.4, o), 1);
  EXPECT_EQ(DistanceConfidence(1.0, o), 1);
  EXPECT_NEAR(DistanceConfidence(2.0, o), 0.5, 1e-15);
  EXPECT_NEAR(DistanceConfidence(4.0, o), 0.25, 1e-15);
  EXPECT_EQ(DistanceConfidence(0, o), 0);
  EXPECT_EQ(DistanceConfidence(kNaN, o), 0);
}

TEST(ThermalConfidenceTest, OperatingConditionAroundFlatFieldEvents) {
  const ThermalConfidenceOptions o;  // settle 0.5, ramp 0.5, onset 60, decay 300 s
  EXPECT_EQ(OperatingConfidence(0.0, false, o), 0);   // shutter closed
  EXPECT_EQ(OperatingConfidence(0.49, false, o), 0);
  EXPECT_NEAR(OperatingConfidence(0.75, false, o), 0.5, 1e-12);  // half-way up the ramp
  EXPECT_EQ(OperatingConfidence(1.0, false, o), 1);
  EXPECT_EQ(OperatingConfidence(30, false, o), 1);
  EXPECT_EQ(OperatingConfidence(60, false, o), 1);
  EXPECT_NEAR(OperatingConfidence(360, false, o), std::exp(-1.0), 1e-15);
  // The frame right after an FFC event is trusted less than one mid-period.
  EXPECT_LT(OperatingConfidence(0.6, false, o), OperatingConfidence(20, false, o));
  // A frozen frame is never trusted, whatever the time; an unknown time is.
  EXPECT_EQ(OperatingConfidence(20, true, o), 0);
  EXPECT_EQ(OperatingConfidence(kNaN, true, o), 0);
  EXPECT_EQ(OperatingConfidence(kNaN, false, o), 1);

  ThermalConfidenceOptions step = o;  // no ramp: 1 from the end of the closure on
  step.ffc_ramp_s = 0;
  EXPECT_EQ(OperatingConfidence(0.49, false, step), 0);
  EXPECT_EQ(OperatingConfidence(0.5, false, step), 1);
  ThermalConfidenceOptions early = o;  // drift from 0.5 s: ramp and decay multiply
  early.drift_onset_s = 0.5;
  EXPECT_NEAR(OperatingConfidence(0.75, false, early), 0.5 * std::exp(-0.25 / 300), 1e-15);
}

TEST(ThermalConfidenceTest, RayConfidenceIsProductOfPowers) {
  const ConfidenceTerms c{.motion = 0.5, .distortion = 0.8, .angle = 0.9, .distance = 0.4,
                          .operating = 0.7};
  const ThermalConfidenceOptions ones;
  EXPECT_NEAR(RayConfidence(c, ones), 0.5 * 0.8 * 0.9 * 0.4 * 0.7, 1e-15);

  ThermalConfidenceOptions o;
  o.motion_power = 1;
  o.distortion_power = 2;
  o.angle_power = 0.5;
  o.distance_power = 0;  // off
  o.operating_power = 3;
  // 0.5 · 0.8² · √0.9 · 1 · 0.7³
  EXPECT_NEAR(RayConfidence(c, o), 0.5 * 0.64 * 0.9486832980505138 * 0.343, 1e-15);

  // 0^0 = 1: a metric that is off does not zero the product even at 0.
  ConfidenceTerms zero_distance = c;
  zero_distance.distance = 0;
  EXPECT_NEAR(RayConfidence(zero_distance, o), RayConfidence(c, o), 0);
  EXPECT_EQ(RayConfidence(zero_distance, ones), 0);
  EXPECT_EQ(RayConfidence(ConfidenceTerms{}, o), 1);
}

}  // namespace
}  // namespace hw::reconstruct
