#include "calibrate/lines_3d.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <utility>

#include <Eigen/Eigenvalues>

#include "core/option_check.h"

namespace hw::calibrate {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // towards the camera (n·p < 0)
  double offset = 0;                                  // n·p + offset = 0
  int pixels = 0;
  double Distance(const Eigen::Vector3d& p) const { return normal.dot(p) + offset; }
};

// Running sums for a PCA plane fit.
struct PlaneSums {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  int n = 0;
  void Add(const Eigen::Vector3d& p) {
    sum += p;
    outer += p * p.transpose();
    ++n;
  }
  std::optional<Plane> Fit() const {
    if (n < 3) return std::nullopt;
    const Eigen::Vector3d mean = sum / n;
    const Eigen::Matrix3d cov = outer / n - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    Plane plane;
    plane.normal = eig.eigenvectors().col(0);
    if (plane.normal.dot(mean) > 0) plane.normal = -plane.normal;
    plane.offset = -plane.normal.dot(mean);
    plane.pixels = n;
    return plane;
  }
};

class Frame {
 public:
  Frame(const cv::Mat& depth_m, const cv::Mat& rays, const DepthLineOptions& options)
      : w_(depth_m.cols), h_(depth_m.rows), options_(options) {
    points_.assign(static_cast<size_t>(w_) * h_, Eigen::Vector3d::Zero());
    valid_.assign(points_.size(), 0);
    for (int v = 0; v < h_; ++v) {
      for (int u = 0; u < w_; ++u) {
        const double z = static_cast<double>(depth_m.at<float>(v, u));
        const cv::Vec2f r = rays.at<cv::Vec2f>(v, u);
        if (!(z >= options.min_depth_m && z <= options.max_depth_m) || std::isnan(r[0])) continue;
        points_[Index(u, v)] = Eigen::Vector3d(static_cast<double>(r[0]) * z, static_cast<double>(r[1]) * z, z);
        valid_[Index(u, v)] = 1;
      }
    }
  }
  // Points averaged over a (2 radius + 1)² window of pixels on the same surface (no depth
  // jump from the centre): the normals' input. Structured-light depth is quantised (about
  // 1 cm steps at 2 m), which central differences of raw points turn into 10°+ normal noise.
  void Smooth(int radius) {
    smooth_.assign(points_.size(), Eigen::Vector3d::Zero());
    for (int v = 0; v < h_; ++v) {
      for (int u = 0; u < w_; ++u) {
        if (!valid_[Index(u, v)]) continue;
        const double z = Z(u, v);
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        int n = 0;
        for (int dv = -radius; dv <= radius; ++dv) {
          for (int du = -radius; du <= radius; ++du) {
            if (!Valid(u + du, v + dv) || !Continuous(z, Z(u + du, v + dv))) continue;
            sum += P(u + du, v + dv);
            ++n;
          }
        }
        smooth_[Index(u, v)] = sum / n;
      }
    }
  }
  const Eigen::Vector3d& S(int u, int v) const { return smooth_[Index(u, v)]; }
  int w() const { return w_; }
  int h() const { return h_; }
  int Index(int u, int v) const { return v * w_ + u; }
  bool Inside(int u, int v) const { return u >= 0 && v >= 0 && u < w_ && v < h_; }
  bool Valid(int u, int v) const { return Inside(u, v) && valid_[Index(u, v)]; }
  const Eigen::Vector3d& P(int u, int v) const { return points_[Index(u, v)]; }
  double Z(int u, int v) const { return points_[Index(u, v)].z(); }
  // Whether b is farther than a by a depth jump.
  bool JumpFarther(double za, double zb) const {
    return zb > za * (1 + options_.occlusion_jump_ratio) + 0.02;
  }
  bool Continuous(double za, double zb) const { return !JumpFarther(za, zb) && !JumpFarther(zb, za); }
  double Tolerance(double z) const {
    return options_.plane_distance_m + options_.plane_distance_per_m * z * z;
  }

 private:
  int w_, h_;
  const DepthLineOptions& options_;
  std::vector<Eigen::Vector3d> points_;
  std::vector<uint8_t> valid_;
  std::vector<Eigen::Vector3d> smooth_;
};

// Unit normals (NaN x where undefined) and a flatness score (residual of the four
// neighbours to the tangent plane, smaller is flatter).
void ComputeNormals(const Frame& f, int step, std::vector<Eigen::Vector3d>* normals,
                    std::vector<float>* flatness) {
  normals->assign(static_cast<size_t>(f.w()) * f.h(), Eigen::Vector3d::Constant(kNaN));
  flatness->assign(normals->size(), std::numeric_limits<float>::infinity());
  for (int v = step; v < f.h() - step; ++v) {
    for (int u = step; u < f.w() - step; ++u) {
      if (!f.Valid(u, v) || !f.Valid(u - step, v) || !f.Valid(u + step, v) || !f.Valid(u, v - step) ||
          !f.Valid(u, v + step)) {
        continue;
      }
      const double z = f.Z(u, v);
      if (!f.Continuous(z, f.Z(u - step, v)) || !f.Continuous(z, f.Z(u + step, v)) ||
          !f.Continuous(z, f.Z(u, v - step)) || !f.Continuous(z, f.Z(u, v + step))) {
        continue;
      }
      const Eigen::Vector3d dx = f.S(u + step, v) - f.S(u - step, v);
      const Eigen::Vector3d dy = f.S(u, v + step) - f.S(u, v - step);
      Eigen::Vector3d n = dx.cross(dy);
      if (n.norm() < 1e-12) continue;
      n.normalize();
      if (n.dot(f.P(u, v)) > 0) n = -n;
      // Flatness: how far the centre lies from the neighbours' mid points (curvature, fold).
      const double bend = std::abs(n.dot(f.S(u + step, v) + f.S(u - step, v) - 2 * f.S(u, v))) +
                          std::abs(n.dot(f.S(u, v + step) + f.S(u, v - step) - 2 * f.S(u, v)));
      (*normals)[f.Index(u, v)] = n;
      (*flatness)[f.Index(u, v)] = static_cast<float>(bend / z);
    }
  }
}

// Region growing into labels (-1 none) and the planes.
void GrowPlanes(const Frame& f, const std::vector<Eigen::Vector3d>& normals,
                const std::vector<float>& flatness, const DepthLineOptions& options,
                std::vector<int>* labels, std::vector<Plane>* planes) {
  const int n = f.w() * f.h();
  labels->assign(n, -1);
  std::vector<int> order;
  for (int i = 0; i < n; ++i) {
    if (std::isfinite(flatness[i])) order.push_back(i);
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return flatness[a] < flatness[b]; });
  const double cos_normal = std::cos(options.plane_normal_deg * kDegToRad);
  const int min_pixels = std::max(30, static_cast<int>(options.min_plane_fraction * n));
  std::vector<int> region, queue;
  std::vector<uint8_t> visited(n, 0);
  int next_label = 0;
  for (const int seed : order) {
    if ((*labels)[seed] >= 0 || visited[seed]) continue;
    Plane plane;
    plane.normal = normals[seed];
    plane.offset = -plane.normal.dot(f.P(seed % f.w(), seed / f.w()));
    PlaneSums sums;
    region.clear();
    queue.assign(1, seed);
    visited[seed] = 1;
    int next_refit = 64;
    for (size_t q = 0; q < queue.size(); ++q) {
      const int i = queue[q];
      const int u = i % f.w(), v = i / f.w();
      region.push_back(i);
      sums.Add(f.P(u, v));
      if (sums.n >= next_refit) {
        if (const auto fit = sums.Fit()) plane = *fit;
        next_refit *= 2;
      }
      static constexpr int kDu[4] = {1, -1, 0, 0}, kDv[4] = {0, 0, 1, -1};
      for (int k = 0; k < 4; ++k) {
        const int uu = u + kDu[k], vv = v + kDv[k];
        if (!f.Inside(uu, vv)) continue;
        const int j = f.Index(uu, vv);
        if (visited[j] || (*labels)[j] >= 0 || !std::isfinite(flatness[j])) continue;
        if (normals[j].dot(plane.normal) < cos_normal) continue;
        if (std::abs(plane.Distance(f.P(uu, vv))) > f.Tolerance(f.Z(uu, vv))) continue;
        visited[j] = 1;
        queue.push_back(j);
      }
    }
    // Pixels of a rejected region may seed or join another region later.
    for (const int i : region) visited[i] = 0;
    if (static_cast<int>(region.size()) < min_pixels) {
      for (const int i : region) visited[i] = 1;  // too small: not a seed again
      continue;
    }
    const auto fit = sums.Fit();
    if (!fit) continue;
    for (const int i : region) (*labels)[i] = next_label;
    planes->push_back(*fit);
    ++next_label;
  }
  // Dilation over the band without normals (and pixels left by the growing) that lies on
  // a neighbouring region's plane: regions then reach their folds and edges.
  const int passes = 2 * std::max(2, options.normal_step_px) + 2;
  for (int pass = 0; pass < passes; ++pass) {
    std::vector<std::pair<int, int>> adds;
    for (int v = 0; v < f.h(); ++v) {
      for (int u = 0; u < f.w(); ++u) {
        const int i = f.Index(u, v);
        if ((*labels)[i] >= 0 || !f.Valid(u, v)) continue;
        int best = -1;
        double best_d = f.Tolerance(f.Z(u, v));
        static constexpr int kDu[4] = {1, -1, 0, 0}, kDv[4] = {0, 0, 1, -1};
        for (int k = 0; k < 4; ++k) {
          const int uu = u + kDu[k], vv = v + kDv[k];
          if (!f.Inside(uu, vv)) continue;
          const int l = (*labels)[f.Index(uu, vv)];
          if (l < 0 || !f.Continuous(f.Z(u, v), f.Z(uu, vv))) continue;
          const double d = std::abs((*planes)[l].Distance(f.P(u, v)));
          if (d <= best_d) best = l, best_d = d;
        }
        if (best >= 0) adds.emplace_back(i, best);
      }
    }
    if (adds.empty()) break;
    for (const auto& [i, l] : adds) (*labels)[i] = l;
  }
}

// A boundary pixel: its image position (moved towards the edge for occlusion pixels), 3D point.
struct BoundaryPixel {
  Eigen::Vector2d px;
  Eigen::Vector3d point;
  Eigen::Vector2d to_background = Eigen::Vector2d::Zero();  // occlusion pixels: unit step to the background
};

// Splits sorted parameters into runs separated by gaps > max_gap; returns [begin, end) index pairs.
std::vector<std::pair<int, int>> Runs(const std::vector<double>& sorted, double max_gap) {
  std::vector<std::pair<int, int>> runs;
  int begin = 0;
  for (int i = 1; i <= static_cast<int>(sorted.size()); ++i) {
    if (i == static_cast<int>(sorted.size()) || sorted[i] - sorted[i - 1] > max_gap) {
      runs.emplace_back(begin, i);
      begin = i;
    }
  }
  return runs;
}

std::optional<Eigen::Vector3d> RayOnPlane(const Eigen::Vector2d& px, const cv::Mat& rays, const Plane& plane) {
  // Bilinear ray at a sub-pixel position (clamped to the image).
  const double x = std::clamp(px.x(), 0.0, rays.cols - 1.001), y = std::clamp(px.y(), 0.0, rays.rows - 1.001);
  const int u = static_cast<int>(x), v = static_cast<int>(y);
  const double fx = x - u, fy = y - v;
  const cv::Vec2f r00 = rays.at<cv::Vec2f>(v, u), r10 = rays.at<cv::Vec2f>(v, u + 1);
  const cv::Vec2f r01 = rays.at<cv::Vec2f>(v + 1, u), r11 = rays.at<cv::Vec2f>(v + 1, u + 1);
  Eigen::Vector3d ray;
  for (int c = 0; c < 2; ++c) {
    ray[c] = (1 - fx) * (1 - fy) * static_cast<double>(r00[c]) + fx * (1 - fy) * static_cast<double>(r10[c]) +
             (1 - fx) * fy * static_cast<double>(r01[c]) + fx * fy * static_cast<double>(r11[c]);
  }
  ray.z() = 1;
  if (!ray.allFinite()) return std::nullopt;
  const double denom = plane.normal.dot(ray);
  if (std::abs(denom) < 1e-6) return std::nullopt;
  const double z = -plane.offset / denom;
  if (z <= 0) return std::nullopt;
  return Eigen::Vector3d(ray * z);
}

}  // namespace

std::string DepthLineOptions::Check() const {
  using core::OptionFail;
  if (!(min_depth_m > 0)) return OptionFail("min_depth_m", min_depth_m, "> 0 m");
  if (!(max_depth_m > min_depth_m)) return OptionFail("max_depth_m", max_depth_m, "> min_depth_m");
  if (normal_step_px < 0) return OptionFail("normal_step_px", normal_step_px, ">= 0 px");
  if (!(plane_normal_deg > 0 && plane_normal_deg < 90)) return "plane_normal_deg: must be in (0, 90) deg, got " + std::to_string(plane_normal_deg);
  if (!(plane_distance_m > 0)) return OptionFail("plane_distance_m", plane_distance_m, "> 0 m");
  if (!(plane_distance_per_m >= 0)) return OptionFail("plane_distance_per_m", plane_distance_per_m, ">= 0 m/m²");
  if (!(min_plane_fraction > 0 && min_plane_fraction < 1)) return "min_plane_fraction: must be in (0, 1), got " + std::to_string(min_plane_fraction);
  if (!(min_fold_angle_deg > 0 && min_fold_angle_deg < 90)) return "min_fold_angle_deg: must be in (0, 90) deg, got " + std::to_string(min_fold_angle_deg);
  if (!(occlusion_jump_ratio > 0)) return OptionFail("occlusion_jump_ratio", occlusion_jump_ratio, "> 0");
  if (!(line_inlier_px > 0)) return OptionFail("line_inlier_px", line_inlier_px, "> 0 px");
  if (!(min_segment_fraction > 0 && min_segment_fraction < 1)) return "min_segment_fraction: must be in (0, 1), got " + std::to_string(min_segment_fraction);
  if (!(max_gap_px >= 0)) return OptionFail("max_gap_px", max_gap_px, ">= 0 px");
  return "";
}

cv::Mat DepthRays(const core::CameraModel& depth_camera) {
  cv::Mat rays(depth_camera.height, depth_camera.width, CV_32FC2);
  for (int v = 0; v < rays.rows; ++v) {
    for (int u = 0; u < rays.cols; ++u) {
      const auto ray = depth_camera.Unproject(Eigen::Vector2d(u, v));
      rays.at<cv::Vec2f>(v, u) = ray ? cv::Vec2f(static_cast<float>(ray->x()), static_cast<float>(ray->y()))
                                     : cv::Vec2f(kNaN, kNaN);
    }
  }
  return rays;
}

std::vector<Segment3d> ExtractDepthLines(const cv::Mat& depth_m, const cv::Mat& rays, double focal_px,
                                         const DepthLineOptions& options_in, DepthLineStats* stats) {
  assert(options_in.Check().empty());
  assert(depth_m.type() == CV_32FC1 && rays.type() == CV_32FC2 && depth_m.size() == rays.size());
  DepthLineOptions options = options_in;
  if (options.normal_step_px == 0) options.normal_step_px = std::max(2, depth_m.cols / 80);
  if (options.max_gap_px == 0) options.max_gap_px = 2.0 * options.normal_step_px + 2;
  Frame f(depth_m, rays, options);
  f.Smooth(std::max(1, options.normal_step_px / 2));
  std::vector<Eigen::Vector3d> normals;
  std::vector<float> flatness;
  ComputeNormals(f, options.normal_step_px, &normals, &flatness);
  std::vector<int> labels;
  std::vector<Plane> planes;
  GrowPlanes(f, normals, flatness, options, &labels, &planes);

  // Boundary walk.
  const int max_walk = 2 * options.normal_step_px + 3;
  std::map<std::pair<int, int>, std::vector<BoundaryPixel>> folds;  // (l, m), l < m
  std::vector<std::vector<BoundaryPixel>> occlusions(planes.size());
  static constexpr int kDu[4] = {1, -1, 0, 0}, kDv[4] = {0, 0, 1, -1};
  for (int v = 0; v < f.h(); ++v) {
    for (int u = 0; u < f.w(); ++u) {
      const int l = labels[f.Index(u, v)];
      if (l < 0) continue;
      const double z = f.Z(u, v);
      for (int k = 0; k < 4; ++k) {
        const int u1 = u + kDu[k], v1 = v + kDv[k];
        if (!f.Inside(u1, v1) || labels[f.Index(u1, v1)] == l) continue;
        bool passed_surface = false;
        for (int s = 1; s <= max_walk; ++s) {
          const int uu = u + s * kDu[k], vv = v + s * kDv[k];
          if (!f.Inside(uu, vv)) break;
          if (!f.Valid(uu, vv)) continue;  // a hole: look past it
          const int m = labels[f.Index(uu, vv)];
          if (m == l) break;
          const double zz = f.Z(uu, vv);
          // Only a jump right after the region (holes aside) is its edge: past other surface
          // pixels the jump is that surface's.
          if (f.JumpFarther(z, zz)) {
            if (!passed_surface) {
              occlusions[l].push_back({Eigen::Vector2d(u + 0.5 * kDu[k], v + 0.5 * kDv[k]), f.P(u, v),
                                       Eigen::Vector2d(kDu[k], kDv[k])});
            }
            break;
          }
          if (f.JumpFarther(zz, z)) break;  // nearer surface: we are the occluded side
          passed_surface = m < 0;
          if (m >= 0) {
            folds[{std::min(l, m), std::max(l, m)}].push_back({Eigen::Vector2d(u, v), f.P(u, v)});
            break;
          }
        }
      }
    }
  }

  const double diagonal_px = std::hypot(f.w(), f.h());
  const double min_len_px = options.min_segment_fraction * diagonal_px;
  const int min_support = std::max(6, static_cast<int>(0.5 * min_len_px));
  std::vector<Segment3d> segments;
  DepthLineStats local;
  local.planes = static_cast<int>(planes.size());

  // Fold lines.
  const double cos_fold = std::cos(options.min_fold_angle_deg * kDegToRad);
  for (const auto& [pair, pixels] : folds) {
    const Plane& a = planes[pair.first];
    const Plane& b = planes[pair.second];
    if (std::abs(a.normal.dot(b.normal)) > cos_fold || static_cast<int>(pixels.size()) < 2 * min_support) continue;
    const Eigen::Vector3d dir = a.normal.cross(b.normal).normalized();
    // The point of both planes nearest the origin: min |p|² s.t. n_a·p = -d_a, n_b·p = -d_b.
    Eigen::Matrix<double, 2, 3> N;
    N.row(0) = a.normal.transpose();
    N.row(1) = b.normal.transpose();
    const Eigen::Vector2d rhs(-a.offset, -b.offset);
    const Eigen::Vector3d p0 = N.transpose() * (N * N.transpose()).ldlt().solve(rhs);
    std::vector<double> params;
    for (const BoundaryPixel& bp : pixels) {
      const Eigen::Vector3d d = bp.point - p0;
      const double s = d.dot(dir);
      // Fold pixels lie within a few normal steps of the line.
      const double off = (d - s * dir).norm();
      if (off > (2.0 * max_walk * bp.point.z() / focal_px) + f.Tolerance(bp.point.z()) * 3) continue;
      params.push_back(s);
    }
    std::sort(params.begin(), params.end());
    // Gaps in metres at the fold's depth.
    const double z_mean = p0.z() > 0 ? std::max(p0.z(), 0.5) : 2.0;
    for (const auto& [i0, i1] : Runs(params, options.max_gap_px * z_mean / focal_px)) {
      // Each fold pixel is reported from both sides: the support is about half the count.
      if ((i1 - i0) / 2 < min_support) continue;
      Segment3d seg;
      seg.a = p0 + params[i0] * dir;
      seg.b = p0 + params[i1 - 1] * dir;
      seg.kind = LineKind::kFold;
      seg.support_px = (i1 - i0) / 2;
      if (seg.a.z() <= 0 || seg.b.z() <= 0) continue;
      const double len_px = focal_px * (seg.a.head<2>() / seg.a.z() - seg.b.head<2>() / seg.b.z()).norm();
      if (len_px < min_len_px) continue;
      segments.push_back(seg);
      ++local.fold_lines;
    }
  }

  // Occlusion lines: sequential RANSAC per plane.
  std::mt19937 rng(12345);
  for (size_t l = 0; l < planes.size(); ++l) {
    std::vector<BoundaryPixel> pts = occlusions[l];
    while (static_cast<int>(pts.size()) >= min_support) {
      std::uniform_int_distribution<int> pick(0, static_cast<int>(pts.size()) - 1);
      int best_count = 0;
      Eigen::Vector2d best_n, best_p;
      for (int it = 0; it < 200; ++it) {
        const Eigen::Vector2d p = pts[pick(rng)].px, q = pts[pick(rng)].px;
        if ((q - p).norm() < 4) continue;
        const Eigen::Vector2d d = (q - p).normalized();
        const Eigen::Vector2d n(-d.y(), d.x());
        int count = 0;
        for (const BoundaryPixel& bp : pts) count += std::abs(n.dot(bp.px - p)) <= options.line_inlier_px;
        if (count > best_count) best_count = count, best_n = n, best_p = p;
      }
      if (best_count < min_support) break;
      // Least-squares refit on the inliers.
      std::vector<Eigen::Vector2d> in;
      std::vector<BoundaryPixel> out;
      Eigen::Vector2d to_background = Eigen::Vector2d::Zero();
      for (const BoundaryPixel& bp : pts) {
        if (std::abs(best_n.dot(bp.px - best_p)) <= options.line_inlier_px) {
          in.push_back(bp.px);
          to_background += bp.to_background;
        } else {
          out.push_back(bp);
        }
      }
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (const auto& p : in) mean += p;
      mean /= in.size();
      Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
      for (const auto& p : in) cov += (p - mean) * (p - mean).transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
      const Eigen::Vector2d dir = eig.eigenvectors().col(1);
      std::vector<double> params;
      for (const auto& p : in) params.push_back(dir.dot(p - mean));
      std::sort(params.begin(), params.end());
      for (const auto& [i0, i1] : Runs(params, options.max_gap_px)) {
        if (i1 - i0 < min_support || params[i1 - 1] - params[i0] < min_len_px) continue;
        const auto a = RayOnPlane(mean + params[i0] * dir, rays, planes[l]);
        const auto b = RayOnPlane(mean + params[i1 - 1] * dir, rays, planes[l]);
        if (!a || !b) continue;
        Segment3d seg;
        seg.a = *a;
        seg.b = *b;
        // One pixel across the line towards the background, at the midpoint, on the plane.
        const Eigen::Vector2d across(-dir.y(), dir.x());
        const Eigen::Vector2d step = across.dot(to_background) >= 0 ? across : Eigen::Vector2d(-across);
        const Eigen::Vector2d mid = mean + 0.5 * (params[i0] + params[i1 - 1]) * dir;
        const auto m0 = RayOnPlane(mid, rays, planes[l]);
        const auto m1 = RayOnPlane(mid + step, rays, planes[l]);
        if (m0 && m1) seg.edge_shift_per_px = *m1 - *m0;
        seg.kind = LineKind::kOcclusion;
        seg.support_px = i1 - i0;
        segments.push_back(seg);
        ++local.occlusion_lines;
      }
      pts = std::move(out);
    }
  }
  if (stats) *stats = local;
  return segments;
}

}  // namespace hw::calibrate
