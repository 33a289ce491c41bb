#include "core/depth_correction.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include "core/strings.h"

namespace hw::core {

namespace {

// Below this, 1 − z·δ sends the point 20× farther than measured or past infinity: such a
// correction is not one the field was fitted to, so the pixel is dropped, not moved.
constexpr double kMinDenominator = 0.05;

std::string RangeCheck(const char* name, const std::array<double, 2>& range) {
  if (!std::isfinite(range[0]) || !std::isfinite(range[1]) || !(range[0] < range[1]) ||
      std::abs(range[0]) > DepthCorrection::kMaxAbsRange ||
      std::abs(range[1]) > DepthCorrection::kMaxAbsRange) {
    return StringPrintf("%s: must be [lo, hi] with -10 <= lo < hi <= 10, got [%g, %g]", name,
                        range[0], range[1]);
  }
  return "";
}

}  // namespace

std::string DepthCorrection::Check() const {
  if (nx < kMinNodes || nx > kMaxNodes) {
    return StringPrintf("nx: must be in [%d, %d], got %d", kMinNodes, kMaxNodes, nx);
  }
  if (ny < kMinNodes || ny > kMaxNodes) {
    return StringPrintf("ny: must be in [%d, %d], got %d", kMinNodes, kMaxNodes, ny);
  }
  if (std::string problem = RangeCheck("x_range", x_range); !problem.empty()) return problem;
  if (std::string problem = RangeCheck("y_range", y_range); !problem.empty()) return problem;
  if (offset_per_m.size() != static_cast<size_t>(nx) * ny) {
    return StringPrintf("offset_per_m: must hold nx*ny = %d values, got %zu", nx * ny,
                        offset_per_m.size());
  }
  for (size_t i = 0; i < offset_per_m.size(); ++i) {
    if (!std::isfinite(offset_per_m[i]) || std::abs(offset_per_m[i]) > kMaxAbsOffsetPerM) {
      return StringPrintf("offset_per_m[%zu]: must be finite with |value| <= %g 1/m, got %g", i,
                          kMaxAbsOffsetPerM, offset_per_m[i]);
    }
  }
  if (plate_affine_per_m) {
    for (int i = 0; i < 3; ++i) {
      const double v = (*plate_affine_per_m)[i];
      if (!std::isfinite(v) || std::abs(v) > kMaxAbsOffsetPerM) {
        return StringPrintf("plate_affine_per_m[%d]: must be finite with |value| <= %g 1/m, got %g", i,
                            kMaxAbsOffsetPerM, v);
      }
    }
  }
  return "";
}

DepthCorrection::Stencil DepthCorrection::StencilAt(double x, double y) const {
  const double gx = std::clamp((x - x_range[0]) / (x_range[1] - x_range[0]) * (nx - 1), 0.0,
                               static_cast<double>(nx - 1));
  const double gy = std::clamp((y - y_range[0]) / (y_range[1] - y_range[0]) * (ny - 1), 0.0,
                               static_cast<double>(ny - 1));
  const int ix = std::min(static_cast<int>(gx), nx - 2);
  const int iy = std::min(static_cast<int>(gy), ny - 2);
  const double fx = gx - ix, fy = gy - iy;
  const int k = iy * nx + ix;
  return {{k, k + 1, k + nx, k + nx + 1},
          {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy}};
}

double DepthCorrection::RmsPerM() const {
  if (offset_per_m.empty()) return 0;
  double sum = 0;
  for (const double v : offset_per_m) sum += v * v;
  return std::sqrt(sum / static_cast<double>(offset_per_m.size()));
}

void DepthCorrection::AddAffine(double a_per_m, double c_x_per_m, double c_y_per_m) {
  assert(offset_per_m.size() == static_cast<size_t>(nx) * ny);
  for (int iy = 0; iy < ny; ++iy) {
    for (int ix = 0; ix < nx; ++ix) {
      const auto [x, y] = NodePosition(ix, iy);
      offset_per_m[static_cast<size_t>(iy) * nx + ix] += a_per_m + c_x_per_m * x + c_y_per_m * y;
    }
  }
}

double DepthCorrection::OffsetAt(double x, double y) const {
  assert(offset_per_m.size() == static_cast<size_t>(nx) * ny);
  const Stencil st = StencilAt(x, y);
  double offset = 0;
  for (int k = 0; k < 4; ++k) offset += st.weight[k] * offset_per_m[st.node[k]];
  return offset;
}

double DepthCorrection::Correct(double z_m, double x, double y) const {
  if (!(z_m > 0)) return 0;
  const double denominator = 1 - z_m * OffsetAt(x, y);
  return denominator > kMinDenominator ? z_m / denominator : 0;
}

DepthCorrection DepthCorrection::ZeroOver(const CameraModel& camera, int nx, int ny) {
  assert(nx >= kMinNodes && nx <= kMaxNodes && ny >= kMinNodes && ny <= kMaxNodes);
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo;
  double y_lo = x_lo, y_hi = -x_lo;
  const auto extend = [&](double u, double v) {
    const std::optional<Eigen::Vector3d> ray = camera.Unproject({u, v});
    assert(ray.has_value());
    x_lo = std::min(x_lo, ray->x());
    x_hi = std::max(x_hi, ray->x());
    y_lo = std::min(y_lo, ray->y());
    y_hi = std::max(y_hi, ray->y());
  };
  // Distortion can bow the borders outwards: walk all four, not only the corners.
  const double u_max = camera.width - 0.5, v_max = camera.height - 0.5;
  for (int i = 0; i <= camera.width; ++i) {
    extend(i - 0.5, -0.5);
    extend(i - 0.5, v_max);
  }
  for (int j = 0; j <= camera.height; ++j) {
    extend(-0.5, j - 0.5);
    extend(u_max, j - 0.5);
  }
  DepthCorrection correction;
  correction.nx = nx;
  correction.ny = ny;
  correction.x_range = {x_lo, x_hi};
  correction.y_range = {y_lo, y_hi};
  correction.offset_per_m.assign(static_cast<size_t>(nx) * ny, 0.0);
  return correction;
}

cv::Mat DepthOffsetMap(const DepthCorrection& correction, const CameraModel& camera) {
  cv::Mat map(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
  for (int v = 0; v < camera.height; ++v) {
    float* row = map.ptr<float>(v);
    for (int u = 0; u < camera.width; ++u) {
      const std::optional<Eigen::Vector3d> ray = camera.Unproject({double(u), double(v)});
      if (ray) row[u] = static_cast<float>(correction.OffsetAt(ray->x(), ray->y()));
    }
  }
  return map;
}

void CorrectDepth(const cv::Mat& offset_map_per_m, cv::Mat* depth_m) {
  assert(depth_m != nullptr && depth_m->type() == CV_32FC1 &&
         offset_map_per_m.type() == CV_32FC1 && depth_m->size() == offset_map_per_m.size());
  for (int v = 0; v < depth_m->rows; ++v) {
    float* z = depth_m->ptr<float>(v);
    const float* delta = offset_map_per_m.ptr<float>(v);
    for (int u = 0; u < depth_m->cols; ++u) {
      if (!(z[u] > 0) || !std::isfinite(z[u])) continue;
      const float denominator = 1.0f - z[u] * delta[u];
      z[u] = denominator > static_cast<float>(kMinDenominator) ? z[u] / denominator : 0.0f;
    }
  }
}

}  // namespace hw::core
