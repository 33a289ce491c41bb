#include "reconstruct/colour_registration.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "reconstruct/float8.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

namespace {

using internal::Float8;
using internal::Int8;

// One registration in float, as the per-pixel loop reads it: cameras, poses (row-major
// rotation and translation; band k's at 12·k in `bands`), the sampling footprint.
struct Registration {
  float depth_cx, depth_cy, inv_fx, inv_fy;  // depth camera
  float fx, fy, cx, cy, u_max, v_max;        // colour camera
  float centre[12];
  const float* bands = nullptr;  // num_bands × 12 floats (rolling shutter), else nullptr
  int num_bands = 1;
  float rows = 0;  // colour image height
  int n = 1;       // samples per side
  const float* offset = nullptr;  // n offsets of the samples, fine pixels
  float step_u = 0, step_v = 0, scale = 0;
  const std::uint8_t* rgb = nullptr;
  size_t rgb_step = 0;  // bytes per row
};

// r · (px, py, z) + t of a pose of 12 floats, and its projection into the colour camera;
// false behind the camera. The order of the sums is the vector loop's.
inline bool ProjectPixel(const Registration& g, const float* pose, float px, float py, float z, float& u, float& v) {
  const float x = pose[0] * px + pose[1] * py + pose[2] * z + pose[9];
  const float y = pose[3] * px + pose[4] * py + pose[5] * z + pose[10];
  const float w = pose[6] * px + pose[7] * py + pose[8] * z + pose[11];
  if (!(w > 0)) return false;
  const float inv_z = 1.0f / w;
  u = g.fx * x * inv_z + g.cx;
  v = g.fy * y * inv_z + g.cy;
  return true;
}

// The band of rows a colour row falls in (clamped as a float: no overflow in the cast; 0
// for a NaN row, whose cast would be undefined: a point whose depth in the colour camera
// underflows).
inline int BandOf(const Registration& g, float row) {
  const float band = (row + 0.5f) * static_cast<float>(g.num_bands) / g.rows;
  return band == band ? static_cast<int>(std::clamp(band, 0.0f, static_cast<float>(g.num_bands - 1))) : 0;
}

inline float Luma(const std::uint8_t* p) { return 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2]; }

// Grey level of depth pixel x of a row (ray_y its unprojected y at depth 1), or false where
// it has none (RegisterGrey's header).
inline bool GreyOfPixel(const Registration& g, float x, float ray_y, float z, float& grey) {
  if (!(z > 0) || std::isinf(z)) return false;
  const float px = (x - g.depth_cx) * g.inv_fx * z, py = ray_y * z;
  float u = 0, v = 0;
  if (!ProjectPixel(g, g.centre, px, py, z, u, v)) return false;
  if (g.bands != nullptr) {
    // The row the point lands on says when it was exposed; twice, as the pose of that time
    // moves it to a neighbouring band at most.
    int k = BandOf(g, v);
    if (!ProjectPixel(g, g.bands + 12 * k, px, py, z, u, v)) return false;
    if (const int k2 = BandOf(g, v); k2 != k && !ProjectPixel(g, g.bands + 12 * (k = k2), px, py, z, u, v)) {
      return false;
    }
  }
  // The mean of the samples' nearest pixels (u, v may be NaN: the tests reject it).
  float sum = 0;
  for (int j = 0; j < g.n; ++j) {
    const float sv = v + g.offset[j] * g.step_v;
    if (!(sv > -0.5f && sv < g.v_max)) continue;
    const std::uint8_t* row = g.rgb + g.rgb_step * static_cast<size_t>(static_cast<int>(sv + 0.5f));
    for (int i = 0; i < g.n; ++i) {
      const float su = u + g.offset[i] * g.step_u;
      if (!(su > -0.5f && su < g.u_max)) continue;
      sum += Luma(row + 3 * static_cast<int>(su + 0.5f));
    }
  }
  grey = sum * g.scale;
  return true;
}

// ProjectPixel on eight lanes, each with its own pose (12 floats at pose + offset[lane]);
// `ok` loses the lanes behind the camera.
[[gnu::always_inline]] inline void ProjectLanes(const Registration& g, const float* pose, Int8 offset, Float8 px, Float8 py, Float8 z,
                         Float8& u, Float8& v, Int8& ok) {
  Float8 r[12];
  // One pose for all lanes (a row of pixels lands in one band of rows but near its edges).
  bool same = true;
  for (int k = 1; k < 8; ++k) same = same && offset[k] == offset[0];
  for (int i = 0; i < 12; ++i) {
    r[i] = same ? internal::Splat8(pose[offset[0] + i]) : internal::Gather8(pose + i, offset);
  }
  const Float8 x = r[0] * px + r[1] * py + r[2] * z + r[9];
  const Float8 y = r[3] * px + r[4] * py + r[5] * z + r[10];
  const Float8 w = r[6] * px + r[7] * py + r[8] * z + r[11];
  ok &= w > 0;
  // Lanes behind the camera divide by a safe 1 (their values are not used).
  const Float8 inv_z = 1.0f / internal::Select8(ok, w, internal::Splat8(1.0f));
  u = g.fx * x * inv_z + g.cx;
  v = g.fy * y * inv_z + g.cy;
}

// BandOf on eight lanes; 0 where not ok and where the row is NaN, as there.
[[gnu::always_inline]] inline Int8 BandsOf(const Registration& g, Float8 row, Int8 ok) {
  Float8 b = (row + 0.5f) * static_cast<float>(g.num_bands) / g.rows;
  b = b < 0.0f ? internal::Splat8(0.0f) : b;
  const float last = static_cast<float>(g.num_bands - 1);
  b = b > last ? internal::Splat8(last) : b;
  return __builtin_convertvector(internal::Masked8(b, ok & (b == b)), Int8);
}

// A row of depth pixels (y: its row, ray_y its unprojected y at depth 1): eight pixels at a
// time, GreyOfPixel's operations in its order lane by lane, then the rest per pixel. Lanes a
// pixel would leave early (no depth, behind a camera) are masked instead; samples outside
// the colour image add +0 where GreyOfPixel skips them (the same sum: it is never −0).
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void RegisterRow(
    const Registration& g, const float* depth_row, float ray_y, int width, float* grey_row) {
  int x = 0;
  for (; x + 8 <= width; x += 8) {
    const Float8 z = internal::Load8(depth_row + x);
    Int8 ok = (z > 0) & (z != std::numeric_limits<float>::infinity());
    if (!(ok[0] | ok[1] | ok[2] | ok[3] | ok[4] | ok[5] | ok[6] | ok[7])) continue;
    const Float8 xs = Float8{0, 1, 2, 3, 4, 5, 6, 7} + static_cast<float>(x);
    // Lanes without depth compute on a safe depth of 1 m (masked out).
    const Float8 zs = internal::Select8(ok, z, internal::Splat8(1.0f));
    const Float8 px = (xs - g.depth_cx) * g.inv_fx * zs, py = ray_y * zs;
    Float8 u, v;
    ProjectLanes(g, g.centre, Int8{}, px, py, zs, u, v, ok);
    if (g.bands != nullptr) {
      const Int8 k = BandsOf(g, v, ok);
      ProjectLanes(g, g.bands, 12 * k, px, py, zs, u, v, ok);
      const Int8 k2 = BandsOf(g, v, ok);
      const Int8 moved = ok & (k2 != k);
      if (moved[0] | moved[1] | moved[2] | moved[3] | moved[4] | moved[5] | moved[6] | moved[7]) {
        Float8 u2, v2;
        Int8 ok2 = moved;
        ProjectLanes(g, g.bands, 12 * k2, px, py, zs, u2, v2, ok2);
        u = internal::Select8(moved, u2, u);
        v = internal::Select8(moved, v2, v);
        ok &= ~moved | ok2;
      }
    }
    Float8 sum = {};
    for (int j = 0; j < g.n; ++j) {
      const Float8 sv = v + g.offset[j] * g.step_v;
      const Int8 row_ok = ok & (sv > -0.5f) & (sv < g.v_max);
      const Int8 row = __builtin_convertvector(internal::Masked8(sv + 0.5f, row_ok), Int8);
      for (int i = 0; i < g.n; ++i) {
        const Float8 su = u + g.offset[i] * g.step_u;
        const Int8 in = row_ok & (su > -0.5f) & (su < g.u_max);
        const Int8 col = __builtin_convertvector(internal::Masked8(su + 0.5f, in), Int8);
        const auto at = [&](int k) { return g.rgb + g.rgb_step * static_cast<size_t>(row[k]) + 3 * col[k]; };
        // One initialiser: lanes set one by one would go through the stack (float8.h).
        const Float8 luma = {Luma(at(0)), Luma(at(1)), Luma(at(2)), Luma(at(3)),
                             Luma(at(4)), Luma(at(5)), Luma(at(6)), Luma(at(7))};
        sum += internal::Masked8(luma, in);
      }
    }
    const Float8 grey = sum * g.scale;
    for (int k = 0; k < 8; ++k) {
      if (ok[k]) grey_row[x + k] = grey[k];
    }
  }
  for (; x < width; ++x) {
    float grey = 0;
    if (GreyOfPixel(g, static_cast<float>(x), ray_y, depth_row[x], grey)) grey_row[x] = grey;
  }
}

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
  // A fine pixel's footprint in the colour image, px (both cameras pinhole: the ratio of
  // focal lengths, over the fine pixels per coarse one), and the samples' offsets from the
  // coarse pixel's centre: fine pixel i's centre lies (i + 0.5 − n/2) fine pixels from it.
  const int n = samples_per_side;
  std::vector<float> offset(n);
  for (int i = 0; i < n; ++i) offset[i] = static_cast<float>(i) + 0.5f - 0.5f * static_cast<float>(n);
  Registration g;
  g.depth_cx = depth_camera.cx;
  g.depth_cy = depth_camera.cy;
  g.inv_fx = 1.0f / depth_camera.fx;
  g.inv_fy = 1.0f / depth_camera.fy;
  g.fx = rgb_camera.fx;
  g.fy = rgb_camera.fy;
  g.cx = rgb_camera.cx;
  g.cy = rgb_camera.cy;
  g.u_max = rgb_camera.width - 0.5f;
  g.v_max = rgb_camera.height - 0.5f;
  g.n = n;
  g.offset = offset.data();
  g.step_u = rgb_camera.fx / (depth_camera.fx * static_cast<float>(n));
  g.step_v = rgb_camera.fy / (depth_camera.fy * static_cast<float>(n));
  g.scale = 1.0f / (255.0f * static_cast<float>(n * n));
  g.rgb = rgb.ptr<std::uint8_t>(0);
  g.rgb_step = rgb.step[0];
  g.rows = static_cast<float>(rgb_camera.height);
  const auto pose_floats = [](const core::Rigid3d& pose, float* out) {
    const Eigen::Matrix3f r = pose.rotation.toRotationMatrix().cast<float>();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) out[3 * i + j] = r(i, j);
      out[9 + i] = static_cast<float>(pose.translation(i));
    }
  };
  pose_floats(rgb_from_depth, g.centre);
  // The colour camera per band of rows (one pose when it has a global shutter): row v was
  // exposed readout_s·(v − (H − 1)/2)/H after the frame's time.
  std::vector<float> bands;
  if (readout_s > 0 && rgb_from_depth_at != nullptr) {
    g.num_bands = kColourBands;
    bands.resize(12 * kColourBands);
    for (int k = 0; k < kColourBands; ++k) {
      pose_floats(rgb_from_depth_at(BandOffsetS(k, kColourBands, rgb_camera.height, readout_s)), &bands[12 * k]);
    }
    g.bands = bands.data();
  }
  ForEachBand(depth_m.rows, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      RegisterRow(g, depth_m.ptr<float>(y), (static_cast<float>(y) - depth_camera.cy) * g.inv_fy, depth_m.cols,
                  grey.ptr<float>(y));
    }
  });
  return grey;
}

}  // namespace hw::reconstruct
