#include "cli/compare.h"

#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"

namespace hw::cli {

std::string CompareCommandOptions::Check() const {
  if (before_path.empty()) return "BEFORE: must be given";
  if (after_path.empty()) return "AFTER: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (num_threads < 0 || num_threads > 256) return core::OptionFail("--threads", num_threads, "in [0, 256]");
  return "";
}

analyze::CompareResult CompareCommand(const CompareCommandOptions& options, bool quiet) {
  analyze::CompareInputs inputs;
  inputs.before_path = options.before_path;
  inputs.after_path = options.after_path;
  inputs.config_path = options.config_path;
  if (!options.config_path.empty()) inputs.config = analyze::ReadAnalyzeConfig(options.config_path);
  inputs.write_images = options.images;
  inputs.num_threads = options.num_threads;
  const analyze::ThermalMesh before = analyze::ReadThermalMesh(options.before_path, inputs.config.field);
  const analyze::ThermalMesh after = analyze::ReadThermalMesh(options.after_path, inputs.config.field);
  core::OutputFolder folder(options.out_folder, "heatwave compare");
  if (!folder.IsEmpty()) {
    if (!options.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + options.out_folder.string() +
                       ": folder is not empty; pass --overwrite to replace the comparison in it");
    }
    folder.Remove({"images", "compare.json"});
  }
  std::unique_ptr<core::ProgressBar> bar;
  analyze::CompareResult result =
      analyze::CompareModels(before, after, inputs, options.out_folder, [&](int done, int total) {
        if (!bar) bar = std::make_unique<core::ProgressBar>("compare", total, "views", quiet);
        bar->Set(done);
      });
  bar.reset();
  folder.Commit();
  return result;
}

int RunCompare(int argc, char** argv) {
  CLI::App app(
      "Align two models of one asset scanned at different times, map the temperature change onto the AFTER "
      "model and list the spots that appeared, vanished, grew, shrank, heated or cooled.",
      "heatwave compare");
  CompareCommandOptions o;
  CommonOptions common;
  AddCommonOptions(app, common);
  app.add_option("before", o.before_path, "PLY mesh with per-vertex temperature_c: the earlier scan")->required();
  app.add_option("after", o.after_path, "PLY mesh with per-vertex temperature_c: the later scan (images drawn on it)")
      ->required();
  app.add_option("--out", o.out_folder, "output folder: images/, compare.json")->required();
  app.add_option("--config", o.config_path, "analyze.yaml: spot detection (both models) and images (README)");
  bool no_images = false;
  app.add_flag("--no-images", no_images, "measure only: compare.json without images");
  app.add_flag("--overwrite", o.overwrite, "replace the comparison files in a non-empty --out");
  app.add_option("--threads", o.num_threads, "threads for alignment and rendering, 0 = all cores")
      ->capture_default_str();
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  o.images = !no_images;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    const analyze::CompareResult result = CompareCommand(o, common.quiet);
    if (!common.quiet) std::cout << analyze::FormatCompareSummary(result) << std::flush;
    return kExitOk;
  });
}

}  // namespace hw::cli
