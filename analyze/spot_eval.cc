#include "analyze/spot_eval.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "core/atomic_file.h"
#include "core/yaml_reader.h"

namespace hw::analyze {

std::vector<TruthSpot> ReadTruthSpots(const std::filesystem::path& path) {
  const core::YamlReader reader(path);
  const YAML::Node root = reader.LoadMapping(core::ReadFile(path, core::kMaxConfigFileBytes));
  const core::YamlReader::Fields top = reader.Mapping(root, "", {"hotspots"});
  const YAML::Node& list = top.Required("hotspots");
  if (!list.IsSequence()) reader.Fail("hotspots", "must be a list, got " + core::Describe(list), list);
  std::vector<TruthSpot> out;
  size_t i = 0;
  for (const YAML::Node& node : list) {
    const std::string key = "hotspots[" + std::to_string(i++) + "]";
    const core::YamlReader::Fields f =
        reader.Mapping(node, key,
                       {"id", "kind", "temperature_c", "threshold_c", "area_m2", "observed_area_m2",
                        "observed_fraction", "length_m", "width_m", "centroid_m"});
    TruthSpot t;
    t.id = reader.String(f.Required("id"), f.Path("id"));
    const std::string kind = reader.String(f.Required("kind"), f.Path("kind"));
    if (kind != "hot" && kind != "cold") {
      reader.Fail(f.Path("kind"), "must be hot or cold, got '" + core::Printable(kind) + "'", f.Required("kind"));
    }
    t.hot = kind == "hot";
    t.temperature_c = reader.Number(f.Required("temperature_c"), f.Path("temperature_c"));
    t.threshold_c = reader.Number(f.Required("threshold_c"), f.Path("threshold_c"));
    t.area_m2 = reader.Number(f.Required("area_m2"), f.Path("area_m2"));
    if (f.Has("observed_area_m2")) {
      t.observed_area_m2 = reader.Number(f.Required("observed_area_m2"), f.Path("observed_area_m2"));
    }
    if (f.Has("observed_fraction")) {
      t.observed_fraction = reader.Number(f.Required("observed_fraction"), f.Path("observed_fraction"));
    }
    t.length_m = reader.Number(f.Required("length_m"), f.Path("length_m"));
    t.width_m = reader.Number(f.Required("width_m"), f.Path("width_m"));
    const std::vector<double> c = reader.NumberList(f.Required("centroid_m"), f.Path("centroid_m"), 3);
    t.centroid_in_world = Eigen::Vector3d(c[0], c[1], c[2]);
    out.push_back(t);
  }
  return out;
}

TruthScore ScoreAgainstTruth(const std::vector<Spot>& spots, const std::vector<TruthSpot>& truth,
                             bool observed_only, double min_observed_fraction, double gate_m) {
  TruthScore score;
  struct Pair {
    double distance;
    size_t truth, spot;
  };
  std::vector<size_t> considered, matchable;
  std::vector<char> scored(truth.size(), 0);
  for (size_t t = 0; t < truth.size(); ++t) {
    const double f = truth[t].observed_fraction;
    scored[t] = !observed_only || f > min_observed_fraction;
    if (scored[t]) considered.push_back(t);
    if (!observed_only || f != 0) matchable.push_back(t);  // -1: not given
  }
  std::vector<Pair> pairs;
  for (size_t t : matchable) {
    const double gate = std::max(gate_m, 0.5 * truth[t].length_m);
    for (size_t s = 0; s < spots.size(); ++s) {
      if (spots[s].hot != truth[t].hot) continue;
      const double d = (spots[s].centroid_in_world - truth[t].centroid_in_world).norm();
      if (d <= gate) pairs.push_back({d, t, s});
    }
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.distance < b.distance; });
  std::vector<int> spot_of_truth(truth.size(), -1);
  std::set<size_t> used;
  for (const Pair& p : pairs) {
    if (spot_of_truth[p.truth] >= 0 || used.count(p.spot)) continue;
    spot_of_truth[p.truth] = static_cast<int>(p.spot);
    used.insert(p.spot);
  }
  for (size_t t : considered) {
    TruthMatch m;
    m.truth_id = truth[t].id;
    const int s = spot_of_truth[t];
    if (s < 0) {
      ++score.missed;
      score.matches.push_back(m);
      continue;
    }
    ++score.found;
    const Spot& spot = spots[static_cast<size_t>(s)];
    const TruthSpot& tr = truth[t];
    m.spot_id = spot.id;
    m.distance_m = (spot.centroid_in_world - tr.centroid_in_world).norm();
    const double area_true = observed_only && tr.observed_area_m2 >= 0 ? tr.observed_area_m2 : tr.area_m2;
    m.area_error = (spot.area_m2 - area_true) / area_true;
    m.area_covered = std::abs(spot.area_m2 - area_true) <= 2 * spot.area_sigma_m2;
    m.delta_error_k = spot.delta_k - 2 * (tr.temperature_c - tr.threshold_c);
    m.delta_covered = std::abs(m.delta_error_k) <= 2 * spot.delta_sigma_k;
    score.max_abs_delta_error_k = std::max(score.max_abs_delta_error_k, std::abs(m.delta_error_k));
    score.max_abs_area_error = std::max(score.max_abs_area_error, std::abs(m.area_error));
    const bool full = !observed_only || tr.observed_fraction >= 0.99 || tr.observed_fraction < 0;
    if (full) {
      m.length_error_m = spot.length_m - tr.length_m;
      m.width_error_m = spot.width_m - tr.width_m;
      m.length_error = m.length_error_m / tr.length_m;
      m.width_error = m.width_error_m / tr.width_m;
      m.length_covered = std::abs(m.length_error_m) <= 2 * spot.length_sigma_m;
      m.width_covered = std::abs(m.width_error_m) <= 2 * spot.width_sigma_m;
      score.max_abs_length_error = std::max(score.max_abs_length_error, std::abs(m.length_error));
      score.max_abs_width_error = std::max(score.max_abs_width_error, std::abs(m.width_error));
    } else {
      m.length_error = m.width_error = std::numeric_limits<double>::quiet_NaN();
      m.length_error_m = m.width_error_m = std::numeric_limits<double>::quiet_NaN();
    }
    if (spot.possible_reflection) score.found_flagged_as_reflections.push_back(spot.id);
    score.matches.push_back(m);
  }
  for (size_t s = 0; s < spots.size(); ++s) {
    if (used.count(s)) continue;
    score.false_spots.push_back(spots[s].id);
    if (spots[s].possible_reflection) score.false_flagged_as_reflections.push_back(spots[s].id);
  }
  for (size_t t : matchable) {
    if (spot_of_truth[t] >= 0 && !scored[t]) {
      score.partly_observed.emplace_back(truth[t].id, spots[static_cast<size_t>(spot_of_truth[t])].id);
    }
  }
  return score;
}

void AddThresholdErrors(const SpotFinder& finder, const std::vector<Spot>& spots,
                        const std::vector<TruthSpot>& truth, bool observed_only, TruthScore* score) {
  std::vector<LevelRequest> requests;
  std::vector<std::pair<TruthMatch*, const TruthSpot*>> targets;
  for (TruthMatch& m : score->matches) {
    if (m.spot_id.empty()) continue;
    const Spot* spot = nullptr;
    for (const Spot& s : spots) {
      if (s.id == m.spot_id) spot = &s;
    }
    const TruthSpot* t = nullptr;
    for (const TruthSpot& x : truth) {
      if (x.id == m.truth_id) t = &x;
    }
    if (spot == nullptr || t == nullptr) continue;
    requests.push_back({spot->peak_in_world, t->hot, t->threshold_c});
    targets.emplace_back(&m, t);
  }
  const std::vector<std::optional<Spot>> measured = finder.MeasureAtLevels(requests);
  for (size_t i = 0; i < measured.size(); ++i) {
    if (!measured[i]) continue;
    TruthMatch& m = *targets[i].first;
    const TruthSpot& t = *targets[i].second;
    const Spot& s = *measured[i];
    const double area_true = observed_only && t.observed_area_m2 >= 0 ? t.observed_area_m2 : t.area_m2;
    m.area_error_at_threshold = (s.area_m2 - area_true) / area_true;
    score->max_abs_area_error_at_threshold =
        std::max(score->max_abs_area_error_at_threshold, std::abs(m.area_error_at_threshold));
    if (!observed_only || t.observed_fraction >= 0.99 || t.observed_fraction < 0) {
      m.length_error_at_threshold_m = s.length_m - t.length_m;
      m.width_error_at_threshold_m = s.width_m - t.width_m;
      m.length_error_at_threshold = m.length_error_at_threshold_m / t.length_m;
      m.width_error_at_threshold = m.width_error_at_threshold_m / t.width_m;
      score->max_abs_length_error_at_threshold =
          std::max(score->max_abs_length_error_at_threshold, std::abs(m.length_error_at_threshold));
      score->max_abs_width_error_at_threshold =
          std::max(score->max_abs_width_error_at_threshold, std::abs(m.width_error_at_threshold));
    }
  }
}

}  // namespace hw::analyze
