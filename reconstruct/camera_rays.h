#pragma once

// The rays of a camera with lens distortion, one per pixel centre, for raycasting the TSDF
// exactly through the lens (raycast.h) instead of through an undistorted resampling of its
// image: a thermal image has few pixels (320×240), and resampling it would blur the very
// temperatures laid onto the model.

#include <cassert>
#include <cmath>
#include <vector>

#include <Eigen/Core>

#include "core/camera.h"
#include "reconstruct/camera_maps.h"

namespace hw::reconstruct {

// The ray of every pixel centre of a camera with its lens model, precomputed once per camera
// (one CameraModel::Unproject per pixel: milliseconds for 320×240). Immutable: share it
// between threads.
class CameraRays {
 public:
  CameraRays() = default;
  // Asserts camera.Check() is empty. Pixels whose undistortion fails (outside the model's
  // invertible range: CameraModel::Undistort, e.g. the corners of a strong barrel lens past
  // the fold of its polynomial) have no ray (valid(x, y) false).
  explicit CameraRays(const core::CameraModel& camera);

  int width() const { return camera_.width; }
  int height() const { return camera_.height; }
  const core::CameraModel& camera() const { return camera_; }

  // Pixel coordinates are asserted to lie in the image.
  bool valid(int x, int y) const { return !std::isnan(xy_[Index(x, y)].x()); }
  // Undistorted normalised coordinates (x/z, y/z) of pixel (x, y)'s centre: the ray in the
  // camera frame is (xy.x, xy.y, 1). NaN when !valid. For a model without distortion
  // (pinhole, or all coefficients 0) exactly PinholeCamera's ((x − cx) / fx, (y − cy) / fy) in
  // float, so that a raycast through it equals the pinhole one bit for bit; else the double
  // Unproject rounded to float (~1e-7 relative: 1e-4 px through fx = 1000).
  Eigen::Vector2f xy(int x, int y) const { return xy_[Index(x, y)]; }
  // A pinhole camera (the model's fx fy, its own cx cy and size) whose image contains the
  // undistorted projection of every valid pixel, for the per-tile depth ranges. It is the
  // model's own pinhole (PinholeCamera::Of) when that contains them (no distortion,
  // pincushion); else it is grown by whole pixels, one more than needed on each side grown
  // so that float rounding of the shifted centre cannot push a projection out.
  const PinholeCamera& covering_pinhole() const { return covering_; }
  // The undistorted projection of pixel (x, y)'s centre in covering_pinhole() (pixels,
  // covering_pinhole().Project of the ray, float): inside its image, -0.5 <= u < width − 0.5
  // and likewise v, for every valid pixel. NaN when !valid.
  Eigen::Vector2f covering_pixel(int x, int y) const {
    const Eigen::Vector2f r = xy(x, y);
    return covering_.Project(Eigen::Vector3f(r.x(), r.y(), 1.0f));
  }
  // How far the lens model moves pixel (x, y): |(x, y) − (fx·xy.x + cx, fy·xy.y + cy)|, pixels
  // (0 for a pinhole model; NaN when !valid). Computed in double from the double preimage.
  float distortion_px(int x, int y) const { return distortion_px_[Index(x, y)]; }

 private:
  size_t Index(int x, int y) const {
    assert(x >= 0 && y >= 0 && x < camera_.width && y < camera_.height);
    return size_t(y) * size_t(camera_.width) + size_t(x);
  }

  core::CameraModel camera_;
  PinholeCamera covering_;
  std::vector<Eigen::Vector2f> xy_;     // row-major, width × height
  std::vector<float> distortion_px_;  // row-major, width × height
};

}  // namespace hw::reconstruct
