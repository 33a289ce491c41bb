#pragma once

// analyze.yaml: what `heatwave analyze` detects and draws. Every key is optional; the
// defaults are those of SpotOptions and the fields below. Example (README, "analyze.yaml"):
//
//   version: 1
//   field: temperature_c            # the per-vertex field measured
//   spots:
//     detect: delta                 # delta | absolute
//     reference: surrounding        # surrounding | ambient
//     ambient_c: 21.5               # with reference: ambient
//     min_delta_k: 2
//     hot_above_c: 60               # with detect: absolute
//     cold_below_c: 12
//     kinds: [hot, cold]
//     boundary_fraction: 0.5
//     min_area_m2: 0.0001
//     max_area_m2: 1
//     background_radius_m: 0.3
//     min_contrast_sigmas: 4        # |ΔT| >= 4 × the surroundings' spread
//     min_views: 3                  # reconstruct's meshes: seen in >= 3 thermal frames
//     min_views_ratio: 0.5          # ... and in >= half the frames that saw its surroundings
//     max_view_spread_ratio: 0.5    # ... whose spread across views is < 0.5 |ΔT|
//     min_emissivity: 0.5           # corrected meshes: no spot on a surface of emissivity < 0.5
//   reflections:                    # is a spot a reflection? (analyze/spot_reflection.h)
//     check: true
//     operator_radius_m: 0.6        # the thermographer's body around the camera
//     operator_max_c: 37            # warmest a person looks
//     min_fraction: 0.5
//   severity:                       # replaces the NETA table
//     - {name: minor, min_delta_k: 1, action: "Monitor"}
//     - {name: serious, min_delta_k: 10, action: "Repair"}
//   images:
//     width: 1280
//     height: 960
//     samples_per_pixel: 4
//     palette: iron                 # iron | rainbow | grey, optionally -inverted
//     span_c: [20, 80]              # fixed colour-bar span; absent: automatic
//     highlight_band_c: [15, 35]    # normal band of thermal highlighting; absent: the spots' levels
//     overviews: 4                  # automatic overview views (0: none)
//     closeups: true                # one close-up per spot
//     float_format: exr             # exr | tiff: raw temperature per pixel
//     legends: true                 # title strip and colour bar on each image
//     up: [0, 0, 1]                 # world up of the overviews (reconstruct started
//                                   # without groundtruth: the first camera's [0, -1, 0])
//     views:                        # extra views
//       - {name: front, eye: [0, -3, 1.5], target: [0, 0, 1], up: [0, 0, 1], fov_y_deg: 50}

#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/spot_detect.h"
#include "analyze/spot_reflection.h"

namespace hw::analyze {

struct UserView {
  std::string name;
  Eigen::Vector3d eye_in_world = Eigen::Vector3d::Zero();
  Eigen::Vector3d target_in_world = Eigen::Vector3d::UnitY();
  Eigen::Vector3d up_in_world = Eigen::Vector3d::UnitZ();
  double fov_y_deg = 45;          // perspective field of view, degrees, (0, 170)
  double ortho_height_m = 0;      // > 0: orthographic view of this height, metres
};

struct AnalyzeConfig {
  std::string field = "temperature_c";
  SpotOptions spots;
  ReflectionOptions reflections;
  int width = 1280;               // pixels, [16, 8192]
  int height = 960;               // pixels, [16, 8192]
  int samples_per_pixel = 4;      // 1, 4, 9 or 16
  std::string palette = "iron";   // ParsePalette name
  double span_min_c = std::numeric_limits<double>::quiet_NaN();  // both NaN: automatic
  double span_max_c = std::numeric_limits<double>::quiet_NaN();
  double highlight_low_c = std::numeric_limits<double>::quiet_NaN();   // both NaN: automatic
  double highlight_high_c = std::numeric_limits<double>::quiet_NaN();
  int overviews = 4;              // [0, 12]
  bool closeups = true;
  std::string float_format = "exr";  // exr | tiff
  // Each image gets a title strip and a colour-bar panel (false: spot labels only — what
  // heatwave audit asks for, since its report draws vector colour bars and captions).
  bool legends = true;
  // World up for the overviews: z up is the fixtures' frame and reconstruct's when it starts
  // at groundtruth; a reconstruction started at its first camera has up ≈ −y.
  Eigen::Vector3d up_in_world = Eigen::Vector3d::UnitZ();
  int max_closeups = 20;             // close-ups for the strongest spots only, [0, 200]
  std::vector<UserView> views;

  // "" or "<field>: must be ..., got ..." (spots.* and severity[i].* prefixed).
  std::string Check() const;
};

// Reads analyze.yaml strictly: unknown keys, wrong types, inverted bands or spans, bad
// options → InputError with path, key and line.
AnalyzeConfig ReadAnalyzeConfig(const std::filesystem::path& path);
AnalyzeConfig ParseAnalyzeConfig(const std::string& yaml_text, const std::filesystem::path& path_for_errors);

}  // namespace hw::analyze
