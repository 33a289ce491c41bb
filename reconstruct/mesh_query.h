#pragma once

// Nearest-point queries on triangle meshes and point sets through sparse uniform grids:
// the closest point of a mesh (with its barycentric weights, to interpolate per-vertex
// fields there), the triangles near a point, the distance to the nearest of a set of points.
// Shared by the surface and temperature evaluations (surface_eval.h, thermal_eval.h).

#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

namespace hw::reconstruct {

// The closest point of a triangle and its barycentric weights (w_a, w_b, w_c): >= 0, sum 1,
// point = w_a·a + w_b·b + w_c·c.
struct TrianglePoint {
  Eigen::Vector3d point;
  Eigen::Vector3d weights;
};

// The closest point to p on triangle (a, b, c) (Ericson, Real-Time Collision Detection
// §5.1.5): on the face, an edge or a vertex. A degenerate (zero-area) triangle whose face
// region is reached gives vertex a (its neighbours in a mesh cover its points).
TrianglePoint ClosestPointOnTriangleWithWeights(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                                const Eigen::Vector3d& b, const Eigen::Vector3d& c);
// ClosestPointOnTriangleWithWeights(p, a, b, c).point.
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// Integer indices binned in the cubic cells (side cell_m, m) of a sparse grid: VisitNear
// visits the items of the cells around a point that come within a radius (<= cell_m) of it.
class SparseGrid {
 public:
  explicit SparseGrid(double cell_m);  // asserts cell_m > 0
  double cell_m() const { return cell_m_; }
  Eigen::Vector3i CellOf(const Eigen::Vector3d& p) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / cell_m_)),
                           static_cast<int>(std::floor(p.y() / cell_m_)),
                           static_cast<int>(std::floor(p.z() / cell_m_)));
  }
  Eigen::Vector3d CellCentre(const Eigen::Vector3i& cell) const {
    return (cell.cast<double>() + Eigen::Vector3d::Constant(0.5)) * cell_m_;
  }
  void Add(const Eigen::Vector3i& cell, int item) { cells_[cell].push_back(item); }
  // The items added to `cell`, nullptr when none.
  const std::vector<int>* Items(const Eigen::Vector3i& cell) const {
    const auto it = cells_.find(cell);
    return it == cells_.end() ? nullptr : &it->second;
  }
  // Squared distance from p to the cube of `cell`, m² (0 inside).
  double SquaredDistanceToCell(const Eigen::Vector3d& p, const Eigen::Vector3i& cell) const {
    const Eigen::Vector3d lo = cell.cast<double>() * cell_m_;
    const Eigen::Vector3d outside =
        (lo - p).cwiseMax(p - (lo + Eigen::Vector3d::Constant(cell_m_))).cwiseMax(0.0);
    return outside.squaredNorm();
  }
  // fn(int item) -> bool for the items of the cells around p's (its 27 neighbours) that come
  // within radius_m (<= cell_m) of p, p's own cell first, each cell's items in the order
  // added, until fn returns false; an item added to several of those cells comes once per
  // cell. Returns false when fn stopped the visit. Every item added to a cell within
  // radius_m of p is visited. radius_m is read again before each cell: fn may shrink the
  // variable it refers to (nearest-item searches).
  template <class Fn>
  bool VisitNear(const Eigen::Vector3d& p, const double& radius_m, Fn&& fn) const {
    const Eigen::Vector3i c = CellOf(p);
    for (int n = 0; n < 27; ++n) {
      // n = 0 is the centre (offset 0, 0, 0); the others follow.
      const int m = n == 0 ? 13 : (n <= 13 ? n - 1 : n);
      const Eigen::Vector3i cell = c + Eigen::Vector3i(m / 9 - 1, (m / 3) % 3 - 1, m % 3 - 1);
      if (n > 0 && SquaredDistanceToCell(p, cell) > radius_m * radius_m) continue;
      const std::vector<int>* items = Items(cell);
      if (!items) continue;
      for (const int item : *items) {
        if (!fn(item)) return false;
      }
    }
    return true;
  }

 private:
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
  double cell_m_;
  std::unordered_map<Eigen::Vector3i, std::vector<int>, CellHash, CellEqual> cells_;
};

// The triangles of a mesh (vertices in m, faces as vertex indices), each in every grid cell
// it may touch (the cells of its bounding box whose centre is within half a cell diagonal
// of it: a large slanted triangle is not put in its whole box). Queries reach cell_m.
// Keeps references: vertices and faces must outlive the grid and not change.
// Asserts cell_m > 0 and face indices in range. Memory grows with the mesh area / cell_m²:
// cells of a few mm on scene meshes of tens of m² cost hundreds of MB.
class TriangleGrid {
 public:
  TriangleGrid(const std::vector<Eigen::Vector3d>& vertices,
               const std::vector<Eigen::Vector3i>& faces, double cell_m);

  struct Closest {
    int face = -1;
    TrianglePoint on_face;  // the closest point and its weights on faces[face]'s vertices
    double distance_m = 0;
  };
  // The closest point of the mesh to p within max_distance_m (asserted in (0, cell_m]), or
  // nullopt when no triangle comes that close. Ties: any of the closest triangles.
  std::optional<Closest> FindClosest(const Eigen::Vector3d& p, double max_distance_m) const;

  // fn(int face) -> bool for candidate triangles near p until it returns false: every
  // triangle within radius_m (<= cell_m) of p is among them (others may be too; a triangle
  // may come several times). Returns false when fn stopped the visit.
  template <class Fn>
  bool VisitCandidates(const Eigen::Vector3d& p, double radius_m, Fn&& fn) const {
    assert(radius_m <= grid_.cell_m());
    return grid_.VisitNear(p, radius_m, fn);
  }

  const std::vector<Eigen::Vector3d>& vertices() const { return vertices_; }
  const std::vector<Eigen::Vector3i>& faces() const { return faces_; }

 private:
  const std::vector<Eigen::Vector3d>& vertices_;
  const std::vector<Eigen::Vector3i>& faces_;
  SparseGrid grid_;
};

// Points (m) binned in a grid of cell_m cells, for "how far is the nearest one" within
// cell_m. Copies the points. Asserts cell_m > 0.
class PointGrid {
 public:
  PointGrid(std::vector<Eigen::Vector3d> points, double cell_m);
  // Distance from p to the nearest point, when it is <= max_distance_m (asserted in
  // (0, cell_m]); nullopt otherwise.
  std::optional<double> NearestDistance(const Eigen::Vector3d& p, double max_distance_m) const;

 private:
  std::vector<Eigen::Vector3d> points_;
  SparseGrid grid_;
};

}  // namespace hw::reconstruct
