#pragma once

// The analyzer's view of a model: a triangle mesh with per-vertex temperature and colour,
// read from any PLY (a fixture's truth/scene.ply, the reconstruct output, a file from
// another tool), cleaned of what would break geometry (non-finite positions, degenerate
// triangles), and with a vertex graph in which coincident vertices are one node, so that
// "connected over the mesh" holds across the seams and duplicated vertices that meshers
// and the fixtures' tessellation leave.

#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/ply.h"

namespace hw::analyze {

// What loading found and dropped; written to analyze.json and printed as warnings.
struct MeshLoadReport {
  int vertices_read = 0;
  int faces_read = 0;
  int vertices_non_finite = 0;      // x y z NaN or infinite: dropped with their faces
  int faces_degenerate = 0;         // repeated index or zero area (< 1e-14 m²): dropped
  int temperatures_non_finite = 0;  // ±Inf temperature_c: treated as unobserved (NaN)
  int temperatures_unobserved = 0;  // NaN temperature_c after loading (incl. the above)
  bool has_temperature = false;     // the PLY has the temperature field (see field below)
  bool has_colour = false;          // red green blue
  std::vector<std::string> warnings;  // one line each, for the summary and analyze.json
};

struct ThermalMesh {
  std::vector<Eigen::Vector3d> points_in_world;  // metres
  std::vector<Eigen::Vector3i> faces;            // counter-clockwise seen from outside
  // Per vertex, °C; NaN = unobserved (never a temperature). Empty when the PLY has no
  // temperature field.
  std::vector<double> temperature_c;
  // The PLY property temperature_c was read from ("temperature_c": the surface temperature
  // after emissivity correction, as reconstruct and the fixtures write it).
  std::string temperature_field;
  // Per vertex, linear RGB in [0, 1] (sRGB-decoded from the PLY's 8-bit colour). Empty
  // without colour.
  std::vector<Eigen::Vector3f> colour_linear;
  // Optional per-vertex fields written by reconstruct (empty when absent):
  std::vector<double> confidence;  // temperature_confidence, [0, 1]
  std::vector<double> views;       // temperature_views, count of thermal frames
  std::vector<double> std_c;       // temperature_std_c, K, spread across views
  std::vector<double> footprint_m; // temperature_footprint_m, m, a thermal pixel on the surface
  // temperature_emissivity: the normal emissivity temperature_c was corrected with (NaN where
  // unobserved). Not the truth's `emissivity` (a material property, exact temperatures).
  std::vector<double> emissivity;
  // temperature_view_x/_y/_z: from the vertex to where the thermal camera saw it from (mean
  // of the views' centres), world frame, m; NaN components where unobserved.
  std::vector<Eigen::Vector3d> view_m;
  // Area-weighted vertex normals (unit; zero for a vertex of no face).
  std::vector<Eigen::Vector3d> normals;
  MeshLoadReport report;

  int NumVertices() const { return static_cast<int>(points_in_world.size()); }
  int NumFaces() const { return static_cast<int>(faces.size()); }
  bool HasTemperature() const { return !temperature_c.empty(); }
  bool HasColour() const { return !colour_linear.empty(); }
  // Area of face f, m².
  double FaceArea(int f) const;
  // Sum of face areas, m².
  double TotalArea() const;
};

// Builds a ThermalMesh from a parsed PLY. `temperature_field` names the property to read
// as temperature (default temperature_c). Vertices with non-finite positions are removed
// with every face using them; faces with a repeated index or zero area are removed;
// vertices no face uses are kept (they do not matter to anything here). ±Inf temperatures
// become NaN. Throws core::InputError(path_for_errors, reason) when no triangle is left
// ("no triangles: the analyzer needs a mesh, not a point cloud", "every triangle is
// degenerate") or when a given temperature_field is absent (only when it is not the
// default: a mesh without temperature_c loads, without temperature).
ThermalMesh MakeThermalMesh(const core::PlyMesh& ply, const std::filesystem::path& path_for_errors,
                            const std::string& temperature_field = "temperature_c");
// ReadPly + MakeThermalMesh.
ThermalMesh ReadThermalMesh(const std::filesystem::path& path,
                            const std::string& temperature_field = "temperature_c");

// Vertex neighbourhoods in compressed-row form: the neighbours of vertex v are
// neighbours[offsets[v] .. offsets[v+1]).
struct VertexGraph {
  std::vector<int> offsets;
  std::vector<int> neighbours;
  int Degree(int v) const { return offsets[v + 1] - offsets[v]; }
};

// The edge graph of the mesh with coincident vertices joined: vertices closer than
// `weld_tolerance_m` are linked to each other (zero-length edges), so a seam or a vertex
// duplicated across an emissivity boundary does not split a region; and pieces that meet
// along an edge divided differently on each side (T-junctions: a border vertex within
// 0.1 mm of another piece's border edge) are linked to that edge's ends. O(V log V + F log F).
VertexGraph BuildVertexGraph(const ThermalMesh& mesh, double weld_tolerance_m = 1e-6);

// The same mesh with every face's vertices mapped to one representative per group of
// coincident vertices (the lowest index), for algorithms that need shared vertices (iso-
// line clipping along a path of triangles). Groups: coordinates equal once rounded to
// `weld_tolerance_m` (exact duplicates always are). O(V log V).
std::vector<int> WeldMap(const std::vector<Eigen::Vector3d>& points_in_world,
                         double weld_tolerance_m = 1e-6);

}  // namespace hw::analyze
