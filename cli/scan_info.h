#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/scan.h"

namespace hw::cli {

// Options of `heatwave scan-info`.
struct ScanInfoOptions {
  std::filesystem::path scan_folder;  // the scan to inspect
  std::filesystem::path rig_path;     // rig.yaml to use instead of <scan>/rig.yaml; empty: none
  std::optional<double> max_association_dt_s;  // seconds, > 0; unset: ScanOptions default
  double gap_factor = 1.5;    // gap = interval > gap_factor x median period; dimensionless, > 1
  bool check_frames = false;  // decode every frame, report those that cannot be loaded
  int threads = 0;            // decoding threads for check_frames, >= 0 (0: all cores)
  bool json = false;          // print the report as JSON instead of text
  bool quiet = false;         // no progress bar, no text report (JSON is still printed)

  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// Everything scan-info reports.
struct ScanInfoReport {
  core::ScanSummary summary;
  bool frames_checked = false;                     // check_frames ran
  int total_frames = 0;                            // frames of all streams
  std::vector<core::FrameProblem> frame_problems;  // frames that cannot be loaded
  // Each indexed stream's frame clock fitted to its stamps (core/frame_clock.h): what
  // `reconstruct` reads the stream at. Index: core::Stream; streams without frames: not fitted.
  std::array<core::StampFit, 3> clocks;
};

// Opens the scan (throws InputError when it is not valid; a valid scan may have warnings)
// and summarises it; with check_frames decodes every frame, with a progress bar on stderr
// unless quiet. Asserts options.Check() is empty.
ScanInfoReport InspectScan(const ScanInfoOptions& options);

// The one-screen text report: streams table, rig, ground truth, warnings, frame check.
std::string FormatScanInfo(const ScanInfoReport& report);
// The same as one JSON object (RFC 8259: every string goes through core::JsonString, so
// the output is valid UTF-8 whatever bytes the scan's paths hold).
std::string FormatScanInfoJson(const ScanInfoReport& report);

}  // namespace hw::cli
