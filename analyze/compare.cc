#include "analyze/compare.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>
#include <utility>
#include <vector>

#include "analyze/mesh_fields.h"
#include "analyze/point_index.h"
#include "core/option_check.h"

namespace hw::analyze {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kChunk = 2048;      // vertices per parallel chunk
constexpr int kNearVertices = 8;  // BEFORE vertices whose faces are tried for the closest point

// The closest point of triangle abc to p, as barycentric weights (Ericson, Real-Time
// Collision Detection, 5.1.5).
Eigen::Vector3d ClosestBarycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                   const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = 1 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1 - v - w, v, w};
}

}  // namespace

std::string CompareOptions::Check() const {
  using core::InRange;
  using core::OptionFail;
  if (!(max_distance_m > 0 && max_distance_m <= 100)) return OptionFail("max_distance_m", max_distance_m, "in (0, 100]");
  if (!InRange(region_radius_m, 0, 10)) return OptionFail("region_radius_m", region_radius_m, "in [0, 10]");
  if (!InRange(max_normal_angle_deg, 1, 180)) return OptionFail("max_normal_angle_deg", max_normal_angle_deg, "in [1, 180]");
  if (!InRange(spot_match_distance_m, 0, 100)) return OptionFail("spot_match_distance_m", spot_match_distance_m, "in [0, 100]");
  if (!InRange(spot_match_radius_factor, 0, 100)) {
    return OptionFail("spot_match_radius_factor", spot_match_radius_factor, "in [0, 100]");
  }
  if (!InRange(area_change_relative, 0, 100)) return OptionFail("area_change_relative", area_change_relative, "in [0, 100]");
  if (!InRange(area_change_sigmas, 0, 100)) return OptionFail("area_change_sigmas", area_change_sigmas, "in [0, 100]");
  if (!InRange(peak_change_k, 0, 1000)) return OptionFail("peak_change_k", peak_change_k, "in [0, 1000]");
  if (!InRange(threads, 0, 256)) return OptionFail("threads", threads, "in [0, 256]");
  return "";
}

TemperatureDifference MapDifference(const ThermalMesh& before, const ThermalMesh& after, const Alignment& alignment,
                                    const CompareOptions& options) {
  if (const std::string bad = options.Check(); !bad.empty()) throw std::invalid_argument(bad);
  const size_t n = static_cast<size_t>(after.NumVertices());
  TemperatureDifference result;
  result.before_c.assign(n, kNaN);
  result.difference_k.assign(n, kNaN);
  result.after_area_m2 = after.TotalArea();
  if (!before.HasTemperature()) return result;

  // BEFORE: its vertices with faces in a k-d tree, and each vertex's faces.
  std::vector<int> used;
  for (int v = 0; v < before.NumVertices(); ++v) {
    if (before.normals[static_cast<size_t>(v)].squaredNorm() > 0) used.push_back(v);
  }
  const PointIndex index(before.points_in_world, used);
  std::vector<int> offsets(static_cast<size_t>(before.NumVertices()) + 1, 0), vertex_faces;
  for (const Eigen::Vector3i& f : before.faces) {
    for (int k = 0; k < 3; ++k) ++offsets[static_cast<size_t>(f[k]) + 1];
  }
  for (size_t v = 0; v + 1 < offsets.size(); ++v) offsets[v + 1] += offsets[v];
  vertex_faces.resize(static_cast<size_t>(offsets.back()));
  {
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (int f = 0; f < before.NumFaces(); ++f) {
      for (int k = 0; k < 3; ++k) vertex_faces[static_cast<size_t>(fill[static_cast<size_t>(before.faces[static_cast<size_t>(f)][k])]++)] = f;
    }
  }
  const std::vector<double> before_area = VertexAreas(before);
  const std::vector<double> after_area = VertexAreas(after);

  const Eigen::Isometry3d before_from_after = alignment.after_from_before.inverse();
  const double cos_normal = std::cos(options.max_normal_angle_deg * kPi / 180);
  const int chunks = static_cast<int>((n + kChunk - 1) / kChunk);
  ParallelChunks(chunks, options.threads, [&](int chunk) {
    std::vector<int> near, region;
    const size_t end = std::min(n, static_cast<size_t>(chunk + 1) * kChunk);
    for (size_t v = static_cast<size_t>(chunk) * kChunk; v < end; ++v) {
      if (after.normals[v].squaredNorm() == 0) continue;  // no face: no surface to compare
      const Eigen::Vector3d p = before_from_after * after.points_in_world[v];
      const Eigen::Vector3d normal = before_from_after.linear() * after.normals[v];
      // The closest point on a nearby BEFORE face that faces the same way.
      index.Nearest(p, kNearVertices, &near);
      double best_d2 = options.max_distance_m * options.max_distance_m;
      int best_face = -1;
      Eigen::Vector3d best_bary, best_point;
      for (int u : near) {
        for (int i = offsets[static_cast<size_t>(u)]; i < offsets[static_cast<size_t>(u) + 1]; ++i) {
          const int f = vertex_faces[static_cast<size_t>(i)];
          const Eigen::Vector3i& t = before.faces[static_cast<size_t>(f)];
          const Eigen::Vector3d& a = before.points_in_world[static_cast<size_t>(t[0])];
          const Eigen::Vector3d& b = before.points_in_world[static_cast<size_t>(t[1])];
          const Eigen::Vector3d& c = before.points_in_world[static_cast<size_t>(t[2])];
          if ((b - a).cross(c - a).normalized().dot(normal) < cos_normal) continue;
          const Eigen::Vector3d bary = ClosestBarycentric(p, a, b, c);
          const Eigen::Vector3d q = bary[0] * a + bary[1] * b + bary[2] * c;
          const double d2 = (q - p).squaredNorm();
          if (d2 <= best_d2) {
            best_d2 = d2;
            best_face = f;
            best_bary = bary;
            best_point = q;
          }
        }
      }
      if (best_face < 0) continue;
      double value = kNaN;
      if (options.region_radius_m > 0) {
        index.Within(best_point, options.region_radius_m, &region);
        std::sort(region.begin(), region.end());  // a fixed summation order
        double sum = 0, weight = 0;
        for (int u : region) {
          const double t = before.temperature_c[static_cast<size_t>(u)];
          if (!std::isfinite(t) || before.normals[static_cast<size_t>(u)].dot(normal) < cos_normal) continue;
          sum += before_area[static_cast<size_t>(u)] * t;
          weight += before_area[static_cast<size_t>(u)];
        }
        if (weight > 0) value = sum / weight;
      }
      if (std::isnan(value)) {  // no radius, or no observed vertex within it
        const Eigen::Vector3i& t = before.faces[static_cast<size_t>(best_face)];
        value = 0;
        for (int k = 0; k < 3; ++k) value += best_bary[k] * before.temperature_c[static_cast<size_t>(t[k])];
      }
      result.before_c[v] = value;  // NaN when an unobserved vertex took part
      if (after.HasTemperature()) result.difference_k[v] = after.temperature_c[v] - value;  // NaN propagates
    }
  });

  std::vector<std::pair<double, double>> weighted, weighted_abs;
  double sum = 0;
  for (size_t v = 0; v < n; ++v) {
    const double d = result.difference_k[v];
    if (!std::isfinite(d)) continue;
    ++result.compared_vertices;
    result.compared_area_m2 += after_area[v];
    sum += after_area[v] * d;
    weighted.emplace_back(d, after_area[v]);
    weighted_abs.emplace_back(std::abs(d), after_area[v]);
  }
  if (result.compared_area_m2 > 0) {
    result.mean_k = sum / result.compared_area_m2;
    result.median_k = WeightedMedian(weighted);
    result.p95_abs_k = WeightedQuantile(weighted_abs, 0.95);
  }
  return result;
}

std::vector<SpotChange> MatchSpots(const std::vector<Spot>& before, const std::vector<Spot>& after,
                                   const Alignment& alignment, const CompareOptions& options) {
  if (const std::string bad = options.Check(); !bad.empty()) throw std::invalid_argument(bad);
  // Every admissible pair, closest first; ties by BEFORE then AFTER order.
  std::vector<std::tuple<double, size_t, size_t>> pairs;
  for (size_t i = 0; i < before.size(); ++i) {
    const Eigen::Vector3d centroid = alignment.after_from_before * before[i].centroid_in_world;
    for (size_t j = 0; j < after.size(); ++j) {
      if (before[i].hot != after[j].hot) continue;
      const double distance = (centroid - after[j].centroid_in_world).norm();
      const double gate = options.spot_match_distance_m +
                          options.spot_match_radius_factor * std::max(before[i].radius_m, after[j].radius_m);
      if (distance <= gate) pairs.emplace_back(distance, i, j);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  std::vector<int> partner_of_after(after.size(), -1);
  std::vector<char> before_taken(before.size(), 0);
  std::vector<double> distance_of_after(after.size(), kNaN);
  for (const auto& [distance, i, j] : pairs) {
    if (before_taken[i] || partner_of_after[j] >= 0) continue;
    before_taken[i] = 1;
    partner_of_after[j] = static_cast<int>(i);
    distance_of_after[j] = distance;
  }

  std::vector<SpotChange> changes;
  auto fill_before = [](SpotChange* c, const Spot& s) {
    c->before_id = s.id;
    c->area_before_m2 = s.area_m2;
    c->peak_before_c = s.peak_c;
    c->delta_before_k = s.delta_k;
    c->before_possible_reflection = s.possible_reflection;
  };
  for (size_t j = 0; j < after.size(); ++j) {
    SpotChange c;
    const Spot& a = after[j];
    c.after_id = a.id;
    c.area_after_m2 = a.area_m2;
    c.peak_after_c = a.peak_c;
    c.delta_after_k = a.delta_k;
    c.after_possible_reflection = a.possible_reflection;
    if (partner_of_after[j] < 0) {
      c.kinds.push_back("appeared");
    } else {
      const Spot& b = before[static_cast<size_t>(partner_of_after[j])];
      fill_before(&c, b);
      c.distance_m = distance_of_after[j];
      const double change_m2 = a.area_m2 - b.area_m2;
      const double sigma_m2 = std::hypot(a.area_sigma_m2, b.area_sigma_m2);
      const bool beyond_noise = std::abs(change_m2) > options.area_change_sigmas * sigma_m2;
      // A spot that had no area (a single vertex) grew by any measurable amount.
      const bool beyond_relative = b.area_m2 > 0 ? std::abs(change_m2) / b.area_m2 > options.area_change_relative
                                                 : change_m2 > 0;
      if (beyond_noise && beyond_relative) c.kinds.push_back(change_m2 > 0 ? "grew" : "shrank");
      const double peak_change_k = a.peak_c - b.peak_c;
      if (peak_change_k > options.peak_change_k) c.kinds.push_back("heated");
      if (peak_change_k < -options.peak_change_k) c.kinds.push_back("cooled");
    }
    changes.push_back(std::move(c));
  }
  for (size_t i = 0; i < before.size(); ++i) {
    if (before_taken[i]) continue;
    SpotChange c;
    fill_before(&c, before[i]);
    c.kinds.push_back("vanished");
    changes.push_back(std::move(c));
  }
  return changes;
}

}  // namespace hw::analyze
