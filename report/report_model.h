#pragma once

// The audit report's content: reads what the pipeline wrote (analyze.json with its images,
// reconstruct.json, the rig) and what the thermographer wrote (job.yaml), and fills the
// document (report/document.h) that the HTML and PDF writers lay out. All wording and
// number formatting happen here, once, so the two forms agree to the character.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/rig.h"
#include "report/document.h"
#include "report/job.h"

namespace hw::report {

struct ReportInputs {
  std::filesystem::path analyze_json;      // required; images are relative to its folder
  std::filesystem::path reconstruct_json;  // "" = no scan statistics section content
  // "" = the rig reconstruct.json names, if that file exists; else no rig figures.
  std::filesystem::path rig_yaml;
  // The model the analysis measured, for the HTML's 3D view; "" = no 3D view.
  std::filesystem::path model_ply;
  Job job;
  std::string creator = "heatwave";  // PDF creator metadata, e.g. "heatwave 0.11.0"
};

// A spot as the report needs it (from analyze.json "spots").
struct ReportSpot {
  std::string id, kind, severity, action, reference, unrolling;
  double peak_c = 0, mean_c = 0, reference_c = 0, delta_k = 0, level_c = 0;
  // analyze.json delta_sigma_k (one sigma) and delta_blur_bound_k: NaN when absent.
  double delta_sigma_k = 0, delta_blur_bound_k = 0;
  double area_m2 = 0, area_sigma_m2 = 0, length_m = 0, length_sigma_m = 0, width_m = 0, width_sigma_m = 0;
  double mean_confidence = 0, mean_views = 0, spread_c = 0;  // spread: NaN when absent
  // The thermal image's resolution over the spot (analyze.json footprint_m, width_px,
  // resolved): NaN / true when absent.
  double footprint_m = 0, width_px = 0;
  bool resolved = true;
  // The reflection check (analyze.json incidence_deg, reflection_fraction,
  // reflection_source, reflection_source_c, possible_reflection): NaN / "" / false when
  // absent or not checked.
  double incidence_deg = 0, reflection_fraction = 0, reflection_source_c = 0;
  std::string reflection_source;
  bool possible_reflection = false;
  Eigen::Vector3d centroid_m = Eigen::Vector3d::Zero(), peak_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  std::vector<std::string> images;  // relative to the analysis folder
};

// Builds the document. Throws core::InputError(path, reason) for a missing or unreadable
// file, invalid JSON, or a missing or mistyped field ("spots[0].area_m2: missing"), and
// for a figure listed in analyze.json whose PNG is missing or unreadable.
Document BuildDocument(const ReportInputs& inputs);

// Formatting shared by the report's text (exposed for tests). Value with its uncertainty,
// the decimals set by the uncertainty's first two significant digits: (0.6704, 0.0096,
// 100, "cm") → "67.04 ± 0.96 cm"; σ NaN → the value alone, 1 decimal.
std::string FormatWithSigma(double value, double sigma, double scale, const std::string& unit);
// "27.8 °C"; "—" for NaN.
std::string FormatCelsius(double value_c);
// An area in cm² below 0.1 m², in m² above, with its uncertainty.
std::string FormatArea(double area_m2, double sigma_m2);
// A length in cm below 1 m, in m above, with its uncertainty.
std::string FormatLength(double length_m, double sigma_m);

}  // namespace hw::report
