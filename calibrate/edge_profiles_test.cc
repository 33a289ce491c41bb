#include "calibrate/edge_profiles.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace hw::calibrate {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A dark square of side 20 px turned 10° about (40.3, 39.6) on a bright background (1),
// integrated over each pixel (8 × 8 samples) and blurred by 0.8 px. Inside, 0 plus
// `pedestal`·exp(−d / 2 px), d the distance to the nearest side: what a heated mask's hole
// shows near its edges (background warmed by the plate). Returns the image and the true
// corners (pixels, centre of the top-left pixel at 0, 0).
struct Drawn {
  cv::Mat image;
  std::array<cv::Point2d, 4> corners;
  cv::Point2d centre;
};
Drawn DrawSquare(double pedestal) {
  constexpr int kSub = 8, kSize = 80;
  constexpr double kHalf = 10, kAngle = 10 * kPi / 180;
  const cv::Point2d centre(40.3, 39.6);
  const double c = std::cos(kAngle), s = std::sin(kAngle);
  cv::Mat fine(kSize * kSub, kSize * kSub, CV_32F);
  for (int b = 0; b < fine.rows; ++b) {
    for (int a = 0; a < fine.cols; ++a) {
      const double x = (a + 0.5) / kSub - 0.5 - centre.x, y = (b + 0.5) / kSub - 0.5 - centre.y;
      const double u = c * x + s * y, v = -s * x + c * y;  // in the square's frame
      const double inside = kHalf - std::max(std::abs(u), std::abs(v));
      fine.at<float>(b, a) = inside > 0 ? static_cast<float>(pedestal * std::exp(-inside / 2.0)) : 1.0f;
    }
  }
  cv::GaussianBlur(fine, fine, cv::Size(0, 0), 0.8 * kSub);
  Drawn d;
  cv::resize(fine, d.image, cv::Size(kSize, kSize), 0, 0, cv::INTER_AREA);
  d.centre = centre;
  const double su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
  for (int k = 0; k < 4; ++k) {
    const double u = su[k] * kHalf, v = sv[k] * kHalf;
    d.corners[k] = centre + cv::Point2d(c * u - s * v, s * u + c * v);
  }
  return d;
}

// Refines from corners 0.7 px off; returns the mean outward shift of the sides (px) and
// the corners' RMS error.
std::pair<double, double> Refine(const Drawn& d, EdgeLocator locator) {
  std::array<cv::Point2d, 4> corners = d.corners;
  for (int k = 0; k < 4; ++k) corners[k] += cv::Point2d(0.5 * (k % 2 ? 1 : -1), 0.5);
  EdgeProfileOptions options;
  options.edge = locator;
  EXPECT_TRUE(RefineSquareCorners(d.image, options, d.centre, corners));
  double outward = 0, sum2 = 0;
  for (int k = 0; k < 4; ++k) {
    const cv::Point2d error = corners[k] - d.corners[k];
    const cv::Point2d diagonal = (d.corners[k] - d.centre) / cv::norm(d.corners[k] - d.centre);
    outward += error.dot(diagonal) / std::sqrt(2.0) / 4;
    sum2 += error.dot(error);
  }
  return {outward, std::sqrt(sum2 / 4)};
}

// A clean blurred step: both locators put the sides on it. Measured: steepest
// −0.0003 px outwards / RMS 0.008 px, mid-level −0.0003 / 0.026 px; bound: a fifth of the
// 0.2 px the square_grid sessions' corners scatter by.
TEST(RefineSquareCorners, BothLocatorsFindACleanBlurredSquare) {
  const Drawn d = DrawSquare(0.0);
  for (const EdgeLocator locator : {EdgeLocator::kSteepest, EdgeLocator::kMidLevel}) {
    const auto [outward, rms] = Refine(d, locator);
    std::printf("clean, %s: outward %+.4f px, RMS %.4f px\n",
                locator == EdgeLocator::kSteepest ? "steepest" : "mid-level", outward, rms);
    EXPECT_LT(std::abs(outward), 0.01);
    EXPECT_LT(rms, 0.04);
  }
}

// A 30 % pedestal inside the edge, falling off over 2 px: it moves both locators into the
// square (its own slope adds to the step's), the mid-level most. Measured: steepest
// −0.150 px, mid-level −0.259 px. Bound: the steepest point moves under 70 % of the
// mid-level's shift.
TEST(RefineSquareCorners, APedestalBesideTheEdgeMovesTheSteepestPointLessThanTheMidLevel) {
  const Drawn d = DrawSquare(0.3);
  const auto [steep_outward, steep_rms] = Refine(d, EdgeLocator::kSteepest);
  const auto [mid_outward, mid_rms] = Refine(d, EdgeLocator::kMidLevel);
  std::printf("pedestal 0.3: steepest outward %+.4f px (RMS %.4f), mid-level %+.4f px (RMS %.4f)\n",
              steep_outward, steep_rms, mid_outward, mid_rms);
  EXPECT_LT(mid_outward, -0.1);
  EXPECT_LT(std::abs(steep_outward), 0.7 * std::abs(mid_outward));
}

// Too small a square (a side under 3 px) or no contrast: false, the corners untouched.
TEST(RefineSquareCorners, FailsWithoutChangingTheCorners) {
  const Drawn d = DrawSquare(0.0);
  std::array<cv::Point2d, 4> tiny = {cv::Point2d(40, 40), {41, 40}, {41, 41}, {40, 41}};
  const auto before = tiny;
  EXPECT_FALSE(RefineSquareCorners(d.image, {}, {40.5, 40.5}, tiny));
  EXPECT_EQ(tiny, before);
  std::array<cv::Point2d, 4> corners = d.corners;
  EXPECT_FALSE(RefineSquareCorners(cv::Mat(80, 80, CV_32F, cv::Scalar(0.5)), {}, d.centre, corners));
  EXPECT_EQ(corners, d.corners);
}

TEST(IntersectLines, CrossingAndParallel) {
  cv::Point2d p;
  ASSERT_TRUE(IntersectLines({0, 1}, {1, 0}, {2, 0}, {0, 1}, &p));
  EXPECT_NEAR(p.x, 2, 1e-12);
  EXPECT_NEAR(p.y, 1, 1e-12);
  EXPECT_FALSE(IntersectLines({0, 0}, {1, 1}, {0, 1}, {2, 2}, &p));
}

}  // namespace
}  // namespace hw::calibrate
