#pragma once

// heatwave calibrate latency: the clock offsets (rig.yaml time_offset_s) of the colour and
// thermal streams against depth, from a scan of an object waved in front of a still
// background (calibrate/latency.h) — estimate, check against --max-sigma-ms, write
// latency.json, rig.yaml with the offsets replaced, diagnostics/signals.png.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "calibrate/latency.h"
#include "calibrate/qa_profile.h"
#include "cli/command.h"
#include "core/rig.h"

namespace hw::cli {

struct LatencyCommandOptions {
  std::filesystem::path scan;        // scan folder with depth, rgb and thermal streams
  std::filesystem::path rig_path;    // rig.yaml read (and rewritten) instead of the scan's; "" = the scan's
  std::filesystem::path out_folder;  // output folder
  bool overwrite = false;            // replace an earlier latency calibration in out_folder
  double max_sigma_ms = 2.0;         // QA: each written offset's σ at most this, ms, (0, 1000]
  calibrate::LatencyOptions latency;

  // "" or "--flag: must be ..., got ..." (--scan, --out given; the options' Check()).
  std::string Check() const;
};

struct LatencyCommandResult {
  calibrate::LatencyResult estimate;
  core::Rig rig_in;   // the rig read (the scan's or --rig)
  core::Rig rig_out;  // rig_in with time_offset_s rgb and thermal replaced
  std::vector<calibrate::QaCheck> checks;
  bool pass = false;
  std::vector<std::string> written;  // files, relative to out_folder
  double seconds = 0;
  double track_seconds = 0;  // of `seconds`: reading the frames and tracking the blob
};

// Estimates and writes out_folder/{latency.json, rig.yaml, diagnostics/signals.png}; the
// folder is touched only once everything is estimated. Throws core::InputError (scan or
// rig unreadable, a stream missing, no moving blob, motion too small, ambiguous offset —
// calibrate::EstimateLatency) and UsageError (out_folder not empty without overwrite). A
// failed QA check is not an error: result.pass.
LatencyCommandResult CalibrateLatency(const LatencyCommandOptions& options, bool quiet);

std::string FormatLatencySummary(const LatencyCommandResult& result, const std::filesystem::path& out_folder);

// `heatwave calibrate latency`: registers the subcommand and its options on the `calibrate`
// app; after parsing, Chosen() says whether it was given and Run() runs it (exit code).
class LatencySubcommand {
 public:
  explicit LatencySubcommand(CLI::App& calibrate);
  bool Chosen() const;
  int Run();

 private:
  CLI::App* app_ = nullptr;
  LatencyCommandOptions options_;
  CommonOptions common_;
};

}  // namespace hw::cli
