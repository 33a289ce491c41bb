#include "cli/analyze.h"

#include <iostream>
#include <memory>

#include "cli/command.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"

namespace hw::cli {

std::string AnalyzeCommandOptions::Check() const {
  if (model_path.empty()) return "MODEL: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (num_threads < 0 || num_threads > 256) return core::OptionFail("--threads", num_threads, "in [0, 256]");
  if (truth_observed_only && truth_path.empty()) return "--truth-observed-only: needs --truth";
  return "";
}

analyze::AnalyzeResult AnalyzeCommand(const AnalyzeCommandOptions& options, bool quiet) {
  analyze::AnalyzeInputs inputs;
  inputs.model_path = options.model_path;
  inputs.config_path = options.config_path;
  if (!options.config_path.empty()) inputs.config = analyze::ReadAnalyzeConfig(options.config_path);
  if (options.legends) inputs.config.legends = *options.legends;
  inputs.truth_path = options.truth_path;
  // Every input is read before the output folder is touched: a bad file leaves nothing.
  if (!options.truth_path.empty()) inputs.truth = analyze::ReadTruthSpots(options.truth_path);
  inputs.truth_observed_only = options.truth_observed_only;
  inputs.write_images = options.images;
  inputs.num_threads = options.num_threads;
  const analyze::ThermalMesh mesh = analyze::ReadThermalMesh(options.model_path, inputs.config.field);
  core::OutputFolder folder(options.out_folder, "heatwave analyze");
  if (!folder.IsEmpty()) {
    if (!options.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + options.out_folder.string() +
                       ": folder is not empty; pass --overwrite to replace the analysis in it");
    }
    folder.Remove({"images", "analyze.json"});
  }
  std::unique_ptr<core::ProgressBar> bar;
  analyze::AnalyzeResult result = analyze::Analyze(mesh, inputs, options.out_folder, [&](int done, int total) {
    if (!bar) bar = std::make_unique<core::ProgressBar>("analyze", total, "views", quiet);
    bar->Set(done);
  });
  bar.reset();
  folder.Commit();
  return result;
}

int RunAnalyze(int argc, char** argv) {
  CLI::App app("Find and measure hot and cold spots on a model with temperature; render it in the four modes.",
               "heatwave analyze");
  AnalyzeCommandOptions o;
  CommonOptions common;
  AddCommonOptions(app, common);
  app.add_option("model", o.model_path, "PLY mesh with per-vertex temperature_c (reconstruct's model.ply, a truth/scene.ply)")
      ->required();
  app.add_option("--out", o.out_folder, "output folder: images/, analyze.json")->required();
  app.add_option("--config", o.config_path, "analyze.yaml: detection, severity table, images (README)");
  app.add_option("--truth", o.truth_path, "truth/hotspots.yaml of a synthetic scan: score the spots against it");
  app.add_flag("--truth-observed-only", o.truth_observed_only,
               "score only the truth spots the scan observed (a reconstruction), areas against observed_area_m2");
  bool no_images = false;
  app.add_flag("--no-images", no_images, "measure only: analyze.json without images");
  app.add_flag("--overwrite", o.overwrite, "replace the analysis files in a non-empty --out");
  app.add_option("--threads", o.num_threads, "render threads, 0 = all cores")->capture_default_str();
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  o.images = !no_images;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    const analyze::AnalyzeResult result = AnalyzeCommand(o, common.quiet);
    if (!common.quiet) std::cout << analyze::FormatAnalyzeSummary(result) << std::flush;
    return kExitOk;
  });
}

}  // namespace hw::cli
