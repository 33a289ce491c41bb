#pragma once

// Surface accuracy of a reconstructed model: the distance from each model vertex to the
// nearest point of a reference mesh (truth/scene.ply of a synthetic scan, a laser scan).

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "reconstruct/mesh_query.h"  // ClosestPointOnTriangle

namespace hw::reconstruct {

struct SurfaceDistanceStats {
  int points = 0;
  int beyond_search = 0;  // points with no reference triangle within max_distance_m
  // Over the points within max_distance_m, m.
  double median_m = 0, mean_m = 0, rms_m = 0, p90_m = 0, max_m = 0;
};

// Unsigned distances from `points` to the triangle mesh (vertices, faces), same frame and
// units (m). Triangles are binned in a uniform grid of max_distance_m cells (TriangleGrid),
// so each query looks at the triangles of its 27 neighbouring cells only: distances beyond
// max_distance_m are not measured (nullopt). Exact point-to-triangle distance (closest point
// on the triangle, its edges or vertices). Asserts max_distance_m > 0 and face indices in range.
std::vector<std::optional<double>> PointToMeshDistances(
    const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& vertices,
    const std::vector<Eigen::Vector3i>& faces, double max_distance_m);

SurfaceDistanceStats SummarizeDistances(const std::vector<std::optional<double>>& distances);

}  // namespace hw::reconstruct
