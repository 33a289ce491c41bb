#pragma once

// Scoring detected spots against a synthetic scan's truth/hotspots.yaml (scan-format.md):
// which planted spots were found, the relative errors of area, length and width, whether
// the reported uncertainty covers the error, and which detections match nothing (false
// spots).

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/spot.h"
#include "analyze/spot_detect.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct TruthSpot {
  std::string id;
  bool hot = true;
  double temperature_c = 0;
  double threshold_c = 0;
  double area_m2 = 0;
  double observed_area_m2 = -1;    // -1 when the file does not give it
  double observed_fraction = -1;   // -1 when the file does not give it
  double length_m = 0;
  double width_m = 0;
  Eigen::Vector3d centroid_in_world = Eigen::Vector3d::Zero();
};

// Reads truth/hotspots.yaml strictly (unknown keys, missing fields, wrong types → InputError
// with path, key and line).
std::vector<TruthSpot> ReadTruthSpots(const std::filesystem::path& path);

struct TruthMatch {
  std::string truth_id;
  std::string spot_id;           // "" when not found
  double distance_m = 0;         // centroid to centroid
  double area_error = 0;         // (measured − true) / true
  double length_error = 0;
  double width_error = 0;
  double length_error_m = 0;     // measured − true, metres
  double width_error_m = 0;
  bool area_covered = false;     // |area error| <= 2 σ (the reported one-sigma uncertainty)
  // ΔT against the truth's: 2 (temperature_c − threshold_c), the fixtures' threshold being
  // half-way from the spot's background to its extreme; K, and within 2 delta_sigma_k.
  double delta_error_k = 0;
  bool delta_covered = false;
  bool length_covered = false;
  bool width_covered = false;
  // The same spot re-measured with the truth's own boundary (threshold_c): the measurement's
  // error without the difference between the truth's boundary and the default half-ΔT
  // one (they differ for spots narrower than a few heat-spreading lengths, whose peak never
  // reaches the plateau the truth's threshold was set from). NaN when not measured.
  double area_error_at_threshold = std::numeric_limits<double>::quiet_NaN();
  double length_error_at_threshold = std::numeric_limits<double>::quiet_NaN();
  double width_error_at_threshold = std::numeric_limits<double>::quiet_NaN();
  double length_error_at_threshold_m = std::numeric_limits<double>::quiet_NaN();
  double width_error_at_threshold_m = std::numeric_limits<double>::quiet_NaN();
};

struct TruthScore {
  std::vector<TruthMatch> matches;     // one per truth spot considered
  std::vector<std::string> false_spots;  // detections matching no truth spot
  // Of those, the ones the reflection check flagged (Spot::possible_reflection): reported
  // with the right diagnosis, but still false spots.
  std::vector<std::string> false_flagged_as_reflections;
  // Found planted spots the reflection check flagged: a true spot wrongly suspected.
  std::vector<std::string> found_flagged_as_reflections;
  // Detections matched to a truth spot the scan saw too little of to be scored
  // (observed_only, 0 < observed_fraction <= min_observed_fraction): neither found nor
  // false; (truth id, spot id).
  std::vector<std::pair<std::string, std::string>> partly_observed;
  int found = 0;
  int missed = 0;
  double max_abs_area_error = 0;       // over found spots
  double max_abs_length_error = 0;
  double max_abs_width_error = 0;
  double max_abs_delta_error_k = 0;    // ΔT, K, over found spots
  double max_abs_area_error_at_threshold = 0;  // over re-measured spots
  double max_abs_length_error_at_threshold = 0;
  double max_abs_width_error_at_threshold = 0;
};

// Matches detections to truth spots of the same kind, one to one, nearest centroid first,
// within max(gate_m, half the truth's length). `observed_only`: score only truth spots with
// observed_fraction > min_observed_fraction and compare the area with observed_area_m2
// (a reconstruction sees part of a pipe band); lengths and widths are then scored only
// for spots observed in full (fraction >= 0.99). A truth spot seen less (but seen) still
// takes its detection, listed in partly_observed, so that finding it is never a false spot.
TruthScore ScoreAgainstTruth(const std::vector<Spot>& spots, const std::vector<TruthSpot>& truth,
                             bool observed_only = false, double min_observed_fraction = 0.5,
                             double gate_m = 0.1);

// Fills the *_at_threshold errors of every found spot of `score`: the region beyond the
// truth's threshold_c grown from the matched spot's peak (SpotFinder::MeasureAtLevels, on
// the finder that detected `spots`).
void AddThresholdErrors(const SpotFinder& finder, const std::vector<Spot>& spots,
                        const std::vector<TruthSpot>& truth, bool observed_only, TruthScore* score);

}  // namespace hw::analyze
