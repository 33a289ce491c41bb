#include "reconstruct/surface_eval.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <unordered_map>

namespace hw::reconstruct {

Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Voronoi regions of the vertices, then the edges, then the face.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return a;  // degenerate (zero-area) triangle: its vertices cover it
  return a + ab * (vb / denom) + ac * (vc / denom);
}

namespace {

struct CellHash {
  size_t operator()(const Eigen::Vector3i& k) const {
    return static_cast<size_t>((static_cast<uint64_t>(k.x()) * 73856093u) ^
                               (static_cast<uint64_t>(k.y()) * 19349669u) ^
                               (static_cast<uint64_t>(k.z()) * 83492791u));
  }
};
struct CellEqual {
  bool operator()(const Eigen::Vector3i& a, const Eigen::Vector3i& b) const { return a == b; }
};

}  // namespace

std::vector<std::optional<double>> PointToMeshDistances(
    const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& vertices,
    const std::vector<Eigen::Vector3i>& faces, double max_distance_m) {
  assert(max_distance_m > 0);
  const double cell = max_distance_m;
  const auto cell_of = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / cell)),
                           static_cast<int>(std::floor(p.y() / cell)),
                           static_cast<int>(std::floor(p.z() / cell)));
  };
  // Each triangle in every cell its bounding box overlaps. Large triangles span many cells;
  // fine for scene meshes whose triangles are at most a few cells wide.
  std::unordered_map<Eigen::Vector3i, std::vector<int>, CellHash, CellEqual> grid;
  for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
    const Eigen::Vector3i& face = faces[f];
    for (int k = 0; k < 3; ++k) assert(face[k] >= 0 && face[k] < static_cast<int>(vertices.size()));
    const Eigen::Vector3d lo = vertices[face[0]].cwiseMin(vertices[face[1]]).cwiseMin(vertices[face[2]]);
    const Eigen::Vector3d hi = vertices[face[0]].cwiseMax(vertices[face[1]]).cwiseMax(vertices[face[2]]);
    const Eigen::Vector3i a = cell_of(lo), b = cell_of(hi);
    for (int x = a.x(); x <= b.x(); ++x)
      for (int y = a.y(); y <= b.y(); ++y)
        for (int z = a.z(); z <= b.z(); ++z) grid[Eigen::Vector3i(x, y, z)].push_back(f);
  }
  std::vector<std::optional<double>> out(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& p = points[i];
    const Eigen::Vector3i c = cell_of(p);
    double best = max_distance_m;
    bool found = false;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = grid.find(c + Eigen::Vector3i(dx, dy, dz));
          if (it == grid.end()) continue;
          for (const int f : it->second) {
            const Eigen::Vector3i& face = faces[f];
            const double d =
                (ClosestPointOnTriangle(p, vertices[face[0]], vertices[face[1]], vertices[face[2]]) - p).norm();
            if (d <= best) {
              best = d;
              found = true;
            }
          }
        }
    if (found) out[i] = best;
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
