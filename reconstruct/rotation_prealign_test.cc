#include "reconstruct/rotation_prealign.h"

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace hw::reconstruct {
namespace {

using ::testing::HasSubstr;

constexpr double kDeg = std::numbers::pi / 180;

// A 160×120 camera (the coarsest level of a 640×480 pyramid).
PinholeCamera Camera() {
  PinholeCamera c;
  c.width = 160;
  c.height = 120;
  c.fx = c.fy = 131.25f;
  c.cx = 79.5f;
  c.cy = 59.5f;
  return c;
}

// Grey level of the textured wall z = 2 m (previous camera frame) at (x, y), m: smooth
// patterns of 17–40 cm, so that a few degrees stay inside one period.
float Texture(double x, double y) {
  return static_cast<float>(0.5 + 0.15 * std::sin(2 * std::numbers::pi * x / 0.4 + 0.3) +
                            0.1 * std::cos(2 * std::numbers::pi * y / 0.3) +
                            0.1 * std::sin(2 * std::numbers::pi * (x + y) / 0.17));
}

// A brick wall: courses 7.5 cm high, bricks 21.5 cm long in a running bond, mortar lines
// 1 cm wide (smooth-edged, so that point sampling does not alias them), and two broad
// features: a dark pipe 20 cm across running diagonally over it, and a pillar's shadow. At 2 m and 131 px focal
// length the courses repeat every 5 px: a turn of a few degrees moves the image several
// courses.
float Bricks(double x, double y) {
  const double course = 0.075, brick = 0.215;
  const double row = std::floor(y / course);
  const double dy = std::abs(y - course * std::round(y / course));
  const double shifted = x + (static_cast<int64_t>(row) % 2 != 0 ? 0.5 * brick : 0.0);
  const double dx = std::abs(shifted - brick * std::round(shifted / brick));
  const auto mortar = [](double d) { return std::exp(-0.5 * (d / 0.006) * (d / 0.006)); };
  const double pipe = std::abs((x - 0.2) * 0.8 + (y + 0.1) * 0.6);  // distance to its axis, m
  const double pillar = std::abs(x + 0.35);
  return static_cast<float>(0.6 - 0.25 * std::max(mortar(dy), mortar(dx)) -
                            0.3 * std::exp(-0.5 * (pipe / 0.07) * (pipe / 0.07)) -
                            0.2 * std::exp(-0.5 * (pillar / 0.1) * (pillar / 0.1)));
}

// The wall seen by a camera at previous_from_camera (exact ray-plane intersection): grey
// and depth along the camera's axis. `offset` is added to every grey level (exposure).
PrealignImage Render(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& t, float offset = 0,
                     float (*texture)(double, double) = Texture) {
  const PinholeCamera cam = Camera();
  PrealignImage image{cv::Mat(cam.height, cam.width, CV_32FC1), cv::Mat(cam.height, cam.width, CV_32FC1), cam, {}};
  const Eigen::Matrix3d r = rotation.toRotationMatrix();
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Eigen::Vector3d ray((x - double{cam.cx}) / double{cam.fx}, (y - double{cam.cy}) / double{cam.fy}, 1);
      const Eigen::Vector3d dir = r * ray;
      const double s = (2.0 - t.z()) / dir.z();
      const Eigen::Vector3d p = t + s * dir;
      image.grey.at<float>(y, x) = texture(p.x(), p.y()) + offset;
      image.depth_m.at<float>(y, x) = static_cast<float>(s);  // ray.z = 1
    }
  }
  return image;
}

double AngleDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) { return a.angularDistance(b) / kDeg; }

TEST(PrealignRotation, RecoversAJerkBeyondThePredictionOnATexturedWall) {
  // The rig turned 1.5° about y and 0.6° about x more than predicted (the prediction: no
  // rotation), while moving 3 cm: 3.4 px at this level, beyond a sharp texture's basin.
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(0.6 * kDeg, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d t(0.03, -0.01, 0.005);
  const PrealignImage previous = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const PrealignImage current = Render(truth, t);
  RotationPrealignResult r =
      PrealignRotation(previous, current, Eigen::Quaterniond::Identity(), t, RotationPrealignOptions{});
  ASSERT_TRUE(r.ok);
  // Both images sampled exactly; what is left is the blur's and the bilinear sampling's
  // bias near the image border: a twentieth of a pixel (0.02°) allowed.
  EXPECT_LT(AngleDeg(r.previous_from_current, truth), 0.02);
  EXPECT_NEAR(r.correction_deg, AngleDeg(truth, Eigen::Quaterniond::Identity()), 0.02);
  EXPECT_LT(r.rms_after, 0.1 * r.rms_before);
  EXPECT_GT(r.pixels, 3000);  // every second pixel of 160×120, less what left the view

  // A prediction already within min_correction_deg (0.5°) is kept: found, not used.
  const Eigen::Quaterniond close = truth * Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * kDeg, Eigen::Vector3d::UnitZ()));
  r = PrealignRotation(previous, current, close, t, RotationPrealignOptions{});
  EXPECT_FALSE(r.ok);
  EXPECT_NEAR(r.correction_deg, 0.3, 0.02);
  EXPECT_LT(AngleDeg(r.previous_from_current, close), 1e-9);
}

TEST(PrealignRotation, AlignsCoarseToFineAcrossRepeatingBrickCourses) {
  // A swing after a dropped frame: 5° about x beyond the prediction (11 px, two courses)
  // and 2° about y. At the finest blur alone the courses lock the alignment onto a wrong
  // one; from the coarsest scale the pipe leads it into the right one.
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(5.0 * kDeg, Eigen::Vector3d::UnitX()) *
                                 Eigen::AngleAxisd(2.0 * kDeg, Eigen::Vector3d::UnitY()));
  const Eigen::Vector3d t(0.02, 0.04, 0.0);
  const PrealignImage previous = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero(), 0, Bricks);
  const PrealignImage current = Render(truth, t, 0.03f, Bricks);
  RotationPrealignOptions one_scale;
  one_scale.scales = 1;
  const RotationPrealignResult fine =
      PrealignRotation(previous, current, Eigen::Quaterniond::Identity(), t, one_scale);
  const RotationPrealignResult coarse_to_fine =
      PrealignRotation(previous, current, Eigen::Quaterniond::Identity(), t, RotationPrealignOptions{});
  ASSERT_TRUE(coarse_to_fine.ok);
  // A course is 2.1° here; found within 0.015°. A pixel (0.44°) bounds what the point-sampled
  // mortar lines and the border could leave: 0.2° allowed. Alone, the finest scale ends 3.8°
  // off (two courses).
  EXPECT_LT(AngleDeg(coarse_to_fine.previous_from_current, truth), 0.2);
  EXPECT_GT(AngleDeg(fine.previous_from_current, truth), 1.0);
}

TEST(PrealignRotation, SkipsACoarseScaleWithTooFewSamples) {
  // Depth on every fourth column only (a structured-light pattern's dropouts): the coarsest
  // scale samples every fourth pixel from column 1 and meets none of them; the finer scales,
  // every second from column 1, meet half. The coarse scale is skipped, not the alignment.
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(-1.5 * kDeg, Eigen::Vector3d::UnitY()));
  const PrealignImage previous = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  PrealignImage current = Render(truth, Eigen::Vector3d::Zero());
  for (int y = 0; y < current.depth_m.rows; ++y) {
    for (int x = 0; x < current.depth_m.cols; ++x) {
      if (x % 4 != 3) current.depth_m.at<float>(y, x) = 0;
    }
  }
  const RotationPrealignResult r = PrealignRotation(previous, current, Eigen::Quaterniond::Identity(),
                                                    Eigen::Vector3d::Zero(), RotationPrealignOptions{});
  ASSERT_TRUE(r.ok);
  // The current image's blur now mixes grey levels over the stripes' gaps (normalised over
  // a quarter of the pixels): 0.05° allowed, two and a half times the full image's bound.
  EXPECT_LT(AngleDeg(r.previous_from_current, truth), 0.05);
}

TEST(PrealignRotation, IgnoresAnExposureChangeAndHoles) {
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(-1.2 * kDeg, Eigen::Vector3d::UnitY()));
  const PrealignImage previous = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  PrealignImage current = Render(truth, Eigen::Vector3d::Zero(), 0.08f);  // 8 % brighter
  // A hole (no depth, no colour: black as the registration leaves it) in each image.
  current.depth_m(cv::Rect(20, 30, 40, 30)).setTo(0);
  current.grey(cv::Rect(20, 30, 40, 30)).setTo(0);
  previous.depth_m(cv::Rect(100, 60, 30, 40)).setTo(0);
  previous.grey(cv::Rect(100, 60, 30, 40)).setTo(0);
  const RotationPrealignResult r = PrealignRotation(previous, current, Eigen::Quaterniond::Identity(),
                                                    Eigen::Vector3d::Zero(), RotationPrealignOptions{});
  ASSERT_TRUE(r.ok);
  EXPECT_LT(AngleDeg(r.previous_from_current, truth), 0.03);
}

TEST(PrealignRotation, KeepsTheGuessWhenNothingConstrainsOrTheCorrectionIsTooLarge) {
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(2.0 * kDeg, Eigen::Vector3d::UnitY()));
  const Eigen::Quaterniond guess = Eigen::Quaterniond::Identity();
  const PrealignImage previous = Render(guess, Eigen::Vector3d::Zero());
  const PrealignImage current = Render(truth, Eigen::Vector3d::Zero());

  // More than max_rotation_deg from the guess: refused, the guess returned.
  RotationPrealignOptions tight;
  tight.max_rotation_deg = 1;
  RotationPrealignResult r = PrealignRotation(previous, current, guess, Eigen::Vector3d::Zero(), tight);
  EXPECT_FALSE(r.ok);
  EXPECT_NEAR(r.correction_deg, 2.0, 0.05);  // what it found, reported
  EXPECT_LT(AngleDeg(r.previous_from_current, guess), 1e-9);

  // A uniform grey wall: no gradient, no rotation information — the guess stays.
  PrealignImage flat_previous = previous, flat_current = current;
  flat_previous.grey = cv::Mat(previous.grey.size(), CV_32FC1, cv::Scalar(0.4f));
  flat_current.grey = cv::Mat(current.grey.size(), CV_32FC1, cv::Scalar(0.4f));
  r = PrealignRotation(flat_previous, flat_current, guess, Eigen::Vector3d::Zero(), RotationPrealignOptions{});
  EXPECT_FALSE(r.ok);
  EXPECT_LT(AngleDeg(r.previous_from_current, guess), 1e-9);

  // Too few pixels with depth.
  PrealignImage empty = current;
  empty.depth_m.setTo(0);
  r = PrealignRotation(previous, empty, guess, Eigen::Vector3d::Zero(), RotationPrealignOptions{});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.pixels, 0);

  // Off: nothing computed.
  RotationPrealignOptions off;
  off.iterations = 0;
  r = PrealignRotation(previous, current, guess, Eigen::Vector3d::Zero(), off);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.iterations, 0);
}

// A person walking by: a slab 0.7 m wide and 0.9 m tall, 1 m from the camera (half the view),
// striped every 30 cm, in front of the textured wall 2 m away, steps 5 cm to the side
// between the frames (6.6 px) while the rig turns exactly as predicted. The grey images follow the person — the alignment moves the
// rotation off the prediction — while the depth says the wall has not moved.
PrealignImage RenderWithPerson(double person_x_m) {
  PrealignImage image = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const PinholeCamera cam = Camera();
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const double px = (x - double{cam.cx}) / double{cam.fx}, py = (y - double{cam.cy}) / double{cam.fy};  // at z = 1 m
      if (px < person_x_m || px > person_x_m + 0.7 || std::abs(py) > 0.45) continue;
      image.grey.at<float>(y, x) = static_cast<float>(0.5 + 0.3 * std::sin(2 * std::numbers::pi * (px - person_x_m) / 0.3));
      image.depth_m.at<float>(y, x) = 1.0f;
    }
  }
  return image;
}

TEST(PrealignRotation, RefusesARotationTheDepthContradictsAPersonWalkingBy) {
  const PrealignImage previous = RenderWithPerson(-0.3), current = RenderWithPerson(-0.25);
  const Eigen::Quaterniond guess = Eigen::Quaterniond::Identity();  // the rig's true turn
  RotationPrealignOptions unchecked;
  unchecked.max_depth_misfit_ratio = 0;
  const RotationPrealignResult followed = PrealignRotation(previous, current, guess, Eigen::Vector3d::Zero(), unchecked);
  // Without the check the person wins: the rotation follows their 2.9° step (2.65° found),
  // accepted — the grey residual fell.
  ASSERT_TRUE(followed.ok);
  EXPECT_GT(followed.correction_deg, 2.0);
  EXPECT_TRUE(std::isnan(followed.depth_misfit_before_m));
  const RotationPrealignResult checked =
      PrealignRotation(previous, current, guess, Eigen::Vector3d::Zero(), RotationPrealignOptions{});
  EXPECT_FALSE(checked.ok);
  EXPECT_TRUE(checked.rejected_by_depth);
  EXPECT_NEAR(checked.correction_deg, followed.correction_deg, 1e-9);  // the same alignment, refused
  EXPECT_GT(checked.depth_misfit_after_m, checked.depth_misfit_before_m);
  EXPECT_LT(AngleDeg(checked.previous_from_current, guess), 1e-9);  // ICP starts from the prediction

  // A real turn is not refused: the jerk of the first test, the depth check on by default.
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(0.6 * kDeg, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d t(0.03, -0.01, 0.005);
  const RotationPrealignResult turn =
      PrealignRotation(Render(guess, Eigen::Vector3d::Zero()), Render(truth, t), guess, t, RotationPrealignOptions{});
  ASSERT_TRUE(turn.ok);
  EXPECT_FALSE(turn.rejected_by_depth);
  EXPECT_LT(turn.depth_misfit_after_m, 0.2 * turn.depth_misfit_before_m);
}

// The misfit on the plain wall: 0 at the true rotation (every point lands on its own depth,
// to the nearest pixel's slope), and at a wrong one the distance of the rotated plane from
// the true one along the rays, averaged: for a 1° turn about y of a wall 2 m away, |Δz| at
// lateral offset x is about x·tan 1° ≈ 0.0175 x, x up to ±1.2 m: a mean of ~1 cm.
TEST(PrealignRotation, DepthMisfitIsZeroAtTheTruthAndGrowsWithTheError) {
  const Eigen::Quaterniond truth(Eigen::AngleAxisd(1.0 * kDeg, Eigen::Vector3d::UnitY()));
  const PrealignImage previous = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const PrealignImage current = Render(truth, Eigen::Vector3d::Zero());
  const double at_truth = internal::DepthMisfit(previous, current, truth.toRotationMatrix(), Eigen::Vector3d::Zero(), 1);
  const double at_identity =
      internal::DepthMisfit(previous, current, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), 1);
  // Nearest-pixel lookup on a plane tilted 1°: a half pixel's depth slope, 2 m · tan 1° / 131 px.
  EXPECT_LT(at_truth, 0.5 * 2.0 * std::tan(1.0 * kDeg) / 131.25 + 1e-6);
  EXPECT_GT(at_identity, 0.005);
  EXPECT_LT(at_identity, 0.02);
  // Capped: a point 0.5 m off counts 0.1 m.
  PrealignImage far = current;
  far.depth_m.setTo(cv::Scalar(1.5f));
  EXPECT_NEAR(internal::DepthMisfit(previous, far, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), 1),
              kDepthMisfitCapM, 1e-6);
}

// The residual's derivative by the left rotation increment and the offset against central
// differences of the residual itself. The gradient images are central differences of the
// blurred image, interpolated; the residual is its bilinear interpolant, whose slope within a
// cell differs from that by up to the image's curvature times a pixel: for a sinusoid of
// period P px, 2π/P of its largest slope — 3.1 % at P = 200 (the x pattern; 150 along y:
// 4.2 %). 5 % of the largest derivative allowed (a wrong sign or axis is off by 100 %).
TEST(PrealignRotation, ResidualDerivativesMatchFiniteDifferences) {
  PrealignImage previous{cv::Mat(120, 160, CV_32FC1), cv::Mat(120, 160, CV_32FC1, cv::Scalar(2.0f)), Camera(), {}};
  for (int y = 0; y < 120; ++y) {
    for (int x = 0; x < 160; ++x) {
      previous.grey.at<float>(y, x) = static_cast<float>(0.5 + 0.2 * std::sin(2 * std::numbers::pi * x / 200) *
                                                                   std::cos(2 * std::numbers::pi * y / 150) +
                                                         0.1 * x / 160.0);
    }
  }
  const internal::PrealignImages images = internal::PreparePrevious(previous, 1.5);
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.02, Eigen::Vector3d(1, 2, 0.5).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.02, -0.01, 0.01);
  int checked = 0;
  for (const Eigen::Vector3d& point : {Eigen::Vector3d(0.1, 0.05, 2.0), Eigen::Vector3d(-0.4, 0.3, 2.1),
                                       Eigen::Vector3d(0.5, -0.35, 1.9), Eigen::Vector3d(-0.2, -0.2, 2.0)}) {
    double r = 0;
    Eigen::Vector4d jacobian;
    ASSERT_TRUE(internal::PrealignResidual(images, rotation, t, point, 0.4f, 0.01, r, jacobian));
    const double h = 1e-4;  // rad: 0.013 px at 2 m, inside one bilinear cell mostly
    for (int k = 0; k < 4; ++k) {
      double plus = 0, minus = 0;
      Eigen::Vector4d unused;
      Eigen::Vector3d omega = Eigen::Vector3d::Zero();
      double offset_plus = 0.01, offset_minus = 0.01;
      if (k < 3) {
        omega[k] = h;
      } else {
        offset_plus += h;
        offset_minus -= h;
      }
      const auto turned = [&](double sign) {
        return (Eigen::AngleAxisd(sign * omega.norm(), omega.norm() > 0 ? omega.normalized() : Eigen::Vector3d::UnitX())
                    .toRotationMatrix() *
                rotation)
            .eval();
      };
      ASSERT_TRUE(internal::PrealignResidual(images, turned(1), t, point, 0.4f, offset_plus, plus, unused));
      ASSERT_TRUE(internal::PrealignResidual(images, turned(-1), t, point, 0.4f, offset_minus, minus, unused));
      const double numeric = (plus - minus) / (2 * h);
      EXPECT_NEAR(jacobian[k], numeric, 0.05 * jacobian.head<3>().cwiseAbs().maxCoeff() + 1e-9)
          << "component " << k << " at " << point.transpose();
      ++checked;
    }
  }
  EXPECT_EQ(checked, 16);
}

// The chunked float accumulation against the same per-point terms (PrealignResidual) weighted
// and summed one by one in double, on a wall seen through a small turn with holes (a quarter
// of the points land beside one, or outside the image) and residuals on both sides of the
// Huber threshold. Float sums of 256 terms are exact to ~1e-6 of their size: 1e-4 of the
// largest entry covers that with margin (a wrong term or weight is off by whole per cent).
// Any thread count gives the same bits: the chunks add up in one order.
TEST(PrealignRotation, FloatAccumulationMatchesTheReferenceForAnyThreadCount) {
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d(0.3, 1, 0.2).normalized()));
  PrealignImage previous = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  const PrealignImage current = Render(turn, Eigen::Vector3d(0.01, 0, 0), 0.03f);
  for (int y = 30; y < 60; ++y) {  // a hole in the previous frame
    for (int x = 40; x < 90; ++x) previous.depth_m.at<float>(y, x) = 0;
  }
  const internal::PrealignImages images = internal::PreparePrevious(previous, 1.5);
  const PinholeCamera cam = Camera();
  internal::PrealignPoints points;
  std::vector<Eigen::Vector3d> reference_points;
  for (int y = 1; y + 1 < cam.height; y += 2) {
    for (int x = 1; x + 1 < cam.width; x += 2) {
      const float d = current.depth_m.at<float>(y, x);
      points.x.push_back(d * (static_cast<float>(x) - cam.cx) / cam.fx);
      points.y.push_back(d * (static_cast<float>(y) - cam.cy) / cam.fy);
      points.z.push_back(d);
      points.grey.push_back(current.grey.at<float>(y, x));
      reference_points.emplace_back(points.x.back(), points.y.back(), points.z.back());
    }
  }
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.5 * kDeg, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d t(0.01, 0, 0);
  const double offset = -0.01, huber = 0.05;
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
  double sum_wr2 = 0, sum_w = 0;
  int used = 0, robust = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    double r = 0;
    Eigen::Vector4d j;
    if (!internal::PrealignResidual(images, rotation, t, reference_points[i], points.grey[i], offset, r, j)) continue;
    const double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
    robust += w < 1;
    normal += w * j * j.transpose();
    rhs -= w * r * j;
    sum_wr2 += w * r * r;
    sum_w += w;
    ++used;
  }
  ASSERT_GT(used, 1000);
  ASSERT_LT(used, static_cast<int>(points.size()) * 9 / 10);  // the hole and the border cost points
  ASSERT_GT(robust, 10);                                      // both branches of the weight
  const internal::PrealignSums one = internal::AccumulatePrealign(images, rotation, t, points, offset, huber, 1);
  EXPECT_EQ(one.used, used);
  EXPECT_LT((one.normal - normal).cwiseAbs().maxCoeff(), 1e-4 * normal.cwiseAbs().maxCoeff());
  EXPECT_LT((one.rhs - rhs).cwiseAbs().maxCoeff(), 1e-4 * rhs.cwiseAbs().maxCoeff());
  EXPECT_NEAR(one.sum_wr2, sum_wr2, 1e-4 * sum_wr2);
  EXPECT_NEAR(one.sum_w, sum_w, 1e-4 * sum_w);
  EXPECT_EQ(one.normal, one.normal.transpose());
  for (int threads : {2, 3, 8}) {
    const internal::PrealignSums many =
        internal::AccumulatePrealign(images, rotation, t, points, offset, huber, threads);
    EXPECT_EQ(many.normal, one.normal) << threads;
    EXPECT_EQ(many.rhs, one.rhs) << threads;
    EXPECT_EQ(many.sum_wr2, one.sum_wr2) << threads;
    EXPECT_EQ(many.used, one.used) << threads;
  }
}

// A frame aligned as the current one hands out its blurs (one per scale, σ 1.5, 3 and 6 px);
// aligning the next frame against it with them gives the bits it gives without them.
TEST(PrealignRotation, TheCurrentFramesBlursServeAsThePreviousFramesNextTime) {
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(1.2 * kDeg, Eigen::Vector3d(0.2, 1, 0).normalized()));
  const PrealignImage first = Render(Eigen::Quaterniond::Identity(), Eigen::Vector3d::Zero());
  PrealignImage second = Render(turn, Eigen::Vector3d(0.01, 0, 0));
  const PrealignImage third = Render(turn * turn, Eigen::Vector3d(0.02, 0, 0));
  std::vector<PrealignBlur> blurs;
  const RotationPrealignOptions options;
  PrealignRotation(first, second, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0, 0), options, &blurs);
  ASSERT_EQ(blurs.size(), 3u);
  EXPECT_EQ(blurs[0].sigma_px, 6.0);  // coarse to fine
  EXPECT_EQ(blurs[2].sigma_px, 1.5);
  const RotationPrealignResult fresh =
      PrealignRotation(second, third, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0, 0), options);
  second.blurs = blurs;
  const RotationPrealignResult cached =
      PrealignRotation(second, third, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, 0, 0), options);
  ASSERT_TRUE(fresh.ok);
  EXPECT_EQ(cached.previous_from_current.coeffs(), fresh.previous_from_current.coeffs());
  EXPECT_EQ(cached.rms_after, fresh.rms_after);
  EXPECT_EQ(cached.iterations, fresh.iterations);
}

TEST(RotationPrealignOptions, CheckNamesTheFieldValueAndConstraint) {
  EXPECT_EQ(RotationPrealignOptions{}.Check(), "");
  RotationPrealignOptions o;
  o.iterations = 51;
  EXPECT_THAT(o.Check(), HasSubstr("iterations: must be in [0, 50], got 51"));
  o = {};
  o.blur_sigma_px = -1;
  EXPECT_THAT(o.Check(), HasSubstr("blur_sigma_px"));
  o = {};
  o.max_rotation_deg = 0;
  EXPECT_THAT(o.Check(), HasSubstr("max_rotation_deg: must be in (0, 90] degrees, got 0"));
  o = {};
  o.min_correction_deg = 15;
  EXPECT_THAT(o.Check(), HasSubstr("min_correction_deg: must be in [0, max_rotation_deg) degrees, got 15"));
  o = {};
  o.huber = std::nan("");
  EXPECT_THAT(o.Check(), HasSubstr("huber"));
  o = {};
  o.min_pixels = 5;
  EXPECT_THAT(o.Check(), HasSubstr("min_pixels: must be >= 10, got 5"));
  o = {};
  o.scales = 0;
  EXPECT_THAT(o.Check(), HasSubstr("scales: must be in [1, 4], got 0"));
  for (double ratio : {0.5, -1.0, std::nan("")}) {
    o = {};
    o.max_depth_misfit_ratio = ratio;
    EXPECT_THAT(o.Check(), HasSubstr("max_depth_misfit_ratio")) << ratio;
  }
  o = {};
  o.max_depth_misfit_ratio = 0;  // off
  EXPECT_EQ(o.Check(), "");
  o = {};
  o.num_threads = -1;
  EXPECT_THAT(o.Check(), HasSubstr("num_threads: must be >= 0 (0: all cores), got -1"));
}

}  // namespace
}  // namespace hw::reconstruct
