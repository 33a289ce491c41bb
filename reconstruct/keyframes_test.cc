#include "reconstruct/keyframes.h"

#include <cmath>
#include <numbers>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace hw::reconstruct {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

// A 160×120 depth image: a plane at `depth_m` with a step of `step_m` on its right third (so
// that descriptors have structure), and a grey ramp.
cv::Mat Depth(float depth_m, float step_m = 0.3f) {
  cv::Mat d(120, 160, CV_32FC1, cv::Scalar(depth_m));
  d.colRange(107, 160) += step_m;
  return d;
}
cv::Mat Grey(float gain = 1, float offset = 0) {
  cv::Mat g(120, 160, CV_32FC1);
  for (int y = 0; y < g.rows; ++y) {
    for (int x = 0; x < g.cols; ++x) g.at<float>(y, x) = offset + gain * (0.2f + 0.5f * x / 160.0f + 0.1f * ((x / 20 + y / 20) % 2));
  }
  return g;
}

TEST(DescribeFrame, BlockMeansBlurredWithoutPullingDepthToZero) {
  const cv::Mat plane(120, 160, CV_32FC1, cv::Scalar(2.0f));
  const KeyframeDescriptor d = DescribeFrame(plane, cv::Mat(), 40);
  ASSERT_EQ(d.width, 40);
  ASSERT_EQ(d.height, 30);
  EXPECT_TRUE(d.grey.empty());
  // Normalised by the valid weight: the border keeps the plane's depth exactly.
  for (float v : d.depth_m) EXPECT_NEAR(v, 2.0f, 1e-5f);

  // The left half a hole: no depth there, the right half's exact, the rim kept.
  cv::Mat holed = plane.clone();
  holed.colRange(0, 80) = 0;
  const KeyframeDescriptor h = DescribeFrame(holed, cv::Mat(), 40);
  for (int y = 0; y < h.height; ++y) {
    EXPECT_EQ(h.depth_m[y * 40 + 0], 0.0f);
    EXPECT_EQ(h.depth_m[y * 40 + 17], 0.0f);  // beyond the kernel's reach of the valid half
    EXPECT_NEAR(h.depth_m[y * 40 + 20], 2.0f, 1e-5f);  // the rim: half its kernel valid
    EXPECT_NEAR(h.depth_m[y * 40 + 39], 2.0f, 1e-5f);
  }
  // A smaller image keeps its own width.
  EXPECT_EQ(DescribeFrame(cv::Mat(30, 40, CV_32FC1, cv::Scalar(1.0f)), cv::Mat(), 64).width, 40);
  // Non-finite depth is none.
  cv::Mat nan_image(120, 160, CV_32FC1, cv::Scalar(std::nanf("")));
  for (float v : DescribeFrame(nan_image, cv::Mat(), 40).depth_m) EXPECT_EQ(v, 0.0f);
}

TEST(DescribeFrame, GreyIsNormalisedAndAUniformImageHasNone) {
  const KeyframeDescriptor a = DescribeFrame(Depth(2), Grey(), 40);
  ASSERT_EQ(a.grey.size(), a.depth_m.size());
  double mean = 0, square = 0;
  for (float g : a.grey) {
    const double gd = g;
    mean += gd;
    square += gd * gd;
  }
  mean /= a.grey.size();
  EXPECT_NEAR(mean, 0, 1e-5);
  EXPECT_NEAR(square / a.grey.size() - mean * mean, 1, 1e-4);
  // Another exposure (gain and offset) is the same descriptor.
  const KeyframeDescriptor b = DescribeFrame(Depth(2), Grey(1.7f, 0.05f), 40);
  for (size_t i = 0; i < a.grey.size(); ++i) EXPECT_NEAR(a.grey[i], b.grey[i], 1e-4f);
  EXPECT_NEAR(KeyframeDistance(a, b), 0, 1e-8);
  const cv::Mat flat(120, 160, CV_32FC1, cv::Scalar(0.4f));
  EXPECT_TRUE(DescribeFrame(Depth(2), flat, 40).grey.empty());
}

TEST(KeyframeDistance, ClosedFormsOfTheTruncatedTerms) {
  const KeyframeDescriptor a = DescribeFrame(Depth(2.0f), cv::Mat(), 40);
  EXPECT_EQ(KeyframeDistance(a, a), 0);
  // 5 cm everywhere: (0.05 / 0.1)² = 0.25; 10 cm or more: truncated at 1.
  EXPECT_NEAR(KeyframeDistance(a, DescribeFrame(Depth(2.05f), cv::Mat(), 40)), 0.25, 1e-4);
  EXPECT_NEAR(KeyframeDistance(a, DescribeFrame(Depth(2.5f), cv::Mat(), 40)), 1.0, 1e-6);
  // With grey in both the two terms are averaged: depth equal, grey reversed → in (0, 1).
  const KeyframeDescriptor g = DescribeFrame(Depth(2.0f), Grey(), 40);
  const KeyframeDescriptor reversed = DescribeFrame(Depth(2.0f), Grey(-1, 1), 40);
  const double d = KeyframeDistance(g, reversed);
  EXPECT_GT(d, 0.2);
  EXPECT_LE(d, 0.5);  // the depth half is 0
  // Less than a quarter of the pixels with depth in both: unlike.
  cv::Mat sliver = Depth(2.0f);
  sliver.colRange(0, 130) = 0;
  EXPECT_EQ(KeyframeDistance(a, DescribeFrame(sliver, cv::Mat(), 40)), 1.0);
  // Depth in one only counts 0.5 at half weight: half the image missing in b, the rest equal
  // → (0.25 · n) / (n + 0.5 · n) = 1/6, give or take the blurred rim.
  cv::Mat half = Depth(2.0f);
  half.colRange(0, 80) = 0;
  EXPECT_NEAR(KeyframeDistance(a, DescribeFrame(half, cv::Mat(), 40)), 1.0 / 6, 0.03);
}

TEST(KeyframeDatabase, NewPlacesAndTheMostAlikeFirst) {
  KeyframeOptions options;  // 0.1 m, 10°, best within 0.5
  KeyframeDatabase db(options);
  const auto at = [](double x, double yaw_deg = 0) {
    core::Rigid3d p = core::Rigid3d::Identity();
    p.translation.x() = x;
    p.rotation = Eigen::AngleAxisd(yaw_deg * std::numbers::pi / 180, Eigen::Vector3d::UnitY());
    return p;
  };
  EXPECT_TRUE(db.IsNewPlace(at(0)));
  db.Add(at(0), DescribeFrame(Depth(2.00f), cv::Mat(), 40));
  EXPECT_FALSE(db.IsNewPlace(at(0.05)));
  EXPECT_FALSE(db.IsNewPlace(at(0.05, 8)));
  EXPECT_TRUE(db.IsNewPlace(at(0.15)));
  EXPECT_TRUE(db.IsNewPlace(at(0, 12)));
  EXPECT_TRUE(db.SamePlace(at(0.3), at(0.38, 9)));
  EXPECT_FALSE(db.SamePlace(at(0.3), at(0.3, 11)));
  db.Add(at(0.2), DescribeFrame(Depth(2.08f), cv::Mat(), 40));  // 0.64 from the query: too unlike
  db.Add(at(0.4), DescribeFrame(Depth(2.03f), cv::Mat(), 40));  // 0.09
  db.Add(at(0.6), DescribeFrame(Depth(2.01f), cv::Mat(), 40));  // 0.01
  ASSERT_EQ(db.size(), 4);
  const KeyframeDescriptor query = DescribeFrame(Depth(2.0f), cv::Mat(), 40);
  EXPECT_THAT(db.MostAlike(query, 10), ElementsAre(0, 3, 2));
  EXPECT_THAT(db.MostAlike(query, 2), ElementsAre(0, 3));
  EXPECT_THAT(db.MostAlike(query, 0), ElementsAre());
}

TEST(KeyframeOptions, CheckNamesTheField) {
  EXPECT_EQ(KeyframeOptions{}.Check(), "");
  const auto with = [](auto set) {
    KeyframeOptions o;
    set(o);
    return o.Check();
  };
  EXPECT_THAT(with([](auto& o) { o.candidates = 11; }), HasSubstr("candidates"));
  EXPECT_THAT(with([](auto& o) { o.candidates = -1; }), HasSubstr("candidates"));
  EXPECT_EQ(with([](auto& o) { o.candidates = 0; }), "");
  EXPECT_THAT(with([](auto& o) { o.min_distance_m = 0; }), HasSubstr("min_distance_m"));
  EXPECT_THAT(with([](auto& o) { o.min_angle_deg = NAN; }), HasSubstr("min_angle_deg"));
  EXPECT_THAT(with([](auto& o) { o.descriptor_width = 4; }), HasSubstr("descriptor_width"));
  EXPECT_THAT(with([](auto& o) { o.max_distance = 0; }), HasSubstr("max_distance"));
  EXPECT_THAT(with([](auto& o) { o.max_distance = 1.5; }), HasSubstr("max_distance"));
}

}  // namespace
}  // namespace hw::reconstruct
