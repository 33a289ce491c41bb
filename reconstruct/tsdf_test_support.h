#pragma once

// Analytic scenes for the TSDF and raycast tests: depth images of planes and spheres
// rendered in closed form through a PinholeCamera.

#include <cmath>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "core/camera.h"
#include "core/transform.h"
#include "reconstruct/camera_maps.h"
#include "reconstruct/tsdf_volume.h"

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

}  // namespace hw::reconstruct::test
