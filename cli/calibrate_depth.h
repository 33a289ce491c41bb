#pragma once

// heatwave calibrate depth: the depth camera's systematic error (rig.yaml depth_correction,
// core/depth_correction.h) from a recording of a flat wall seen from near to far
// (calibrate/depth_correction_fit.h) — estimate, check against the QA thresholds, write
// depth_correction.json, rig.yaml with the correction, diagnostics/{field,sigma}.png.

#include <filesystem>
#include <string>
#include <vector>

#include "calibrate/depth_correction_fit.h"
#include "calibrate/qa_profile.h"
#include "cli/command.h"
#include "core/rig.h"

namespace hw::cli {

struct DepthCommandOptions {
  std::filesystem::path scan;        // scan folder with a depth stream of a flat wall
  std::filesystem::path rig_path;    // rig.yaml read (and rewritten) instead of the scan's; "" = the scan's
  std::filesystem::path out_folder;  // output folder
  bool overwrite = false;            // replace an earlier depth calibration in out_folder
  // QA: every node's 1σ, as depth at 3 m (z²·σ), at most this, mm, (0, 1000]. A Kinect-class
  // field is 10–30 mm at 3 m; 2 mm keeps what is left under a tenth of it.
  double max_sigma_mm = 2.0;
  // QA: at least this fraction of the grid's nodes backed by 50 samples of a plane, [0, 1].
  double min_coverage = 0.9;
  calibrate::DepthCorrectionOptions fit;

  // "" or "--flag: must be ..., got ..." (--scan, --out given; the options' Check()).
  std::string Check() const;
};

struct DepthCommandResult {
  calibrate::DepthCorrectionResult estimate;
  core::Rig rig_in;   // the rig read (the scan's or --rig); a correction it had is replaced
  core::Rig rig_out;  // rig_in with depth_correction set
  std::vector<calibrate::QaCheck> checks;
  bool pass = false;
  std::vector<std::string> written;  // files, relative to out_folder
  double seconds = 0;
  double read_seconds = 0;  // of `seconds`: reading and sampling the depth frames
};

// Estimates and writes out_folder/{depth_correction.json, rig.yaml, diagnostics/field.png,
// diagnostics/sigma.png}; the folder is touched only once everything is estimated. The
// depth is read raw (any correction in the rig is ignored and replaced). Throws
// core::InputError (scan or rig unreadable, no depth, too few frames holding a plane) and
// UsageError (out_folder not empty without overwrite). A failed QA check is not an error:
// result.pass.
DepthCommandResult CalibrateDepth(const DepthCommandOptions& options, bool quiet);

std::string FormatDepthSummary(const DepthCommandResult& result, const std::filesystem::path& out_folder);

// `heatwave calibrate depth`: registers the subcommand and its options on the `calibrate`
// app; after parsing, Chosen() says whether it was given and Run() runs it (exit code).
class DepthSubcommand {
 public:
  explicit DepthSubcommand(CLI::App& calibrate);
  bool Chosen() const;
  int Run();

 private:
  CLI::App* app_ = nullptr;
  DepthCommandOptions options_;
  CommonOptions common_;
};

}  // namespace hw::cli
