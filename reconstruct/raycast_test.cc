#include "reconstruct/raycast.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "reconstruct/tsdf_test_support.h"

namespace hw::reconstruct {
namespace {

using test::LookAt;
using test::SmallCamera;
using test::SmallOptions;

constexpr double kDegree = M_PI / 180;

RaycastOptions Options(int num_threads = 2) {
  RaycastOptions o;
  o.num_threads = num_threads;
  return o;
}

double AngleRad(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::acos(std::clamp(static_cast<double>(a.normalized().dot(b.normalized())), -1.0, 1.0));
}

// A frontal plane fuses into a field linear in z within the band (exact, see
// tsdf_volume_test), and trilinear interpolation of a linear field is exact, so the zero
// found by regula falsi is exact up to float rounding (1e-7 relative at 1 m): 1e-4 m = 0.01
// voxel leaves room for that and nothing else. Normals: the exact gradient, 0.01°.
TEST(Raycast, FrontalPlaneIsExact) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  TsdfVolume volume(SmallOptions());
  volume.Integrate(test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0), camera, pose);
  const PointMap map = Raycast(volume, camera, pose, Options());
  ASSERT_EQ(map.width, camera.width);
  ASSERT_EQ(map.height, camera.height);
  EXPECT_TRUE(map.colours.empty());
  // Rays near the image border meet cells with a corner outside every view (unobserved).
  EXPECT_GT(map.NumValid(), 0.9 * camera.width * camera.height);
  int normals = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const size_t i = map.Index(x, y);
      if (!IsValid(map.points[i])) continue;
      EXPECT_NEAR(map.points[i].z(), 1.0f, 1e-4f) << x << " " << y;
      // On the ray of its pixel.
      const Eigen::Vector2f uv = camera.Project(map.points[i]);
      EXPECT_NEAR(uv.x(), x, 1e-3f);
      EXPECT_NEAR(uv.y(), y, 1e-3f);
      // Near the rim a normal's 32 voxels reach outside the view: the point stays valid.
      if (!IsValid(map.normals[i])) continue;
      ++normals;
      EXPECT_LT(AngleRad(map.normals[i], -Eigen::Vector3f::UnitZ()), 0.01 * kDegree);
    }
  }
  EXPECT_GT(normals, 0.95 * map.NumValid());
}

// A tilted plane (35° to the view axis), fused from one pose and cast from another. Its
// projective field p_z (c − n·p) / (n·p) is not linear, but it vanishes on the plane and its
// gradient there is along −n; the curvature over a voxel gives trilinear errors of order
// h² · |∇²f| ≈ 1e-5 m. Bilinear depth between pixels adds the second-order error of
// interpolating 1/(n·ray) over a pixel (< 1e-5 m at 1 m). So 0.1 voxel (1 mm) is a loose
// bound; normals within 1°.
TEST(Raycast, TiltedPlaneFromAnotherPose) {
  const PinholeCamera camera = SmallCamera();
  // Facing the fusing camera: the sdf gradient points towards it.
  const Eigen::Vector3d normal = Eigen::Vector3d(std::sin(35 * kDegree), 0, -std::cos(35 * kDegree));
  const double offset = normal.dot(Eigen::Vector3d(0, 0, 1.2));
  TsdfVolume volume(SmallOptions());
  const core::Rigid3d fuse_pose = LookAt({0, 0, 0}, {0, 0, 1.2});
  volume.Integrate(test::RenderPlane(camera, fuse_pose, normal, offset), camera, fuse_pose);
  const core::Rigid3d cast_pose = LookAt({0.1, -0.05, 0.1}, {0.05, 0.05, 1.2});
  const PointMap map = Raycast(volume, camera, cast_pose, Options());
  EXPECT_GT(map.NumValid(), camera.width * camera.height / 2);
  double worst = 0, worst_angle = 0;
  const core::Rigid3d camera_from_world = fuse_pose.Inverse();
  for (size_t i = 0; i < map.points.size(); ++i) {
    if (!IsValid(map.points[i])) continue;
    // Voxels seen within a pixel of the fusing image's border had no bilinear depth (the
    // nearest pixel's is off by up to half a pixel times the slope): not held to the bound.
    const Eigen::Vector2f uv = camera.Project((camera_from_world * map.points[i].cast<double>()).cast<float>());
    if (uv.x() < 1.5f || uv.y() < 1.5f || uv.x() > camera.width - 2.5f || uv.y() > camera.height - 2.5f) continue;
    const double error = std::abs(normal.dot(map.points[i].cast<double>()) - offset);
    worst = std::max(worst, error);
    // A normal reads voxels up to 2 voxels (< 2 pixels here) farther: 2 more pixels of border.
    const bool inner = uv.x() > 3.5f && uv.y() > 3.5f && uv.x() < camera.width - 4.5f && uv.y() < camera.height - 4.5f;
    if (inner && IsValid(map.normals[i])) {
      worst_angle = std::max(worst_angle, AngleRad(map.normals[i], normal.cast<float>()));
    }
  }
  EXPECT_LT(worst, 0.1 * volume.options().voxel_size_m);
  EXPECT_LT(worst_angle, 1 * kDegree);
  RecordProperty("worst_error_m", std::to_string(worst));
}

// A sphere fused from five views: every view's projective field vanishes on the sphere, so
// their weighted mean does too; what remains is trilinear interpolation of a field curved
// on the scale of the radius (error ≈ h² / (8 R) = 0.04 mm for R = 0.25 m) and bilinear
// depth near the rim, where the depth slope is steep: rays meeting the surface at less than
// 60° from its normal are held to 0.1 voxel.
TEST(Raycast, SphereWithinATenthOfAVoxel) {
  const PinholeCamera camera = SmallCamera();
  const Eigen::Vector3d centre(0, 0, 1.0);
  const double radius = 0.25;
  TsdfVolume volume(SmallOptions());
  for (const Eigen::Vector3d& eye : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.2, 0, 0.05),
                                    Eigen::Vector3d(-0.2, 0, 0.05), Eigen::Vector3d(0, 0.2, 0.05),
                                    Eigen::Vector3d(0, -0.2, 0.05)}) {
    const core::Rigid3d pose = LookAt(eye, centre);
    volume.Integrate(test::RenderSphere(camera, pose, centre, radius), camera, pose);
  }
  const core::Rigid3d pose = LookAt({0.05, 0.03, 0.02}, centre);
  const PointMap map = Raycast(volume, camera, pose, Options());
  int checked = 0;
  std::vector<double> angles;
  double worst = 0, worst_angle = 0;
  for (size_t i = 0; i < map.points.size(); ++i) {
    if (!IsValid(map.points[i])) continue;
    const Eigen::Vector3d p = map.points[i].cast<double>();
    const Eigen::Vector3d n = (p - centre).normalized();
    const Eigen::Vector3d view = (pose.translation - p).normalized();
    if (n.dot(view) < std::cos(60 * kDegree)) continue;
    ++checked;
    worst = std::max(worst, std::abs((p - centre).norm() - radius));
    if (!IsValid(map.normals[i])) continue;
    angles.push_back(AngleRad(map.normals[i], n.cast<float>()));
  }
  // The sphere covers a disc of ~30 pixels radius; 3/4 of it within 60°.
  EXPECT_GT(checked, 1500);
  EXPECT_GT(angles.size(), 0.95 * checked);
  EXPECT_LT(worst, 0.1 * volume.options().voxel_size_m);
  std::sort(angles.begin(), angles.end());
  const double median_angle = angles[angles.size() / 2], p95_angle = angles[angles.size() * 95 / 100];
  worst_angle = angles.back();
  // Normals: each view's field has its gradient along the sphere normal on the surface,
  // but with its own slope (1 / cos of its viewing angle), and neighbouring voxels average
  // different subsets of views (one saw a voxel, not the next; or its value hit the +1
  // clamp): the mixture's slope varies from voxel to voxel and tilts the central difference
  // where the subsets change. Measured: median 0.17°, 95 % 0.99°, max 4.5°.
  EXPECT_LT(median_angle, 0.5 * kDegree);
  EXPECT_LT(p95_angle, 1.5 * kDegree);
  EXPECT_LT(worst_angle, 6 * kDegree);
  RecordProperty("median_angle_deg", std::to_string(median_angle / kDegree));
  RecordProperty("p95_angle_deg", std::to_string(p95_angle / kDegree));
  RecordProperty("worst_error_m", std::to_string(worst));
}

TEST(Raycast, InvalidWhereNothingIsThere) {
  const PinholeCamera camera = SmallCamera();
  TsdfVolume volume(SmallOptions());
  const PointMap empty = Raycast(volume, camera, core::Rigid3d::Identity(), Options());
  EXPECT_EQ(empty.NumValid(), 0);
  const core::Rigid3d pose = core::Rigid3d::Identity();
  volume.Integrate(test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0), camera, pose);
  // Looking away from it.
  EXPECT_EQ(Raycast(volume, camera, LookAt({0, 0, 0}, {0, 0, -1}), Options()).NumValid(), 0);
  // From 1 m farther back, the fused patch covers the middle half of the image: the rays
  // through the outer pixels miss it.
  const core::Rigid3d back(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -1));
  const PointMap map = Raycast(volume, camera, back, Options());
  int inside = 0, outside = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const bool valid = IsValid(map.points[map.Index(x, y)]);
      const bool in_patch = std::abs(x - camera.cx) < 0.45f * camera.width / 2 &&
                            std::abs(y - camera.cy) < 0.45f * camera.height / 2;
      const bool off_patch = std::abs(x - camera.cx) > 0.55f * camera.width / 2 ||
                             std::abs(y - camera.cy) > 0.55f * camera.height / 2;
      if (in_patch) inside += valid;
      if (off_patch) {
        EXPECT_FALSE(valid) << x << " " << y;
        outside += 1;
      }
      if (valid) {
        EXPECT_NEAR(map.points[map.Index(x, y)].z(), 1.0f, 1e-4f);
      }
    }
  }
  EXPECT_GT(outside, 0);
  EXPECT_GT(inside, 0.9 * (0.45 * camera.width) * (0.45 * camera.height));
  // Beyond max_depth_m: nothing.
  RaycastOptions short_range = Options();
  short_range.max_depth_m = 0.9;
  EXPECT_EQ(Raycast(volume, camera, pose, short_range).NumValid(), 0);
}

// Fused from the front, the wall's band reads − then + from behind: no surface.
TEST(Raycast, WallSeenFromBehindIsInvalid) {
  const PinholeCamera camera = SmallCamera();
  TsdfVolume volume(SmallOptions());
  const core::Rigid3d pose = core::Rigid3d::Identity();
  volume.Integrate(test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0), camera, pose);
  EXPECT_EQ(Raycast(volume, camera, LookAt({0, 0, 2}, {0, 0, 0}), Options()).NumValid(), 0);
  EXPECT_EQ(Raycast(volume, camera, LookAt({0.2, 0.1, 1.6}, {0, 0, 1}), Options()).NumValid(), 0);
}

TEST(Raycast, ColourAndThreadCounts) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  ColourView colour;
  colour.rgb = cv::Mat(camera.height, camera.width, CV_8UC3, cv::Scalar(200, 100, 50));
  colour.camera = camera;
  colour.world_from_camera = pose;
  TsdfVolume volume(SmallOptions());
  volume.Integrate(test::RenderSphere(camera, pose, {0, 0, 1}, 0.3), camera, pose, &colour);
  RaycastOptions options = Options(1);
  options.with_colour = true;
  const PointMap one = Raycast(volume, camera, pose, options);
  options.num_threads = 3;
  const PointMap three = Raycast(volume, camera, pose, options);
  ASSERT_EQ(one.colours.size(), one.points.size());
  EXPECT_GT(one.NumValid(), 1000);
  int painted = 0;
  for (size_t i = 0; i < one.points.size(); ++i) {
    EXPECT_EQ(one.colours[i], three.colours[i]);
    if (!IsValid(one.points[i])) {
      EXPECT_FALSE(IsValid(three.points[i]));
      EXPECT_EQ(one.colours[i], Rgb8::Zero());
      continue;
    }
    EXPECT_EQ(one.points[i], three.points[i]);
    // Near the rim the projective distance of the voxels around the surface exceeds the
    // truncation (grazing view): no voxel there was painted, the pixel is black.
    if (one.colours[i] == Rgb8(200, 100, 50)) {
      ++painted;
    } else {
      EXPECT_EQ(one.colours[i], Rgb8::Zero());
    }
  }
  EXPECT_GT(painted, 0.9 * one.NumValid());
}

// Projecting only the blocks of regions in view gives the very same depth ranges as
// projecting every block: blocks scattered all around the camera (behind it, beside it,
// straddling its plane, beyond both depth limits), seen from several poses.
TEST(Raycast, RegionCullingKeepsEveryBlockInView) {
  const PinholeCamera camera = SmallCamera();
  TsdfVolume volume(SmallOptions());  // 8 cm blocks, 64 cm regions
  std::mt19937 random(7);
  std::uniform_int_distribution<int> coordinate(-60, 60);  // ±4.8 m
  for (int i = 0; i < 20000; ++i) {
    volume.GetOrCreateBlock(BlockKey(coordinate(random), coordinate(random), coordinate(random)));
  }
  const core::Rigid3d poses[] = {core::Rigid3d::Identity(), LookAt({0.3, -0.2, 0.1}, {1, 0.5, 2}),
                                 LookAt({-1, 0.5, 0.3}, {-1.2, 0.4, -1}), LookAt({0.05, 0.6, 0}, {0, 3, 0.2})};
  for (const core::Rigid3d& pose : poses) {
    const auto all = internal::ProjectBlocks(volume, camera, pose, 0.3f, 4.0f, false);
    const auto culled = internal::ProjectBlocks(volume, camera, pose, 0.3f, 4.0f, true);
    ASSERT_EQ(all.near_m.size(), culled.near_m.size());
    int covered = 0;
    for (size_t i = 0; i < all.near_m.size(); ++i) {
      EXPECT_EQ(all.near_m[i], culled.near_m[i]) << i;
      EXPECT_EQ(all.far_m[i], culled.far_m[i]) << i;
      covered += all.near_m[i] <= all.far_m[i];
    }
    EXPECT_GT(covered, 0.9 * static_cast<double>(all.near_m.size()));  // the cloud fills the view
  }
  // Blocks created after a call (here in a new region) are projected by the next one.
  TsdfVolume grown(SmallOptions());
  const core::Rigid3d pose = core::Rigid3d::Identity();
  grown.GetOrCreateBlock(BlockKey(0, 0, 20));  // 1.6 m ahead
  const auto before = internal::ProjectBlocks(grown, camera, pose, 0.3f, 4.0f, true);
  grown.GetOrCreateBlock(BlockKey(0, 0, 10));  // 0.8 m ahead, in front of it
  const auto after = internal::ProjectBlocks(grown, camera, pose, 0.3f, 4.0f, true);
  const auto expected = internal::ProjectBlocks(grown, camera, pose, 0.3f, 4.0f, false);
  EXPECT_NE(before.near_m, after.near_m);
  EXPECT_EQ(after.near_m, expected.near_m);
  EXPECT_EQ(after.far_m, expected.far_m);
}

TEST(RaycastOptions, CheckNamesTheField) {
  RaycastOptions o;
  EXPECT_EQ(o.Check(), "");
  o.step_fraction = 0;
  EXPECT_NE(o.Check().find("step_fraction"), std::string::npos);
  o = RaycastOptions();
  o.max_depth_m = 0.1;
  EXPECT_NE(o.Check().find("max_depth_m"), std::string::npos);
}

}  // namespace
}  // namespace hw::reconstruct
