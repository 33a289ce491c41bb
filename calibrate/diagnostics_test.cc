#include "calibrate/diagnostics.h"

#include <opencv2/imgproc.hpp>

#include <gtest/gtest.h>

namespace hw::calibrate {
namespace {

bool IsBackground(const cv::Vec3b& p) { return p == cv::Vec3b(30, 30, 30); }

TEST(DiagnosticsTest, DetectionIsDrawnAtItsCornersOnAnUpscaledThermalImage) {
  cv::Mat image(240, 320, CV_16UC1, cv::Scalar(30000));
  Detection d;
  d.view = "thermal/0";
  d.accepted = true;
  d.homography_rms_px = 0.3;
  d.corner_ids = {0, 1};
  d.pixels = {{100, 100}, {200, 150}};
  const cv::Mat out = DrawDetection(image, d);
  ASSERT_EQ(out.cols, 640);  // × 2 below 640 px
  ASSERT_EQ(out.rows, 480);
  // The cross of corner 1 at ((200 + 0.5)·2 − 0.5, (150 + 0.5)·2 − 0.5) = (400.5, 300.5) is green.
  const cv::Vec3b p = out.at<cv::Vec3b>(300, 400);
  EXPECT_GT(p[1], 150);
  EXPECT_LT(p[2], 120);
}

TEST(DiagnosticsTest, ResidualArrowReachesScaledLength) {
  const std::vector<std::vector<Eigen::Vector2d>> corners = {{{100, 100}}}, residuals = {{{2, 0}}};
  const cv::Mat out = DrawResidualField(640, 480, corners, residuals, {{false}}, 10);
  // From (100, 100) to (120, 100): drawn along the way, nothing beyond the tip.
  EXPECT_FALSE(IsBackground(out.at<cv::Vec3b>(100, 110)));
  EXPECT_FALSE(IsBackground(out.at<cv::Vec3b>(100, 119)));
  EXPECT_TRUE(IsBackground(out.at<cv::Vec3b>(100, 124)));
  // An outlier is red.
  const cv::Mat bad = DrawResidualField(640, 480, corners, residuals, {{true}}, 10);
  const cv::Vec3b p = bad.at<cv::Vec3b>(100, 110);
  EXPECT_GT(p[2], 200);
  EXPECT_LT(p[0], 80);
}

TEST(DiagnosticsTest, UncertaintyMapColoursByValue) {
  // 2 × 1 cells: 0 px (turbo's dark blue end) and max (its dark red end).
  const cv::Mat out = DrawUncertaintyMap(640, 480, {0.0, 1.0}, 2, 1, 1.0, "t");
  const cv::Vec3b low = out.at<cv::Vec3b>(400, 100), high = out.at<cv::Vec3b>(400, 500);
  EXPECT_GT(low[0], low[2]);    // blue dominates
  EXPECT_GT(high[2], high[0]);  // red dominates
}

TEST(DiagnosticsTest, HistogramPeaksAtZeroForSmallResiduals) {
  std::vector<std::vector<Eigen::Vector2d>> residuals(1);
  for (int i = 0; i < 200; ++i) residuals[0].emplace_back(0.001 * (i % 3 - 1), 0.0);
  const std::vector<std::vector<bool>> outlier(1, std::vector<bool>(200, false));
  const cv::Mat out = DrawResidualHistogram(residuals, outlier, 0.3);
  ASSERT_EQ(out.size(), cv::Size(640, 400));
  // The central bin (x ≈ 320) is filled well above the axis; a bin at +3σ is empty.
  EXPECT_NE(out.at<cv::Vec3b>(200, 320), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(out.at<cv::Vec3b>(355, 320 + static_cast<int>(0.375 * 560)), cv::Vec3b(255, 255, 255));
}

}  // namespace
}  // namespace hw::calibrate
