#pragma once

// The analysis behind `heatwave analyze` (and the audit): spots on a mesh with temperature,
// images of the model in the four modes from automatic and configured views, close-ups of
// every spot, and analyze.json, which the report module reads. Everything is written into
// one output folder, each file atomically.

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "analyze/analyze_config.h"
#include "analyze/palette.h"
#include "analyze/render.h"
#include "analyze/spot_detect.h"
#include "analyze/spot_eval.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct AnalyzeImage {
  std::string file;        // PNG, relative to the output folder (images/…)
  std::string float_file;  // EXR/TIFF of the raw field per pixel (thermal mode only), or ""
  std::string view;        // "overview-1", "top", a configured name, or the spot id
  std::string mode;        // ViewModeName
  std::string spot_id;     // close-ups: the spot framed
  double visible_fraction = -1;  // close-ups: the spot's visible fraction; -1 otherwise
  Camera camera;
  Span span;                      // the colour bar's span (°C)
  std::vector<std::string> labelled_spots;  // spots labelled (visible) in the image
};

struct AnalyzeTimings {
  double detect_s = 0, reflections_s = 0, bvh_s = 0, render_s = 0, compose_s = 0, write_s = 0, total_s = 0;
  int renders = 0;
};

struct AnalyzeResult {
  std::filesystem::path out_folder;
  int vertices = 0, faces = 0;
  double area_m2 = 0;
  double observed_area_m2 = 0;   // area of faces whose three vertices have a temperature
  double temperature_min_c = 0, temperature_median_c = 0, temperature_max_c = 0;  // area-weighted
  std::optional<SpotDetection> detection;  // none for a mesh without temperature
  // Whether the spots went through the reflection check (config.reflections.check, a
  // temperature to measure and view vectors in the model).
  bool checked_reflections = false;
  Span span;                                // the overviews' colour-bar span
  Span highlight_band;                      // the normal band of the highlighting views
  std::vector<AnalyzeImage> images;
  std::optional<TruthScore> truth;
  AnalyzeTimings timings;
  std::vector<std::string> warnings;
};

struct AnalyzeInputs {
  std::filesystem::path model_path;  // for analyze.json only
  AnalyzeConfig config;
  std::filesystem::path config_path;  // "" when defaults
  std::filesystem::path truth_path;   // truth/hotspots.yaml scored against (for analyze.json)
  std::optional<std::vector<TruthSpot>> truth;  // its spots (ReadTruthSpots), read by the caller
  bool truth_observed_only = false;   // score a reconstruction: only observed truth spots
  bool write_images = true;
  int num_threads = 0;                // renderer threads; 0 = all cores
};

// Runs the analysis of `mesh` and writes images/ and analyze.json into out_folder (created
// if needed). `progress(done, total)` is called after each rendered view (may be null).
// Throws core::OutputError when a file cannot be written. Asserts inputs.config.Check() == "".
AnalyzeResult Analyze(const ThermalMesh& mesh, const AnalyzeInputs& inputs,
                      const std::filesystem::path& out_folder,
                      const std::function<void(int done, int total)>& progress);

// analyze.json's text.
std::string AnalyzeJson(const ThermalMesh& mesh, const AnalyzeInputs& inputs, const AnalyzeResult& result);

// The one-screen summary the command prints.
std::string FormatAnalyzeSummary(const AnalyzeResult& result);

}  // namespace hw::analyze
