#include "reconstruct/camera_rays.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <optional>

namespace hw::reconstruct {

namespace {

// True when Distort is the identity: a pinhole, or an OpenCV model with all coefficients 0.
// (Never a splined model: with all controls 0 it is still the stereographic projection.)
bool IsDistortionFree(const core::CameraModel& camera) {
  if (camera.type == core::CameraModelType::kSplined) return false;
  return std::all_of(camera.distortion.begin(), camera.distortion.end(), [](double k) { return k == 0; });
}

// Grows the image [-0.5, size − 0.5) of one axis so that it holds [lo, hi] (pixels): returns
// the whole pixels added before it (`shift`, added to the principal point) and the new size.
// A side that has to grow gets one pixel more than needed: the shifted principal point
// (cx + shift, in float) rounds differently from cx, by far less than a pixel.
void Cover(float lo, float hi, int size, int& shift, int& new_size) {
  shift = 0;
  if (lo < -0.5f) shift = static_cast<int>(std::ceil(-0.5f - lo)) + 1;
  int end = size;  // one past the last pixel, unshifted
  if (!(hi < size - 0.5f)) end = static_cast<int>(std::floor(hi + 0.5f)) + 2;
  new_size = end + shift;
}

}  // namespace

CameraRays::CameraRays(const core::CameraModel& camera) : camera_(camera) {
  assert(camera.Check().empty());
  const size_t n = size_t(camera.width) * size_t(camera.height);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  xy_.assign(n, Eigen::Vector2f::Constant(nan));
  distortion_px_.assign(n, nan);
  const PinholeCamera pinhole = PinholeCamera::Of(camera);
  const bool distortion_free = IsDistortionFree(camera);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const size_t i = Index(x, y);
      if (distortion_free) {
        // The very expression of the pinhole raycast (raycast.cc), for equal bits.
        xy_[i] = Eigen::Vector2f((static_cast<float>(x) - pinhole.cx) / pinhole.fx,
                                 (static_cast<float>(y) - pinhole.cy) / pinhole.fy);
        distortion_px_[i] = 0;
        continue;
      }
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(Eigen::Vector2d(x, y));
      if (!ray) continue;
      xy_[i] = ray->head<2>().cast<float>();
      distortion_px_[i] = static_cast<float>(
          Eigen::Vector2d(x - (camera.fx * ray->x() + camera.cx), y - (camera.fy * ray->y() + camera.cy))
              .norm());
    }
  }

  // The covering pinhole: the model's own, grown to the undistorted projections' extent.
  float u_lo = std::numeric_limits<float>::infinity(), u_hi = -u_lo, v_lo = u_lo, v_hi = -u_lo;
  for (const Eigen::Vector2f& r : xy_) {
    if (std::isnan(r.x())) continue;
    const Eigen::Vector2f uv = pinhole.Project(Eigen::Vector3f(r.x(), r.y(), 1.0f));
    u_lo = std::min(u_lo, uv.x());
    u_hi = std::max(u_hi, uv.x());
    v_lo = std::min(v_lo, uv.y());
    v_hi = std::max(v_hi, uv.y());
  }
  covering_ = pinhole;
  if (u_lo <= u_hi) {  // else no valid pixel: the model's pinhole covers nothing, trivially
    int shift_x, shift_y;
    Cover(u_lo, u_hi, pinhole.width, shift_x, covering_.width);
    Cover(v_lo, v_hi, pinhole.height, shift_y, covering_.height);
    covering_.cx += static_cast<float>(shift_x);
    covering_.cy += static_cast<float>(shift_y);
  }
#ifndef NDEBUG
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      if (!valid(x, y)) continue;
      const Eigen::Vector2f uv = covering_pixel(x, y);
      assert(uv.x() >= -0.5f && uv.x() < covering_.width - 0.5f);
      assert(uv.y() >= -0.5f && uv.y() < covering_.height - 0.5f);
    }
  }
#endif
}

}  // namespace hw::reconstruct
