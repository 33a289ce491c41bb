#pragma once

// Strict reading of the pipeline's JSON outputs (analyze.json, reconstruct.json) into what
// the report uses. Internal to hw_report: the public interface is report_model.h.

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "report/report_model.h"

namespace hw::report {

struct ReportImageRecord {
  std::string file;  // relative to the analysis folder
  std::string view, mode, spot;
  analyze::Span span;
};

struct SeverityRecord {
  std::string name, action;
  double min_delta_k = 0;
};

struct AnalysisRecord {
  std::filesystem::path folder;  // of analyze.json
  std::string model, field, palette = "iron";
  bool legends = true;  // the images carry their own title strip and colour bar
  int vertices = 0, faces = 0, unobserved = 0;
  double area_m2 = 0, observed_area_m2 = 0, min_c = 0, median_c = 0, max_c = 0;
  bool has_colour = false;
  // detection settings
  std::string detect, reference;
  double min_delta_k = 0, min_area_m2 = 0, max_area_m2 = 0, background_radius_m = 0, boundary_fraction = 0;
  double ambient_c = 0, hot_above_c = 0, cold_below_c = 0;  // NaN when null
  bool find_hot = true, find_cold = true;
  std::vector<SeverityRecord> severity;  // as listed
  int candidates = 0;
  std::vector<ReportSpot> spots;
  std::vector<std::pair<std::string, std::string>> rejected;  // kind+peak, reason
  analyze::Span span, band;
  std::vector<ReportImageRecord> images;
  std::vector<std::string> warnings;
};

struct ReconstructionRecord {
  std::string scan;
  std::string rig;  // the rig.yaml the reconstruction used, as given to it
  int depth_frames = 0, fused = 0, tracked = 0, recovered = 0, lost = 0, no_depth = 0, missing = 0;
  int vertices = 0, faces = 0;
  double area_m2 = 0, total_s = 0, frames_per_s = 0;
  double voxel_size_m = 0;
  std::optional<double> ate_rmse_m;  // synthetic scans with groundtruth
  bool has_thermal = false;
  int thermal_frames = 0, thermal_fused = 0, vertices_with_temperature = 0;
  // Frames skipped by frame selection and its window (s); 0 and 0 in a reconstruct.json
  // written before it (stop 48), which lacks the keys.
  int thermal_skipped = 0;
  double thermal_frame_interval_s = 0;
  std::string thermal_method, emissivity;
  std::vector<std::string> warnings;
};

// Throw core::InputError naming the file and the field.
AnalysisRecord ReadAnalysisRecord(const std::filesystem::path& analyze_json);
ReconstructionRecord ReadReconstructionRecord(const std::filesystem::path& reconstruct_json);

}  // namespace hw::report
