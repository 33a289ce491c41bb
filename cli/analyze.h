#pragma once

// heatwave analyze: hot and cold spots measured on a model with per-vertex temperature,
// images in the four modes, analyze.json for the report.

#include <filesystem>
#include <optional>
#include <string>

#include "analyze/analyzer.h"

namespace hw::cli {

struct AnalyzeCommandOptions {
  std::filesystem::path model_path;
  std::filesystem::path out_folder;
  std::filesystem::path config_path;  // analyze.yaml, or "" for defaults
  std::filesystem::path truth_path;   // truth/hotspots.yaml to score against, or ""
  bool truth_observed_only = false;
  bool overwrite = false;
  bool images = true;
  int num_threads = 0;
  // Overrides analyze.yaml's images.legends (heatwave audit: false, its report draws them).
  std::optional<bool> legends;

  std::string Check() const;
};

// Reads the model and config, analyses, writes DIR/images and DIR/analyze.json. Throws
// core::InputError / OutputError (bad files), UsageError (a non-empty --out without
// --overwrite).
analyze::AnalyzeResult AnalyzeCommand(const AnalyzeCommandOptions& options, bool quiet);

}  // namespace hw::cli
