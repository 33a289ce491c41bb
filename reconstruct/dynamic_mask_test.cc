#include "reconstruct/dynamic_mask.h"

#include <cmath>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace hw::reconstruct {
namespace {

// A wall at z = 2 m seen by a 64×48 pinhole at identity: the model view.
PointMap WallModel(const PinholeCamera& camera, float z_m) {
  PointMap map(camera.width, camera.height);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      map.points[map.Index(x, y)] = camera.Unproject(static_cast<float>(x), static_cast<float>(y), z_m);
      map.normals[map.Index(x, y)] = Eigen::Vector3f(0, 0, -1);
    }
  }
  return map;
}

TEST(DynamicMask, MasksExactlyWhatStandsInFrontOfTheModel) {
  const PinholeCamera camera{64, 48, 50, 50, 31.5f, 23.5f};
  PointMap model = WallModel(camera, 2.0f);
  // No model surface in the right quarter (never seen): anything there is new, not moved in.
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 48; x < camera.width; ++x) model.points[model.Index(x, y)] = InvalidPoint();
  }
  // A box 0.5 m in front of the wall, in the model at x 40–45, y 36–43.
  for (int y = 36; y < 44; ++y) {
    for (int x = 40; x < 46; ++x) model.points[model.Index(x, y)] = camera.Unproject(x, y, 1.5f);
  }
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(2.0f));
  // ... and live a pixel wider on each side (edge fattening, a model silhouette a voxel off):
  // its rim is the box's, not something that moved in.
  depth(cv::Rect(39, 35, 8, 10)).setTo(1.5f);
  depth(cv::Rect(10, 10, 8, 8)).setTo(1.0f);     // a person 1 m in front: masked
  depth(cv::Rect(30, 10, 8, 8)).setTo(1.92f);    // 8 cm in front, margin max(0.1, 0.05·1.92): kept
  depth(cv::Rect(30, 30, 8, 8)).setTo(1.85f);    // 15 cm in front: masked
  depth(cv::Rect(10, 30, 8, 8)).setTo(2.6f);     // behind the wall (it moved away): kept
  depth(cv::Rect(50, 10, 8, 8)).setTo(1.0f);     // in front of unseen space: kept
  depth(cv::Rect(20, 40, 4, 4)).setTo(0.0f);     // no measurement: stays none
  cv::Mat masked = depth.clone();
  DynamicMaskOptions options;
  const int n = MaskInFrontOfModel(masked, camera, core::Rigid3d(), model, camera, core::Rigid3d(), options, 2);
  EXPECT_EQ(n, 2 * 64);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const bool person = (x >= 10 && x < 18 && y >= 10 && y < 18) || (x >= 30 && x < 38 && y >= 30 && y < 38);
      EXPECT_EQ(masked.at<float>(y, x), person ? 0.0f : depth.at<float>(y, x)) << x << ", " << y;
    }
  }
  // Off: nothing changes.
  cv::Mat untouched = depth.clone();
  options.margin_m = options.margin_fraction = 0;
  EXPECT_EQ(MaskInFrontOfModel(untouched, camera, core::Rigid3d(), model, camera, core::Rigid3d(), options), 0);
  EXPECT_EQ(cv::norm(untouched, depth, cv::NORM_INF), 0);
}

// The depth camera moved since the model view was cast (the model view is up to
// raycast_interval frames old): the comparison happens along the model view's rays, so the
// wall stays the wall and the person stays masked, at any pose.
TEST(DynamicMask, ComparesAlongTheModelViewWhenTheCameraMoved) {
  const PinholeCamera camera{64, 48, 50, 50, 31.5f, 23.5f};
  const PointMap model = WallModel(camera, 2.0f);
  core::Rigid3d world_from_depth;
  world_from_depth.translation = Eigen::Vector3d(0.05, -0.03, 0.1);  // 10 cm nearer the wall
  world_from_depth.rotation = Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitY());
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      // Exact range to the wall z = 2 (world) along this pixel's ray from the moved camera.
      const Eigen::Vector3d ray = world_from_depth.rotation * Eigen::Vector3d((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1);
      const double t = (2.0 - world_from_depth.translation.z()) / ray.z();
      depth.at<float>(y, x) = static_cast<float>(t);  // z in the depth camera = t (ray has z 1)
      const bool person = x >= 20 && x < 28 && y >= 20 && y < 28;
      if (person) depth.at<float>(y, x) = 0.8f;
    }
  }
  cv::Mat masked = depth.clone();
  const int n = MaskInFrontOfModel(masked, camera, world_from_depth, model, camera, core::Rigid3d(), DynamicMaskOptions{});
  EXPECT_EQ(n, 64);
  for (int y = 20; y < 28; ++y) {
    for (int x = 20; x < 28; ++x) EXPECT_EQ(masked.at<float>(y, x), 0.0f);
  }
}

// A wall 2 m away with a pillar 0.5 m in front of it (model and live alike): at the pose
// the frame was taken from nothing conflicts; placed 0.2 m to the side (a relocalisation one
// pillar over), the live pillar stands in front of the model's wall and the live wall behind
// the model's pillar.
TEST(DynamicMask, ModelConflictIsZeroAtTheTruePoseAndLargeAtAWrongOne) {
  const PinholeCamera camera{64, 48, 50, 50, 31.5f, 23.5f};
  PointMap model = WallModel(camera, 2.0f);
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(2.0f));
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 24; x < 36; ++x) {
      model.points[model.Index(x, y)] = camera.Unproject(static_cast<float>(x), static_cast<float>(y), 1.5f);
      depth.at<float>(y, x) = 1.5f;
    }
  }
  const DynamicMaskOptions options;
  const ModelConflict at_truth =
      MeasureModelConflict(depth, camera, core::Rigid3d(), model, camera, core::Rigid3d(), options, 2);
  EXPECT_EQ(at_truth.in_front, 0);
  EXPECT_EQ(at_truth.seen_through, 0);
  EXPECT_EQ(at_truth.depth_pixels, 64 * 48);
  EXPECT_EQ(at_truth.model_points, 64 * 48);
  EXPECT_EQ(at_truth.Fraction(), 0.0);

  core::Rigid3d wrong;
  wrong.translation = Eigen::Vector3d(0.2, 0, 0);  // 6.7 px at the pillar, 5 px at the wall
  const cv::Mat before = depth.clone();
  const ModelConflict off = MeasureModelConflict(depth, camera, wrong, model, camera, core::Rigid3d(), options, 2);
  EXPECT_EQ(cv::norm(depth, before, cv::NORM_INF), 0);  // the frame is left as it was
  // The two measures it combines, on the same inputs.
  cv::Mat masked = depth.clone();
  EXPECT_EQ(off.in_front, MaskInFrontOfModel(masked, camera, wrong, model, camera, core::Rigid3d(), options, 1));
  EXPECT_EQ(off.seen_through, static_cast<int>(ModelSeenThrough(depth, camera, wrong, model, options, 1).size()));
  // Analytic: the live pillar (columns 24–35) lands 6.67 px right in the model view, columns
  // 31–42; those whose 3×3 neighbourhood misses the model's pillar (37–42: 6 columns) stand
  // 0.5 m in front of its wall, on 46 rows (the border rows lack a neighbour). The model's
  // pillar lands 6.67 px left in the frame, columns 17–28; those whose 3×3 neighbourhood is
  // all live wall (17–22: 6 columns) are seen through, on 46 rows (the border excluded).
  EXPECT_EQ(off.in_front, 6 * 46);
  EXPECT_EQ(off.seen_through, 6 * 46);
  EXPECT_DOUBLE_EQ(off.Fraction(), static_cast<double>(off.in_front) / (64 * 48) +
                                       static_cast<double>(off.seen_through) / (64 * 48));
  EXPECT_GT(off.Fraction(), 0.1);

  // Off: nothing is compared, the totals are still counted.
  DynamicMaskOptions none;
  none.margin_m = none.margin_fraction = 0;
  const ModelConflict unchecked = MeasureModelConflict(depth, camera, wrong, model, camera, core::Rigid3d(), none);
  EXPECT_EQ(unchecked.in_front + unchecked.seen_through, 0);
  EXPECT_EQ(unchecked.depth_pixels, 64 * 48);
  EXPECT_EQ(unchecked.Fraction(), 0.0);
}

// The mask's rounding to a pixel index against std::lround, at the halves, just either side
// of them (one float step), across both ends of the range, and on non-finite values.
TEST(DynamicMask, RoundedIndexIsLroundInRange) {
  std::vector<float> xs = {NAN, INFINITY, -INFINITY, 1e30f, -1e30f};
  for (int k = -3; k <= 643; ++k) {
    for (const float half : {-0.5f, 0.0f, 0.5f}) {
      const float x = static_cast<float>(k) + half;
      xs.insert(xs.end(), {x, std::nextafter(x, -INFINITY), std::nextafter(x, INFINITY)});
    }
  }
  int inside = 0;
  for (const auto& [lo, hi] : {std::pair{0, 640}, {1, 639}, {0, 1}}) {
    for (const float x : xs) {
      int index = -7;
      const bool in = internal::RoundedIndex(x, lo, hi, index);
      const bool expected = std::isfinite(x) && std::abs(x) < 1e9f && std::lround(x) >= lo && std::lround(x) < hi;
      ASSERT_EQ(in, expected) << x << " in [" << lo << ", " << hi << ")";
      if (in) {
        ASSERT_EQ(index, std::lround(x)) << x;
        ++inside;
      }
    }
  }
  EXPECT_GT(inside, 5000);
}

TEST(DynamicMask, OptionsCheckNamesTheField) {
  DynamicMaskOptions o;
  o.margin_m = -1;
  EXPECT_NE(o.Check().find("margin_m"), std::string::npos);
  o = DynamicMaskOptions{};
  o.margin_fraction = 1;
  EXPECT_NE(o.Check().find("margin_fraction"), std::string::npos);
}

}  // namespace
}  // namespace hw::reconstruct
