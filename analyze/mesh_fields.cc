#include "analyze/mesh_fields.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

namespace hw::analyze {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
size_t U(int i) { return static_cast<size_t>(i); }

}  // namespace

double WeightedQuantile(std::vector<std::pair<double, double>>& samples, double fraction) {
  if (samples.empty()) return kNaN;
  std::sort(samples.begin(), samples.end());
  double total = 0;
  for (const auto& s : samples) total += s.second;
  double sum = 0;
  for (const auto& s : samples) {
    sum += s.second;
    if (sum >= fraction * total) return s.first;
  }
  return samples.back().first;
}

// One third of the area of every face around each vertex, m².
std::vector<double> VertexAreas(const ThermalMesh& mesh) {
  std::vector<double> area(U(mesh.NumVertices()), 0.0);
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const double a = mesh.FaceArea(f) / 3;
    for (int k = 0; k < 3; ++k) area[U(mesh.faces[U(f)][k])] += a;
  }
  return area;
}

// The local background: area-weighted median of the field within `radius_m`, evaluated per
// cell of a grid of radius/2 and taken by every vertex of the cell. Each cell contributes
// at most kPerCell vertices (evenly strided, weights scaled to the cell's area) so the cost
// does not grow with the mesh's local density.
std::vector<double> LocalBackground(const ThermalMesh& mesh, const std::vector<double>& field,
                                    const std::vector<double>& vertex_area, double radius_m) {
  constexpr int kPerCell = 48;
  const double cell_m = radius_m / 2;
  struct Key {
    std::int64_t x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      return static_cast<size_t>(k.x * 73856093 ^ k.y * 19349663 ^ k.z * 83492791);
    }
  };
  auto key_of = [&](const Eigen::Vector3d& p) {
    return Key{static_cast<std::int64_t>(std::floor(p.x() / cell_m)),
               static_cast<std::int64_t>(std::floor(p.y() / cell_m)),
               static_cast<std::int64_t>(std::floor(p.z() / cell_m))};
  };
  std::unordered_map<Key, std::vector<int>, KeyHash> cells;
  for (int v = 0; v < mesh.NumVertices(); ++v) {
    if (std::isfinite(field[U(v)]) && vertex_area[U(v)] > 0) cells[key_of(mesh.points_in_world[U(v)])].push_back(v);
  }
  struct Sampled {
    std::vector<std::pair<double, double>> values;  // (field, weight)
  };
  std::unordered_map<Key, Sampled, KeyHash> sampled;
  for (const auto& [key, members] : cells) {
    Sampled s;
    const size_t stride = std::max<size_t>(1, members.size() / kPerCell);
    double area_all = 0, area_kept = 0;
    for (int v : members) area_all += vertex_area[U(v)];
    for (size_t i = 0; i < members.size(); i += stride) {
      s.values.emplace_back(field[U(members[i])], vertex_area[U(members[i])]);
      area_kept += vertex_area[U(members[i])];
    }
    for (auto& value : s.values) value.second *= area_all / area_kept;
    sampled.emplace(key, std::move(s));
  }
  std::unordered_map<Key, double, KeyHash> cell_background;
  std::vector<std::pair<double, double>> gathered;
  const int reach = 2;  // cells within radius of the cell centre
  for (const auto& [key, members] : cells) {
    (void)members;
    gathered.clear();
    for (std::int64_t dx = -reach; dx <= reach; ++dx) {
      for (std::int64_t dy = -reach; dy <= reach; ++dy) {
        for (std::int64_t dz = -reach; dz <= reach; ++dz) {
          if (dx * dx + dy * dy + dz * dz > (reach + 1) * (reach + 1) - 1) continue;  // a ball
          const auto it = sampled.find(Key{key.x + dx, key.y + dy, key.z + dz});
          if (it == sampled.end()) continue;
          gathered.insert(gathered.end(), it->second.values.begin(), it->second.values.end());
        }
      }
    }
    cell_background[key] = WeightedMedian(gathered);
  }
  std::vector<double> background(U(mesh.NumVertices()), kNaN);
  for (const auto& [key, members] : cells) {
    const double b = cell_background[key];
    for (int v : members) background[U(v)] = b;
  }
  return background;
}

}  // namespace hw::analyze
