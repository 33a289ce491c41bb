#include "reconstruct/colour_registration.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

namespace {

// The colour camera's pose for one band of rows, in float.
struct BandPose {
  Eigen::Matrix3f r;
  Eigen::Vector3f t;
};

}  // namespace

double BandOffsetS(int k, int bands, int height, double readout_s) {
  const double row = (k + 0.5) * height / bands - 0.5;
  return readout_s * (row - 0.5 * (height - 1)) / height;
}

cv::Mat RegisterGrey(const cv::Mat& depth_m, const PinholeCamera& depth_camera, const cv::Mat& rgb,
                     const PinholeCamera& rgb_camera, int samples_per_side, const core::Rigid3d& rgb_from_depth,
                     int num_threads, double readout_s,
                     const std::function<core::Rigid3d(double)>& rgb_from_depth_at) {
  assert(depth_m.type() == CV_32FC1 && rgb.type() == CV_8UC3 && samples_per_side >= 1);
  cv::Mat grey(depth_m.size(), CV_32FC1, cv::Scalar(0));
  const float u_max = rgb_camera.width - 0.5f, v_max = rgb_camera.height - 0.5f;
  // A fine pixel's footprint in the colour image, px (both cameras pinhole: the ratio of
  // focal lengths, over the fine pixels per coarse one), and the samples' offsets from the
  // coarse pixel's centre: fine pixel i's centre lies (i + 0.5 − n/2) fine pixels from it.
  const int n = samples_per_side;
  const float step_u = rgb_camera.fx / (depth_camera.fx * static_cast<float>(n));
  const float step_v = rgb_camera.fy / (depth_camera.fy * static_cast<float>(n));
  std::vector<float> offset(n);
  for (int i = 0; i < n; ++i) offset[i] = static_cast<float>(i) + 0.5f - 0.5f * static_cast<float>(n);
  const float scale = 1.0f / (255.0f * static_cast<float>(n * n));
  // The colour camera per band of rows (one pose when it has a global shutter): row v was
  // exposed readout_s·(v − (H − 1)/2)/H after the frame's time.
  const bool rolling = readout_s > 0 && rgb_from_depth_at != nullptr;
  const int bands = rolling ? kColourBands : 1;
  std::vector<BandPose> band_pose(bands);
  const float rows = static_cast<float>(rgb_camera.height);
  for (int k = 0; k < bands; ++k) {
    const core::Rigid3d pose =
        rolling ? rgb_from_depth_at(BandOffsetS(k, bands, rgb_camera.height, readout_s)) : rgb_from_depth;
    band_pose[k] = {pose.rotation.toRotationMatrix().cast<float>(), pose.translation.cast<float>()};
  }
  const BandPose centre = {rgb_from_depth.rotation.toRotationMatrix().cast<float>(),
                           rgb_from_depth.translation.cast<float>()};
  // In float, without Eigen or lround in the per-pixel loop (a full-size frame per frame).
  const float inv_fx = 1.0f / depth_camera.fx, inv_fy = 1.0f / depth_camera.fy;
  ForEachBand(depth_m.rows, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* depth_row = depth_m.ptr<float>(y);
      float* grey_row = grey.ptr<float>(y);
      const float ray_y = (static_cast<float>(y) - depth_camera.cy) * inv_fy;
      for (int x = 0; x < depth_m.cols; ++x) {
        const float z = depth_row[x];
        if (!(z > 0) || std::isinf(z)) continue;
        const float px = (static_cast<float>(x) - depth_camera.cx) * inv_fx * z, py = ray_y * z;
        float u = 0, v = 0;
        const auto project = [&](const BandPose& p) {
          const Eigen::Matrix3f& R = p.r;
          const float cx = R(0, 0) * px + R(0, 1) * py + R(0, 2) * z + p.t.x();
          const float cy = R(1, 0) * px + R(1, 1) * py + R(1, 2) * z + p.t.y();
          const float cz = R(2, 0) * px + R(2, 1) * py + R(2, 2) * z + p.t.z();
          if (!(cz > 0)) return false;
          const float inv_z = 1.0f / cz;
          u = rgb_camera.fx * cx * inv_z + rgb_camera.cx;
          v = rgb_camera.fy * cy * inv_z + rgb_camera.cy;
          return true;
        };
        if (!project(centre)) continue;
        if (rolling) {
          // The row the point lands on says when it was exposed; twice, as the pose of that
          // time moves it to a neighbouring band at most.
          const auto band = [&](float row) {  // clamped as a float: no overflow in the cast
            return static_cast<int>(
                std::clamp((row + 0.5f) * static_cast<float>(bands) / rows, 0.0f, static_cast<float>(bands - 1)));
          };
          int k = band(v);
          if (!project(band_pose[k])) continue;
          if (const int k2 = band(v); k2 != k && !project(band_pose[k = k2])) continue;
        }
        // The mean of the samples' nearest pixels (u, v may be NaN: the tests reject it).
        float sum = 0;
        for (int j = 0; j < n; ++j) {
          const float sv = v + offset[j] * step_v;
          if (!(sv > -0.5f && sv < v_max)) continue;
          const std::uint8_t* row = rgb.ptr<std::uint8_t>(static_cast<int>(sv + 0.5f));
          for (int i = 0; i < n; ++i) {
            const float su = u + offset[i] * step_u;
            if (!(su > -0.5f && su < u_max)) continue;
            const std::uint8_t* p = row + 3 * static_cast<int>(su + 0.5f);
            sum += 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
          }
        }
        grey_row[x] = sum * scale;
      }
    }
  });
  return grey;
}

}  // namespace hw::reconstruct
