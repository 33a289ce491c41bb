#pragma once

// heatwave reconstruct: a scan folder (or a TUM RGB-D sequence with --rig) into a tracked
// trajectory, a coloured mesh and a report of what happened to every frame.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "reconstruct/reconstruction.h"
#include "reconstruct/surface_eval.h"
#include "reconstruct/trajectory_eval.h"

namespace hw::cli {

struct ReconstructCommandOptions {
  std::filesystem::path scan_folder;
  std::filesystem::path out_folder;
  std::filesystem::path rig_path;  // empty: <scan>/rig.yaml
  bool overwrite = false;          // replace an earlier reconstruction's files in out_folder
  reconstruct::ReconstructionOptions reconstruction;
  reconstruct::ScanReconstructionOptions scan;

  std::string Check() const;
};

// What a run produced, for the summary and the tests.
struct ReconstructCommandResult {
  std::filesystem::path out_folder;
  int depth_frames = 0;  // depth frames in the range used
  int fused = 0, tracked = 0, recovered = 0, lost = 0, no_depth = 0, missing = 0, coloured = 0;
  size_t vertices = 0, faces = 0;
  double area_m2 = 0;
  reconstruct::MeshStats mesh_stats;
  size_t blocks = 0;
  size_t volume_bytes = 0;
  size_t peak_rss_bytes = 0;
  double load_seconds = 0, process_seconds = 0, mesh_seconds = 0, total_seconds = 0;
  // Mean wall time per processed frame of each stage, ms.
  double prepare_ms = 0, track_ms = 0, integrate_ms = 0, raycast_ms = 0;
  std::optional<reconstruct::TrajectoryEval> evaluation;  // when the scan has groundtruth
  // Model vertices (in the truth's frame: see RunReconstruction) to truth/scene.ply, when
  // the scan has both (synthetic scans).
  std::optional<reconstruct::SurfaceDistanceStats> surface;
  std::vector<std::string> warnings;
};

// Runs the whole job: opens the scan, reconstructs, writes out_folder/trajectory.txt,
// model.ply and reconstruct.json (each atomically; the folder is marked incomplete until all
// three are written, core/output_folder.h). Throws core::InputError for a bad scan or frame,
// core::OutputError when out_folder is a file or cannot be written, UsageError for a
// non-empty out_folder without overwrite. Asserts options.Check() is empty.
ReconstructCommandResult RunReconstruction(const ReconstructCommandOptions& options, bool quiet);

// The one-screen summary printed at the end.
std::string FormatReconstructSummary(const ReconstructCommandResult& result);

// Peak resident set size of this process so far, bytes (getrusage).
size_t PeakRssBytes();

}  // namespace hw::cli
