// Raycast with hints (RayHints): where a hint is right the hits are the plain raycast's, where
// it holds no surface the pixel is cast as without it, and a hint past a surface the model
// still holds in front finds the one behind.

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "reconstruct/raycast.h"
#include "reconstruct/tsdf_test_support.h"

namespace hw::reconstruct {
namespace {

using test::LookAt;
using test::SmallOptions;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// The covering pinhole of `rays` grown by 24 px on every side (raycast_test's Widened):
// fusing through it observes every cell the lens's rays cross near its pose.
PinholeCamera FuseCamera(const CameraRays& rays) {
  PinholeCamera camera = rays.covering_pinhole();
  camera.width += 48;
  camera.height += 48;
  camera.cx += 24;
  camera.cy += 24;
  return camera;
}

// A sphere 0.25 m in radius 1 m ahead before a wall at z = 1.5 m, seen from fuse_pose; with
// `wall_first`, the bare wall is fused first, so that the model also holds the wall behind
// the sphere (as after the sphere — a person — stepped in front of a wall already mapped).
void FuseSphereBeforeWall(TsdfVolume& volume, const PinholeCamera& camera, const core::Rigid3d& fuse_pose,
                          bool wall_first) {
  const cv::Mat wall = test::RenderPlane(camera, fuse_pose, Eigen::Vector3d::UnitZ(), 1.5);
  if (wall_first) volume.Integrate(wall, camera, fuse_pose);
  cv::Mat depth = test::RenderSphere(camera, fuse_pose, {0, 0, 1.0}, 0.25);
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) {
      if (depth.at<float>(y, x) == 0) depth.at<float>(y, x) = wall.at<float>(y, x);
    }
  }
  volume.Integrate(depth, camera, fuse_pose);
}

bool SameBytes(const PointMap& a, const PointMap& b) {
  return a.points.size() == b.points.size() &&
         std::memcmp(a.points.data(), b.points.data(), a.points.size() * sizeof(Eigen::Vector3f)) == 0 &&
         std::memcmp(a.normals.data(), b.normals.data(), a.normals.size() * sizeof(Eigen::Vector3f)) == 0;
}

// Hints at each plain hit's range, off by up to ±1.5 cm (half the 3 cm band: a depth
// reading's noise), give the plain hits: the same pixels hit, and those seen within 60° of
// their normal within 1 mm (a tenth of a voxel: the two marches bracket the crossing with
// different samples, and regula falsi stops within 0.005 of the band, 0.15 mm, of the zero,
// which along a ray at 60° is 0.3 mm each) with the normal within 1°; pixels without a hint
// (NaN) are the plain raycast's, bit for bit.
TEST(RaycastHints, HintsNearTheSurfaceGiveThePlainHits) {
  const CameraRays rays(test::ThermalCamera());
  TsdfVolume volume(SmallOptions());
  FuseSphereBeforeWall(volume, FuseCamera(rays), LookAt({0.03, 0.02, 0}, {0.2, 0.1, 1.0}), false);
  const core::Rigid3d pose = LookAt({0.05, 0.03, 0.02}, {0.2, 0.1, 1.0});
  RaycastOptions options;
  options.max_depth_m = 2.0;
  options.num_threads = 2;
  const PointMap plain = Raycast(volume, rays, pose, options);
  std::mt19937 random(3);
  std::uniform_real_distribution<float> noise_m(-0.015f, 0.015f);
  std::vector<float> range_m(plain.points.size(), kNaN);
  int hinted = 0;
  for (size_t i = 0; i < range_m.size(); ++i) {
    if (!IsValid(plain.points[i]) || i % 5 == 0) continue;  // every fifth pixel: no hint
    range_m[i] = (plain.points[i] - pose.translation.cast<float>()).norm() + noise_m(random);
    ++hinted;
  }
  ASSERT_GT(hinted, 40000);
  RayHints hints;
  hints.range_m = range_m;
  const PointMap map = Raycast(volume, rays, pose, options, hints);
  double worst_m = 0, worst_deg = 0;
  int compared = 0;
  for (size_t i = 0; i < map.points.size(); ++i) {
    ASSERT_EQ(IsValid(map.points[i]), IsValid(plain.points[i])) << i;
    if (!std::isfinite(range_m[i])) {
      EXPECT_EQ(std::memcmp(&map.points[i], &plain.points[i], sizeof(Eigen::Vector3f)), 0) << i;
      EXPECT_EQ(std::memcmp(&map.normals[i], &plain.normals[i], sizeof(Eigen::Vector3f)), 0) << i;
      continue;
    }
    if (!IsValid(map.normals[i]) || !IsValid(plain.normals[i])) continue;
    // Within 60° of the normal (the tolerance holds along the normal: a ray at θ to it moves
    // the hit by that over cos θ, up to 1.4 mm at the sphere's grazing rim).
    const Eigen::Vector3f to_camera = (pose.translation.cast<float>() - plain.points[i]).normalized();
    if (plain.normals[i].dot(to_camera) < 0.5f) continue;
    worst_m = std::max(worst_m, double((map.points[i] - plain.points[i]).norm()));
    {
      const double cos_angle = std::clamp(double(map.normals[i].dot(plain.normals[i])), -1.0, 1.0);
      worst_deg = std::max(worst_deg, std::acos(cos_angle) * 180 / M_PI);
      ++compared;
    }
  }
  RecordProperty("worst_m", std::to_string(worst_m));
  RecordProperty("worst_normal_deg", std::to_string(worst_deg));
  EXPECT_GT(compared, 0.8 * hinted);
  EXPECT_LT(worst_m, 1e-3);
  EXPECT_LT(worst_deg, 1.0);
}

// Hints with no surface in their window — in the empty space in front of the sphere, beyond
// the wall, or invalid (0, negative, infinite, NaN) — leave the plain raycast, bit for bit.
TEST(RaycastHints, HintsWithoutASurfaceFallBack) {
  const CameraRays rays(test::ThermalCamera());
  TsdfVolume volume(SmallOptions());
  FuseSphereBeforeWall(volume, FuseCamera(rays), core::Rigid3d::Identity(), false);
  RaycastOptions options;
  options.max_depth_m = 2.5;
  options.num_threads = 2;
  const PointMap plain = Raycast(volume, rays, core::Rigid3d::Identity(), options);
  ASSERT_GT(plain.NumValid(), 70000);
  for (float hint : {0.45f, 2.2f, 0.0f, -1.0f, std::numeric_limits<float>::infinity(), kNaN}) {
    const std::vector<float> range_m(plain.points.size(), hint);
    RayHints hints;
    hints.range_m = range_m;
    EXPECT_TRUE(SameBytes(Raycast(volume, rays, core::Rigid3d::Identity(), options, hints), plain)) << hint;
  }
}

// The model holds the wall behind the sphere (fused before the sphere came): hints at the
// wall's range on the sphere's pixels find the wall (within a tenth of a voxel of z = 1.5),
// where the plain raycast stops at the sphere; with hints on the sphere they find the sphere.
TEST(RaycastHints, HintPastASurfaceInFrontFindsTheOneBehind) {
  const CameraRays rays(test::ThermalCamera());
  TsdfVolume volume(SmallOptions());
  const core::Rigid3d pose = core::Rigid3d::Identity();
  FuseSphereBeforeWall(volume, FuseCamera(rays), pose, true);
  RaycastOptions options;
  options.max_depth_m = 2.0;
  options.num_threads = 2;
  const PointMap plain = Raycast(volume, rays, pose, options);
  std::vector<float> wall_range_m(plain.points.size(), kNaN), sphere_range_m(plain.points.size(), kNaN);
  int on_sphere = 0;
  for (int y = 0; y < plain.height; ++y) {
    for (int x = 0; x < plain.width; ++x) {
      const size_t i = plain.Index(x, y);
      const Eigen::Vector3f& p = plain.points[i];
      // Sphere pixels well inside its silhouette (the band around it mixes both surfaces).
      if (!IsValid(p) || p.z() > 0.9f) continue;
      const Eigen::Vector2f xy = rays.xy(x, y);
      wall_range_m[i] = 1.5f * Eigen::Vector3f(xy.x(), xy.y(), 1).norm();
      sphere_range_m[i] = p.norm();
      ++on_sphere;
    }
  }
  ASSERT_GT(on_sphere, 5000);
  RayHints hints;
  hints.range_m = wall_range_m;
  const PointMap to_wall = Raycast(volume, rays, pose, options, hints);
  hints.range_m = sphere_range_m;
  const PointMap to_sphere = Raycast(volume, rays, pose, options, hints);
  double worst_wall_m = 0, worst_sphere_m = 0;
  for (size_t i = 0; i < plain.points.size(); ++i) {
    if (!std::isfinite(wall_range_m[i])) continue;
    ASSERT_TRUE(IsValid(to_wall.points[i])) << i;
    ASSERT_TRUE(IsValid(to_sphere.points[i])) << i;
    worst_wall_m = std::max(worst_wall_m, std::abs(double(to_wall.points[i].z()) - 1.5));
    worst_sphere_m = std::max(worst_sphere_m, double((to_sphere.points[i] - plain.points[i]).norm()));
  }
  RecordProperty("worst_wall_m", std::to_string(worst_wall_m));
  EXPECT_LT(worst_wall_m, 0.1 * volume.options().voxel_size_m);
  EXPECT_LT(worst_sphere_m, 1e-3);
}

}  // namespace
}  // namespace hw::reconstruct
