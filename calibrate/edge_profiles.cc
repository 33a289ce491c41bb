#include "calibrate/edge_profiles.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace hw::calibrate {

namespace {

double Cross(const cv::Point2d& a, const cv::Point2d& b) { return a.x * b.y - a.y * b.x; }

}  // namespace

bool IntersectLines(const cv::Point2d& p1, const cv::Point2d& d1, const cv::Point2d& p2, const cv::Point2d& d2,
                    cv::Point2d* out) {
  const double den = Cross(d1, d2);
  if (std::abs(den) < 1e-9) return false;
  *out = p1 + d1 * (Cross(p2 - p1, d2) / den);
  return true;
}

double SampleBilinear(const cv::Mat& f, double x, double y) {
  assert(f.type() == CV_32F);
  x = std::clamp(x, 0.0, f.cols - 1.001);
  y = std::clamp(y, 0.0, f.rows - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double ax = x - x0, ay = y - y0;
  const double a = f.at<float>(y0, x0), b = f.at<float>(y0, x0 + 1);
  const double c = f.at<float>(y0 + 1, x0), d = f.at<float>(y0 + 1, x0 + 1);
  return (1 - ay) * ((1 - ax) * a + ax * b) + ay * ((1 - ax) * c + ax * d);
}

bool RefineSquareCorners(const cv::Mat& f, const EdgeProfileOptions& options, const cv::Point2d& centre,
                         std::array<cv::Point2d, 4>& corners) {
  const double edge_sigma_px = options.edge_sigma_px;
  constexpr double kStep = 0.1;  // profile sampling, pixels
  // d/ds of the Gaussian-smoothed profile = the profile's central differences smoothed
  // (kSteepest only: the mid-level needs neither the kernel nor samples beyond the window).
  const bool steepest = options.edge == EdgeLocator::kSteepest;
  const int r = steepest ? static_cast<int>(std::ceil(3 * edge_sigma_px / kStep)) : 0;
  std::vector<double> kernel(2 * r + 1);
  double kernel_sum = 0;
  for (int j = -r; j <= r; ++j) {
    kernel[j + r] = std::exp(-0.5 * std::pow(j * kStep / edge_sigma_px, 2));
    kernel_sum += kernel[j + r];
  }
  for (double& w : kernel) w /= kernel_sum * 2 * kStep;
  std::array<cv::Point2d, 4> point, dir;
  std::vector<double> profile, slope;
  for (int k = 0; k < 4; ++k) {
    const cv::Point2d a = corners[k], b = corners[(k + 1) % 4];
    const double len = cv::norm(b - a);
    if (len < 3) return false;
    const cv::Point2d d = (b - a) / len;
    cv::Point2d n(d.y, -d.x);
    if (n.dot(0.5 * (a + b) - centre) < 0) n = -n;
    const double half = std::clamp(0.3 * len, 2.0, 5.0);
    const int m = static_cast<int>(half / kStep);
    const int pad = steepest ? r + 1 : 0;  // samples beyond the window for the smoothing
    std::vector<cv::Point2f> edge;
    for (double t = 0.2 * len; t <= 0.8 * len; t += 0.5) {
      const cv::Point2d p = a + d * t;
      profile.resize(2 * (m + pad) + 1);
      for (int i = -m - pad; i <= m + pad; ++i) {
        const cv::Point2d q = p + n * (i * kStep);
        profile[i + m + pad] = SampleBilinear(f, q.x, q.y);
      }
      // Contrast across the window's ends (half a pixel each): the outside must differ.
      double inner = 0, outer = 0;
      const int ends = static_cast<int>(0.5 / kStep);
      for (int i = 0; i < ends; ++i) {
        inner += profile[pad + i] / ends;
        outer += profile[pad + 2 * m - i] / ends;
      }
      if (std::abs(outer - inner) < 0.05) continue;
      if (!steepest) {
        const double mid = 0.5 * (inner + outer);
        double best = 1e18;
        for (int i = pad; i < pad + 2 * m; ++i) {
          const double p0 = profile[i] - mid, p1 = profile[i + 1] - mid;
          if ((p0 <= 0) == (p1 <= 0)) continue;
          const double at = (i - pad + p0 / (p0 - p1) - m) * kStep;
          if (std::abs(at) < std::abs(best)) best = at;
        }
        if (std::abs(best) > half) continue;
        const cv::Point2d e = p + n * best;
        edge.emplace_back(static_cast<float>(e.x), static_cast<float>(e.y));
        continue;
      }
      const double sign = outer > inner ? 1 : -1;
      slope.assign(2 * m + 1, 0.0);
      double strongest = 0;
      for (int i = 1; i < 2 * m; ++i) {
        double acc = 0;
        for (int j = -r; j <= r; ++j) {
          const int c = pad + i + j;
          acc += kernel[j + r] * (profile[c + 1] - profile[c - 1]);
        }
        slope[i] = sign * acc;
        strongest = std::max(strongest, slope[i]);
      }
      int peak = -1;
      for (int i = 2; i < 2 * m - 1; ++i) {
        if (slope[i] < 0.5 * strongest || slope[i] < slope[i - 1] || slope[i] < slope[i + 1]) continue;
        if (peak < 0 || std::abs(i - m) < std::abs(peak - m)) peak = i;
      }
      if (peak < 0) continue;
      const double y0 = slope[peak - 1], y1 = slope[peak], y2 = slope[peak + 1];
      const double curvature = y0 - 2 * y1 + y2;
      const double offset = curvature < 0 ? std::clamp(0.5 * (y0 - y2) / curvature, -0.5, 0.5) : 0.0;
      const cv::Point2d e = p + n * ((peak + offset - m) * kStep);
      edge.emplace_back(static_cast<float>(e.x), static_cast<float>(e.y));
    }
    if (edge.size() < 3) return false;
    cv::Vec4f line;
    cv::fitLine(edge, line, cv::DIST_HUBER, 0, 0.01, 0.01);
    dir[k] = cv::Point2d(line[0], line[1]);
    point[k] = cv::Point2d(line[2], line[3]);
  }
  std::array<cv::Point2d, 4> out;
  for (int k = 0; k < 4; ++k) {
    if (!IntersectLines(point[(k + 3) % 4], dir[(k + 3) % 4], point[k], dir[k], &out[k])) return false;
    if (cv::norm(out[k] - corners[k]) > std::max(2.0, 0.3 * cv::norm(corners[k] - centre))) return false;
  }
  corners = out;
  return true;
}

}  // namespace hw::calibrate
