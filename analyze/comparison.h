#pragma once

// The comparison behind `heatwave compare BEFORE AFTER`: the two models of one asset are
// aligned (ICP from a coarse start, analyze/align.h), BEFORE's temperature is carried onto
// AFTER's surface and subtracted (analyze/compare.h), the spots of both are detected with
// the same options, checked for reflections where the models carry view vectors, and paired
// (appeared, vanished, grew, shrank, heated, cooled), and the difference is drawn on the AFTER
// model. Everything is written into one output folder:
// images/ and compare.json, each file atomically.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "analyze/align.h"
#include "analyze/analyze_config.h"
#include "analyze/analyzer.h"
#include "analyze/compare.h"
#include "analyze/palette.h"
#include "analyze/spot_detect.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct CompareInputs {
  std::filesystem::path before_path;  // for compare.json and error messages
  std::filesystem::path after_path;
  // Spot detection (config.spots, used for both models), images (size, samples, overviews,
  // close-ups, palette of the AFTER thermal view, float format, up, extra views) and the
  // field read. config.spots.min_delta_k is also the half-width of the difference
  // highlighting band, K.
  AnalyzeConfig config;
  std::filesystem::path config_path;  // "" when defaults
  AlignOptions align;
  CompareOptions compare;
  bool write_images = true;
  // Threads for rendering, alignment and mapping; 0 = all cores, [0, 256]. Overrides
  // align.threads and compare.threads.
  int num_threads = 0;
};

struct CompareTimings {
  // reflections_s: the reflection check of both models' spots, their BVH builds excluded
  // (in bvh_s: AFTER's, shared with the images, and BEFORE's when it was checked).
  double align_s = 0, difference_s = 0, detect_s = 0, reflections_s = 0, bvh_s = 0, render_s = 0, compose_s = 0,
         write_s = 0, total_s = 0;
  int renders = 0;
};

struct CompareResult {
  std::filesystem::path out_folder;
  Alignment alignment;
  // The alignment's rotation angle (degrees) and translation length (metres): the motion
  // between the scans as a reader checks it.
  double rotation_deg = 0, translation_m = 0;
  double after_mean_edge_m = 0;  // mean edge length of AFTER's faces, metres (the residual's scale)
  TemperatureDifference difference;
  SpotDetection before_spots, after_spots;
  // Whether each model's spots went through the reflection check (config.reflections.check
  // and view vectors in the model).
  bool before_checked_reflections = false, after_checked_reflections = false;
  std::vector<SpotChange> changes;  // MatchSpots order
  Span span_k;            // the difference images' colour-bar span, K, symmetric about 0
  Span highlight_band_k;  // ±config.spots.min_delta_k
  Span after_span_c;      // the AFTER thermal view's span, °C
  std::vector<AnalyzeImage> images;  // view "overview-1" …, or a change's name (ChangeName)
  CompareTimings timings;
  std::vector<std::string> warnings;
};

// A change's name in images and labels: AFTER's spot id when it has one ("H1"), else
// "before-" + BEFORE's id ("before-H2", a vanished spot).
std::string ChangeName(const SpotChange& change);

// Compares the two models and writes images/ and compare.json into out_folder (created if
// needed). `progress(done, total)` is called after each rendered view (may be null).
// Throws core::InputError(path, "no temperature_c: nothing to compare") when either mesh
// has no temperature field or no vertex with a temperature; core::OutputError when a file
// cannot be written; std::invalid_argument when the align or compare options fail their
// Check(). Asserts inputs.config.Check() == "".
CompareResult CompareModels(const ThermalMesh& before, const ThermalMesh& after, const CompareInputs& inputs,
                            const std::filesystem::path& out_folder,
                            const std::function<void(int done, int total)>& progress);

// compare.json's text.
std::string CompareJson(const ThermalMesh& before, const ThermalMesh& after, const CompareInputs& inputs,
                        const CompareResult& result);

// The one-screen summary the command prints.
std::string FormatCompareSummary(const CompareResult& result);

}  // namespace hw::analyze
