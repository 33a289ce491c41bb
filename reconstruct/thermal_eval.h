#pragma once

// Temperature accuracy of a reconstructed model: each model vertex's estimated surface
// temperature against the true temperature at the closest point of a reference mesh that
// carries one per vertex (truth/scene.ply of a synthetic scan, scan-format.md "truth/").
//
// Typical use:
//   const TemperatureTruth truth = ReadTemperatureTruth(scan / "truth" / "scene.ply");
//   const TemperatureComparison c =
//       CompareTemperatures(mesh.positions, mesh.faces, fused_c, truth, {});
//   ... c.stats.rmse_k, c.stats.rmse_uniform_k
//   const TemperatureErrorStats latest = TemperatureErrors(c, latest_c);  // another method

#include <cstdint>
#include <array>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/ply.h"

namespace hw::reconstruct {

// The truth a model's temperatures are compared with: a mesh with a temperature per vertex.
struct TemperatureTruth {
  std::vector<Eigen::Vector3d> vertices;  // m, world frame
  std::vector<Eigen::Vector3i> faces;
  std::vector<double> temperature_c;  // per vertex, true surface temperature
  std::vector<double> emissivity;     // per vertex, normal emissivity (may be empty)
};

// From truth/scene.ply (vertex properties x y z temperature_c [emissivity], faces). Throws
// core::InputError naming the file when it cannot be read as PLY, lacks positions, faces or
// the temperature_c property, or holds a non-finite temperature_c (naming the vertex).
TemperatureTruth ReadTemperatureTruth(const std::filesystem::path& scene_ply);
// The same from a mesh already read (scene_ply only names it in errors).
TemperatureTruth TemperatureTruthFromPly(const core::PlyMesh& mesh, const std::filesystem::path& scene_ply);

// Which model vertices are compared, and which form the "uniform" subset. Defaults for a
// 5 mm voxel model of a hand-held RGB-D + thermal scan at 0.5–3 m.
struct TemperatureErrorOptions {
  // Model vertices farther than this from the truth surface are not compared (the geometry
  // is wrong there, not the temperature), m, > 0. 1 cm = two 5 mm voxels, beyond the few mm
  // a tracked TSDF model deviates from the truth.
  double max_distance_m = 0.01;
  // ... nor those closer than this to a boundary vertex of the model mesh (an edge used by
  // exactly one face: depth edges, holes and silhouettes, where edge pixels are
  // misregistered and thermal rays graze the surface), m, >= 0 (0: none excluded). 1 cm:
  // two voxels, the reach of flying depth pixels into the TSDF.
  double edge_exclusion_m = 0.01;
  // "Uniform" subset: also drop vertices where the true temperature varies by more than
  // uniform_range_k within uniform_radius_m of the closest truth point (hot-spot borders a
  // 5 mm voxel grid cannot resolve; reported separately, never hidden). The radius is two
  // voxels (what trilinear voxel interpolation blurs, and about two thermal pixels of a
  // 320×240, 56° camera at 1.5 m), m, > 0.
  double uniform_radius_m = 0.01;
  // K, > 0. 0.5 K: a quarter of a radiometric core's ±2 K accuracy and 10× its NETD, so
  // variation below it does not show in the error budget.
  double uniform_range_k = 0.5;
  // "Resolved" subset: the uniform subset less the vertices where the truth varies by more
  // than uniform_range_k within this many thermal pixel footprints (the vertex's
  // footprint_m given to CompareTemperatures) of the closest truth point, when that reaches
  // beyond uniform_radius_m. A fixed radius is two pixels at 1.5 m but under one at 4 m
  // (a 320×240, 56° camera's pixel is 13 mm there), where a slot or a corner a few cm from
  // another surface is mixed into every pixel that sees it: an error of the camera's
  // resolution, not of the fusion. Two footprints is the reach of what a pixel centred up
  // to half a pixel from the vertex integrates — its box (±0.5 px) and the optics' PSF
  // (±~1 px for an f/1 LWIR lens: Airy radius 1.22 λ N ≈ 12 µm at 10 µm, a 12–17 µm
  // pixel pitch). Dimensionless, >= 0 (0: the subset is the uniform one).
  double resolved_footprints = 2;
  // Threads for the per-vertex queries, >= 0 (0: hardware concurrency). The result does not
  // depend on it.
  int num_threads = 0;

  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

struct TemperatureErrorStats {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  int vertices = 0;          // model vertices given
  int observed = 0;          // with a finite estimate
  int compared = 0;          // observed, near the truth, away from model boundaries
  int compared_uniform = 0;  // compared and in the uniform subset
  // Over `compared` (error = estimate − truth), K; NaN when none. p95_abs_k: the 95th
  // percentile of |error| interpolated linearly between order statistics (rank 0.95·(n−1),
  // numpy's default).
  double rmse_k = kNaN, p95_abs_k = kNaN, mean_k = kNaN, max_abs_k = kNaN;
  // Over compared_uniform, K; NaN when none.
  double rmse_uniform_k = kNaN, p95_abs_uniform_k = kNaN, mean_uniform_k = kNaN;
  // Over compared_uniform after taking out the camera's radiometric calibration error (a gain
  // and an offset per session, ±1–2 K for uncooled cameras, which no fusion rule can see and
  // the calibration bench measures): estimate ≈ affine_gain · truth + affine_offset_k fitted
  // by least squares of the estimate on the truth, the gain held within [0.9, 1.1] (a camera
  // is off by a few per cent; beyond, the fit would be taking out the fusion's own loss of
  // contrast), refitted twice without the vertices
  // beyond max(5 σ (MAD), 1 K) of the fit, and the error of (estimate − offset) / gain over every
  // vertex; NaN with fewer than 2 vertices or no spread. (Until stop 58 the fit regressed
  // the truth on the estimate, which the estimate's outliers shrank towards a gain of 0.)
  double affine_gain = kNaN, affine_offset_k = kNaN;
  double rmse_affine_k = kNaN, p95_abs_affine_k = kNaN;
  // Over the resolved subset (TemperatureComparison::resolved) after the uniform subset's
  // gain/offset map above, K; 0 compared and NaN without that map or a resolved subset.
  int compared_resolved = 0;
  double rmse_resolved_affine_k = kNaN, p95_abs_resolved_affine_k = kNaN;
  // Over compared vertices on low-emissivity surfaces (truth emissivity < kLowEmissivity:
  // bare metal, where most of the reading is reflection), K; NaN when none.
  int compared_low_emissivity = 0;
  double rmse_low_emissivity_k = kNaN, mean_low_emissivity_k = kNaN;
};

// Surfaces below this normal emissivity are scored apart (TemperatureErrorStats).
inline constexpr double kLowEmissivity = 0.5;
// A vertex whose resolved ball (TemperatureErrorOptions::resolved_footprints) would be wider
// than this is not resolved, m: its pixels average over more than an audit's spots.
inline constexpr double kMaxResolvedRadiusM = 0.1;

// truth_c and uniform depend on the geometry only, not on an estimate: TemperatureErrors
// applies them to any estimate over the same model vertices.
struct TemperatureComparison {
  // Per model vertex, the true temperature at the closest truth point, °C; NaN where the
  // vertex is not compared whatever its estimate (beyond max_distance_m or within
  // edge_exclusion_m of a model boundary).
  std::vector<double> truth_c;
  // Per model vertex, 1 where truth_c is finite, the true temperature within
  // uniform_radius_m of the closest truth point spans at most uniform_range_k, and (when the
  // truth has emissivity) the surface is not a low-emissivity one (below
  // kLowEmissivity: those are reported apart).
  std::vector<uint8_t> uniform;
  // Per model vertex, the truth's normal emissivity at the closest truth point (the nearest
  // vertex of its triangle: no blending across a patch border); NaN where truth_c is or the
  // truth has none.
  std::vector<double> truth_emissivity;
  // Per model vertex, 1 where uniform and the true temperature also spans at most
  // uniform_range_k within max(uniform_radius_m, resolved_footprints · footprint_m) of the
  // closest truth point (TemperatureErrorOptions::resolved_footprints); empty when
  // CompareTemperatures was given no footprints.
  std::vector<uint8_t> resolved;
  TemperatureErrorStats stats;  // of the estimate given to CompareTemperatures
};

// Per model vertex (positions in the truth's frame, m; faces of the model mesh):
// - the closest truth point within max_distance_m (exact point-to-triangle search in a grid)
//   and the true temperature there: the barycentric interpolation of the closest triangle's
//   vertex temperatures; none (NaN) beyond;
// - NaN as well within edge_exclusion_m (Euclidean) of a boundary vertex of the model;
// - the uniform flag: the range of the truth's piecewise-linear temperature over the ball of
//   uniform_radius_m around the closest truth point, computed exactly on every truth
//   triangle the ball meets (the truth's vertices in the ball, its edges' crossings of the
//   sphere, the in-plane extremes of the linear field on the ball's disc), so it does not
//   depend on how coarsely the truth is tessellated away from its vertices;
// - when footprint_m is given (per model vertex, m: a thermal pixel's size on the surface,
//   PointTemperatures::footprint_m; NaN = unobserved, then not resolved), the resolved flag:
//   the same range over the ball of max(uniform_radius_m, resolved_footprints · footprint)
//   (TemperatureComparison::resolved);
// then the stats of estimate_c (per model vertex, °C, NaN = unobserved).
// Asserts options.Check() == "", estimate_c.size() == model_positions.size(), footprint_m
// empty or of that size, model face indices in range and truth.temperature_c.size() ==
// truth.vertices.size().
// Memory: the truth's triangles in a grid of max(max_distance_m, uniform_radius_m) cells.
TemperatureComparison CompareTemperatures(const std::vector<Eigen::Vector3f>& model_positions,
                                          const std::vector<Eigen::Vector3i>& model_faces,
                                          const std::vector<double>& estimate_c,
                                          const TemperatureTruth& truth,
                                          const TemperatureErrorOptions& options,
                                          const std::vector<double>& footprint_m = {});

// Stats of another estimate over the same vertices (reuses truth_c/uniform: cheap, for
// comparing several methods on one model). Asserts estimate_c has one value per vertex.
TemperatureErrorStats TemperatureErrors(const TemperatureComparison& comparison,
                                        const std::vector<double>& estimate_c);

// The errors of an estimate in three classes of view quality, so that the rules can be
// compared where the views were poor — grazing, blurred, far, or right after a shutter event
// — which is where confidence weighting is meant to beat the plain mean (issue 9): the
// uniform subset's vertices (comparison.uniform) with a finite `quality` split at its
// terciles over them, lowest first. `quality` per vertex: e.g. the plain mean's confidence,
// the mean C_R of all the views of the vertex's region (PointTemperatures::confidence of
// ThermalMethod::kMean), the same for every estimate compared. Per class: the quality range
// [from, to], the vertices compared (estimate finite as well), the RMSE (K) and the RMSE
// after `stats`'s gain/offset map (the estimate's own over the whole uniform subset:
// TemperatureErrors), NaN when none. Asserts one value per vertex in both vectors.
struct ViewQualityClass {
  double quality_from = TemperatureErrorStats::kNaN, quality_to = TemperatureErrorStats::kNaN;
  int compared = 0;
  double rmse_k = TemperatureErrorStats::kNaN, rmse_affine_k = TemperatureErrorStats::kNaN;
};
std::array<ViewQualityClass, 3> TemperatureErrorsByViewQuality(const TemperatureComparison& comparison,
                                                              const TemperatureErrorStats& stats,
                                                              const std::vector<double>& estimate_c,
                                                              const std::vector<double>& quality);

}  // namespace hw::reconstruct
