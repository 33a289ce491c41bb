#include "reconstruct/mesh_query.h"

#include <cassert>
#include <utility>

namespace hw::reconstruct {

TrianglePoint ClosestPointOnTriangleWithWeights(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                                const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Voronoi regions of the vertices, then the edges, then the face.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {a, {1, 0, 0}};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {b, {0, 1, 0}};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {a + v * ab, {1 - v, v, 0}};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {c, {0, 0, 1}};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {a + w * ac, {1 - w, 0, w}};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), {0, 1 - w, w}};
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) return {a, {1, 0, 0}};  // degenerate: its vertices cover it
  const double v = vb / denom, w = vc / denom;
  return {a + ab * v + ac * w, {1 - v - w, v, w}};
}

Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return ClosestPointOnTriangleWithWeights(p, a, b, c).point;
}

SparseGrid::SparseGrid(double cell_m) : cell_m_(cell_m) { assert(cell_m > 0); }

TriangleGrid::TriangleGrid(const std::vector<Eigen::Vector3d>& vertices,
                           const std::vector<Eigen::Vector3i>& faces, double cell_m)
    : vertices_(vertices), faces_(faces), grid_(cell_m) {
  // A cell the triangle touches has its centre within half a diagonal of it; the margin
  // covers rounding of points on cell faces.
  const double reach_m = 0.5 * std::sqrt(3.0) * cell_m * (1 + 1e-9);
  for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
    const Eigen::Vector3i& face = faces[f];
    for (int k = 0; k < 3; ++k) assert(face[k] >= 0 && face[k] < static_cast<int>(vertices.size()));
    const Eigen::Vector3d &a = vertices[face[0]], &b = vertices[face[1]], &c = vertices[face[2]];
    const Eigen::Vector3i lo = grid_.CellOf(a.cwiseMin(b).cwiseMin(c));
    const Eigen::Vector3i hi = grid_.CellOf(a.cwiseMax(b).cwiseMax(c));
    const bool one_cell = lo == hi;
    for (int x = lo.x(); x <= hi.x(); ++x)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int z = lo.z(); z <= hi.z(); ++z) {
          const Eigen::Vector3i cell(x, y, z);
          if (!one_cell) {
            const Eigen::Vector3d centre = grid_.CellCentre(cell);
            if ((ClosestPointOnTriangle(centre, a, b, c) - centre).norm() > reach_m) continue;
          }
          grid_.Add(cell, f);
        }
  }
}

std::optional<TriangleGrid::Closest> TriangleGrid::FindClosest(const Eigen::Vector3d& p,
                                                               double max_distance_m) const {
  // The closest point q of a triangle within cell_m of p lies in one of the 27 cells around
  // p's, and the triangle is binned in q's cell: the query is exact. A cell farther than the
  // best distance so far cannot hold a closer q: it is skipped (p's own cell comes first).
  assert(max_distance_m > 0 && max_distance_m <= grid_.cell_m());
  Closest best;
  best.distance_m = max_distance_m;
  bool found = false;
  grid_.VisitNear(p, best.distance_m, [&](int f) {
    const Eigen::Vector3i& face = faces_[f];
    const TrianglePoint q =
        ClosestPointOnTriangleWithWeights(p, vertices_[face[0]], vertices_[face[1]], vertices_[face[2]]);
    const double d = (q.point - p).norm();
    if (d <= best.distance_m) {
      best = {f, q, d};
      found = true;
    }
    return true;
  });
  if (!found) return std::nullopt;
  return best;
}

PointGrid::PointGrid(std::vector<Eigen::Vector3d> points, double cell_m)
    : points_(std::move(points)), grid_(cell_m) {
  for (int i = 0; i < static_cast<int>(points_.size()); ++i) grid_.Add(grid_.CellOf(points_[i]), i);
}

std::optional<double> PointGrid::NearestDistance(const Eigen::Vector3d& p, double max_distance_m) const {
  assert(max_distance_m > 0 && max_distance_m <= grid_.cell_m());
  double best = max_distance_m;
  bool found = false;
  grid_.VisitNear(p, best, [&](int i) {
    const double d = (points_[i] - p).norm();
    if (d <= best) {
      best = d;
      found = true;
    }
    return true;
  });
  if (!found) return std::nullopt;
  return best;
}

}  // namespace hw::reconstruct
