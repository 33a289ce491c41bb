#include "reconstruct/raycast.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>
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

// Rays are marched several at a time per thread, in turn (RayMarch::kLanes), and which rays
// share a thread's lanes depends on the thread count: a ray that read another's state would
// change with it. A sphere before a wall, cast from beside the fusing pose with a camera
// whose size is not a multiple of the 8-pixel tiles (the last tile column and row are
// partial) on 1, 2, 3 and 7 threads: the same bits everywhere, and the partial tiles' pixels
// cast (the wall fills the view).
TEST(Raycast, RaysMarchedTogetherGiveTheSameMapOnAnyThreadCount) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.2);
  const cv::Mat sphere = test::RenderSphere(camera, pose, {0.05, 0, 0.9}, 0.2);
  sphere.copyTo(depth, sphere > 0);  // 0 where the ray misses the sphere
  TsdfVolume volume(SmallOptions());
  volume.Integrate(depth, camera, pose);
  // Narrower than the fusing camera (f 150 vs 120): every ray stays inside the fused view.
  const PinholeCamera odd{157, 117, 150.0f, 150.0f, 78.0f, 58.0f};
  const core::Rigid3d cast_pose = LookAt({0.03, -0.02, 0.02}, {0.02, 0, 1.0});
  RaycastOptions options = Options(1);
  options.with_colour = true;
  const PointMap one = Raycast(volume, odd, cast_pose, options);
  EXPECT_GT(one.NumValid(), 0.95 * odd.width * odd.height);
  int last_column = 0, last_row = 0;
  for (int y = 0; y < odd.height; ++y) last_column += IsValid(one.points[one.Index(odd.width - 1, y)]);
  for (int x = 0; x < odd.width; ++x) last_row += IsValid(one.points[one.Index(x, odd.height - 1)]);
  EXPECT_GT(last_column, 0.9 * odd.height);
  EXPECT_GT(last_row, 0.9 * odd.width);
  for (int threads : {2, 3, 7}) {
    options.num_threads = threads;
    const PointMap other = Raycast(volume, odd, cast_pose, options);
    int differing = 0;
    for (size_t i = 0; i < one.points.size(); ++i) {
      // Bitwise: NaN (invalid) equals NaN.
      differing += std::memcmp(&one.points[i], &other.points[i], sizeof(Eigen::Vector3f)) != 0 ||
                   std::memcmp(&one.normals[i], &other.normals[i], sizeof(Eigen::Vector3f)) != 0 ||
                   one.colours[i] != other.colours[i];
    }
    EXPECT_EQ(differing, 0) << threads << " threads";
  }
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
    // Projected on several threads (chunks of >= 2,000 blocks: 20,000 blocks make up to 10):
    // the same ranges, bit for bit.
    for (int threads : {2, 3}) {
      for (bool cull : {false, true}) {
        const auto split = internal::ProjectBlocks(volume, camera, pose, 0.3f, 4.0f, cull, threads);
        EXPECT_EQ(split.near_m, all.near_m) << threads << " " << cull;
        EXPECT_EQ(split.far_m, all.far_m) << threads << " " << cull;
      }
    }
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

// The covering pinhole of `rays` grown by margin_px on every side: fusing through it
// observes every cell the distorted camera's rays cross near its pose.
PinholeCamera Widened(const CameraRays& rays, int margin_px) {
  PinholeCamera camera = rays.covering_pinhole();
  camera.width += 2 * margin_px;
  camera.height += 2 * margin_px;
  camera.cx += static_cast<float>(margin_px);
  camera.cy += static_cast<float>(margin_px);
  return camera;
}

// A hit's pixel through the lens model: world point to camera frame (double), Project.
Eigen::Vector2d PixelOf(const core::CameraModel& camera, const core::Rigid3d& world_from_camera,
                        const Eigen::Vector3f& point_in_world) {
  return camera.Project(world_from_camera.Inverse() * point_in_world.cast<double>());
}

// A frontal plane 1 m ahead, fused through a pinhole 24 px (8 voxels at 1 m) wider than
// every ray of the thermal lens: every pixel has a ray and every ray meets the plane, with
// the exactness of FrontalPlaneIsExact (1e-4 m), on its own ray: CameraModel::Project of the
// hit returns the pixel centre. The corner rays are 34 px away from the pinhole's, so a
// raycast ignoring the lens would miss this by 10 cm at 1 m.
TEST(Raycast, DistortedRaysFrontalPlaneFillsTheView) {
  const CameraRays rays(test::ThermalCamera());
  const PinholeCamera fuse_camera = Widened(rays, 24);
  const core::Rigid3d pose = core::Rigid3d::Identity();
  TsdfVolume volume(SmallOptions());
  volume.Integrate(test::RenderPlane(fuse_camera, pose, Eigen::Vector3d::UnitZ(), 1.0), fuse_camera, pose);
  const PointMap map = Raycast(volume, rays, pose, Options());
  ASSERT_EQ(map.width, 320);
  ASSERT_EQ(map.height, 240);
  EXPECT_EQ(map.NumValid(), 320 * 240);
  double worst_px = 0, worst_m = 0;
  for (int y = 0; y < map.height; ++y) {
    for (int x = 0; x < map.width; ++x) {
      const Eigen::Vector3f& p = map.points[map.Index(x, y)];
      if (!IsValid(p)) continue;
      worst_m = std::max(worst_m, std::abs(double(p.z()) - 1.0));
      worst_px = std::max(worst_px, (PixelOf(rays.camera(), pose, p) - Eigen::Vector2d(x, y)).norm());
    }
  }
  EXPECT_LT(worst_m, 1e-4);
  // Float world points (6e-8 m at 1 m) through f = 300: 2e-5 px.
  EXPECT_LT(worst_px, 0.01);
  RecordProperty("worst_reprojection_px", std::to_string(worst_px));
}

// The first + to − crossing of the sdf (TsdfVolume::SdfAt, nothing shared with the raycast)
// along origin + t · direction for depths t in [t_min, t_max], in steps of step_m along the
// ray: false when the ray meets no surface or meets one from behind first.
bool BruteForceHit(const TsdfVolume& volume, const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                   float t_min, float t_max, float step_m, Eigen::Vector3f& hit) {
  const float dt = step_m / direction.norm();
  std::optional<float> previous;
  for (float t = t_min; t <= t_max; t += dt) {
    const std::optional<float> sdf = volume.SdfAt(origin + t * direction);
    if (sdf && previous && *previous > 0 && *sdf <= 0) {
      hit = origin + (t - dt * *sdf / (*sdf - *previous)) * direction;
      return true;
    }
    if (sdf && previous && *previous < 0 && *sdf > 0) return false;
    previous = sdf;
  }
  return false;
}

// A sphere 0.25 m in radius before a wall 0.5 m behind its centre, cast through the thermal
// lens from a pose turned so that the sphere sits in the upper left of the image, where the
// lens bends rays by up to 18 px. Every hit is on its pixel's ray (0.01 px) and on the
// surface (0.1 voxel; on the sphere for rays within 60° of its normal, as
// SphereWithinATenthOfAVoxel), and the hits are those of a brute-force march, ray by ray.
// For that the field along the cast rays must leave no room to the step pattern: fused from
// one pose 2 cm and ~1° away (along every cast ray the field is close to that view's
// projective distance; from distant poses it reads +1 right beside surfaces their rays
// graze), and marched with step_fraction 0.1. At the default 0.5 the march steps 1.5 cm,
// and behind a single view's surface the observed band can end after ~1 cm where the block
// behind was not allocated: the step jumps it and the ray misses (the pinhole overload
// misses 52 of 10474 rays of this scene that way; not a property of the lens rays).
TEST(Raycast, DistortedRaysSphereBeforeAWall) {
  const CameraRays rays(test::ThermalCamera());
  const PinholeCamera fuse_camera = Widened(rays, 24);
  const Eigen::Vector3d centre(0, 0, 1.0);
  const double radius = 0.25, wall_z = 1.5;
  TsdfVolume volume(SmallOptions());
  const core::Rigid3d fuse_pose = LookAt({0.03, 0.02, 0}, {0.24, 0.16, 1.0});
  cv::Mat depth = test::RenderSphere(fuse_camera, fuse_pose, centre, radius);
  const cv::Mat wall = test::RenderPlane(fuse_camera, fuse_pose, Eigen::Vector3d::UnitZ(), wall_z);
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) {
      if (depth.at<float>(y, x) == 0) depth.at<float>(y, x) = wall.at<float>(y, x);
    }
  }
  volume.Integrate(depth, fuse_camera, fuse_pose);
  const core::Rigid3d pose = LookAt({0.05, 0.03, 0.02}, {0.25, 0.15, 1.0});
  RaycastOptions options = Options();
  options.max_depth_m = 2.0;
  options.step_fraction = 0.1;
  const PointMap map = Raycast(volume, rays, pose, options);
  ASSERT_EQ(map.width, 320);
  ASSERT_EQ(map.height, 240);
  double worst_px = 0, worst_sphere_m = 0, worst_wall_m = 0;
  int sphere_hits = 0, wall_hits = 0;
  float sphere_distortion_px = 0;
  for (int y = 0; y < map.height; ++y) {
    for (int x = 0; x < map.width; ++x) {
      const Eigen::Vector3f& p = map.points[map.Index(x, y)];
      if (!IsValid(p)) continue;
      worst_px = std::max(worst_px, (PixelOf(rays.camera(), pose, p) - Eigen::Vector2d(x, y)).norm());
      const Eigen::Vector3d q = p.cast<double>();
      const double to_sphere = (q - centre).norm() - radius, to_wall = q.z() - wall_z;
      if (std::abs(to_sphere) < std::abs(to_wall)) {
        sphere_distortion_px = std::max(sphere_distortion_px, rays.distortion_px(x, y));
        const Eigen::Vector3d n = (q - centre).normalized();
        if (n.dot((pose.translation - q).normalized()) < std::cos(60 * kDegree)) continue;
        ++sphere_hits;
        worst_sphere_m = std::max(worst_sphere_m, std::abs(to_sphere));
      } else {
        ++wall_hits;
        worst_wall_m = std::max(worst_wall_m, std::abs(to_wall));
      }
    }
  }
  RecordProperty("sphere_hits", std::to_string(sphere_hits));
  RecordProperty("wall_hits", std::to_string(wall_hits));
  RecordProperty("worst_sphere_m", std::to_string(worst_sphere_m));
  RecordProperty("worst_wall_m", std::to_string(worst_wall_m));
  RecordProperty("worst_reprojection_px", std::to_string(worst_px));
  RecordProperty("sphere_distortion_px", std::to_string(sphere_distortion_px));
  EXPECT_GT(sphere_hits, 5000);
  EXPECT_GT(wall_hits, 30000);
  EXPECT_GT(sphere_distortion_px, 10.0f);
  EXPECT_LT(worst_px, 0.01);
  EXPECT_LT(worst_sphere_m, 0.1 * volume.options().voxel_size_m);
  EXPECT_LT(worst_wall_m, 0.1 * volume.options().voxel_size_m);

  // Brute force on every third pixel, 2 mm steps (a fifteenth of the truncation band).
  // Excluded: rays passing within a truncation (3 cm) of the sphere's silhouette, where the
  // interpolated field mixes voxels that saw the sphere with voxels that saw the wall, and
  // the wall's edge of the sphere's shadow (unobserved cells) lies within ~1 cm of them
  // (2 cm baseline × 0.5 m / 1.5 m parallax): there the crossing found depends on where the
  // samples fall.
  const Eigen::Matrix3f rotation = pose.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f origin = pose.translation.cast<float>();
  int brute_hits = 0, raycast_hits = 0, compared = 0;
  double worst_apart_m = 0;
  for (int y = 1; y < map.height; y += 3) {
    for (int x = 1; x < map.width; x += 3) {
      ASSERT_TRUE(rays.valid(x, y));
      const Eigen::Vector2f xy = rays.xy(x, y);
      const Eigen::Vector3f direction = rotation * Eigen::Vector3f(xy.x(), xy.y(), 1);
      const Eigen::Vector3d unit = direction.cast<double>().normalized();
      const Eigen::Vector3d to_centre = centre - pose.translation;
      const double from_silhouette_m = (to_centre - to_centre.dot(unit) * unit).norm() - radius;
      if (std::abs(from_silhouette_m) < 0.03) continue;
      ++compared;
      Eigen::Vector3f hit;
      const bool brute = BruteForceHit(volume, origin, direction, static_cast<float>(options.min_depth_m),
                                       static_cast<float>(options.max_depth_m), 0.002f, hit);
      const Eigen::Vector3f& p = map.points[map.Index(x, y)];
      brute_hits += brute;
      raycast_hits += IsValid(p);
      EXPECT_EQ(brute, IsValid(p)) << x << " " << y;
      if (brute && IsValid(p)) worst_apart_m = std::max(worst_apart_m, double((hit - p).norm()));
    }
  }
  RecordProperty("brute_hits", std::to_string(brute_hits));
  RecordProperty("worst_apart_m", std::to_string(worst_apart_m));
  EXPECT_EQ(raycast_hits, brute_hits);
  EXPECT_GT(brute_hits, 0.9 * compared);
  // The brute force's linear interpolation across a 2 mm step of a field linear to 1e-5
  // over it: both find the same zero to far less than a millimetre.
  EXPECT_LT(worst_apart_m, 1e-3);
}

// Without distortion the lens overload is the pinhole one, bit for bit: the same rays, depth
// ranges and march (points, normals, colours; one thread and three), for a pinhole model and
// for an OpenCV model whose coefficients are all 0.
TEST(Raycast, DistortionFreeRaysEqualThePinholeOverload) {
  const PinholeCamera camera = SmallCamera();
  core::CameraModel pinhole = core::CameraModel::Pinhole(camera.width, camera.height, camera.fx, camera.fy);
  pinhole.cx = camera.cx;
  pinhole.cy = camera.cy;
  core::CameraModel zero_opencv = pinhole;
  zero_opencv.type = core::CameraModelType::kOpenCV;
  zero_opencv.distortion = {0, 0, 0, 0};
  const core::Rigid3d fuse_pose = core::Rigid3d::Identity();
  ColourView colour;
  colour.rgb = cv::Mat(camera.height, camera.width, CV_8UC3, cv::Scalar(200, 100, 50));
  colour.camera = camera;
  colour.world_from_camera = fuse_pose;
  TsdfVolume volume(SmallOptions());
  cv::Mat depth = test::RenderSphere(camera, fuse_pose, {0, 0, 1}, 0.3);
  const cv::Mat wall = test::RenderPlane(camera, fuse_pose, Eigen::Vector3d::UnitZ(), 1.6);
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) {
      if (depth.at<float>(y, x) == 0) depth.at<float>(y, x) = wall.at<float>(y, x);
    }
  }
  volume.Integrate(depth, camera, fuse_pose, &colour);
  for (const core::CameraModel& model : {pinhole, zero_opencv}) {
    const CameraRays rays(model);
    for (const core::Rigid3d& pose : {fuse_pose, LookAt({0.04, -0.03, 0.02}, {0.1, 0.05, 1.0})}) {
      for (int threads : {1, 3}) {
        RaycastOptions options = Options(threads);
        options.with_colour = true;
        const PointMap expected = Raycast(volume, camera, pose, options);
        const PointMap map = Raycast(volume, rays, pose, options);
        ASSERT_EQ(map.width, expected.width);
        ASSERT_EQ(map.height, expected.height);
        EXPECT_GT(expected.NumValid(), camera.width * camera.height / 2);
        // Byte comparison: NaN == NaN, and -0 differs from +0.
        ASSERT_EQ(map.points.size(), expected.points.size());
        ASSERT_EQ(map.colours.size(), expected.colours.size());
        EXPECT_EQ(std::memcmp(map.points.data(), expected.points.data(), map.points.size() * sizeof(Eigen::Vector3f)), 0);
        EXPECT_EQ(std::memcmp(map.normals.data(), expected.normals.data(), map.normals.size() * sizeof(Eigen::Vector3f)), 0);
        EXPECT_EQ(map.colours, expected.colours);
      }
    }
  }
}

// Steps in units of each block's narrowest band (RaycastOptions::band_steps) find the same
// surfaces as steps of truncation_m: a room corner 3.3–3.9 m away — a wall seen nearly
// head-on and a floor 1 m below the camera met at 70–80° from its normal — fused from three
// poses a few centimetres apart with the default band (2 cm, widened to 3 σ of the depth
// noise: 5–8 cm there), cast from a fourth. Both marches refine the crossing to 0.005 of a
// band (< 0.4 mm here) on the same trilinear field, so where both hit they agree to 1 mm
// (two refinement tolerances plus the field's curvature between their brackets) — except
// within 3 cm of the corner, where the wall's and the floor's bands overlap and the samples
// decide which crossing is met first, and 12 px from the image border, where the fusing
// views' rims cross the floor at 80° and their samples bracket the bend differently. Hits and misses are checked ray by ray against a
// brute-force march (2 mm steps): a band step that passed a surface's negative side would
// miss it. Both marches disagree with it on a few rays where the observed field ends within
// a step of the surface, the views' rim (7 with band steps and 4 with fixed ones of 19 200
// here; which ones depends on where the samples fall): at most 0.1 % of the rays each.
TEST(Raycast, BandStepsFindTheSurfacesFixedStepsFind) {
  const PinholeCamera camera = SmallCamera();
  TsdfOptions tsdf;  // defaults: 5 mm voxels, 2 cm band widened with the noise
  tsdf.num_threads = 2;
  TsdfVolume volume(tsdf);
  const Eigen::Vector3d wall_normal = Eigen::Vector3d(0.2, 0.0, -1.0).normalized();
  const double wall_offset = wall_normal.dot(Eigen::Vector3d(0, 0, 3.6));
  const Eigen::Vector3d floor_normal(0, -1, 0);  // y down: the floor 1 m below, facing up
  const double floor_offset = -1.0;
  for (const Eigen::Vector3d& eye : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.04, -0.02, 0.03),
                                     Eigen::Vector3d(-0.03, 0.02, -0.02)}) {
    const core::Rigid3d pose = LookAt(eye, {0.1, 0.35, 3.4});
    cv::Mat depth = test::RenderPlane(camera, pose, wall_normal, wall_offset);
    const cv::Mat floor = test::RenderPlane(camera, pose, floor_normal, floor_offset);
    for (int y = 0; y < depth.rows; ++y) {
      for (int x = 0; x < depth.cols; ++x) {
        float& d = depth.at<float>(y, x);
        const float f = floor.at<float>(y, x);
        if (f > 0 && (d <= 0 || f < d)) d = f;
        if (d > 5.0f) d = 0;  // beyond the sensor
      }
    }
    volume.Integrate(depth, camera, pose);
  }
  int wide = 0, blocks = 0;
  volume.ForEachBlock([&](const VoxelBlock& block) {
    ++blocks;
    wide += block.min_band_m > 2 * static_cast<float>(tsdf.truncation_m);
  });
  EXPECT_GT(wide, blocks / 2);  // the rule has room to act

  const core::Rigid3d pose = LookAt({0.02, 0.01, 0.05}, {0.12, 0.3, 3.4});
  RaycastOptions band = Options(), fixed = Options();
  band.max_depth_m = fixed.max_depth_m = 5.0;
  fixed.band_steps = false;
  ASSERT_TRUE(band.band_steps);  // the default
  const PointMap a = Raycast(volume, camera, pose, band);
  const PointMap b = Raycast(volume, camera, pose, fixed);
  const Eigen::Matrix3f rotation = pose.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f origin = pose.translation.cast<float>();
  int both = 0, floor_hits = 0, corner = 0, brute_hits = 0, band_off = 0, fixed_off = 0;
  double worst_m = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const size_t i = a.Index(x, y);
      const Eigen::Vector3f direction =
          rotation * Eigen::Vector3f((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1.0f);
      Eigen::Vector3f hit;
      const bool brute = BruteForceHit(volume, origin, direction, static_cast<float>(band.min_depth_m),
                                       static_cast<float>(band.max_depth_m), 0.002f, hit);
      brute_hits += brute;
      band_off += IsValid(a.points[i]) != brute;
      fixed_off += IsValid(b.points[i]) != brute;
      if (!IsValid(a.points[i]) || !IsValid(b.points[i])) continue;
      const Eigen::Vector3d p = a.points[i].cast<double>();
      const double to_wall = std::abs(wall_normal.dot(p) - wall_offset), to_floor = std::abs(floor_normal.dot(p) - floor_offset);
      if (to_wall < 0.03 && to_floor < 0.03) {
        ++corner;
        continue;
      }
      // The fused views' rim (the poses' images differ by up to ~5 px there): cells with
      // voxels one view saw and another did not, where the field bends.
      if (x < 12 || y < 12 || x >= camera.width - 12 || y >= camera.height - 12) continue;
      ++both;
      floor_hits += to_floor < to_wall;
      worst_m = std::max(worst_m, double((a.points[i] - b.points[i]).norm()));
    }
  }
  RecordProperty("hits", std::to_string(both));
  RecordProperty("floor_hits", std::to_string(floor_hits));
  RecordProperty("corner_hits", std::to_string(corner));
  RecordProperty("band_vs_brute", std::to_string(band_off));
  RecordProperty("fixed_vs_brute", std::to_string(fixed_off));
  RecordProperty("worst_apart_m", std::to_string(worst_m));
  EXPECT_GT(brute_hits, camera.width * camera.height * 3 / 4);
  EXPECT_GT(floor_hits, 1000);
  // A handful either way, where the observed field ends within a step of the surface;
  // stepping past surfaces would miss hundreds (the floor alone gives 3 444 hits).
  EXPECT_LE(band_off, camera.width * camera.height / 1000);
  EXPECT_LE(fixed_off, camera.width * camera.height / 1000);
  EXPECT_LT(worst_m, 1e-3);
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
