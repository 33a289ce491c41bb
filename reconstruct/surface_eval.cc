#include "reconstruct/surface_eval.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace hw::reconstruct {

std::vector<std::optional<double>> PointToMeshDistances(
    const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& vertices,
    const std::vector<Eigen::Vector3i>& faces, double max_distance_m) {
  assert(max_distance_m > 0);
  const TriangleGrid grid(vertices, faces, max_distance_m);
  std::vector<std::optional<double>> out(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    if (const auto closest = grid.FindClosest(points[i], max_distance_m)) out[i] = closest->distance_m;
  }
  return out;
}

SurfaceDistanceStats SummarizeDistances(const std::vector<std::optional<double>>& distances) {
  SurfaceDistanceStats s;
  s.points = static_cast<int>(distances.size());
  std::vector<double> d;
  d.reserve(distances.size());
  for (const auto& x : distances) {
    if (x) {
      d.push_back(*x);
    } else {
      ++s.beyond_search;
    }
  }
  if (d.empty()) return s;
  std::sort(d.begin(), d.end());
  const auto quantile = [&](double q) { return d[std::min(d.size() - 1, static_cast<size_t>(q * (d.size() - 1) + 0.5))]; };
  s.median_m = d.size() % 2 ? d[d.size() / 2] : 0.5 * (d[d.size() / 2 - 1] + d[d.size() / 2]);
  s.p90_m = quantile(0.9);
  s.max_m = d.back();
  double sum = 0, sum2 = 0;
  for (const double x : d) {
    sum += x;
    sum2 += x * x;
  }
  s.mean_m = sum / d.size();
  s.rms_m = std::sqrt(sum2 / d.size());
  return s;
}

}  // namespace hw::reconstruct
