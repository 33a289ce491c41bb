#pragma once

// Per-vertex quantities over a ThermalMesh that spot detection and comparison share.

#include <utility>
#include <vector>

#include "analyze/thermal_mesh.h"

namespace hw::analyze {

// The smallest value of (value, weight) pairs whose cumulative weight reaches fraction × the
// total; NaN for none. Sorts `samples`.
double WeightedQuantile(std::vector<std::pair<double, double>>& samples, double fraction);

// Area-weighted median: WeightedQuantile at 0.5.
inline double WeightedMedian(std::vector<std::pair<double, double>>& samples) {
  return WeightedQuantile(samples, 0.5);
}

// One third of the area of every face around each vertex, m².
std::vector<double> VertexAreas(const ThermalMesh& mesh);

// The local background: area-weighted median of the field within `radius_m`, evaluated per
// cell of a grid of radius/2 and taken by every vertex of the cell. Each cell contributes
// at most 48 vertices (evenly strided, weights scaled to the cell's area) so the cost does
// not grow with the mesh's local density. NaN for vertices with a non-finite value or no area.
std::vector<double> LocalBackground(const ThermalMesh& mesh, const std::vector<double>& field,
                                    const std::vector<double>& vertex_area, double radius_m);

}  // namespace hw::analyze
