#pragma once

// Before/after comparison of two aligned models: BEFORE's temperature carried onto AFTER's
// vertices and the difference, and how the hot and cold spots changed.

#include <limits>
#include <string>
#include <vector>

#include "analyze/align.h"
#include "analyze/spot.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct CompareOptions {
  // m, an AFTER vertex farther than this from BEFORE's surface has no correspondence
  // (NaN), (0, 100].
  double max_distance_m = 0.05;
  // m, BEFORE's temperature is averaged (by vertex area) over BEFORE's vertices within this
  // radius of the corresponding point, on the same side (normals within
  // max_normal_angle_deg), to compare regions rather than single noisy vertices; 0 = the
  // value interpolated at the point, [0, 10].
  double region_radius_m = 0.05;
  // degrees, no correspondence between surfaces whose normals differ by more (the other
  // side of a thin wall), [1, 180].
  double max_normal_angle_deg = 60;
  // m, spots match when their centroids (BEFORE's mapped into AFTER's frame) are within
  // spot_match_distance_m + spot_match_radius_factor × max(radius_m of the two), [0, 100].
  double spot_match_distance_m = 0.1;
  // dimensionless, [0, 100].
  double spot_match_radius_factor = 1.0;
  // "grew"/"shrank": |area_after − area_before| / area_before above this (dimensionless,
  // [0, 100]) AND above area_change_sigmas × √(σ_before² + σ_after²) (dimensionless, [0, 100]).
  double area_change_relative = 0.2;
  double area_change_sigmas = 2;
  // K, "heated"/"cooled": the peak temperature changed by more than this, [0, 1000].
  double peak_change_k = 1.0;
  // Worker threads, [0, 256]; 0 = one per hardware thread. The result does not depend on it.
  int threads = 0;

  // "" or "field: must be …, got …".
  std::string Check() const;
};

struct TemperatureDifference {
  std::vector<double> before_c;      // per AFTER vertex: BEFORE's temperature there, NaN if none
  std::vector<double> difference_k;  // after − before per AFTER vertex; NaN where either is unobserved or no correspondence
  int compared_vertices = 0;
  double mean_k = 0, median_k = 0, p95_abs_k = 0;  // area-weighted over compared surface
  double compared_area_m2 = 0, after_area_m2 = 0;
};

// For every AFTER vertex: the corresponding point on BEFORE's surface (AFTER's vertex mapped
// by alignment.after_from_before⁻¹, then the closest point on a BEFORE triangle near its
// nearest BEFORE vertices whose normal agrees), BEFORE's temperature there (averaged over
// region_radius_m), and the difference. A vertex's area is a third of its faces' areas; the
// statistics weigh vertices by it (median and p95: the smallest value whose cumulative
// weight reaches 50 % / 95 %); all 0 when nothing was compared. A mesh without temperature
// gives NaN everywhere it would be needed (no exception). Throws std::invalid_argument when
// options.Check() fails.
TemperatureDifference MapDifference(const ThermalMesh& before, const ThermalMesh& after, const Alignment& alignment,
                                    const CompareOptions& options);

struct SpotChange {
  std::vector<std::string> kinds;  // any of "appeared", "vanished", "grew", "shrank", "heated", "cooled"; empty = unchanged
  std::string before_id, after_id;  // "" when absent
  double distance_m = std::numeric_limits<double>::quiet_NaN();  // centroid distance after alignment
  double area_before_m2 = std::numeric_limits<double>::quiet_NaN();
  double area_after_m2 = std::numeric_limits<double>::quiet_NaN();
  double peak_before_c = std::numeric_limits<double>::quiet_NaN();
  double peak_after_c = std::numeric_limits<double>::quiet_NaN();
  double delta_before_k = std::numeric_limits<double>::quiet_NaN();
  double delta_after_k = std::numeric_limits<double>::quiet_NaN();
  // The spots' Spot::possible_reflection: a change whose reading may be a reflection (a
  // spot that "appeared" where the thermographer's body was mirrored, one that "vanished"
  // because the second scan looked from elsewhere) is not a change of the asset until a
  // second view confirms it.
  bool before_possible_reflection = false, after_possible_reflection = false;
};

// Whether a change stands on a reading that may be a reflection and so needs a second view
// before it is called a change of the asset: a change (any kind) with either spot flagged,
// or an unchanged pair with both flagged. An unchanged pair with one spot flagged needs
// none: the other scan, from another angle, read the same.
inline bool NeedsSecondView(const SpotChange& change) {
  const bool either = change.before_possible_reflection || change.after_possible_reflection;
  const bool both = change.before_possible_reflection && change.after_possible_reflection;
  return change.kinds.empty() ? both : either;
}

// Pairs BEFORE's spots with AFTER's: same kind (hot/cold), centroids within the gate (see
// CompareOptions), one-to-one, closest pairs first (ties by list order). A pair's kinds:
// "grew"/"shrank" when the area changed beyond both thresholds, "heated"/"cooled" when
// peak_c rose/fell by more than peak_change_k (for a cold spot "cooled" means its minimum
// got colder). Unpaired BEFORE spots "vanished", unpaired AFTER spots "appeared".
// Order: AFTER's spots in their order (paired or appeared), then the vanished in BEFORE's
// order. The reflection flags are copied from the spots (run CheckReflections first). Throws std::invalid_argument when options.Check() fails.
std::vector<SpotChange> MatchSpots(const std::vector<Spot>& before, const std::vector<Spot>& after,
                                   const Alignment& alignment, const CompareOptions& options);

}  // namespace hw::analyze
