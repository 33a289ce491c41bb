// SpotOptions::Check and the severity table (spot_detect.h).
#include <cmath>
#include <string>
#include <vector>

#include "analyze/spot_detect.h"
#include "core/option_check.h"
#include "core/yaml_reader.h"

namespace hw::analyze {

std::vector<SeverityBand> NetaSeverityTable() {
  return {{1.0, "possible", "Possible deficiency: warrants investigation"},
          {4.0, "probable", "Probable deficiency: repair as time permits"},
          {16.0, "major", "Major discrepancy: repair immediately"}};
}

std::string CheckSeverityTable(const std::vector<SeverityBand>& table) {
  if (table.empty()) return "severity: must have at least one band";
  for (size_t i = 0; i < table.size(); ++i) {
    const std::string key = "severity[" + std::to_string(i) + "]";
    if (table[i].name.empty()) return key + ".name: must not be empty";
    if (!std::isfinite(table[i].min_delta_k) || table[i].min_delta_k < 0) {
      return core::OptionFail(key + ".min_delta_k", table[i].min_delta_k, "finite and >= 0");
    }
    if (i > 0 && !(table[i].min_delta_k > table[i - 1].min_delta_k)) {
      return core::OptionFail(key + ".min_delta_k", table[i].min_delta_k,
                              "> the previous band's " + core::RoundedNumber(table[i - 1].min_delta_k) +
                                  " (bands in increasing order)");
    }
  }
  return "";
}

const SeverityBand* SeverityFor(const std::vector<SeverityBand>& table, double delta_k) {
  const SeverityBand* band = nullptr;
  for (const SeverityBand& b : table) {
    if (std::abs(delta_k) >= b.min_delta_k) band = &b;
  }
  return band;
}

std::string SpotOptions::Check() const {
  if (reference == Reference::kAmbient && !std::isfinite(ambient_c)) {
    return core::OptionFail("ambient_c", ambient_c, "finite with reference ambient");
  }
  if (!(min_delta_k > 0) || !std::isfinite(min_delta_k)) return core::OptionFail("min_delta_k", min_delta_k, "> 0");
  if (detect == Detect::kAbsolute) {
    if (find_hot && !std::isfinite(hot_above_c)) {
      return core::OptionFail("hot_above_c", hot_above_c, "finite with detect absolute (or find no hot spots)");
    }
    if (find_cold && !std::isfinite(cold_below_c)) {
      return core::OptionFail("cold_below_c", cold_below_c, "finite with detect absolute (or find no cold spots)");
    }
    if (find_hot && find_cold && !(cold_below_c < hot_above_c)) {
      return core::OptionFail("cold_below_c", cold_below_c, "< hot_above_c (an inverted band)");
    }
  }
  if (!find_hot && !find_cold) return "find_hot, find_cold: at least one must be true";
  if (!(boundary_fraction > 0 && boundary_fraction < 1)) {
    return core::OptionFail("boundary_fraction", boundary_fraction, "in (0, 1)");
  }
  if (!core::InRange(min_area_m2, 0, 1e6)) return core::OptionFail("min_area_m2", min_area_m2, "in [0, 1e6]");
  if (!(max_area_m2 > min_area_m2) || !std::isfinite(max_area_m2)) {
    return core::OptionFail("max_area_m2", max_area_m2, "finite and > min_area_m2");
  }
  if (!core::InRange(background_radius_m, 1e-3, 100)) {
    return core::OptionFail("background_radius_m", background_radius_m, "in [0.001, 100]");
  }
  if (!core::InRange(ring_gap_m, 0, 10)) return core::OptionFail("ring_gap_m", ring_gap_m, "in [0, 10]");
  if (!core::InRange(ring_gap_tails, 0, 20)) {
    return core::OptionFail("ring_gap_tails", ring_gap_tails, "in [0, 20]");
  }
  if (!core::InRange(ring_width_m, 1e-3, 10)) return core::OptionFail("ring_width_m", ring_width_m, "in [0.001, 10]");
  if (!(ring_max_normal_change_deg > 0 && ring_max_normal_change_deg <= 180)) {
    return core::OptionFail("ring_max_normal_change_deg", ring_max_normal_change_deg, "in (0, 180]");
  }
  if (!core::InRange(ring_normal_radius_m, 0, 1)) {
    return core::OptionFail("ring_normal_radius_m", ring_normal_radius_m, "in [0, 1]");
  }
  if (!core::InRange(min_ring_area_ratio, 0, 1e6)) {
    return core::OptionFail("min_ring_area_ratio", min_ring_area_ratio, "in [0, 1e6]");
  }
  if (!core::InRange(min_ring_coverage, 0, 1)) {
    return core::OptionFail("min_ring_coverage", min_ring_coverage, "in [0, 1]");
  }
  if (!core::InRange(min_contrast_sigmas, 0, 100)) {
    return core::OptionFail("min_contrast_sigmas", min_contrast_sigmas, "in [0, 100]");
  }
  if (!core::InRange(min_views, 0, 1e6)) return core::OptionFail("min_views", min_views, "in [0, 1e6]");
  if (!core::InRange(min_views_ratio, 0, 1)) return core::OptionFail("min_views_ratio", min_views_ratio, "in [0, 1]");
  if (!core::InRange(max_view_spread_ratio, 0, 1e6)) {
    return core::OptionFail("max_view_spread_ratio", max_view_spread_ratio, "in [0, 1e6]");
  }
  if (!core::InRange(min_emissivity, 0, 1)) return core::OptionFail("min_emissivity", min_emissivity, "in [0, 1]");
  if (!core::InRange(optics_psf_px, 0, 20)) return core::OptionFail("optics_psf_px", optics_psf_px, "in [0, 20]");
  if (!core::InRange(min_resolved_px, 0, 1000)) {
    return core::OptionFail("min_resolved_px", min_resolved_px, "in [0, 1000]");
  }
  if (max_candidates < 1) return core::OptionFail("max_candidates", max_candidates, ">= 1");
  if (!severity.empty()) return CheckSeverityTable(severity);
  return "";
}

}  // namespace hw::analyze
