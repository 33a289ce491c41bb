#include "reconstruct/thermal_eval.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "core/error.h"
#include "core/median.h"
#include "core/ply.h"
#include "reconstruct/mesh_query.h"
#include "reconstruct/option_check.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

using internal::Fail;

std::string TemperatureErrorOptions::Check() const {
  if (!(max_distance_m > 0) || !std::isfinite(max_distance_m)) {
    return Fail("max_distance_m", max_distance_m, "finite and > 0 m");
  }
  if (!(edge_exclusion_m >= 0) || !std::isfinite(edge_exclusion_m)) {
    return Fail("edge_exclusion_m", edge_exclusion_m, "finite and >= 0 m");
  }
  if (!(uniform_radius_m > 0) || !std::isfinite(uniform_radius_m)) {
    return Fail("uniform_radius_m", uniform_radius_m, "finite and > 0 m");
  }
  if (!(uniform_range_k > 0) || !std::isfinite(uniform_range_k)) {
    return Fail("uniform_range_k", uniform_range_k, "finite and > 0 K");
  }
  if (!(resolved_footprints >= 0) || !(resolved_footprints <= 10)) {
    return Fail("resolved_footprints", resolved_footprints, "in [0, 10] footprints");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  return "";
}

TemperatureTruth ReadTemperatureTruth(const std::filesystem::path& scene_ply) {
  return TemperatureTruthFromPly(core::ReadPly(scene_ply), scene_ply);
}

TemperatureTruth TemperatureTruthFromPly(const core::PlyMesh& mesh, const std::filesystem::path& scene_ply) {
  if (!mesh.HasPositions()) throw core::InputError(scene_ply, "no vertex positions (x y z)");
  if (mesh.faces.empty()) throw core::InputError(scene_ply, "no faces: a truth mesh needs triangles");
  const core::PlyProperty* temperature = mesh.Find("temperature_c");
  if (!temperature) throw core::InputError(scene_ply, "no vertex property temperature_c");
  TemperatureTruth truth;
  truth.vertices = mesh.Positions();
  truth.faces = mesh.faces;
  truth.temperature_c = temperature->values;
  for (size_t i = 0; i < truth.temperature_c.size(); ++i) {
    if (!std::isfinite(truth.temperature_c[i])) {
      throw core::InputError(scene_ply, "vertex " + std::to_string(i) + ": temperature_c is not finite");
    }
  }
  if (const core::PlyProperty* emissivity = mesh.Find("emissivity")) truth.emissivity = emissivity->values;
  return truth;
}

namespace {

// Widens [lo, hi] by the range of the linear field t (t[k] at corner k) of triangle
// (a, b, c) over its part inside the ball (q, r). That part is the triangle cut by a disc
// (the ball's section by the triangle's plane), a convex set: a linear function is extreme
// on it at a triangle vertex inside the disc, a crossing of an edge and the circle, or the
// circle's point along ±the in-plane gradient when it lies inside the triangle. The first
// two are the ends of each edge's piece inside the ball.
void WidenByFieldInBall(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                        const Eigen::Vector3d& t, const Eigen::Vector3d& q, double r, double& lo, double& hi) {
  const auto take = [&](double value) {
    lo = std::min(lo, value);
    hi = std::max(hi, value);
  };
  const Eigen::Vector3d corners[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& u = corners[k];
    const Eigen::Vector3d d = corners[(k + 1) % 3] - u;
    const double tu = t[k], tv = t[(k + 1) % 3];
    // |u + s d − q|² = r²: s² |d|² + 2 s d·(u − q) + |u − q|² − r² = 0.
    const Eigen::Vector3d w = u - q;
    const double dd = d.squaredNorm();
    if (!(dd > 0)) {
      if (w.norm() <= r) take(tu);
      continue;
    }
    const double half_b = d.dot(w), cc = w.squaredNorm() - r * r;
    const double disc = half_b * half_b - dd * cc;
    if (disc < 0) continue;
    const double root = std::sqrt(disc);
    const double s0 = std::max(0.0, (-half_b - root) / dd), s1 = std::min(1.0, (-half_b + root) / dd);
    if (s0 > s1) continue;
    take(tu + s0 * (tv - tu));
    take(tu + s1 * (tv - tu));
  }
  // The field in the plane: T(a + α e1 + β e2) = t_a + α (t_b − t_a) + β (t_c − t_a).
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const double det = g11 * g22 - g12 * g12;
  if (!(det > 1e-12 * g11 * g22)) return;  // degenerate: the edges cover it
  const Eigen::Vector3d normal = e1.cross(e2).normalized();
  const double height = (q - a).dot(normal);
  const double rho2 = r * r - height * height;
  if (!(rho2 > 0)) return;
  // Gradient g = α e1 + β e2 with g·e1 = t_b − t_a, g·e2 = t_c − t_a.
  const double dt1 = t[1] - t[0], dt2 = t[2] - t[0];
  const double ga = (g22 * dt1 - g12 * dt2) / det, gb = (g11 * dt2 - g12 * dt1) / det;
  const Eigen::Vector3d gradient = ga * e1 + gb * e2;
  const double gradient_norm = gradient.norm();
  if (!(gradient_norm > 0)) return;
  const Eigen::Vector3d centre = q - height * normal;
  for (const double sign : {-1.0, 1.0}) {
    const Eigen::Vector3d x = centre + sign * std::sqrt(rho2) / gradient_norm * gradient - a;
    const double x1 = x.dot(e1), x2 = x.dot(e2);
    const double alpha = (g22 * x1 - g12 * x2) / det, beta = (g11 * x2 - g12 * x1) / det;
    constexpr double kInside = -1e-12;
    if (alpha >= kInside && beta >= kInside && 1 - alpha - beta >= kInside) take(t[0] + alpha * dt1 + beta * dt2);
  }
}

// The model's boundary vertices: those of edges used by exactly one face. Edges as sorted
// 64-bit keys (8 bytes per face side, no hash-map nodes: a 4M-vertex model has 23M sides).
std::vector<Eigen::Vector3d> BoundaryVertices(const std::vector<Eigen::Vector3f>& positions,
                                              const std::vector<Eigen::Vector3i>& faces) {
  std::vector<uint64_t> edges;
  edges.reserve(faces.size() * 3);
  for (const Eigen::Vector3i& face : faces) {
    for (int k = 0; k < 3; ++k) {
      assert(face[k] >= 0 && face[k] < static_cast<int>(positions.size()));
      const int u = face[k], v = face[(k + 1) % 3];
      edges.push_back((static_cast<uint64_t>(std::min(u, v)) << 32) | static_cast<uint32_t>(std::max(u, v)));
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<uint8_t> on_boundary(positions.size(), 0);
  for (size_t i = 0; i < edges.size();) {
    size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) {
      on_boundary[edges[i] >> 32] = 1;
      on_boundary[edges[i] & 0xffffffffu] = 1;
    }
    i = j;
  }
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < positions.size(); ++i) {
    if (on_boundary[i]) out.push_back(positions[i].cast<double>());
  }
  return out;
}

struct ErrorSummary {
  double rmse = TemperatureErrorStats::kNaN, p95_abs = TemperatureErrorStats::kNaN;
  double mean = TemperatureErrorStats::kNaN, max_abs = TemperatureErrorStats::kNaN;
};

// The gains the camera's gain/offset map may take (TemperatureErrors).
constexpr double kMinCameraGain = 0.9, kMaxCameraGain = 1.1;

ErrorSummary Summarize(const std::vector<double>& errors) {
  ErrorSummary s;
  if (errors.empty()) return s;
  double sum = 0, sum2 = 0;
  std::vector<double> abs_errors;
  abs_errors.reserve(errors.size());
  for (const double e : errors) {
    sum += e;
    sum2 += e * e;
    abs_errors.push_back(std::abs(e));
  }
  const double n = static_cast<double>(errors.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum2 / n);
  std::sort(abs_errors.begin(), abs_errors.end());
  const double rank = 0.95 * (n - 1);
  const size_t below = static_cast<size_t>(std::floor(rank));
  const size_t above = std::min(below + 1, abs_errors.size() - 1);
  s.p95_abs = abs_errors[below] + (rank - static_cast<double>(below)) * (abs_errors[above] - abs_errors[below]);
  s.max_abs = abs_errors.back();
  return s;
}

}  // namespace

TemperatureErrorStats TemperatureErrors(const TemperatureComparison& comparison,
                                        const std::vector<double>& estimate_c) {
  assert(estimate_c.size() == comparison.truth_c.size());
  assert(comparison.uniform.size() == comparison.truth_c.size());
  TemperatureErrorStats stats;
  stats.vertices = static_cast<int>(estimate_c.size());
  std::vector<double> errors, uniform_errors;
  for (size_t i = 0; i < estimate_c.size(); ++i) {
    if (!std::isfinite(estimate_c[i])) continue;
    ++stats.observed;
    if (!std::isfinite(comparison.truth_c[i])) continue;
    const double error = estimate_c[i] - comparison.truth_c[i];
    errors.push_back(error);
    if (comparison.uniform[i]) uniform_errors.push_back(error);
  }
  std::vector<double> low_errors;
  if (comparison.truth_emissivity.size() == estimate_c.size()) {
    for (size_t i = 0; i < estimate_c.size(); ++i) {
      if (std::isfinite(estimate_c[i]) && std::isfinite(comparison.truth_c[i]) &&
          comparison.truth_emissivity[i] < kLowEmissivity) {
        low_errors.push_back(estimate_c[i] - comparison.truth_c[i]);
      }
    }
  }
  const ErrorSummary low = Summarize(low_errors);
  stats.compared_low_emissivity = static_cast<int>(low_errors.size());
  stats.rmse_low_emissivity_k = low.rmse;
  stats.mean_low_emissivity_k = low.mean;
  stats.compared = static_cast<int>(errors.size());
  stats.compared_uniform = static_cast<int>(uniform_errors.size());
  const ErrorSummary all = Summarize(errors), uniform = Summarize(uniform_errors);
  stats.rmse_k = all.rmse;
  stats.p95_abs_k = all.p95_abs;
  stats.mean_k = all.mean;
  stats.max_abs_k = all.max_abs;
  stats.rmse_uniform_k = uniform.rmse;
  stats.p95_abs_uniform_k = uniform.p95_abs;
  stats.mean_uniform_k = uniform.mean;

  // The camera's radiometric error acts on its reading: estimate ≈ gain · truth + offset,
  // fitted over the uniform subset by least squares of the estimate on the truth (the errors
  // are the estimate's). Regressing the truth on the estimate instead shrinks the gain
  // towards 0 by the estimate's error variance over its total (regression dilution): a few
  // vertices tens of kelvin off — a reflection on metal, a misplaced edge — took it to 0.004
  // on a tracked sweep, and the "error after the map" became the truth's own spread. Robust:
  // refitted twice on the vertices within max(5 σ, 1 K) (σ = 1.4826 · MAD) of the last fit,
  // so that such vertices do not tilt it; the error after the map is then reported over every
  // vertex.
  struct Pair {
    double truth, estimate;
  };
  std::vector<Pair> pairs;
  for (size_t i = 0; i < estimate_c.size(); ++i) {
    if (!std::isfinite(estimate_c[i]) || !comparison.uniform[i] || !std::isfinite(comparison.truth_c[i])) continue;
    pairs.push_back({comparison.truth_c[i], estimate_c[i]});
  }
  std::vector<uint8_t> inlier(pairs.size(), 1);
  double gain = std::numeric_limits<double>::quiet_NaN(), offset = gain;
  for (int pass = 0; pass < 3; ++pass) {
    double n = 0, mean_t = 0, mean_e = 0;
    for (size_t i = 0; i < pairs.size(); ++i) {
      if (!inlier[i]) continue;
      ++n;
      mean_t += (pairs[i].truth - mean_t) / n;
      mean_e += (pairs[i].estimate - mean_e) / n;
    }
    double stt = 0, ste = 0;
    for (size_t i = 0; i < pairs.size(); ++i) {
      if (!inlier[i]) continue;
      stt += (pairs[i].truth - mean_t) * (pairs[i].truth - mean_t);
      ste += (pairs[i].truth - mean_t) * (pairs[i].estimate - mean_e);
    }
    if (n < 2 || !(stt > 0)) break;
    // A camera's radiometric gain is off by a few per cent at most (±2 % for the standard
    // class, 5 % for low-cost cores): a fit beyond ±10 % is fitting the fusion's own loss of
    // contrast (misregistered hot edges smeared onto cool surroundings: 0.23 on a tracked
    // sweep), which the error after the map must keep.
    gain = std::clamp(ste / stt, kMinCameraGain, kMaxCameraGain);
    offset = mean_e - gain * mean_t;
    if (pass == 2) break;
    std::vector<double> residual(pairs.size());
    for (size_t i = 0; i < pairs.size(); ++i) residual[i] = pairs[i].estimate - (gain * pairs[i].truth + offset);
    const double median = core::Median(residual);
    std::vector<double> deviation(residual.size());
    for (size_t i = 0; i < residual.size(); ++i) deviation[i] = std::abs(residual[i] - median);
    const double sigma = 1.4826 * core::Median(std::move(deviation));
    // At least 1 K: the trimming is for gross errors, not for resolving the noise (a
    // two-valued residual has a MAD of 0).
    const double limit = std::max(5 * sigma, 1.0);
    for (size_t i = 0; i < pairs.size(); ++i) inlier[i] = std::abs(residual[i] - median) <= limit;
  }
  if (std::isfinite(gain) && !comparison.resolved.empty()) {
    assert(comparison.resolved.size() == estimate_c.size());
    std::vector<double> residuals;
    for (size_t i = 0; i < estimate_c.size(); ++i) {
      if (!comparison.resolved[i] || !std::isfinite(estimate_c[i])) continue;
      residuals.push_back((estimate_c[i] - offset) / gain - comparison.truth_c[i]);
    }
    const ErrorSummary resolved = Summarize(residuals);
    stats.compared_resolved = static_cast<int>(residuals.size());
    stats.rmse_resolved_affine_k = resolved.rmse;
    stats.p95_abs_resolved_affine_k = resolved.p95_abs;
  }
  if (std::isfinite(gain)) {
    stats.affine_gain = gain;
    stats.affine_offset_k = offset;
    std::vector<double> residuals;
    residuals.reserve(pairs.size());
    for (const Pair& p : pairs) residuals.push_back((p.estimate - offset) / gain - p.truth);
    const ErrorSummary affine = Summarize(residuals);
    stats.rmse_affine_k = affine.rmse;
    stats.p95_abs_affine_k = affine.p95_abs;
  }
  return stats;
}

TemperatureComparison CompareTemperatures(const std::vector<Eigen::Vector3f>& model_positions,
                                          const std::vector<Eigen::Vector3i>& model_faces,
                                          const std::vector<double>& estimate_c,
                                          const TemperatureTruth& truth,
                                          const TemperatureErrorOptions& options,
                                          const std::vector<double>& footprint_m) {
  assert(options.Check().empty());
  assert(estimate_c.size() == model_positions.size());
  assert(footprint_m.empty() || footprint_m.size() == model_positions.size());
  assert(truth.temperature_c.size() == truth.vertices.size());
  const size_t n = model_positions.size();
  TemperatureComparison out;
  out.truth_c.assign(n, TemperatureErrorStats::kNaN);
  out.uniform.assign(n, 0);
  out.truth_emissivity.assign(n, TemperatureErrorStats::kNaN);
  const bool has_emissivity = truth.emissivity.size() == truth.vertices.size();

  std::optional<PointGrid> boundary;
  if (options.edge_exclusion_m > 0) {
    boundary.emplace(BoundaryVertices(model_positions, model_faces), options.edge_exclusion_m);
  }
  // One grid serves both the closest-point search and the ball around the closest point.
  const TriangleGrid grid(truth.vertices, truth.faces,
                          std::max(options.max_distance_m, options.uniform_radius_m));
  const double r = options.uniform_radius_m;
  // The resolved subset's balls: as wide as the footprints ask, up to kMaxResolvedRadiusM
  // (a vertex whose pixels reach farther resolves nothing an audit measures: not resolved).
  const bool resolve = !footprint_m.empty();
  double resolved_cell_m = r;
  if (resolve) {
    out.resolved.assign(n, 0);
    for (const double f : footprint_m) {
      if (std::isfinite(f)) resolved_cell_m = std::max(resolved_cell_m, std::min(options.resolved_footprints * f, kMaxResolvedRadiusM));
    }
  }
  std::optional<TriangleGrid> resolved_grid;
  if (resolve && resolved_cell_m > r) resolved_grid.emplace(truth.vertices, truth.faces, resolved_cell_m);
  // The range of the truth's field over the ball (q, radius) of `on` (a grid whose cells
  // reach it), widening [lo, hi]; false as soon as it exceeds uniform_range_k. `visited`
  // holds the last vertex that looked at a face (a face is binned in several cells).
  const auto in_range = [&](const TriangleGrid& on, const Eigen::Vector3d& q, double radius, int i,
                            std::vector<int>& visited, double& lo, double& hi) {
    return on.VisitCandidates(q, radius, [&](int f) {
      if (visited[f] == i) return true;
      visited[f] = i;
      const Eigen::Vector3i& g = truth.faces[f];
      const Eigen::Vector3d &a = truth.vertices[g[0]], &b = truth.vertices[g[1]], &c = truth.vertices[g[2]];
      if ((ClosestPointOnTriangle(q, a, b, c) - q).norm() > radius) return true;
      const Eigen::Vector3d tf(truth.temperature_c[g[0]], truth.temperature_c[g[1]], truth.temperature_c[g[2]]);
      WidenByFieldInBall(a, b, c, tf, q, radius, lo, hi);
      return hi - lo <= options.uniform_range_k;
    });
  };
  ForEachBand(static_cast<int>(n), options.num_threads, [&](int begin, int end) {
    std::vector<int> visited(truth.faces.size(), -1);  // the last model vertex that looked at a face
    std::vector<int> visited_resolved(resolved_grid ? truth.faces.size() : 0, -1);
    for (int i = begin; i < end; ++i) {
      const Eigen::Vector3d p = model_positions[i].cast<double>();
      const auto closest = grid.FindClosest(p, options.max_distance_m);
      if (!closest) continue;
      // Strictly closer than the exclusion distance: with edge_exclusion_m = 0 nothing is.
      if (boundary) {
        const auto d = boundary->NearestDistance(p, options.edge_exclusion_m);
        if (d && *d < options.edge_exclusion_m) continue;
      }
      const Eigen::Vector3i& face = truth.faces[closest->face];
      const Eigen::Vector3d t(truth.temperature_c[face[0]], truth.temperature_c[face[1]],
                              truth.temperature_c[face[2]]);
      out.truth_c[i] = closest->on_face.weights.dot(t);
      if (has_emissivity) {
        int corner = 0;
        closest->on_face.weights.maxCoeff(&corner);
        out.truth_emissivity[i] = truth.emissivity[face[corner]];
        if (out.truth_emissivity[i] < kLowEmissivity) continue;  // not uniform: scored apart
      }

      // The range over the ball, stopping as soon as it exceeds uniform_range_k.
      const Eigen::Vector3d& q = closest->on_face.point;
      double lo = out.truth_c[i], hi = out.truth_c[i];
      out.uniform[i] = in_range(grid, q, r, i, visited, lo, hi);
      if (!resolve || !out.uniform[i] || !std::isfinite(footprint_m[i])) continue;
      const double radius = std::max(r, options.resolved_footprints * footprint_m[i]);
      if (radius <= r) {
        out.resolved[i] = 1;
      } else if (radius <= kMaxResolvedRadiusM) {
        // The larger ball holds the smaller one: its range starts from the uniform one's.
        out.resolved[i] = in_range(*resolved_grid, q, radius, i, visited_resolved, lo, hi);
      }
    }
  });
  out.stats = TemperatureErrors(out, estimate_c);
  return out;
}

std::array<ViewQualityClass, 3> TemperatureErrorsByViewQuality(const TemperatureComparison& comparison,
                                                              const TemperatureErrorStats& stats,
                                                              const std::vector<double>& estimate_c,
                                                              const std::vector<double>& quality) {
  assert(estimate_c.size() == comparison.truth_c.size() && quality.size() == comparison.truth_c.size());
  std::array<ViewQualityClass, 3> classes;
  std::vector<double> sorted;
  for (size_t i = 0; i < quality.size(); ++i) {
    if (comparison.uniform[i] && std::isfinite(quality[i])) sorted.push_back(quality[i]);
  }
  if (sorted.empty()) return classes;
  std::sort(sorted.begin(), sorted.end());
  // Class k holds the qualities of ranks [k·n/3, (k+1)·n/3): ties at a border go to the
  // lower class (upper_bound), so that one quality never lands in two classes.
  const size_t n = sorted.size();
  // A vertex is in the first class whose upper bound (its last rank's quality) it does not
  // exceed; the range reported is that of the vertices the class then holds.
  const std::array<double, 2> upper = {sorted[std::max<size_t>(n / 3, 1) - 1], sorted[std::max<size_t>(2 * n / 3, 1) - 1]};
  const bool affine = std::isfinite(stats.affine_gain) && std::isfinite(stats.affine_offset_k);
  std::array<double, 3> sum{}, sum_affine{};
  for (size_t i = 0; i < quality.size(); ++i) {
    if (!comparison.uniform[i] || !std::isfinite(quality[i])) continue;
    int k = 0;
    while (k < 2 && quality[i] > upper[k]) ++k;
    ViewQualityClass& c = classes[k];
    c.quality_from = std::isfinite(c.quality_from) ? std::min(c.quality_from, quality[i]) : quality[i];
    c.quality_to = std::isfinite(c.quality_to) ? std::max(c.quality_to, quality[i]) : quality[i];
    if (!std::isfinite(estimate_c[i])) continue;
    const double error = estimate_c[i] - comparison.truth_c[i];
    const double error_affine = (estimate_c[i] - stats.affine_offset_k) / stats.affine_gain - comparison.truth_c[i];
    ++classes[k].compared;
    sum[k] += error * error;
    sum_affine[k] += error_affine * error_affine;
  }
  for (int k = 0; k < 3; ++k) {
    if (classes[k].compared == 0) continue;
    classes[k].rmse_k = std::sqrt(sum[k] / classes[k].compared);
    if (affine) classes[k].rmse_affine_k = std::sqrt(sum_affine[k] / classes[k].compared);
  }
  return classes;
}

}  // namespace hw::reconstruct
