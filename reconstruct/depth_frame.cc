#include "reconstruct/depth_frame.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "reconstruct/float8.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {
namespace {

std::string Fail(const char* field, double value, const char* constraint) {
  std::ostringstream s;
  s << field << ": must be " << constraint << ", got " << value;
  return s.str();
}

// The bilateral's range weight of t² = (dz / sigma)²: (1 − t²/32)^16, within 0.02 of
// KinectFusion's exp(−t²/2) and cheap (four squarings, no exp, no table, no branch), cut to 0
// beyond 3 sigma (where the Gaussian is < 0.011).
constexpr float kRangeCutoffSq = 9.0f;
inline float RangeWeight(float t_sq) {
  float a = 1.0f - t_sq * (1.0f / 32.0f);
  a *= a;
  a *= a;
  a *= a;
  return a * a;
}

// Eight floats at a time (reconstruct/float8.h): the per-pixel loops below, which -O2 does
// not vectorise by itself, cloned for AVX2 and AVX-512.
using internal::Abs8;
using internal::Float8;
using internal::Int8;
using internal::Load8;
using internal::LoadTriples8;
using internal::Masked8;
using internal::Select8;
using internal::Splat8;
using internal::Sqrt8;
using internal::Store8;
using internal::StoreTriples8;

// RangeWeight, with t² clamped to the cutoff so that masked-off lanes stay finite.
inline Float8 RangeWeight8(Float8 t_sq) {
  const Float8 cutoff = Splat8(kRangeCutoffSq);
  const Float8 clamped = t_sq < cutoff ? t_sq : cutoff;
  Float8 a = 1.0f - clamped * (1.0f / 32.0f);
  a *= a;
  a *= a;
  a *= a;
  return a * a;
}

// One window offset of the bilateral over pixels [x_begin, x_end) of a row: the pair of
// neighbours a[x] and b[x] (mirror images through the centre c[x]) adds its weights and
// weighted depths to sum_w and sum_wz when both are valid and within the range cutoff.
// Every pixel gets the same operations in the same order whether it falls in a vector or
// in the scalar tail, and in every clone: the result does not depend on the CPU.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void AddPairs(
    const float* c, const float* a, const float* b, const float* inv_sigma, float weight,
    int x_begin, int x_end, float* sum_w, float* sum_wz) {
  const Float8 weight8 = Splat8(weight);
  int x = x_begin;
  for (; x + 8 <= x_end; x += 8) {
    const Float8 z = Load8(c + x), za = Load8(a + x), zb = Load8(b + x);
    const Float8 inv = Load8(inv_sigma + x);
    const Float8 ta = (za - z) * inv, tb = (zb - z) * inv;
    const Float8 ta_sq = ta * ta, tb_sq = tb * tb;
    // Both valid and on this side of any edge, or neither counts.
    const Int8 pair = (za > 0) & (zb > 0) & (ta_sq < kRangeCutoffSq) & (tb_sq < kRangeCutoffSq);
    const Float8 wa = Masked8(weight8 * RangeWeight8(ta_sq), pair);
    const Float8 wb = Masked8(weight8 * RangeWeight8(tb_sq), pair);
    Store8(sum_w + x, Load8(sum_w + x) + wa + wb);
    Store8(sum_wz + x, Load8(sum_wz + x) + wa * za + wb * zb);
  }
  for (; x < x_end; ++x) {
    const float z = c[x], za = a[x], zb = b[x];
    const float ta = (za - z) * inv_sigma[x], tb = (zb - z) * inv_sigma[x];
    const float ta_sq = ta * ta, tb_sq = tb * tb;
    if (!(za > 0 && zb > 0 && ta_sq < kRangeCutoffSq && tb_sq < kRangeCutoffSq)) continue;
    const float wa = weight * RangeWeight(ta_sq), wb = weight * RangeWeight(tb_sq);
    sum_w[x] = sum_w[x] + wa + wb;  // the vector loop's order of additions
    sum_wz[x] = sum_wz[x] + wa * za + wb * zb;
  }
}

// dst[x] = src[x] where it lies in [min_m, max_m] and is > 0, else 0 (NaN fails the
// comparisons), eight at a time; the same result in every clone.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void RangeLimitedRow(
    const float* src, int w, float min_m, float max_m, float* dst) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const Float8 z = Load8(src + x);
    Store8(dst + x, Masked8(z, (z >= min_m) & (z <= max_m) & (z > 0)));
  }
  for (; x < w; ++x) {
    const float z = src[x];
    dst[x] = (z >= min_m && z <= max_m && z > 0) ? z : 0.0f;
  }
}

// One row of the flying-pixel test: dst[x] = row[x], or 0 where a valid 4-neighbour
// (row[x ± 1], up[x], down[x]; 0 is missing, as beyond the border) lies more than
// fraction · row[x] away. Rows range-limited (≥ 0). Eight at a time inside the row, the
// ends scalar: the same comparisons, so the same result in every clone.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void EdgeCleanedRow(
    const float* up, const float* row, const float* down, int w, float fraction, float* dst) {
  const auto scalar = [&](int x) {
    const float z = row[x];
    const float limit = fraction * z;
    auto jumps = [&](float n) { return n > 0 && std::abs(n - z) > limit; };
    const bool jump = (x > 0 && jumps(row[x - 1])) || (x + 1 < w && jumps(row[x + 1])) ||
                      jumps(up[x]) || jumps(down[x]);
    dst[x] = z > 0 && jump ? 0.0f : z;
  };
  if (w == 0) return;
  scalar(0);
  int x = 1;
  for (; x + 9 <= w; x += 8) {
    const Float8 z = Load8(row + x);
    const Float8 limit = fraction * z;
    auto jumps = [&](Float8 n) { return (n > 0) & (Abs8(n - z) > limit); };
    const Int8 jump = jumps(Load8(row + x - 1)) | jumps(Load8(row + x + 1)) | jumps(Load8(up + x)) |
                      jumps(Load8(down + x));
    // z == 0 stays 0 either way.
    Store8(dst + x, Masked8(z, ~jump));
  }
  for (; x < w; ++x) scalar(x);
}

// A bilateral row's start: the inverse range sigma of each centre (0 where it is missing)
// and the centre's own weight (spatial and range weights 1). Eight at a time; the same
// operations in every clone.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void BilateralRowStart(
    const float* c, int w, float sigma_depth, float* inv_sigma, float* sum_w, float* sum_wz) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const Float8 z = Load8(c + x);
    Store8(inv_sigma + x, Masked8(1.0f / (sigma_depth * z * z), z > 0));
    Store8(sum_w + x, Splat8(1.0f));
    Store8(sum_wz + x, z);
  }
  for (; x < w; ++x) {
    const float z = c[x];
    inv_sigma[x] = z > 0 ? 1.0f / (sigma_depth * z * z) : 0.0f;
    sum_w[x] = 1;
    sum_wz[x] = z;
  }
}

// A bilateral row's end: the weighted mean where the centre is valid, else 0.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void BilateralRowEnd(
    const float* c, const float* sum_w, const float* sum_wz, int w, float* dst) {
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    Store8(dst + x, Masked8(Load8(sum_wz + x) / Load8(sum_w + x), Load8(c + x) > 0));
  }
  for (; x < w; ++x) dst[x] = c[x] > 0 ? sum_wz[x] / sum_w[x] : 0.0f;
}

// Range limits and flying pixels in one pass over the image: depths outside [min, max] (and
// NaN, inf, negatives) become 0, and so does a valid pixel with a valid (range-limited)
// 4-neighbour more than `fraction` of its depth away (fraction >= 1: none is dropped).
cv::Mat RangeLimitedAndEdgeCleaned(const cv::Mat& depth_m, float min_m, float max_m,
                                   float fraction, int num_threads) {
  cv::Mat out(depth_m.size(), CV_32FC1);
  const int w = depth_m.cols, h = depth_m.rows;
  const bool clean = fraction < 1;
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    std::vector<float> rows[3];  // range-limited rows y - 1, y, y + 1 (0 beyond the image)
    for (auto& r : rows) r.assign(size_t(w), 0.0f);
    auto load = [&](std::vector<float>& dst, int y) {
      if (y < 0 || y >= h) {
        std::fill(dst.begin(), dst.end(), 0.0f);
        return;
      }
      RangeLimitedRow(depth_m.ptr<float>(y), w, min_m, max_m, dst.data());
    };
    load(rows[0], y0 - 1);
    load(rows[1], y0);
    for (int y = y0; y < y1; ++y) {
      load(rows[2], y + 1);
      const float* up = rows[0].data();
      const float* row = rows[1].data();
      const float* down = rows[2].data();
      float* dst = out.ptr<float>(y);
      // A missing neighbour (0, or beyond the border) never counts as a jump.
      if (clean) {
        EdgeCleanedRow(up, row, down, w, fraction, dst);
      } else {
        std::copy_n(row, w, dst);
      }
      std::swap(rows[0], rows[1]);
      std::swap(rows[1], rows[2]);
    }
  });
  return out;
}

// KinectFusion's bilateral filter over valid pixels (invalid centres stay 0), with symmetric
// support: a neighbour counts only together with its mirror image through the centre. A
// window cut on one side (image border, hole, depth edge) would otherwise average a slanted
// surface's depth off-centre, a first-order bias of the depth gradient (mm to cm per pixel on
// a wall seen at a grazing angle) that shifts ICP's estimate; pairs cancel it to second order.
// Computed a row at a time, one window offset at a time, branch-free in the inner loop.
cv::Mat Bilateral(const cv::Mat& depth_m, const DepthFilterOptions& options) {
  const int r = options.bilateral_radius_px;
  if (r == 0) return depth_m.clone();
  const int w = depth_m.cols, h = depth_m.rows;
  // Half of the window: offsets (dx, dy) with dy > 0, or dy == 0 and dx > 0; their mirrors
  // (-dx, -dy) make up the other half.
  struct Offset {
    int dx, dy;
    float weight;
  };
  std::vector<Offset> half;
  const double inv_two_sigma_sq =
      1.0 / (2.0 * options.bilateral_sigma_px * options.bilateral_sigma_px);
  for (int dy = 0; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      if (dy == 0 && dx <= 0) continue;
      half.push_back(
          {dx, dy, static_cast<float>(std::exp(-(dx * dx + dy * dy) * inv_two_sigma_sq))});
    }
  }
  const float sigma_depth = static_cast<float>(options.bilateral_sigma_depth_m);
  cv::Mat out(depth_m.size(), CV_32FC1);
  ForEachBand(h, options.num_threads, [&](int y0, int y1) {
    std::vector<float> sum_w(w), sum_wz(w), inv_sigma(w);
    for (int y = y0; y < y1; ++y) {
      const float* c = depth_m.ptr<float>(y);
      BilateralRowStart(c, w, sigma_depth, inv_sigma.data(), sum_w.data(), sum_wz.data());
      for (const Offset& o : half) {
        if (y + o.dy >= h || y - o.dy < 0) continue;  // the pair needs both rows
        const float* a = depth_m.ptr<float>(y + o.dy) + o.dx;
        const float* b = depth_m.ptr<float>(y - o.dy) - o.dx;
        const int reach = std::abs(o.dx);
        AddPairs(c, a, b, inv_sigma.data(), o.weight, reach, w - reach, sum_w.data(),
                 sum_wz.data());
      }
      BilateralRowEnd(c, sum_w.data(), sum_wz.data(), w, out.ptr<float>(y));
    }
  });
  return out;
}

// KinectFusion's pyramid step: the mean of each 2×2 block over the pixels within 3 range
// sigmas of the block's first valid pixel, so that a block straddling an edge takes one side.
cv::Mat HalfDepth(const cv::Mat& depth_m, float sigma_depth_m, int num_threads) {
  const int w = depth_m.cols / 2, h = depth_m.rows / 2;
  cv::Mat out(h, w, CV_32FC1);
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* top = depth_m.ptr<float>(2 * y);
      const float* bottom = depth_m.ptr<float>(2 * y + 1);
      float* dst = out.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        const float block[4] = {top[2 * x], top[2 * x + 1], bottom[2 * x], bottom[2 * x + 1]};
        float first = 0;
        for (float z : block) {
          if (z > 0) {
            first = z;
            break;
          }
        }
        if (first == 0) {
          dst[x] = 0;
          continue;
        }
        const float limit = 3.0f * sigma_depth_m * first * first;
        float sum = 0;
        int n = 0;
        for (float z : block) {
          if (z > 0 && std::abs(z - first) <= limit) {
            sum += z;
            ++n;
          }
        }
        dst[x] = sum / static_cast<float>(n);
      }
    }
  });
  return out;
}

// One row of MapOf's normals (NaN where none), from the row's points and the rows above
// and below (nullptr beyond the image), all packed float triples with NaN where missing:
// the cross product of central differences, one-sided where a neighbour is missing or
// jumps by more than max_jump_fraction of the depth, oriented towards the camera. Eight
// pixels at a time inside the row when both neighbouring rows exist, the rest per pixel:
// the same operations either way, so the same result in every clone.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void NormalsRow(
    const float* up, const float* row, const float* down, int w, float max_jump_fraction, float* normals) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const auto scalar = [&](int x) {
    const float* p = row + 3 * x;
    const float z = p[2];
    normals[3 * x] = normals[3 * x + 1] = normals[3 * x + 2] = nan;  // unless computed below
    if (std::isnan(z)) return;
    const float limit = max_jump_fraction * z;
    // A neighbour is usable when valid (NaN fails the test) and within the jump limit.
    const float* right = x + 1 < w ? p + 3 : nullptr;
    const float* left = x > 0 ? p - 3 : nullptr;
    const float* below = down != nullptr ? down + 3 * x : nullptr;
    const float* above = up != nullptr ? up + 3 * x : nullptr;
    if (right != nullptr && !(std::abs(right[2] - z) <= limit)) right = nullptr;
    if (left != nullptr && !(std::abs(left[2] - z) <= limit)) left = nullptr;
    if (below != nullptr && !(std::abs(below[2] - z) <= limit)) below = nullptr;
    if (above != nullptr && !(std::abs(above[2] - z) <= limit)) above = nullptr;
    // Central differences, one-sided where a side is missing.
    if (right == nullptr && left == nullptr) return;
    if (below == nullptr && above == nullptr) return;
    const float* a = right != nullptr ? right : p;
    const float* b = left != nullptr ? left : p;
    const float* c = below != nullptr ? below : p;
    const float* d = above != nullptr ? above : p;
    const float ux = a[0] - b[0], uy = a[1] - b[1], uz = a[2] - b[2];
    const float vx = c[0] - d[0], vy = c[1] - d[1], vz = c[2] - d[2];
    const float nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    const float norm_sq = nx * nx + ny * ny + nz * nz;
    if (!(norm_sq > 0)) return;
    // Towards the camera: n · p < 0.
    const float scale = (nx * p[0] + ny * p[1] + nz * z > 0 ? -1.0f : 1.0f) / std::sqrt(norm_sq);
    normals[3 * x] = nx * scale;
    normals[3 * x + 1] = ny * scale;
    normals[3 * x + 2] = nz * scale;
  };
  int x = 0;
  if (up != nullptr && down != nullptr && w > 0) {
    scalar(0);
    for (x = 1; x + 9 <= w; x += 8) {
      Float8 p[3], right[3], left[3], below[3], above[3];
      LoadTriples8(row + 3 * x, p);
      LoadTriples8(row + 3 * (x + 1), right);
      LoadTriples8(row + 3 * (x - 1), left);
      LoadTriples8(down + 3 * x, below);
      LoadTriples8(up + 3 * x, above);
      const Float8 z = p[2];
      const Float8 limit = max_jump_fraction * z;
      // Usable neighbours (a NaN depth, own or the neighbour's, fails the test).
      const Int8 has_right = Abs8(right[2] - z) <= limit, has_left = Abs8(left[2] - z) <= limit;
      const Int8 has_below = Abs8(below[2] - z) <= limit, has_above = Abs8(above[2] - z) <= limit;
      Float8 u[3], v[3];
      for (int k = 0; k < 3; ++k) {
        u[k] = Select8(has_right, right[k], p[k]) - Select8(has_left, left[k], p[k]);
        v[k] = Select8(has_below, below[k], p[k]) - Select8(has_above, above[k], p[k]);
      }
      const Float8 nx = u[1] * v[2] - u[2] * v[1], ny = u[2] * v[0] - u[0] * v[2],
                   nz = u[0] * v[1] - u[1] * v[0];
      const Float8 norm_sq = nx * nx + ny * ny + nz * nz;
      const Int8 ok = (z == z) & (has_right | has_left) & (has_below | has_above) & (norm_sq > 0);
      const Float8 sign = Select8(nx * p[0] + ny * p[1] + nz * z > 0, Splat8(-1.0f), Splat8(1.0f));
      const Float8 scale = sign / Sqrt8(norm_sq);
      const Float8 n[3] = {Select8(ok, nx * scale, Splat8(nan)), Select8(ok, ny * scale, Splat8(nan)),
                           Select8(ok, nz * scale, Splat8(nan))};
      StoreTriples8(n, normals + 3 * x);
    }
  }
  for (; x < w; ++x) scalar(x);
}

// Points by unprojection, normals from the cross product of central differences (one-sided
// where a neighbour is missing or jumps), oriented towards the camera.
PointMap MapOf(const cv::Mat& depth_m, const PinholeCamera& camera, float max_jump_fraction,
               int num_threads) {
  const int w = depth_m.cols, h = depth_m.rows;
  // Not PointMap(w, h): its NaN fill would write both maps once more; every pixel is written
  // below (Eigen vectors are left uninitialised by resize).
  PointMap map;
  map.width = w;
  map.height = h;
  map.points.resize(size_t(w) * h);
  map.normals.resize(size_t(w) * h);
  const float inv_fx = 1.0f / camera.fx, inv_fy = 1.0f / camera.fy;
  const Eigen::Vector3f invalid = InvalidPoint();
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* row = depth_m.ptr<float>(y);
      Eigen::Vector3f* points = map.points.data() + map.Index(0, y);
      for (int x = 0; x < w; ++x) {
        const float z = row[x];
        points[x] =
            z > 0 ? Eigen::Vector3f((x - camera.cx) * inv_fx * z, (y - camera.cy) * inv_fy * z, z)
                  : invalid;
      }
    }
  });
  // Normals read the neighbouring rows' points: a second pass after all points exist.
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* up = y > 0 ? map.points[map.Index(0, y - 1)].data() : nullptr;
      const float* down = y + 1 < h ? map.points[map.Index(0, y + 1)].data() : nullptr;
      NormalsRow(up, map.points[map.Index(0, y)].data(), down, w, max_jump_fraction,
                 map.normals[map.Index(0, y)].data());
    }
  });
  return map;
}

// Rec. 601 luma of an RGB image, in [0, 1].
cv::Mat Grey(const cv::Mat& rgb, int num_threads) {
  cv::Mat out(rgb.size(), CV_32FC1);
  ForEachBand(rgb.rows, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const std::uint8_t* src = rgb.ptr<std::uint8_t>(y);
      float* dst = out.ptr<float>(y);
      for (int x = 0; x < rgb.cols; ++x) {
        dst[x] = (0.299f * src[3 * x] + 0.587f * src[3 * x + 1] + 0.114f * src[3 * x + 2]) *
                 (1.0f / 255.0f);
      }
    }
  });
  return out;
}

// 2×2 block means.
cv::Mat HalfIntensity(const cv::Mat& intensity, int num_threads) {
  cv::Mat out(intensity.rows / 2, intensity.cols / 2, CV_32FC1);
  ForEachBand(out.rows, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* top = intensity.ptr<float>(2 * y);
      const float* bottom = intensity.ptr<float>(2 * y + 1);
      float* dst = out.ptr<float>(y);
      for (int x = 0; x < out.cols; ++x) {
        dst[x] = 0.25f * (top[2 * x] + top[2 * x + 1] + bottom[2 * x] + bottom[2 * x + 1]);
      }
    }
  });
  return out;
}

}  // namespace

Undistorter::Undistorter(const core::CameraModel& camera) : pinhole_(PinholeCamera::Of(camera)) {
  // A splined model with all controls 0 is still stereographic, never the identity.
  identity_ = camera.type == core::CameraModelType::kPinhole ||
              (camera.type == core::CameraModelType::kOpenCV &&
               std::all_of(camera.distortion.begin(), camera.distortion.end(),
                           [](double k) { return k == 0; }));
  if (identity_) return;
  map_x_.create(camera.height, camera.width, CV_32FC1);
  map_y_.create(camera.height, camera.width, CV_32FC1);
  for (int v = 0; v < camera.height; ++v) {
    float* mx = map_x_.ptr<float>(v);
    float* my = map_y_.ptr<float>(v);
    for (int u = 0; u < camera.width; ++u) {
      // The pinhole pixel's ray at z = 1, seen through the real lens.
      const Eigen::Vector3d ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      const Eigen::Vector2d distorted = camera.Project(ray);
      mx[u] = static_cast<float>(distorted.x());
      my[u] = static_cast<float>(distorted.y());
    }
  }
}

cv::Mat Undistorter::UndistortDepth(const cv::Mat& depth_m) const {
  assert(depth_m.type() == CV_32FC1);
  if (identity_) return depth_m;
  assert(depth_m.cols == pinhole_.width && depth_m.rows == pinhole_.height);
  cv::Mat out;
  // Nearest rounds the map to the closest pixel; outside the image: 0 = no depth.
  cv::remap(depth_m, out, map_x_, map_y_, cv::INTER_NEAREST, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

cv::Mat Undistorter::UndistortColour(const cv::Mat& rgb) const {
  assert(rgb.type() == CV_8UC3);
  if (identity_) return rgb;
  assert(rgb.cols == pinhole_.width && rgb.rows == pinhole_.height);
  cv::Mat out;
  cv::remap(rgb, out, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  return out;
}

std::string DepthFilterOptions::Check() const {
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) {
    return Fail("min_depth_m", min_depth_m, ">= 0 m and finite");
  }
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return Fail("max_depth_m", max_depth_m, "> min_depth_m m and finite");
  }
  if (bilateral_radius_px < 0 || bilateral_radius_px > 10) {
    return Fail("bilateral_radius_px", bilateral_radius_px, "in [0, 10] px");
  }
  if (!(bilateral_sigma_px > 0) || !std::isfinite(bilateral_sigma_px)) {
    return Fail("bilateral_sigma_px", bilateral_sigma_px, "> 0 px and finite");
  }
  if (!(bilateral_sigma_depth_m > 0) || !std::isfinite(bilateral_sigma_depth_m)) {
    return Fail("bilateral_sigma_depth_m", bilateral_sigma_depth_m, "> 0 m and finite");
  }
  if (!(edge_jump_fraction > 0 && edge_jump_fraction <= 1)) {
    return Fail("edge_jump_fraction", edge_jump_fraction, "in (0, 1]");
  }
  if (num_levels < 1 || num_levels > 5) return Fail("num_levels", num_levels, "in [1, 5]");
  if (!(normal_max_jump_fraction > 0 && normal_max_jump_fraction <= 1)) {
    return Fail("normal_max_jump_fraction", normal_max_jump_fraction, "in (0, 1]");
  }
  if (first_map_level < 0 || first_map_level >= num_levels) {
    return Fail("first_map_level", first_map_level, "in [0, num_levels)");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0 (0: hardware concurrency)");
  return "";
}

DepthPyramid BuildDepthPyramid(const cv::Mat& depth_m, const PinholeCamera& camera,
                               const DepthFilterOptions& options, const cv::Mat& rgb) {
  assert(options.Check().empty());
  assert(depth_m.type() == CV_32FC1);
  assert(depth_m.cols == camera.width && depth_m.rows == camera.height);
  DepthPyramid pyramid;
  // A fraction of 1 keeps all (the header's contract), though |dz| > z is possible.
  pyramid.raw_depth_m = RangeLimitedAndEdgeCleaned(
      depth_m, static_cast<float>(options.min_depth_m), static_cast<float>(options.max_depth_m),
      static_cast<float>(options.edge_jump_fraction), options.num_threads);
  const float normal_jump = static_cast<float>(options.normal_max_jump_fraction);
  pyramid.levels.reserve(options.num_levels);
  DepthLevel level0;
  level0.camera = camera;
  level0.depth_m = Bilateral(pyramid.raw_depth_m, options);
  if (options.first_map_level == 0) {
    level0.map = MapOf(level0.depth_m, camera, normal_jump, options.num_threads);
  }
  if (!rgb.empty()) {
    assert(rgb.type() == CV_8UC3 && rgb.cols == camera.width && rgb.rows == camera.height);
    level0.intensity = Grey(rgb, options.num_threads);
  }
  pyramid.levels.push_back(std::move(level0));
  for (int l = 1; l < options.num_levels; ++l) {
    const DepthLevel& above = pyramid.levels.back();
    if (above.depth_m.cols < 2 || above.depth_m.rows < 2) break;  // nothing left to halve
    DepthLevel level;
    level.camera = above.camera.Half();
    level.depth_m = HalfDepth(above.depth_m, static_cast<float>(options.bilateral_sigma_depth_m),
                              options.num_threads);
    if (l >= options.first_map_level) {
      level.map = MapOf(level.depth_m, level.camera, normal_jump, options.num_threads);
    }
    if (!above.intensity.empty()) level.intensity = HalfIntensity(above.intensity, options.num_threads);
    pyramid.levels.push_back(std::move(level));
  }
  return pyramid;
}

void SetIntensity(DepthPyramid& pyramid, const cv::Mat& grey, int first_level, int num_threads) {
  assert(first_level >= 0 && first_level < static_cast<int>(pyramid.levels.size()));
  assert(grey.type() == CV_32FC1 && grey.cols == pyramid.levels[first_level].camera.width &&
         grey.rows == pyramid.levels[first_level].camera.height);
  for (int l = 0; l < first_level; ++l) pyramid.levels[l].intensity.release();
  pyramid.levels[first_level].intensity = grey;
  for (size_t l = first_level + 1; l < pyramid.levels.size(); ++l) {
    pyramid.levels[l].intensity = HalfIntensity(pyramid.levels[l - 1].intensity, num_threads);
  }
}

}  // namespace hw::reconstruct
