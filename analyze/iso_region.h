#pragma once

// The geometry of a hot or cold spot on a mesh: the part of a set of faces on one side of an
// iso-temperature line, with each triangle clipped along the line (the field is linear over
// each triangle), and its length and width as the minimal-area bounding rectangle of the
// region flattened onto the plane — projected when the surface is flat, unrolled when it is
// a cylinder (a pipe) or two planes meeting at a crease (a wall–ceiling junction, a box edge).

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct IsoSegment {  // one piece of the iso-line, inside one face
  Eigen::Vector3d a_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_in_world = Eigen::Vector3d::Zero();
  double gradient_k_per_m = 0;  // |∇field| within the face (field linear per triangle)
  int face = -1;
};

struct ClippedPiece {  // the part of one face inside the region: 3 or 4 points
  int face = -1;
  int num_points = 0;
  std::array<Eigen::Vector3d, 4> points_in_world;  // in the face's winding order
};

struct IsoRegion {
  double area_m2 = 0;
  Eigen::Vector3d centroid_in_world = Eigen::Vector3d::Zero();  // area-weighted
  Eigen::Vector3d normal_in_world = Eigen::Vector3d::UnitZ();   // area-weighted unit normal
  double perimeter_m = 0;  // total length of the iso-line (not mesh borders)
  std::vector<IsoSegment> boundary;
  std::vector<ClippedPiece> pieces;
  std::vector<int> faces;            // faces with a part inside (of positive area)
  int faces_skipped_unobserved = 0;  // faces with a NaN vertex value, left out
};

// The part of `faces` (indices into mesh.faces) where the per-vertex field, linear over each
// triangle, is >= level (above = true) or <= level (above = false): each triangle clipped
// along the iso-line (not whole triangles). Units: metres (mesh frame = world), field in its
// own unit (K or °C: gradient_k_per_m is per metre of that unit).
// - Faces with a non-finite vertex value are left out and counted in
//   faces_skipped_unobserved (their part of the iso-line is unknown).
// - A vertex exactly at the level is inside. The iso-line is reported once: by the face on
//   its outside (a face with a vertex strictly outside); so a segment lying along a mesh edge
//   whose vertices are both at the level belongs to the outside face, which has no piece.
// - The region is bounded by the iso-line and by the border of `faces`; only the former
//   counts in perimeter_m and boundary.
// - An empty result (nothing inside) has area 0, centroid 0 and normal +z.
// `field` must have one value per mesh vertex and `level` must be finite (asserted: a bug).
IsoRegion ClipToLevel(const ThermalMesh& mesh, const std::vector<double>& field,
                      const std::vector<int>& faces, double level, bool above);

struct ExtentOptions {
  // A curved region is still measured on its best-fit plane when projecting it shortens
  // lengths by at most this fraction. The shortening is estimated from the face normals as
  // (λ2 − λ3)/2, λ the eigenvalues of their area-weighted second moment (λ1 ≥ λ2 ≥ λ3): for a
  // cylinder arc of angle α that is α²/24, exactly the chord's 1 − 2 sin(α/2)/α to leading
  // order, and for a fold of angle φ it is 1 − cos(φ/2) to leading order; isotropic normal
  // noise adds to λ2 and λ3 alike and cancels. Fraction, in (0, 0.5] (0.5 ≥ any estimate:
  // always plane).
  double max_plane_distortion = 0.005;
  // A cylinder or fold is used only when its RMS distance from the points is at most
  // 1/min_curved_residual_gain of the plane's; otherwise the curvature the normals show is
  // not in the shape (staircase or noise normals of a flat, reconstructed wall) and the plane
  // is kept. Ratio, >= 1.
  double min_curved_residual_gain = 2.0;

  std::string Check() const;
};

struct Extent {
  double length_m = 0, width_m = 0;  // sides of the minimal-area bounding rectangle, length >= width
  // Direction of the long side at the centroid (unit; +x for an empty region).
  Eigen::Vector3d length_axis_in_world = Eigen::Vector3d::UnitX();
  std::string unrolling = "plane";  // "plane", "cylinder" or "fold"
  double unroll_error_m = 0;        // RMS distance of the points from the fitted developable surface
  // Model parameters, for reports and tests: the cylinder's radius (0 otherwise), the fold's
  // angle between the two planes' normals (0 otherwise), and whether a cylinder region goes
  // all the way round (then its circumferential side is 2π·radius_m).
  double radius_m = 0;
  double fold_angle_rad = 0;
  bool full_ring = false;
};

// Length and width of the region on the surface: the clipped pieces' points flattened
// (unrolled) to 2D, their convex hull, the minimal-area enclosing rectangle (rotating
// calipers). The flattening is chosen from the data alone:
// - plane when the normals' spread predicts a small distortion (ExtentOptions), or when no
//   curved model fits markedly better than the plane: points projected on the plane through
//   the centroid with the region's mean normal;
// - otherwise a cylinder (axis = eigenvector of the smallest eigenvalue of the normals'
//   second moment, centre and radius by least squares on centroid = centre + radius·normal in
//   the cross-section, then all refined by Gauss–Newton on the mesh vertices' distances from
//   the axis; unrolled to (r·θ, axial), cut at the largest angular gap the pieces
//   leave, a full ring measured as 2πr by its axial extent) or a fold (the normals split in
//   two clusters by optimal 1D 2-means of their angles around the same axis; one plane per
//   cluster; each unfolded onto the other about their intersection line), whichever has the
//   smaller RMS distance from the points.
// Metres, world frame. An empty region gives zeros. O(n log n) in the number of points.
Extent MeasureExtent(const IsoRegion& region, const ThermalMesh& mesh, const ExtentOptions& options);

// The building blocks, exposed for tests and other measurements.

// Convex hull of 2D points, counter-clockwise, without collinear points; fewer than 3 points
// when they are all collinear (the two extremes) or coincide.
std::vector<Eigen::Vector2d> ConvexHull2d(const std::vector<Eigen::Vector2d>& points);

struct Rectangle2d {
  double length = 0, width = 0;                          // length >= width
  Eigen::Vector2d length_axis = Eigen::Vector2d::UnitX();  // unit
};
// Minimal-area rectangle enclosing a convex polygon given counter-clockwise (as ConvexHull2d
// returns it), by rotating calipers: one side lies along a polygon edge. O(n).
Rectangle2d MinAreaRectangle(const std::vector<Eigen::Vector2d>& hull_ccw);

}  // namespace hw::analyze
