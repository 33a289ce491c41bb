#pragma once

// Surface accuracy of a reconstructed model: the distance from each model vertex to the
// nearest point of a reference mesh (truth/scene.ply of a synthetic scan, a laser scan).

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/transform.h"
#include "reconstruct/mesh_query.h"  // ClosestPointOnTriangle, TriangleGrid

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
// on the triangle, its edges or vertices). Runs on all cores (ForEachBand); the result does
// not depend on their number. Asserts max_distance_m > 0 and face indices in range.
std::vector<std::optional<double>> PointToMeshDistances(
    const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& vertices,
    const std::vector<Eigen::Vector3i>& faces, double max_distance_m);

// The same through a grid already built (cell >= max_distance_m, asserted by FindClosest).
std::vector<std::optional<double>> PointToMeshDistances(const std::vector<Eigen::Vector3d>& points,
                                                        const TriangleGrid& grid, double max_distance_m);

SurfaceDistanceStats SummarizeDistances(const std::vector<std::optional<double>>& distances);

// Rigid registration of a model to its reference mesh before measuring its shape, as surface
// benchmarks do (ICL-NUIM, Handa et al. 2014, registers each reconstruction to the true model
// before measuring distances): a tracked map sits in the world with the error of its first
// frames (a fraction of a degree turns a 4 m wall by millimetres), which says nothing about
// the shape the audit measures on. The distances after it are the shape's error; the
// transform is the map's pose error. Both are reported, never one for the other.
struct MeshRegistrationOptions {
  int max_points = 100000;          // points used: an evenly strided subset when more (count)
  int max_iterations = 30;          // Gauss-Newton iterations (count)
  double max_distance_m = 0.05;     // correspondences farther are ignored (m; <= the grid's cell)
  double outlier_median_ratio = 3;  // and those beyond this many times the iteration's median
                                    // distance (ratio; a point's own error scale, not a fixed one)
  double min_eigenvalue_ratio = 1e-6;  // directions whose normal-equation eigenvalue falls below
                                       // this fraction of the largest are left unmoved (ratio):
                                       // a plane does not fix sliding along itself
  double converged_m = 1e-7;        // stop when an update moves the points' RMS by less (m)
  // Empty when valid, else a message naming the field, its value and the constraint.
  std::string Check() const;
};

struct MeshRegistration {
  core::Rigid3d reference_from_points;  // apply to the points to register them
  int iterations = 0;
  int correspondences = 0;      // used in the last iteration
  int constrained_directions = 0;  // of the 6, those the reference's shape fixes
  bool converged = false;
  double rotation_deg = 0, translation_m = 0;  // the size of reference_from_points
};

// Point-to-surface ICP of `points` (m) onto the mesh of `grid`, from the identity: each
// iteration finds every point's closest mesh point within max_distance_m, drops those beyond
// outlier_median_ratio × the median distance, and takes the Gauss-Newton step that reduces the
// sum of squared distances (the residual is the distance along the direction to the closest
// point: the face normal on a face, sliding allowed), in the constrained directions only.
// Fewer than 6 correspondences: the identity, 0 iterations. Asserts options valid.
MeshRegistration RegisterToMesh(const std::vector<Eigen::Vector3d>& points, const TriangleGrid& grid,
                                const MeshRegistrationOptions& options);

}  // namespace hw::reconstruct
