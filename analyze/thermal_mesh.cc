#include "analyze/thermal_mesh.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <unordered_map>
#include <cmath>
#include <numeric>
#include <string>

#include <Eigen/Geometry>

#include "analyze/srgb.h"
#include "core/error.h"

namespace hw::analyze {
namespace {

std::vector<double> OptionalField(const core::PlyMesh& ply, const char* name,
                                  const std::vector<int>& kept) {
  const core::PlyProperty* p = ply.Find(name);
  if (p == nullptr) return {};
  std::vector<double> out(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    const double v = p->values[static_cast<size_t>(kept[i])];
    out[i] = std::isfinite(v) ? v : std::nan("");
  }
  return out;
}


// Surfaces that meet along an edge but were divided differently (a wall and a ceiling
// meshed on their own, a junction of two patches) share no vertices there: every vertex
// of one side lies on an edge of the other (a T-junction). Each mesh-border vertex lying
// within the tolerance of another piece's border edge is linked to that edge's two ends,
// so regions grow across such seams as across welded ones.
void StitchTJunctions(const ThermalMesh& mesh, const std::vector<int>& rep, double weld_tolerance_m,
                      std::vector<std::pair<int, int>>* edges) {
  // Border edges: used by one face once coincident vertices are joined (counted by sorting
  // packed keys: a map of 15 million edges would take seconds).
  std::vector<std::uint64_t> keys;
  keys.reserve(mesh.faces.size() * 3);
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      auto a = static_cast<std::uint64_t>(rep[static_cast<size_t>(f[k])]);
      auto b = static_cast<std::uint64_t>(rep[static_cast<size_t>(f[(k + 1) % 3])]);
      if (a > b) std::swap(a, b);
      keys.push_back(a << 32 | b);
    }
  }
  std::sort(keys.begin(), keys.end());
  std::vector<std::pair<int, int>> border;
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    if (j - i == 1) border.emplace_back(static_cast<int>(keys[i] >> 32), static_cast<int>(keys[i] & 0xffffffffu));
    i = j;
  }
  if (border.empty()) return;
  // A T-junction's vertex is off the other side's edge by the rounding of float32 positions
  // (~1e-7 relative, so ~1e-6 m at a few metres); 1e-4 m is far below any mesh edge.
  const double tolerance = std::max(weld_tolerance_m, 1e-4);
  const double cell = 0.05;
  auto key = [&](double x, double y, double z) {
    return std::array<std::int64_t, 3>{static_cast<std::int64_t>(std::floor(x / cell)),
                                       static_cast<std::int64_t>(std::floor(y / cell)),
                                       static_cast<std::int64_t>(std::floor(z / cell))};
  };
  struct CellHash {
    size_t operator()(const std::array<std::int64_t, 3>& k) const {
      return static_cast<size_t>(k[0] * 73856093 ^ k[1] * 19349663 ^ k[2] * 83492791);
    }
  };
  std::unordered_map<std::array<std::int64_t, 3>, std::vector<int>, CellHash> grid;
  for (size_t e = 0; e < border.size(); ++e) {
    const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(border[e].first)];
    const Eigen::Vector3d& b = mesh.points_in_world[static_cast<size_t>(border[e].second)];
    const Eigen::Vector3d lo = a.cwiseMin(b).array() - tolerance, hi = a.cwiseMax(b).array() + tolerance;
    const auto k0 = key(lo.x(), lo.y(), lo.z()), k1 = key(hi.x(), hi.y(), hi.z());
    // A long border edge spans many cells; cap the work for pathological inputs.
    if ((k1[0] - k0[0] + 1) * (k1[1] - k0[1] + 1) * (k1[2] - k0[2] + 1) > 4096) continue;
    for (std::int64_t x = k0[0]; x <= k1[0]; ++x) {
      for (std::int64_t y = k0[1]; y <= k1[1]; ++y) {
        for (std::int64_t z = k0[2]; z <= k1[2]; ++z) grid[{x, y, z}].push_back(static_cast<int>(e));
      }
    }
  }
  std::vector<char> on_border(mesh.points_in_world.size(), 0);
  for (const auto& [a, b] : border) on_border[static_cast<size_t>(a)] = on_border[static_cast<size_t>(b)] = 1;
  for (size_t v = 0; v < on_border.size(); ++v) {
    if (!on_border[v]) continue;
    const Eigen::Vector3d& p = mesh.points_in_world[v];
    const auto it = grid.find(key(p.x(), p.y(), p.z()));
    if (it == grid.end()) continue;
    for (int e : it->second) {
      const int a = border[static_cast<size_t>(e)].first, b = border[static_cast<size_t>(e)].second;
      if (a == static_cast<int>(v) || b == static_cast<int>(v)) continue;
      const Eigen::Vector3d& pa = mesh.points_in_world[static_cast<size_t>(a)];
      const Eigen::Vector3d ab = mesh.points_in_world[static_cast<size_t>(b)] - pa;
      const double t = std::clamp((p - pa).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      if ((pa + t * ab - p).norm() > tolerance) continue;
      for (int end : {a, b}) {
        edges->emplace_back(static_cast<int>(v), end);
        edges->emplace_back(end, static_cast<int>(v));
      }
    }
  }
}

}  // namespace

double ThermalMesh::FaceArea(int f) const {
  const Eigen::Vector3i& t = faces[static_cast<size_t>(f)];
  const Eigen::Vector3d& a = points_in_world[static_cast<size_t>(t[0])];
  return 0.5 * (points_in_world[static_cast<size_t>(t[1])] - a)
                   .cross(points_in_world[static_cast<size_t>(t[2])] - a)
                   .norm();
}

double ThermalMesh::TotalArea() const {
  double sum = 0;
  for (int f = 0; f < NumFaces(); ++f) sum += FaceArea(f);
  return sum;
}

ThermalMesh MakeThermalMesh(const core::PlyMesh& ply, const std::filesystem::path& path_for_errors,
                            const std::string& temperature_field) {
  ThermalMesh mesh;
  MeshLoadReport& report = mesh.report;
  if (!ply.HasPositions()) throw core::InputError(path_for_errors, "no x y z vertex properties");
  const std::vector<Eigen::Vector3d> positions = ply.Positions();
  report.vertices_read = static_cast<int>(positions.size());
  report.faces_read = static_cast<int>(ply.faces.size());
  if (ply.faces.empty()) {
    throw core::InputError(path_for_errors, "no triangles: the analyzer needs a mesh, not a point cloud");
  }
  const core::PlyProperty* temperature = ply.Find(temperature_field);
  if (temperature == nullptr && temperature_field != "temperature_c") {
    throw core::InputError(path_for_errors, "no vertex property '" + temperature_field + "'");
  }

  // Keep finite vertices, renumbered.
  std::vector<int> new_index(positions.size(), -1);
  std::vector<int> kept;
  kept.reserve(positions.size());
  for (size_t v = 0; v < positions.size(); ++v) {
    if (positions[v].allFinite()) {
      new_index[v] = static_cast<int>(kept.size());
      kept.push_back(static_cast<int>(v));
    } else {
      ++report.vertices_non_finite;
    }
  }
  mesh.points_in_world.reserve(kept.size());
  for (int v : kept) mesh.points_in_world.push_back(positions[static_cast<size_t>(v)]);

  int faces_non_finite = 0;
  mesh.faces.reserve(ply.faces.size());
  for (const Eigen::Vector3i& f : ply.faces) {
    const Eigen::Vector3i g(new_index[static_cast<size_t>(f[0])], new_index[static_cast<size_t>(f[1])],
                            new_index[static_cast<size_t>(f[2])]);
    if (g.minCoeff() < 0) {
      ++faces_non_finite;
      continue;
    }
    if (g[0] == g[1] || g[1] == g[2] || g[0] == g[2]) {
      ++report.faces_degenerate;
      continue;
    }
    const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(g[0])];
    const double twice_area = (mesh.points_in_world[static_cast<size_t>(g[1])] - a)
                                  .cross(mesh.points_in_world[static_cast<size_t>(g[2])] - a)
                                  .norm();
    if (!(twice_area >= 2e-14)) {
      ++report.faces_degenerate;
      continue;
    }
    mesh.faces.push_back(g);
  }
  if (mesh.faces.empty()) {
    throw core::InputError(path_for_errors,
                           "every triangle is degenerate or has a non-finite vertex (" +
                               std::to_string(report.faces_read) + " faces read)");
  }
  if (report.vertices_non_finite > 0) {
    report.warnings.push_back(std::to_string(report.vertices_non_finite) +
                              " vertices with non-finite x y z dropped with their " +
                              std::to_string(faces_non_finite) + " faces");
  }
  if (report.faces_degenerate > 0) {
    report.warnings.push_back(std::to_string(report.faces_degenerate) +
                              " degenerate triangles (repeated vertex or zero area) dropped");
  }

  if (temperature != nullptr) {
    report.has_temperature = true;
    mesh.temperature_field = temperature_field;
    mesh.temperature_c.resize(kept.size());
    for (size_t i = 0; i < kept.size(); ++i) {
      const double t = temperature->values[static_cast<size_t>(kept[i])];
      if (std::isinf(t)) ++report.temperatures_non_finite;
      mesh.temperature_c[i] = std::isfinite(t) ? t : std::nan("");
      if (!std::isfinite(mesh.temperature_c[i])) ++report.temperatures_unobserved;
    }
    if (report.temperatures_non_finite > 0) {
      report.warnings.push_back(std::to_string(report.temperatures_non_finite) + " infinite " +
                                temperature_field + " values treated as unobserved");
    }
  } else {
    report.warnings.push_back("no temperature_c vertex property: only colour can be rendered, "
                              "no spot can be measured");
  }
  if (ply.HasColors()) {
    report.has_colour = true;
    const std::vector<core::Rgb8> colours = ply.Colors();
    mesh.colour_linear.reserve(kept.size());
    for (int v : kept) {
      const core::Rgb8& c = colours[static_cast<size_t>(v)];
      mesh.colour_linear.emplace_back(SrgbToLinear(c[0] / 255.0f), SrgbToLinear(c[1] / 255.0f),
                                      SrgbToLinear(c[2] / 255.0f));
    }
  }
  mesh.confidence = OptionalField(ply, "temperature_confidence", kept);
  mesh.views = OptionalField(ply, "temperature_views", kept);
  mesh.std_c = OptionalField(ply, "temperature_std_c", kept);
  mesh.footprint_m = OptionalField(ply, "temperature_footprint_m", kept);
  mesh.emissivity = OptionalField(ply, "temperature_emissivity", kept);
  {
    const std::vector<double> vx = OptionalField(ply, "temperature_view_x", kept);
    const std::vector<double> vy = OptionalField(ply, "temperature_view_y", kept);
    const std::vector<double> vz = OptionalField(ply, "temperature_view_z", kept);
    if (!vx.empty() && !vy.empty() && !vz.empty()) {
      mesh.view_m.resize(kept.size());
      for (size_t i = 0; i < kept.size(); ++i) mesh.view_m[i] = Eigen::Vector3d(vx[i], vy[i], vz[i]);
    } else if (!vx.empty() || !vy.empty() || !vz.empty()) {
      mesh.report.warnings.push_back(
          "temperature_view_x/_y/_z: only some of the three are present; the reflection check is off");
    }
  }

  // Area-weighted normals (the cross product's length is twice the area).
  mesh.normals.assign(kept.size(), Eigen::Vector3d::Zero());
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(f[0])];
    const Eigen::Vector3d n = (mesh.points_in_world[static_cast<size_t>(f[1])] - a)
                                  .cross(mesh.points_in_world[static_cast<size_t>(f[2])] - a);
    for (int k = 0; k < 3; ++k) mesh.normals[static_cast<size_t>(f[k])] += n;
  }
  for (Eigen::Vector3d& n : mesh.normals) {
    const double norm = n.norm();
    n = norm > 0 ? Eigen::Vector3d(n / norm) : Eigen::Vector3d::Zero();
  }
  return mesh;
}

ThermalMesh ReadThermalMesh(const std::filesystem::path& path, const std::string& temperature_field) {
  return MakeThermalMesh(core::ReadPly(path), path, temperature_field);
}

std::vector<int> WeldMap(const std::vector<Eigen::Vector3d>& points_in_world, double weld_tolerance_m) {
  // Points are grouped by their coordinates rounded to the tolerance (sorted keys): exact
  // duplicates, the case of seams and split vertices, always share a key; two points within
  // the tolerance but on either side of a rounding boundary are not joined (harmless: the
  // T-junction stitching of BuildVertexGraph links such borders). A sweep along x alone
  // would be quadratic on marching-cubes meshes, whose vertices share x by the thousand.
  const int n = static_cast<int>(points_in_world.size());
  using Key = std::array<std::int64_t, 3>;
  std::vector<std::pair<Key, int>> keyed(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector3d& p = points_in_world[static_cast<size_t>(v)];
    keyed[static_cast<size_t>(v)] = {Key{std::llround(p.x() / weld_tolerance_m), std::llround(p.y() / weld_tolerance_m),
                                         std::llround(p.z() / weld_tolerance_m)},
                                     v};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> rep(static_cast<size_t>(n));
  for (size_t i = 0; i < keyed.size();) {
    size_t j = i;
    while (j < keyed.size() && keyed[j].first == keyed[i].first) ++j;
    for (size_t k = i; k < j; ++k) rep[static_cast<size_t>(keyed[k].second)] = keyed[i].second;  // lowest index
    i = j;
  }
  return rep;
}

VertexGraph BuildVertexGraph(const ThermalMesh& mesh, double weld_tolerance_m) {
  const int n = mesh.NumVertices();
  const std::vector<int> rep = WeldMap(mesh.points_in_world, weld_tolerance_m);
  std::vector<std::pair<int, int>> edges;
  edges.reserve(mesh.faces.size() * 6 + static_cast<size_t>(n));
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      const int a = f[k], b = f[(k + 1) % 3];
      edges.emplace_back(a, b);
      edges.emplace_back(b, a);
    }
  }
  for (int v = 0; v < n; ++v) {
    const int r = rep[static_cast<size_t>(v)];
    if (r != v) {
      edges.emplace_back(v, r);
      edges.emplace_back(r, v);
    }
  }
  StitchTJunctions(mesh, rep, weld_tolerance_m, &edges);
  // Weld-group members link to their representative: a region grows across a seam in two hops.
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  VertexGraph graph;
  graph.offsets.assign(static_cast<size_t>(n) + 1, 0);
  for (const auto& e : edges) ++graph.offsets[static_cast<size_t>(e.first) + 1];
  for (int v = 0; v < n; ++v) graph.offsets[static_cast<size_t>(v) + 1] += graph.offsets[static_cast<size_t>(v)];
  graph.neighbours.resize(edges.size());
  for (size_t i = 0; i < edges.size(); ++i) graph.neighbours[i] = edges[i].second;
  return graph;
}

}  // namespace hw::analyze
