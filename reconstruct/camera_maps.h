#pragma once

// Types shared by the stages of reconstruct/: an ideal pinhole camera and per-pixel maps of
// points, normals and colours. Everything after the first step of a frame (undistortion,
// reconstruct/depth_frame.h) works on distortion-free pinhole images, so that projecting a
// point — done millions of times per frame by integration, raycasting and ICP — is four
// multiply-adds instead of an iterative lens model. The one exception is raycasting through
// a camera's own lens (camera_rays.h: rays precomputed per pixel, so still no lens model
// per ray).

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "core/camera.h"

namespace hw::reconstruct {

// An ideal pinhole camera (no distortion), OpenCV conventions as core::CameraModel: x right,
// y down, z forward; pixel (0, 0) is the centre of the top-left pixel.
struct PinholeCamera {
  int width = 0, height = 0;  // pixels
  float fx = 0, fy = 0;       // pixels
  float cx = 0, cy = 0;       // pixels

  // The pinhole part (fx fy cx cy, size) of `camera`, its distortion dropped.
  static PinholeCamera Of(const core::CameraModel& camera) {
    return {camera.width, camera.height, static_cast<float>(camera.fx),
            static_cast<float>(camera.fy), static_cast<float>(camera.cx),
            static_cast<float>(camera.cy)};
  }
  // The camera of an image downsampled by 2 (pixel centres: x' = (x + 0.5) / 2 − 0.5).
  PinholeCamera Half() const {
    return {width / 2, height / 2, fx / 2, fy / 2, (cx + 0.5f) / 2 - 0.5f,
            (cy + 0.5f) / 2 - 0.5f};
  }
  // Pixel of a point in the camera frame (metres); callers cull z <= 0.
  Eigen::Vector2f Project(const Eigen::Vector3f& point_in_camera) const {
    const float inv_z = 1.0f / point_in_camera.z();
    return {fx * point_in_camera.x() * inv_z + cx, fy * point_in_camera.y() * inv_z + cy};
  }
  // The point at depth z (metres, along the optical axis) seen at pixel (u, v).
  Eigen::Vector3f Unproject(float u, float v, float z) const {
    return {(u - cx) / fx * z, (v - cy) / fy * z, z};
  }
  // The nearest pixel to `pixel` when it lies inside the image, else false.
  bool NearestPixel(const Eigen::Vector2f& pixel, int& x, int& y) const {
    x = static_cast<int>(std::lround(pixel.x()));
    y = static_cast<int>(std::lround(pixel.y()));
    return x >= 0 && y >= 0 && x < width && y < height;
  }
};

// A missing point or normal: every component NaN. Test with IsValid().
inline Eigen::Vector3f InvalidPoint() {
  return Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
}
inline bool IsValid(const Eigen::Vector3f& v) { return !std::isnan(v.x()); }

using Rgb8 = Eigen::Matrix<std::uint8_t, 3, 1>;

// Per-pixel points and normals of one view (row-major, width × height), in the frame the
// producer names (camera frame for a depth frame, world frame for a raycast). Pixels without
// a point hold InvalidPoint() in both maps; a point may have an invalid normal (at depth
// edges), never the reverse. `colours` is empty or one per pixel.
struct PointMap {
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;
  std::vector<Rgb8> colours;

  PointMap() = default;
  PointMap(int w, int h)
      : width(w), height(h), points(size_t(w) * h, InvalidPoint()),
        normals(size_t(w) * h, InvalidPoint()) {}
  size_t Index(int x, int y) const { return size_t(y) * width + x; }
  int NumValid() const {
    int n = 0;
    for (const auto& p : points) n += IsValid(p);
    return n;
  }
};

}  // namespace hw::reconstruct
