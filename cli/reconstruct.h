#pragma once

// heatwave reconstruct: a scan folder (or a TUM RGB-D sequence with --rig) into a tracked
// trajectory, a coloured mesh and a report of what happened to every frame.

#include <array>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "reconstruct/reconstruction.h"
#include "reconstruct/surface_eval.h"
#include "reconstruct/thermal_eval.h"
#include "reconstruct/trajectory_eval.h"

namespace hw::cli {

// Default TSDF truncation distance, in voxels.
inline constexpr double kTruncationVoxels = 4;

struct ReconstructCommandOptions {
  std::filesystem::path scan_folder;
  std::filesystem::path out_folder;
  std::filesystem::path rig_path;  // empty: <scan>/rig.yaml
  std::filesystem::path poses_path;  // TUM trajectory to fuse along instead of tracking
  bool overwrite = false;          // replace an earlier reconstruction's files in out_folder
  reconstruct::ReconstructionOptions reconstruction;
  // ICP's depth-noise gate (IcpOptions::noise_gate_sigmas), --icp-noise-gate. Unset:
  // kNoiseGateWithMeasuredScale when rig.yaml's depth_correction includes a depth scale
  // measured on the extrinsics plate (DepthCorrection::ScaleMeasured: far depth free of
  // systematic error), else 0. RunReconstruction resolves it into reconstruction.icp, with
  // the TSDF's depth-noise model.
  std::optional<double> icp_noise_gate_sigmas;
  static constexpr double kNoiseGateWithMeasuredScale = 3;
  reconstruct::ScanReconstructionOptions scan;
  // Each stream's stamps replaced by exposure times fitted to its frame clock where they fit
  // one (core::ScanOptions::regularise_stamps); --keep-stamps turns it off.
  bool regularise_stamps = true;
  core::StampRegularisationOptions stamps;
  // Thermal fusion, when the scan has a thermal stream and thermal is true.
  bool thermal = true;
  reconstruct::ThermalFusionOptions thermal_fusion;
  std::filesystem::path emissivity_path;  // user emissivity file; empty: rig.yaml's for all
  // On-site values replacing rig.yaml's thermal emissivity (0.01..1) and reflected apparent
  // temperature (°C) — the scene default an emissivity file falls back to (heatwave audit:
  // job.yaml's conditions).
  std::optional<double> emissivity;
  std::optional<double> reflected_c;
  // Synthetic scans: each region's emissivity from truth/scene.ply (needs
  // scan.start_at_groundtruth), to measure fusion without the error of a wrong emissivity.
  bool emissivity_from_truth = false;

  std::string Check() const;
};

// What thermal fusion did (reconstruct.json "thermal"), for the summary and the tests.
struct ThermalCommandResult {
  int frames = 0;  // thermal frames of the scan
  int fused = 0, frozen = 0, no_pose = 0, no_surface = 0, missing = 0, after_end = 0;
  int skipped = 0;  // a more confident frame of its window fused instead (--thermal-frame-interval)
  double frame_interval_s = 0;
  bool background = false;  // shading and splatting ran beside the depth pipeline
  int64_t rays = 0, hits = 0, rays_fused = 0;  // over all frames given to fusion
  int64_t rays_occluded = 0;  // hits behind something the live depth saw nearer
  int occluded_frames = 0;    // frames with such rays
  int live_depth_frames = 0;  // frames given a depth frame for the occlusion test
  // Mirror rays traced, and fused rays whose mirror met the operator or a surface with a
  // temperature (ThermalFusionOptions::reflections).
  int64_t mirror_traced = 0, mirror_operator = 0, mirror_surface = 0;
  size_t regions = 0, observations = 0, memory_bytes = 0;
  size_t observations_dropped = 0;  // by ThermalFusionOptions::max_views_per_region
  int64_t offline_rejected = 0;
  double seconds = 0, load_seconds = 0, finish_seconds = 0;
  double raycast_ms = 0, reflect_ms = 0, fuse_ms = 0;  // mean per fused frame
  // Scene-based offset correction: on at all, fused frames with their own offset estimate,
  // range of the offsets removed (K), RMS of the pixel offsets at the end (K).
  bool scene_correction = false;
  int offset_estimated = 0;
  double offset_min_k = 0, offset_max_k = 0, pixel_offset_rms_k = 0;
  int vertices_observed = 0;           // model vertices with a temperature
  std::string method;                  // the estimate written to temperature_c
  std::string emissivity;              // where emissivity came from
  // Synthetic scans: every method's surface-temperature error against truth/scene.ply.
  std::vector<std::pair<reconstruct::ThermalMethod, reconstruct::TemperatureErrorStats>> evaluation;
  // The same per class of view quality (terciles of the plain mean's confidence, the mean
  // C_R of a region's views: reconstruct::TemperatureErrorsByViewQuality), in evaluation's order.
  std::vector<std::array<reconstruct::ViewQualityClass, 3>> evaluation_by_view_quality;
};

// What a run produced, for the summary and the tests.
struct ReconstructCommandResult {
  std::filesystem::path out_folder;
  int depth_frames = 0;  // depth frames in the range used
  // The rig's depth_correction applied to every depth frame: "17 x 13 nodes", "" = none.
  std::string depth_correction;
  // The streams' frame clocks, one line: "depth 30.0 Hz, jitter 1.9 ms -> exposure times
  // (±0.2 ms); thermal: kept (reason)"; "" with --keep-stamps.
  std::string stamps;
  double noise_gate_sigmas = 0;  // ICP's depth-noise gate used (IcpOptions::noise_gate_sigmas)
  int fused = 0, tracked = 0, recovered = 0, lost = 0, no_depth = 0, missing = 0, coloured = 0;
  int integrated = 0;  // fused frames whose depth went into the volume
  int64_t blocks_updated = 0, blocks_coarse = 0;  // block updates over the run, and coarse ones
  int dynamic_frames = 0;      // frames with depth pixels masked as in front of the model
  int64_t dynamic_pixels = 0;  // ... and those pixels
  int carved_frames = 0;       // frames that saw through model points (carved as free space)
  int64_t carved_points = 0;   // ... and those points
  int posed = 0, unposed = 0;  // with poses_path: fused at a given pose; not covered by them
  int held = 0;  // tracked frames with directions held at the prediction (FrameRecord)
  // Tracked (or recovered) frames aligned on depth alone (FrameRecord::depth_alone).
  int tracked_depth_only = 0;
  // The basin check (ReconstructionOptions::basin_check_m): frames checked, those found
  // unconstrained (fused, or with drop_unconstrained tracked but not fused), and the median
  // basin_m of the checked ones (NaN: none).
  int basin_checked = 0, unconstrained = 0;
  int unconstrained_not_fused = 0;  // FrameStatus::kUnconstrained: posed for the motion only
  double basin_check_m = 0;  // the options' (ReconstructionOptions)
  bool drop_unconstrained = false;
  double median_basin_m = std::numeric_limits<double>::quiet_NaN();
  int widened = 0;  // tracked frames aligned only on the widened gate (FrameRecord)
  int relocalisations_rejected = 0;  // candidates rejected for model conflict (FrameRecord)
  int prealign_rejected_by_depth = 0;  // frames whose pre-aligned rotation the depth contradicted
  int keyframes = 0;                // kept for relocalisation (Reconstruction::keyframes)
  int recovered_from_keyframe = 0;  // recovered frames relocalised from a keyframe's pose
  int raycasts = 0;  // frames after which the model view was raycast (raycast_interval)
  size_t vertices = 0, faces = 0;
  double area_m2 = 0;
  reconstruct::MeshStats mesh_stats;
  size_t blocks = 0;
  size_t volume_bytes = 0;
  size_t peak_rss_bytes = 0;
  double load_seconds = 0, process_seconds = 0, mesh_seconds = 0, total_seconds = 0;
  // Mean wall time per processed frame of each stage, ms.
  double prepare_ms = 0, track_ms = 0, integrate_ms = 0, raycast_ms = 0;
  double prepare_ahead_ms = 0;  // mean FrameRecord::prepare_ahead_ms (beside, not in the total)
  std::optional<reconstruct::TrajectoryEval> evaluation;  // when the scan has groundtruth
  // Model vertices (in the truth's frame: see RunReconstruction) to truth/scene.ply, when
  // the scan has both (synthetic scans).
  std::optional<reconstruct::SurfaceDistanceStats> surface;
  // The same after registering the model onto truth/scene.ply (the shape's error; the
  // registration says how far the map sat from the world).
  std::optional<reconstruct::MeshRegistration> registration;
  std::optional<reconstruct::SurfaceDistanceStats> surface_registered;
  std::optional<ThermalCommandResult> thermal;  // when the scan has thermal frames and a
                                                // thermal camera, and options.thermal
  std::vector<std::string> warnings;
};

// Runs the whole job: opens the scan, reconstructs (fusing the thermal stream when there is
// one: model.ply then carries temperature_c, temperature_apparent_c, temperature_confidence,
// temperature_views, temperature_std_c, temperature_footprint_m and temperature_view_x/_y/_z
// per vertex, NaN / 0 views
// where unobserved),
// writes out_folder/trajectory.txt,
// model.ply and reconstruct.json (each atomically; the folder is marked incomplete until all
// three are written, core/output_folder.h). Throws core::InputError for a bad scan or frame
// (or emissivity file),
// core::OutputError when out_folder is a file or cannot be written, UsageError for a
// non-empty out_folder without overwrite. Asserts options.Check() is empty.
ReconstructCommandResult RunReconstruction(const ReconstructCommandOptions& options, bool quiet);

// The one-screen summary printed at the end.
std::string FormatReconstructSummary(const ReconstructCommandResult& result);

// Peak resident set size of this process so far, bytes (getrusage).
size_t PeakRssBytes();

}  // namespace hw::cli
