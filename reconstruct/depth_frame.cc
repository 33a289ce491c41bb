#include "reconstruct/depth_frame.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "reconstruct/row_bands.h"

namespace hw::reconstruct {
namespace {

std::string Fail(const char* field, double value, const char* constraint) {
  std::ostringstream s;
  s << field << ": must be " << constraint << ", got " << value;
  return s.str();
}

// The bilateral's range weight exp(-t/2) of t = (dz / sigma)², tabulated on [0, 9): beyond
// 3 sigma the weight (< 0.011) is cut to 0. A table lookup instead of an exp per neighbour is
// what keeps the filter at a few ms per 640×480 frame; its step (9/2048) changes a weight by
// at most 0.0011.
constexpr int kRangeTableSize = 2048;
constexpr float kRangeCutoffSq = 9.0f;

struct RangeTable {
  std::array<float, kRangeTableSize + 1> weight{};
  RangeTable() {
    for (int i = 0; i <= kRangeTableSize; ++i) {
      const double t = (i + 0.5) * double(kRangeCutoffSq) / kRangeTableSize;
      weight[i] = static_cast<float>(std::exp(-0.5 * t));
    }
  }
};

const RangeTable& Table() {
  static const RangeTable table;
  return table;
}

// Range limits: depths outside [min, max] (and NaN, inf, negatives) become 0.
cv::Mat RangeLimited(const cv::Mat& depth_m, float min_m, float max_m) {
  cv::Mat out(depth_m.size(), CV_32FC1);
  for (int y = 0; y < depth_m.rows; ++y) {
    const float* src = depth_m.ptr<float>(y);
    float* dst = out.ptr<float>(y);
    for (int x = 0; x < depth_m.cols; ++x) {
      const float z = src[x];
      dst[x] = (z >= min_m && z <= max_m && z > 0) ? z : 0.0f;  // NaN fails the comparisons
    }
  }
  return out;
}

// Drops flying pixels: a valid pixel with a valid 4-neighbour more than `fraction` of its
// depth away.
cv::Mat EdgeCleaned(const cv::Mat& depth_m, float fraction, int num_threads) {
  cv::Mat out(depth_m.size(), CV_32FC1);
  const int w = depth_m.cols, h = depth_m.rows;
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* row = depth_m.ptr<float>(y);
      const float* up = y > 0 ? depth_m.ptr<float>(y - 1) : nullptr;
      const float* down = y + 1 < h ? depth_m.ptr<float>(y + 1) : nullptr;
      float* dst = out.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        const float z = row[x];
        dst[x] = z;
        if (z <= 0) continue;
        const float limit = fraction * z;
        auto jumps = [&](float n) { return n > 0 && std::abs(n - z) > limit; };
        if ((x > 0 && jumps(row[x - 1])) || (x + 1 < w && jumps(row[x + 1])) ||
            (up != nullptr && jumps(up[x])) || (down != nullptr && jumps(down[x]))) {
          dst[x] = 0;
        }
      }
    }
  });
  return out;
}

// KinectFusion's bilateral filter over valid pixels (invalid centres stay 0), with symmetric
// support: a neighbour counts only together with its mirror image through the centre. A
// window cut on one side (image border, hole, depth edge) would otherwise average a slanted
// surface's depth off-centre, a first-order bias of the depth gradient (mm to cm per pixel on
// a wall seen at a grazing angle) that shifts ICP's estimate; pairs cancel it to second order.
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
  const double inv_two_sigma_sq = 1.0 / (2.0 * options.bilateral_sigma_px * options.bilateral_sigma_px);
  for (int dy = 0; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      if (dy == 0 && dx <= 0) continue;
      half.push_back({dx, dy, static_cast<float>(std::exp(-(dx * dx + dy * dy) * inv_two_sigma_sq))});
    }
  }
  const float sigma_depth = static_cast<float>(options.bilateral_sigma_depth_m);
  const float table_scale = kRangeTableSize / kRangeCutoffSq;
  const float* range = Table().weight.data();
  const size_t step = depth_m.step1();
  cv::Mat out(depth_m.size(), CV_32FC1);
  ForEachBand(h, options.num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* centre_row = depth_m.ptr<float>(y);
      float* dst = out.ptr<float>(y);
      // Rows y ± r inside the image, and likewise columns: the interior needs no bounds test.
      const bool rows_inside = y >= r && y + r < h;
      for (int x = 0; x < w; ++x) {
        const float z = centre_row[x];
        if (z <= 0) {
          dst[x] = 0;
          continue;
        }
        const float inv_sigma = 1.0f / (sigma_depth * z * z);
        const bool inside = rows_inside && x >= r && x + r < w;
        const float* centre = centre_row + x;
        float sum_w = 1, sum_wz = z;  // the centre: spatial and range weights 1
        for (const Offset& o : half) {
          if (!inside && (x + o.dx < 0 || x + o.dx >= w || x - o.dx < 0 || x - o.dx >= w ||
                          y + o.dy >= h || y - o.dy < 0)) {
            continue;
          }
          const ptrdiff_t offset = ptrdiff_t(o.dy) * ptrdiff_t(step) + o.dx;
          const float za = centre[offset], zb = centre[-offset];
          const float ta = (za - z) * inv_sigma, tb = (zb - z) * inv_sigma;
          const float ta_sq = ta * ta, tb_sq = tb * tb;
          // Both valid and on this side of any edge, or neither counts.
          if (za <= 0 || zb <= 0 || ta_sq >= kRangeCutoffSq || tb_sq >= kRangeCutoffSq) continue;
          const float wa = o.weight * range[static_cast<int>(ta_sq * table_scale)];
          const float wb = o.weight * range[static_cast<int>(tb_sq * table_scale)];
          sum_w += wa + wb;
          sum_wz += wa * za + wb * zb;
        }
        dst[x] = sum_wz / sum_w;
      }
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

// Points by unprojection, normals from the cross product of central differences (one-sided
// where a neighbour is missing or jumps), oriented towards the camera.
PointMap MapOf(const cv::Mat& depth_m, const PinholeCamera& camera, float max_jump_fraction,
               int num_threads) {
  const int w = depth_m.cols, h = depth_m.rows;
  PointMap map(w, h);
  const float inv_fx = 1.0f / camera.fx, inv_fy = 1.0f / camera.fy;
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* row = depth_m.ptr<float>(y);
      Eigen::Vector3f* points = map.points.data() + map.Index(0, y);
      for (int x = 0; x < w; ++x) {
        const float z = row[x];
        if (z > 0) points[x] = {(x - camera.cx) * inv_fx * z, (y - camera.cy) * inv_fy * z, z};
      }
    }
  });
  // Normals read the neighbouring rows' points: a second pass after all points exist.
  ForEachBand(h, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      for (int x = 0; x < w; ++x) {
        const size_t i = map.Index(x, y);
        const Eigen::Vector3f& p = map.points[i];
        if (!IsValid(p)) continue;
        const float limit = max_jump_fraction * p.z();
        auto usable = [&](int nx, int ny) {
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) return false;
          const Eigen::Vector3f& q = map.points[map.Index(nx, ny)];
          return IsValid(q) && std::abs(q.z() - p.z()) <= limit;
        };
        auto difference = [&](int ax, int ay, int bx, int by, Eigen::Vector3f& d) {
          const bool a = usable(ax, ay), b = usable(bx, by);
          if (a && b) {
            d = map.points[map.Index(ax, ay)] - map.points[map.Index(bx, by)];
          } else if (a) {
            d = map.points[map.Index(ax, ay)] - p;
          } else if (b) {
            d = p - map.points[map.Index(bx, by)];
          } else {
            return false;
          }
          return true;
        };
        Eigen::Vector3f dx, dy;
        if (!difference(x + 1, y, x - 1, y, dx) || !difference(x, y + 1, x, y - 1, dy)) continue;
        Eigen::Vector3f n = dx.cross(dy);
        const float norm = n.norm();
        if (!(norm > 0)) continue;
        n /= norm;
        if (n.dot(p) > 0) n = -n;
        map.normals[i] = n;
      }
    }
  });
  return map;
}

}  // namespace

Undistorter::Undistorter(const core::CameraModel& camera) : pinhole_(PinholeCamera::Of(camera)) {
  identity_ = camera.type == core::CameraModelType::kPinhole ||
              std::all_of(camera.distortion.begin(), camera.distortion.end(),
                          [](double k) { return k == 0; });
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
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0 (0: hardware concurrency)");
  return "";
}

DepthPyramid BuildDepthPyramid(const cv::Mat& depth_m, const PinholeCamera& camera,
                               const DepthFilterOptions& options) {
  assert(options.Check().empty());
  assert(depth_m.type() == CV_32FC1);
  assert(depth_m.cols == camera.width && depth_m.rows == camera.height);
  DepthPyramid pyramid;
  pyramid.raw_depth_m = RangeLimited(depth_m, static_cast<float>(options.min_depth_m),
                                     static_cast<float>(options.max_depth_m));
  // A fraction of 1 keeps all (the header's contract), though |dz| > z is possible.
  if (options.edge_jump_fraction < 1) {
    pyramid.raw_depth_m = EdgeCleaned(pyramid.raw_depth_m,
                                      static_cast<float>(options.edge_jump_fraction),
                                      options.num_threads);
  }
  const float normal_jump = static_cast<float>(options.normal_max_jump_fraction);
  pyramid.levels.reserve(options.num_levels);
  DepthLevel level0;
  level0.camera = camera;
  level0.depth_m = Bilateral(pyramid.raw_depth_m, options);
  level0.map = MapOf(level0.depth_m, camera, normal_jump, options.num_threads);
  pyramid.levels.push_back(std::move(level0));
  for (int l = 1; l < options.num_levels; ++l) {
    const DepthLevel& above = pyramid.levels.back();
    if (above.depth_m.cols < 2 || above.depth_m.rows < 2) break;  // nothing left to halve
    DepthLevel level;
    level.camera = above.camera.Half();
    level.depth_m = HalfDepth(above.depth_m, static_cast<float>(options.bilateral_sigma_depth_m),
                              options.num_threads);
    level.map = MapOf(level.depth_m, level.camera, normal_jump, options.num_threads);
    pyramid.levels.push_back(std::move(level));
  }
  return pyramid;
}

}  // namespace hw::reconstruct
