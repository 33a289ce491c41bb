#pragma once

// Analytic scenes for the TSDF and raycast tests: depth images of planes and spheres
// rendered in closed form through a PinholeCamera.

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numbers>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/core/mat.hpp>

#include "core/camera.h"
#include "core/transform.h"
#include "reconstruct/camera_maps.h"
#include "reconstruct/tsdf_volume.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct::test {

// 160×120, 60°-ish horizontal field of view.
inline PinholeCamera SmallCamera() { return {160, 120, 120.0f, 120.0f, 79.5f, 59.5f}; }

// The thermal camera of the synthetic rig's design (fixtures/synth_rig.h): 320×240, f 300,
// strong barrel distortion (k1 −0.3, k2 0.12, k3 −0.02), 34 px at the corners.
inline core::CameraModel ThermalCamera() {
  core::CameraModel camera;
  camera.width = 320;
  camera.height = 240;
  camera.type = core::CameraModelType::kOpenCV;
  camera.fx = 300;
  camera.fy = 300.5;
  camera.cx = 161.2;
  camera.cy = 118.4;
  camera.distortion = {-0.3, 0.12, 0, 0, -0.02};
  return camera;
}

// Depth (along the optical axis) of the plane {x : n·x = offset} (world frame) seen from
// world_from_camera; 0 where the ray misses it or meets it behind the camera.
inline cv::Mat RenderPlane(const PinholeCamera& camera, const core::Rigid3d& world_from_camera,
                           const Eigen::Vector3d& normal, double offset) {
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
  const Eigen::Vector3d n = normal.normalized();
  const Eigen::Vector3d o = world_from_camera.translation;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector3d ray = world_from_camera.rotation *
                                  Eigen::Vector3d((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1.0);
      const double denom = n.dot(ray);
      if (std::abs(denom) < 1e-12) continue;
      const double t = (offset - n.dot(o)) / denom;  // depth along the optical axis
      if (t > 0) depth.at<float>(y, x) = static_cast<float>(t);
    }
  }
  return depth;
}

// Depth of a sphere (world centre, radius m), 0 where the ray misses it.
inline cv::Mat RenderSphere(const PinholeCamera& camera, const core::Rigid3d& world_from_camera,
                            const Eigen::Vector3d& centre, double radius) {
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
  const Eigen::Vector3d o = world_from_camera.translation;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector3d ray = world_from_camera.rotation *
                                  Eigen::Vector3d((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1.0);
      // |o + t·ray − c|² = r²
      const Eigen::Vector3d oc = o - centre;
      const double a = ray.squaredNorm(), b = 2 * ray.dot(oc), c = oc.squaredNorm() - radius * radius;
      const double disc = b * b - 4 * a * c;
      if (disc < 0) continue;
      const double t = (-b - std::sqrt(disc)) / (2 * a);
      if (t > 0) depth.at<float>(y, x) = static_cast<float>(t);
    }
  }
  return depth;
}

// A camera at `eye` looking at `target` (y axis roughly along `down`).
inline core::Rigid3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                            const Eigen::Vector3d& down = Eigen::Vector3d::UnitY()) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = down.cross(z).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  return core::Rigid3d(Eigen::Quaterniond(r), eye);
}

// Options of the small tests: 1 cm voxels, 3 cm truncation.
inline TsdfOptions SmallOptions(int num_threads = 2) {
  TsdfOptions o;
  o.voxel_size_m = 0.01;
  o.truncation_m = 0.03;
  o.num_threads = num_threads;
  return o;
}

// Whether this CPU runs the AVX2 kernels (else only the scalar ones run).
inline bool CpuRunsTheSimdKernel() { return internal::CpuHasAvx2(); }

// Integrate has a SIMD kernel (AVX2, where the CPU has it) and the scalar one it replaces
// where not; both must write the same bits. A scene with what sends voxels down every
// branch: depth edges (a sphere before a slanted wall), noise, holes and NaN pixels, a wall
// filling the image to its last row and column, colour through an offset camera whose image
// also ends inside the view, and a weight cap the voxels reach.
struct SimdScene {
  double target_z = 1.1;      // the cameras look at (0.05, 0, target_z), m
  double wall_offset = 1.2;   // the wall {x : n·x = offset}, n ∝ (0.3, 0.1, 1), m
  double sphere_z = 1.0, sphere_radius = 0.15;  // the sphere at (0.05, 0.02, sphere_z), m
  float noise_m = 0.003f;     // depth noise (one σ), m
  unsigned seed = 7;
};
// Block updates over the frames: coarse (TsdfOptions::coarse_far) and whole.
struct SimdTotals {
  int64_t coarse_blocks = 0, fine_blocks = 0;
};
// Integrates the same noisy frames with the AVX2 kernel and the scalar one and expects the
// same bits in every voxel (and the same blocks seen near).
// colour_bands > 0: a rolling-shutter colour camera turning 0.3° about y per band of rows.
inline SimdTotals ExpectSimdWritesTheScalarBits(TsdfOptions options, int colour_bands = 0,
                                                const SimdScene& scene = {}) {
  const PinholeCamera camera = SmallCamera();
  std::mt19937 random(scene.seed);
  std::normal_distribution<float> noise(0.0f, scene.noise_m);
  std::uniform_int_distribution<int> byte(0, 255), percent(0, 99);
  options.max_weight = 3;
  TsdfVolume simd(options), scalar(options);
  SimdTotals totals;
  const Eigen::Vector3d eyes[] = {{0, 0, 0}, {0.1, -0.05, 0.05}, {-0.08, 0.04, -0.1}, {0.02, 0.1, 0.0}};
  for (const Eigen::Vector3d& eye : eyes) {
    const core::Rigid3d pose = LookAt(eye, {0.05, 0, scene.target_z});
    const cv::Mat wall = RenderPlane(camera, pose, Eigen::Vector3d(0.3, 0.1, 1.0), scene.wall_offset);
    const cv::Mat sphere = RenderSphere(camera, pose, {0.05, 0.02, scene.sphere_z}, scene.sphere_radius);
    cv::Mat depth(camera.height, camera.width, CV_32FC1);
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const float s = sphere.at<float>(y, x), w = wall.at<float>(y, x);
        float d = s > 0 && (w <= 0 || s < w) ? s : w;
        const int drop = percent(random);
        if (d > 0) d += noise(random);
        if (drop < 3) d = 0;
        if (drop == 3) d = std::numeric_limits<float>::quiet_NaN();
        depth.at<float>(y, x) = d;
      }
    }
    ColourView colour;
    colour.camera = {150, 110, 118.0f, 119.0f, 74.5f, 54.5f};
    colour.rgb = cv::Mat(colour.camera.height, colour.camera.width, CV_8UC3);
    for (int y = 0; y < colour.rgb.rows; ++y) {
      for (int x = 0; x < 3 * colour.rgb.cols; ++x) colour.rgb.ptr<std::uint8_t>(y)[x] = static_cast<std::uint8_t>(byte(random));
    }
    colour.world_from_camera = pose * core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY())),
                                                    Eigen::Vector3d(0.025, 0.002, 0));
    for (int k = 0; k < colour_bands; ++k) {
      const double turn = 0.3 * (k - 0.5 * (colour_bands - 1)) * std::numbers::pi / 180;
      colour.world_from_camera_bands.push_back(
          colour.world_from_camera *
          core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitY())), Eigen::Vector3d::Zero()));
    }
    internal::integrate_simd = true;
    const IntegrateStats a = simd.Integrate(depth, camera, pose, &colour);
    internal::integrate_simd = false;
    const IntegrateStats b = scalar.Integrate(depth, camera, pose, &colour);
    internal::integrate_simd = true;
    EXPECT_GT(a.voxels_updated, 100000);
    EXPECT_EQ(a.voxels_updated, b.voxels_updated);
    EXPECT_EQ(a.blocks_visible, b.blocks_visible);
    EXPECT_EQ(a.blocks_coarse, b.blocks_coarse);
    totals.coarse_blocks += a.blocks_coarse;
    totals.fine_blocks += a.blocks_visible - a.blocks_coarse;
  }
  EXPECT_EQ(simd.NumBlocks(), scalar.NumBlocks());
  if (simd.NumBlocks() != scalar.NumBlocks()) return totals;
  int64_t differ = 0, capped = 0, painted = 0;
  simd.ForEachBlock([&](const VoxelBlock& block) {
    const VoxelBlock* other = scalar.FindBlock(block.key);
    ASSERT_NE(other, nullptr);
    EXPECT_EQ(block.seen_near, other->seen_near);
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Voxel &p = block.voxels[i], &q = other->voxels[i];
      differ += std::memcmp(&p, &q, sizeof(Voxel)) != 0;
      capped += p.weight() == 3;
      painted += p.colour_weight > 0;
    }
  });
  EXPECT_EQ(differ, 0);
  EXPECT_GT(capped, 10000);  // the cap was reached
  EXPECT_GT(painted, 10000);
  return totals;
}


}  // namespace hw::reconstruct::test
