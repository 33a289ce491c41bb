#pragma once

// heatwave compare: two models of one asset scanned at different times, aligned; the
// temperature change mapped onto the AFTER model and the spots that appeared, vanished,
// grew, shrank, heated or cooled; compare.json and images.

#include <filesystem>
#include <string>

#include "analyze/comparison.h"

namespace hw::cli {

struct CompareCommandOptions {
  std::filesystem::path before_path;  // PLY with per-vertex temperature
  std::filesystem::path after_path;   // PLY with per-vertex temperature
  std::filesystem::path out_folder;
  std::filesystem::path config_path;  // analyze.yaml (spots, images), or "" for defaults
  bool overwrite = false;
  bool images = true;
  int num_threads = 0;  // [0, 256], 0 = all cores

  std::string Check() const;
};

// Reads both models and the config, compares, writes DIR/images and DIR/compare.json.
// Throws core::InputError / OutputError (bad files, a model without temperature),
// UsageError (a non-empty --out without --overwrite).
analyze::CompareResult CompareCommand(const CompareCommandOptions& options, bool quiet);

}  // namespace hw::cli
