#include "cli/reconstruct.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <iostream>
#include <memory>
#include <system_error>

#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/median.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/ply.h"
#include "core/progress.h"
#include "core/scan.h"
#include "core/strings.h"
#include "cli/reconstruct_json.h"
#include "cli/reconstruct_thermal.h"

namespace hw::cli {

namespace {

namespace fs = std::filesystem;
using reconstruct::FrameRecord;
using reconstruct::FrameStatus;

// What a reconstruction folder holds: removed by --overwrite.
const std::vector<std::string>& OutputEntries() {
  static const std::vector<std::string> entries = {"trajectory.txt", "model.ply", "reconstruct.json"};
  return entries;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

size_t PeakRssBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<size_t>(usage.ru_maxrss) * 1024;  // Linux: kilobytes
}

std::string ReconstructCommandOptions::Check() const {
  if (scan_folder.empty()) return "scan: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (std::string m = reconstruction.Check(); !m.empty()) return m;
  if (std::string m = thermal_fusion.Check(); !m.empty()) return "thermal." + m;
  if (std::string m = stamps.Check(); !m.empty()) return "stamps." + m;
  if (icp_noise_gate_sigmas && !(*icp_noise_gate_sigmas >= 0 && *icp_noise_gate_sigmas <= 10)) {
    return core::OptionFail("icp_noise_gate_sigmas", *icp_noise_gate_sigmas, "in [0, 10]");
  }
  if (emissivity_from_truth && !emissivity_path.empty()) {
    return "--emissivity-from-truth: cannot be combined with --emissivity";
  }
  if (emissivity && !(*emissivity >= core::ThermalSettings::kMinEmissivity && *emissivity <= 1)) {
    return core::OptionFail("emissivity", *emissivity, "in [0.01, 1]");
  }
  if (reflected_c && !(std::abs(*reflected_c) <= core::ThermalSettings::kMaxReflectedC)) {
    return core::OptionFail("reflected_c", *reflected_c, "finite, within ±3000 °C");
  }
  if (emissivity_from_truth && !scan.start_at_groundtruth) {
    return "--emissivity-from-truth: needs --start-at-groundtruth (the truth is in the scan's world frame)";
  }
  return scan.Check();
}

namespace {
ReconstructCommandResult ReconstructInto(const ReconstructCommandOptions& options,
                                         const core::Scan& scan, core::OutputFolder& folder,
                                         std::chrono::steady_clock::time_point start, bool quiet);
}  // namespace

ReconstructCommandResult RunReconstruction(const ReconstructCommandOptions& options, bool quiet) {
  assert(options.Check().empty());
  const auto start = std::chrono::steady_clock::now();
  core::ScanOptions scan_options;
  scan_options.rig_path = options.rig_path;
  scan_options.regularise_stamps = options.regularise_stamps;
  scan_options.stamps = options.stamps;
  const core::Scan scan = core::Scan::Open(options.scan_folder, scan_options);
  ReconstructCommandOptions resolved = options;
  // One depth-noise model: ICP's gate uses the TSDF band's. The gate pays only where far
  // depth is free of systematic error (IcpOptions::noise_gate_sigmas).
  resolved.reconstruction.icp.depth_noise = options.reconstruction.tsdf.noise;
  const bool scale_measured = scan.rig().depth_correction && scan.rig().depth_correction->ScaleMeasured();
  resolved.reconstruction.icp.noise_gate_sigmas = options.icp_noise_gate_sigmas.value_or(
      scale_measured ? ReconstructCommandOptions::kNoiseGateWithMeasuredScale : 0.0);
  if (!options.poses_path.empty()) {
    resolved.scan.poses = core::ReadTumTrajectory(options.poses_path);
    if (resolved.scan.poses->empty()) throw core::InputError(options.poses_path, "holds no pose");
  }

  // The output folder only once the input opened: a bad scan leaves nothing behind.
  std::error_code ec;
  if (fs::exists(options.out_folder, ec) && !fs::is_directory(options.out_folder, ec)) {
    throw core::OutputError(options.out_folder, "exists and is not a folder");
  }
  const bool created_folder = !fs::exists(options.out_folder, ec);
  core::OutputFolder folder(options.out_folder, "heatwave reconstruct");
  try {
    return ReconstructInto(resolved, scan, folder, start, quiet);
  } catch (...) {
    // A failed run leaves nothing of its own: outputs are written only at the very end
    // (atomically), so the folder holds at most the run marker — removed, with the folder
    // itself when this run created it. (An interrupted run leaves the marker: incomplete.)
    if (folder.IsEmpty()) {
      folder.Abandon();
      if (created_folder) fs::remove(options.out_folder, ec);
    }
    throw;
  }
}

namespace {

ReconstructCommandResult ReconstructInto(const ReconstructCommandOptions& options,
                                         const core::Scan& scan, core::OutputFolder& folder,
                                         std::chrono::steady_clock::time_point start, bool quiet) {
  if (!folder.IsEmpty()) {
    if (!options.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + options.out_folder.string() +
                       ": folder is not empty; pass --overwrite to replace the reconstruction in it");
    }
    folder.Remove(OutputEntries());
  }

  reconstruct::Reconstruction reconstruction(scan.rig(), options.reconstruction);
  ReconstructCommandResult r;
  r.out_folder = options.out_folder;
  for (const std::string& w : scan.warnings()) r.warnings.push_back(w);
  if (options.regularise_stamps) {
    for (const core::Stream stream : core::kAllStreams) {
      if (scan.NumFrames(stream) == 0) continue;
      const core::StampFit& f = scan.StampRegularisation(stream);
      if (!r.stamps.empty()) r.stamps += "; ";
      r.stamps += core::StreamName(stream) +
                  (f.applied ? core::StringPrintf(" %.1f Hz, jitter %.1f ms -> exposure times (±%.2f ms)",
                                                  1 / f.period_s, 1e3 * f.jitter_s, 1e3 * f.time_std_s)
                             : " stamps kept: " + f.reason);
    }
  }
  std::string emissivity_source;
  std::unique_ptr<reconstruct::ThermalFusion> thermal =
      MakeThermalFusion(options, scan, r.warnings, emissivity_source);
  reconstruct::ScanReconstruction run;
  {
    std::unique_ptr<core::ProgressBar> bar;
    run = reconstruct::ReconstructScan(
        scan, reconstruction, options.scan,
        [&](int done, int total) {
          if (!bar) bar = std::make_unique<core::ProgressBar>("reconstruct", total, "frames", quiet);
          bar->Set(done);
        },
        thermal.get());
  }
  if (thermal) {
    r.thermal.emplace();
    r.thermal->emissivity = emissivity_source;
    SummarizeThermal(*thermal, run, scan, *r.thermal);
  }
  r.warnings.insert(r.warnings.end(), run.warnings.begin(), run.warnings.end());
  r.load_seconds = run.load_seconds;
  r.process_seconds = run.process_seconds;
  r.missing = run.missing_frames;
  r.unposed = run.unposed_frames;
  r.keyframes = reconstruction.keyframes().size();
  r.depth_frames = static_cast<int>(reconstruction.frames().size()) + run.missing_frames + run.unposed_frames;
  if (const auto& c = scan.rig().depth_correction) {
    r.depth_correction = core::StringPrintf("%d x %d nodes%s", c->nx, c->ny,
                                            c->ScaleMeasured() ? ", depth scale measured on the plate" : "");
  }
  r.noise_gate_sigmas = options.reconstruction.icp.noise_gate_sigmas;
  std::vector<double> basins;
  for (const FrameRecord& f : reconstruction.frames()) {
    r.fused += f.fused;
    r.integrated += f.integrated;
    r.blocks_updated += f.blocks_updated;
    r.blocks_coarse += f.blocks_coarse;
    r.dynamic_frames += f.dynamic_pixels > 0;
    r.dynamic_pixels += f.dynamic_pixels;
    r.carved_frames += f.carved_points > 0;
    r.carved_points += f.carved_points;
    r.coloured += f.coloured;
    r.tracked += f.status == FrameStatus::kTracked;
    r.recovered += f.status == FrameStatus::kRecovered;
    r.recovered_from_keyframe += f.status == FrameStatus::kRecovered && f.keyframe >= 0;
    if (std::isfinite(f.basin_m)) basins.push_back(f.basin_m);
    r.unconstrained += f.unconstrained;
    r.tracked_depth_only +=
        f.depth_alone && (f.status == FrameStatus::kTracked || f.status == FrameStatus::kRecovered);
    r.held += f.held_directions > 0 &&
              (f.status == FrameStatus::kTracked || f.status == FrameStatus::kRecovered);
    r.widened += f.status == FrameStatus::kTracked && f.widened_gate;
    r.relocalisations_rejected += f.conflict_rejections;
    r.prealign_rejected_by_depth += f.prealign_rejected_by_depth;
    r.lost += f.status == FrameStatus::kLost;
    r.unconstrained_not_fused += f.status == FrameStatus::kUnconstrained;
    r.no_depth += f.status == FrameStatus::kNoDepth;
    r.posed += f.status == FrameStatus::kPosed;
    r.prepare_ms += f.prepare_ms;
    r.prepare_ahead_ms += f.prepare_ahead_ms;
    r.track_ms += f.track_ms;
    r.integrate_ms += f.integrate_ms;
    r.raycast_ms += f.raycast_ms;
    r.raycasts += f.raycast_ms > 0;
  }
  r.basin_checked = static_cast<int>(basins.size());
  r.basin_check_m = options.reconstruction.basin_check_m;
  r.drop_unconstrained = options.reconstruction.drop_unconstrained;
  if (!basins.empty()) r.median_basin_m = core::Median(basins);

  const double n = std::max<size_t>(1, reconstruction.frames().size());
  r.prepare_ms /= n;
  r.prepare_ahead_ms /= n;
  r.track_ms /= n;
  r.integrate_ms /= n;
  r.raycast_ms /= n;

  const auto mesh_start = std::chrono::steady_clock::now();
  const reconstruct::TriangleMesh mesh = reconstruction.ExtractMesh(&r.mesh_stats);
  r.mesh_seconds = Seconds(mesh_start);
  r.vertices = mesh.positions.size();
  r.faces = mesh.faces.size();
  r.area_m2 = mesh.AreaM2();
  r.blocks = reconstruction.volume().NumBlocks();
  r.volume_bytes = reconstruction.volume().MemoryBytes();
  // Nothing reads the volume after the mesh (the temperatures are the thermal fusion's own
  // regions): its memory goes back before the evaluation and the output, which would
  // otherwise add to it at the peak (README, Scale).
  reconstruction.ReleaseVolume();

  if (scan.groundtruth() && reconstruction.trajectory().size() >= 3) {
    try {
      r.evaluation = reconstruct::EvaluateTrajectory(reconstruction.trajectory(), *scan.groundtruth(),
                                                     reconstruct::TrajectoryEvalOptions{});
    } catch (const std::invalid_argument& e) {
      r.warnings.push_back(std::string("groundtruth evaluation skipped: ") + e.what());
    }
  }

  // Synthetic scans carry their true surface: measure the model against it, in the truth's
  // frame: the model is already there with --start-at-groundtruth, else it is moved there by
  // the first fused pose (the ATE's position-only alignment is not used: a short sweep's
  // positions are nearly collinear and leave the rotation about them free).
  const fs::path truth_mesh = scan.folder() / "truth" / "scene.ply";
  if (r.evaluation && core::ProbePath(truth_mesh).kind == core::PathKind::kRegularFile) {
    core::Rigid3d truth_from_model;
    if (!options.scan.start_at_groundtruth) {
      const core::TimedPose& first = reconstruction.trajectory().poses().front();
      if (const auto truth_first = scan.groundtruth()->At(first.timestamp_s)) {
        truth_from_model = *truth_first * first.world_from_sensor.Inverse();
      }
    }
    const core::PlyMesh truth = core::ReadPly(truth_mesh);
    const std::vector<Eigen::Vector3d> truth_positions = truth.Positions();
    const reconstruct::TriangleGrid truth_grid(truth_positions, truth.faces, kSurfaceSearchM);
    std::vector<Eigen::Vector3d> points;
    points.reserve(mesh.positions.size());
    for (const Eigen::Vector3f& p : mesh.positions) points.push_back(truth_from_model * p.cast<double>());
    r.surface = reconstruct::SummarizeDistances(reconstruct::PointToMeshDistances(points, truth_grid, kSurfaceSearchM));
    if (thermal && truth.Find("temperature_c")) {
      // Temperatures are compared in the world frame, not the registered one below: the
      // registration fixes distances to the surface, not sliding along it, which is what
      // pairs a vertex with its true temperature (registered, eqT4's errors rose by
      // 0.004–0.008 K).
      std::vector<Eigen::Vector3f> points_in_truth;
      points_in_truth.reserve(points.size());
      for (const Eigen::Vector3d& p : points) points_in_truth.push_back(p.cast<float>());
      EvaluateThermalMethods(*thermal, mesh.positions, points_in_truth, mesh.faces,
                             reconstruct::TemperatureTruthFromPly(truth, truth_mesh), *r.thermal);
    }
    // The shape's own error: the model registered onto the truth first (surface_eval.h), the
    // registration's size being the map's pose error. Not reported when no vertex came
    // within reach of the truth (nothing to register on).
    const reconstruct::MeshRegistration registration =
        reconstruct::RegisterToMesh(points, truth_grid, reconstruct::MeshRegistrationOptions{});
    if (registration.iterations > 0) {
      for (Eigen::Vector3d& p : points) p = registration.reference_from_points * p;
      r.registration = registration;
      r.surface_registered =
          reconstruct::SummarizeDistances(reconstruct::PointToMeshDistances(points, truth_grid, kSurfaceSearchM));
    } else {
      r.warnings.push_back(core::StringPrintf("shape not measured: too few model vertices within %.0f mm of %s",
                                              1000 * kSurfaceSearchM, truth_mesh.c_str()));
    }
  }

  core::PlyMesh ply = reconstruct::ToPly(mesh);
  if (thermal) {
    const reconstruct::PointTemperatures t = thermal->Sample(mesh.positions, thermal->options().method);
    for (uint16_t views : t.views) r.thermal->vertices_observed += views > 0;
    AddTemperatureProperties(t, mesh.positions, thermal->emissivity(), ply);
  }
  ply.comments.push_back("heatwave reconstruct: world frame, metres");
  core::WriteTumTrajectory(options.out_folder / "trajectory.txt", reconstruction.trajectory());
  core::WritePly(options.out_folder / "model.ply", ply);
  r.peak_rss_bytes = PeakRssBytes();
  r.total_seconds = Seconds(start);
  core::WriteFileAtomically(options.out_folder / "reconstruct.json",
                            ReconstructReportJson(options, scan, r, reconstruction, run, thermal.get()));
  folder.Commit();
  return r;
}

}  // namespace

std::string FormatReconstructSummary(const ReconstructCommandResult& r) {
  std::string out;
  out += core::StringPrintf("Frames     %d depth frames: %d fused (%d tracked, %d recovered, %d at given poses), "
                            "%d lost, %s%d without depth, %d missing, %d without a given pose; %d coloured\n",
                            r.depth_frames, r.fused, r.tracked, r.recovered, r.posed, r.lost,
                            r.unconstrained_not_fused > 0
                                ? core::StringPrintf("%d unconstrained (tracked, not fused), ", r.unconstrained_not_fused)
                                      .c_str()
                                : "",
                            r.no_depth, r.missing, r.unposed, r.coloured);
  if (r.integrated < r.fused) {
    out += core::StringPrintf("Fusion     depth of %d of the %d fused frames integrated (the others tracked between "
                              "raycasts: --integrate-between-raycasts false)\n",
                              r.integrated, r.fused);
  }
  if (r.blocks_coarse > 0) {
    out += core::StringPrintf("Fusion     %.0f%% of the block updates coarse (far blocks never seen nearer: --coarse-far)\n",
                              100.0 * static_cast<double>(r.blocks_coarse) / static_cast<double>(r.blocks_updated));
  }
  if (r.dynamic_frames > 0 || r.carved_frames > 0) {
    out += core::StringPrintf("Dynamic    %lld depth pixels of %d frames not integrated (in front of the model: something "
                              "moved in); %lld model points of %d frames carved (seen through: something left); "
                              "--dynamic-margin\n",
                              static_cast<long long>(r.dynamic_pixels), r.dynamic_frames,
                              static_cast<long long>(r.carved_points), r.carved_frames);
  }
  if (r.tracked_depth_only > 0 && 2 * r.tracked_depth_only >= r.tracked + r.recovered) {
    out += core::StringPrintf("Tracking   %d of %d frames aligned on depth alone: along a plain wall it can slide "
                              "undetected (README, Tracking without colour); track with colour, or check the "
                              "trajectory\n",
                              r.tracked_depth_only, r.tracked + r.recovered);
  }
  if (r.basin_checked > 0) {
    out += core::StringPrintf("Tracking   basin check: %d of %d depth-alone frames unconstrained (ICP moved %.0f mm along "
                              "its weakest direction came back less than half way; median %.1f mm apart)%s "
                              "(--basin-check)\n",
                              r.unconstrained, r.basin_checked, 1e3 * r.basin_check_m, 1e3 * r.median_basin_m,
                              r.drop_unconstrained ? ", not fused" : "");
  }
  if (r.widened > 0) {
    out += core::StringPrintf("Tracking   %d frames aligned only on the widened association gate "
                              "(no velocity yet, or more motion than the gate)\n", r.widened);
  }
  if (r.recovered_from_keyframe > 0) {
    out += core::StringPrintf("Tracking   %d of the %d recovered frames relocalised from a keyframe's pose "
                              "(%d keyframes kept; --relocalisation-candidates)\n",
                              r.recovered_from_keyframe, r.recovered, r.keyframes);
  }
  if (r.relocalisations_rejected > 0) {
    out += core::StringPrintf("Tracking   %d relocalisation candidates rejected: the live depth contradicted the "
                              "model seen from there (--relocalisation-max-conflict)\n",
                              r.relocalisations_rejected);
  }
  if (r.prealign_rejected_by_depth > 0) {
    out += core::StringPrintf("Tracking   %d rotation pre-alignments not used: the depth disagreed with the "
                              "rotation the grey images gave (something moving in view?) "
                              "(--prealign-max-depth-misfit-ratio)\n",
                              r.prealign_rejected_by_depth);
  }
  if (r.held > 0) {
    out += core::StringPrintf("Tracking   %d frames with directions the geometry left free held at the "
                              "constant-velocity prediction\n", r.held);
  }
  if (!r.depth_correction.empty()) {
    out += "Depth      corrected with rig.yaml's depth_correction (" + r.depth_correction + ")\n";
  }
  if (!r.stamps.empty()) out += "Stamps     " + r.stamps + "\n";
  if (r.noise_gate_sigmas > 0 && r.tracked > 0) {  // (fusing along given poses tracks nothing)
    out += core::StringPrintf("Tracking   ICP gate and Huber threshold widened to %g sigmas of the depth noise "
                              "where wider (--icp-noise-gate)\n", r.noise_gate_sigmas);
  }
  const int processed = r.depth_frames - r.missing;
  // Frames prepared ahead: their preparation ran beside the previous frame's processing and
  // is not part of the per-frame total; said so with its own time.
  const std::string ahead =
      r.prepare_ahead_ms > 0 ? core::StringPrintf(" (+%.1f ahead, beside)", r.prepare_ahead_ms) : std::string();
  out += core::StringPrintf("Speed      %.1f frames/s processing (%.1f ms/frame: prepare %.1f%s, track %.1f, "
                            "integrate %.1f, raycast %.1f after %d of them); decoding %.1f s\n",
                            processed / std::max(r.process_seconds, 1e-9),
                            1000 * r.process_seconds / std::max(processed, 1), r.prepare_ms, ahead.c_str(),
                            r.track_ms, r.integrate_ms, r.raycast_ms, r.raycasts, r.load_seconds);
  out += core::StringPrintf("Model      %zu vertices, %zu triangles, %.3f m2; %d fragments removed "
                            "(%d triangles); meshing %.2f s\n",
                            r.vertices, r.faces, r.area_m2, r.mesh_stats.components_removed,
                            r.mesh_stats.triangles_removed, r.mesh_seconds);
  out += core::StringPrintf("Memory     %zu blocks, volume %.1f MB, peak %.1f MB\n", r.blocks,
                            r.volume_bytes / 1e6, r.peak_rss_bytes / 1e6);
  if (r.evaluation) {
    const std::string rpe =
        r.evaluation->rpe_m.count > 0
            ? core::StringPrintf("RPE %.2f mm / %.3f deg per 1 s", 1000 * r.evaluation->rpe_m.rmse,
                                 r.evaluation->rpe_deg.rmse)
            : std::string("RPE n/a (no poses 1 s apart)");
    out += core::StringPrintf("Accuracy   against groundtruth.txt: ATE RMSE %.2f mm (max %.2f mm), %s\n",
                              1000 * r.evaluation->ate_m.rmse, 1000 * r.evaluation->ate_m.max,
                              rpe.c_str());
  }
  if (r.surface) {
    out += core::StringPrintf("Surface    model to truth/scene.ply: median %.2f mm, 90%% %.2f mm, "
                              "%d of %d vertices beyond %.0f mm\n",
                              1000 * r.surface->median_m, 1000 * r.surface->p90_m,
                              r.surface->beyond_search, r.surface->points, 1000 * kSurfaceSearchM);
  }
  if (r.surface_registered && r.registration) {
    out += core::StringPrintf("Shape      registered onto the truth (moved %.3f deg, %.2f mm): median %.2f mm, "
                              "90%% %.2f mm\n",
                              r.registration->rotation_deg, 1000 * r.registration->translation_m,
                              1000 * r.surface_registered->median_m, 1000 * r.surface_registered->p90_m);
  }
  if (r.thermal) out += FormatThermalSummary(*r.thermal);
  constexpr size_t kMaxListed = 8;
  if (!r.warnings.empty()) {
    out += core::StringPrintf("Warnings   %zu (all in reconstruct.json)\n", r.warnings.size());
    for (size_t i = 0; i < std::min(kMaxListed, r.warnings.size()); ++i) {
      out += "  " + r.warnings[i] + "\n";
    }
    if (r.warnings.size() > kMaxListed) out += core::StringPrintf("  ... %zu more\n", r.warnings.size() - kMaxListed);
  }
  out += core::StringPrintf("Wrote      %s/{trajectory.txt, model.ply, reconstruct.json} in %.1f s\n",
                            r.out_folder.c_str(), r.total_seconds);
  return out;
}

int RunReconstruct(int argc, char** argv) {
  CLI::App app("Track the depth stream and fuse it into a coloured 3D model (KinectFusion on the CPU).",
               "heatwave reconstruct");
  ReconstructCommandOptions o;
  CommonOptions common;
  AddCommonOptions(app, common);
  auto& r = o.reconstruction;
  app.add_option("scan", o.scan_folder, "scan folder (or TUM RGB-D sequence with --rig)")->required();
  app.add_option("--out", o.out_folder, "output folder: trajectory.txt, model.ply, reconstruct.json")
      ->required();
  app.add_option("--rig", o.rig_path, "rig.yaml to use instead of the scan's (TUM sequences)");
  app.add_option("--poses", o.poses_path,
                 "fuse along this TUM trajectory (world_from_depth: motion capture, another SLAM, "
                 "groundtruth.txt) instead of tracking");
  app.add_flag("--overwrite", o.overwrite, "replace the reconstruction files in a non-empty --out");
  app.add_option("--voxel-size", r.tsdf.voxel_size_m, "TSDF voxel side, m")->capture_default_str();
  std::optional<double> truncation_m;
  app.add_option("--truncation", truncation_m, "TSDF truncation distance, m; default: 4 voxels");
  app.add_option("--truncation-noise-sigmas", r.tsdf.truncation_noise_sigmas,
                 "widen the truncation band to this many sigmas of the depth noise where that is wider (0: fixed band)")
      ->capture_default_str();
  app.add_option("--max-weight", r.tsdf.max_weight, "TSDF weight cap, frames (a whole number)")->capture_default_str();
  app.add_option("--coarse-far", r.tsdf.coarse_far,
                 "update blocks seen only from where one reading's noise and a depth pixel outgrow a voxel (2.6 m "
                 "at 5 mm, 525 px) on every other voxel, the others interpolated, until seen nearer: true or false")
      ->capture_default_str();
  app.add_option("--min-depth", r.min_depth_m, "nearest depth used, m")->capture_default_str();
  app.add_option("--max-depth", r.max_depth_m, "farthest depth used, m")->capture_default_str();
  bool no_colour = false;
  app.add_flag("--no-colour", no_colour, "do not paint the model with the rgb stream");
  app.add_option("--photometric-weight", r.icp.photometric_weight,
                 "weight of ICP's colour term, m per grey level (0: geometry only)")->capture_default_str();
  app.add_option("--photometric-offset", r.icp.photometric_offset,
                 "estimate a brightness offset between the model's grey levels and the frame's in ICP's colour "
                 "term (auto exposure): true or false")
      ->capture_default_str();
  app.add_option("--icp-noise-depth", r.icp.noise_reference_depth_m,
                 "ICP residuals of a point at depth z count (this / z)x: depth noise grows with distance, m "
                 "(0: all alike; helps scenes at 1-2 m, hurts at 3-4 m: README)")
      ->capture_default_str();
  app.add_option("--icp-noise-gate", o.icp_noise_gate_sigmas,
                 "pair ICP points up to this many sigmas of the depth noise apart where that exceeds the gate, "
                 "Huber threshold alike (0: fixed gate); default 3 when rig.yaml's depth_correction includes the "
                 "depth scale measured on the extrinsics plate, else 0 (it hurts with systematic depth error: README)");
  app.add_option("--raycast-level", r.raycast_level,
                 "track against the model raycast at this pyramid level (0 full, 1 half resolution)")
      ->capture_default_str();
  app.add_option("--raycast-band-steps", r.raycast.band_steps,
                 "march rays in steps of each block's narrowest fused band (fewer samples before far surfaces) "
                 "instead of the fixed truncation: true or false")
      ->capture_default_str();
  app.add_option("--raycast-interval", r.raycast_interval,
                 "fused frames between model raycasts for tracking (1: after every frame)")
      ->capture_default_str();
  app.add_option("--reuse-max-motion", r.reuse_max_motion_m,
                 "raycast the model view again before --raycast-interval when the next frame would be this far "
                 "from where the view was cast, m")
      ->capture_default_str();
  app.add_option("--reuse-max-motion-deg", r.reuse_max_motion_deg,
                 "the same limit on the rotation, degrees")
      ->capture_default_str();
  app.add_option("--integrate-max-motion", r.integrate_max_motion_m,
                 "integrate a frame tracked between raycasts when it lies this far from the last integrated "
                 "frame, m (with --integrate-between-raycasts false)")
      ->capture_default_str();
  app.add_option("--integrate-max-motion-deg", r.integrate_max_motion_deg, "the same limit on the rotation, degrees")
      ->capture_default_str();
  app.add_option("--reuse-lead", r.reuse_lead,
                 "cast the model view from where the camera will be this fraction of the view's reuse window "
                 "later (constant velocity), so that the frames reusing it lie on both sides of it, [0, 1]")
      ->capture_default_str();
  app.add_option("--integrate-between-raycasts", r.integrate_between_raycasts,
                 "integrate the depth of the frames tracked between two raycasts too (false: only of the "
                 "frames after which the model is raycast and of those as far as the reuse limits from the last "
                 "integrated one; the others still get a pose): true or false")
      ->capture_default_str();
  app.add_option("--dynamic-margin", r.dynamic.margin_m,
                 "depth this far (m, or dynamic fraction of its depth if more) in front of the model it was "
                 "tracked against is not integrated: something moved in (0 with --dynamic-fraction 0: off)")
      ->capture_default_str();
  app.add_option("--dynamic-fraction", r.dynamic.margin_fraction,
                 "the same margin as a fraction of the pixel's depth, [0, 1)")
      ->capture_default_str();
  app.add_option("--prealign-iterations", r.prealign.iterations,
                 "before ICP, align each frame's coarse grey image to the previous frame's by rotation (a jerk "
                 "turns the rig past the constant-velocity prediction), this many Gauss-Newton iterations, "
                 "[0, 50] (0: off; needs colour)")
      ->capture_default_str();
  app.add_option("--prealign-scales", r.prealign.scales,
                 "blur scales of the pre-alignment, coarse to fine, each twice the next one's blur, the "
                 "iterations at each, [1, 4]")
      ->capture_default_str();
  app.add_option("--prealign-max-depth-misfit-ratio", r.prealign.max_depth_misfit_ratio,
                 "the pre-aligned rotation is used only when the frame's depth meets the previous frame's no "
                 "worse than this times at the prediction (mean |dz|), >= 1 (0: no depth check)")
      ->capture_default_str();
  app.add_option("--relocalisation-candidates", r.keyframes.candidates,
                 "after a loss that the last pose cannot bridge, try aligning from this many of the keyframes the "
                 "frame looks most alike, [0, 10] (0: no keyframes)")
      ->capture_default_str();
  app.add_option("--basin-check", r.basin_check_m,
                 "on frames tracked on depth alone, rerun ICP from its result moved this far along its weakest "
                 "direction: coming back less than half way marks the frame unconstrained (a plain wall), m, "
                 "[0, 0.1] (0: off)")
      ->capture_default_str();
  app.add_option("--drop-unconstrained", r.drop_unconstrained,
                 "do not fuse unconstrained frames (--basin-check; their poses still carry the motion on): true or "
                 "false")
      ->capture_default_str();
  app.add_option("--relocalisation-max-conflict", r.relocalisation_max_conflict,
                 "a relocalised pose is accepted only when at most this fraction of the live depth stands in "
                 "front of the model or sees through it (or 3x the recent frames' median), [0, 1] (1: off)")
      ->capture_default_str();
  app.add_option("--keyframe-spacing", r.keyframes.min_distance_m,
                 "a tracked frame farther than this from every keyframe becomes one, m")->capture_default_str();
  app.add_option("--keyframe-spacing-deg", r.keyframes.min_angle_deg,
                 "... or turned more than this from every keyframe, degrees")->capture_default_str();
  app.add_option("--min-component-triangles", r.mesh.min_component_triangles,
                 "remove mesh fragments with fewer triangles")->capture_default_str();
  app.add_option("--threads", r.num_threads, "worker threads, 0 = all cores")->capture_default_str();
  bool no_prepare_ahead = false;
  app.add_flag("--no-prepare-ahead", no_prepare_ahead,
               "prepare each depth frame (correction, undistortion, pyramid) after the previous one is "
               "fused, not beside it on a thread of its own (the same results)");
  bool keep_stamps = false;
  app.add_flag("--keep-stamps", keep_stamps,
               "use every stream's stamps as indexed, not exposure times fitted to its frame clock");
  app.add_option("--stamp-window", o.stamps.window_s,
                 "span of the line fitted to the stamps around each frame, s")->capture_default_str();
  app.add_flag("--start-at-groundtruth", o.scan.start_at_groundtruth,
               "place the first frame at its groundtruth.txt pose (model in the scan's world frame)");
  app.add_option("--first-frame", o.scan.first_frame, "first depth frame to use")->capture_default_str();
  app.add_option("--max-frames", o.scan.max_frames, "number of depth frames to use, 0 = all")
      ->capture_default_str();
  auto& t = o.thermal_fusion;
  bool no_thermal = false;
  app.add_flag("--no-thermal", no_thermal, "do not fuse the thermal stream (model without temperature)");
  std::string method = reconstruct::ThermalMethodName(t.method);
  app.add_option("--thermal-method", method,
                 "estimate written to temperature_c: latest, mean, capped-mean, online (the paper's rule), "
                 "offline (robust confidence-weighted mean)")
      ->capture_default_str();
  app.add_option("--recency-bias", t.recency_bias, "b of the online rule, [0, 1]")->capture_default_str();
  std::vector<double> powers = {t.confidence.motion_power, t.confidence.distortion_power, t.confidence.angle_power,
                                t.confidence.distance_power, t.confidence.operating_power};
  app.add_option("--confidence-powers", powers,
                 "powers p1..p5 of the ray confidence's motion, lens distortion, angle, distance and "
                 "operating-condition terms (0 switches one off)")
      ->expected(5)
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--min-ray-confidence", t.min_ray_confidence, "rays below this confidence are not fused")
      ->capture_default_str();
  app.add_option("--thermal-edge-radius", t.edge_radius_px,
                 "thermal pixels within this many pixels of a silhouette (a neighbour's hit farther or "
                 "nearer than any surface fused could put it, or none) are not fused; 0: off")
      ->capture_default_str();
  app.add_option("--thermal-occlusion-margin", t.occlusion_margin_m,
                 "thermal rays whose model surface lies this far (m, or --thermal-occlusion-fraction of the "
                 "depth if more) behind what the depth camera saw at the time are not fused: someone or "
                 "something passing in front (0 with the fraction 0: off)")
      ->capture_default_str();
  app.add_option("--thermal-occlusion-fraction", t.occlusion_margin_fraction,
                 "the same margin as a fraction of the depth seen, [0, 1)")
      ->capture_default_str();
  app.add_option("--thermal-max-views", t.max_views_per_region,
                 "views per surface region kept for the offline estimate, the most confident ones "
                 "(bounds memory on long scans); 0: all")
      ->capture_default_str();
  app.add_option("--thermal-frame-interval", t.frame_interval_s,
                 "fuse only the most confident (least blurred, farthest from a shutter event) thermal frame of "
                 "each window this long (s), skipping the others: a 30 Hz camera's consecutive frames are "
                 "nearly the same view, and each costs a raycast; 0: every frame, [0, 1]")
      ->capture_default_str();
  app.add_flag_callback("--no-thermal-background", [&t] { t.background = false; },
                        "shade and splat each fused thermal frame inline, not on a thread of its own beside the "
                        "depth pipeline (with --thermal-frame-interval > 0; the same model either way)");
  app.add_option("--thermal-vignetting", t.vignetting,
                 "thermal radiance lost at the image corners after the camera's own calibration "
                 "(pixels read L (1 - v r^2)), corrected before fusion; 0: none")
      ->capture_default_str();
  std::string scene_correction = t.scene_correction.frame_offset
                                     ? (t.scene_correction.pixel_offset ? "both" : "frame")
                                     : (t.scene_correction.pixel_offset ? "pixel" : "off");
  app.add_option("--thermal-scene-correction", scene_correction,
                 "correct the thermal camera's offsets against the model as it grows: frame (the jump of the "
                 "common offset at each shutter event), pixel (fixed pattern, column noise, vignetting left "
                 "over), both, off")
      ->check(CLI::IsMember({"off", "frame", "pixel", "both"}))
      ->capture_default_str();
  app.add_option("--thermal-reflections", t.reflections.trace,
                 "follow each shiny surface's mirror ray on the model (the operator's body behind the camera, "
                 "a surface with a temperature, or the room) instead of taking the whole reflection as the "
                 "uniform reflected temperature")
      ->capture_default_str();
  app.add_option("--thermal-reflection-min-weight", t.reflections.min_specular_weight,
                 "trace a mirror ray only where the specular weight (1 - emissivity at the angle) x specular share "
                 "reaches this, [0, 1]: below it the uniform reflected temperature stands in")
      ->capture_default_str();
  app.add_option("--operator-c", t.reflections.operator_apparent_c,
                 "apparent temperature of the person holding the rig, as a shiny surface reflects them, degC")
      ->capture_default_str();
  app.add_option("--operator-distance", t.reflections.operator_distance_m,
                 "how far behind the thermal camera the operator's body is, m (an upright ellipse, "
                 "--operator-size wide and tall)")
      ->capture_default_str();
  std::vector<double> operator_size = {2 * t.reflections.operator_half_width_m, 2 * t.reflections.operator_half_height_m};
  app.add_option("--operator-size", operator_size, "width and height of the operator's body, m (0,0: no body)")
      ->expected(2)
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--emissivity", o.emissivity_path,
                 "emissivity file: regions of other emissivity / reflected temperature (README)");
  app.add_flag("--emissivity-from-truth", o.emissivity_from_truth,
               "synthetic scans: emissivity from truth/scene.ply (needs --start-at-groundtruth)");
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  o.thermal = !no_thermal;
  o.regularise_stamps = !keep_stamps;
  o.scan.prepare_ahead = !no_prepare_ahead;
  t.reflections.operator_body = operator_size[0] > 0 || operator_size[1] > 0;
  if (t.reflections.operator_body) {
    t.reflections.operator_half_width_m = operator_size[0] / 2;
    t.reflections.operator_half_height_m = operator_size[1] / 2;
  }
  t.confidence.motion_power = powers[0];
  t.confidence.distortion_power = powers[1];
  t.confidence.angle_power = powers[2];
  t.confidence.distance_power = powers[3];
  t.confidence.operating_power = powers[4];
  r.integrate_colour = !no_colour;
  // Truncation follows the voxel: 4 voxels keeps the band about as wide as the sensor's noise
  // at the default size, and a coarser volume still has voxels on both sides of a surface.
  r.tsdf.truncation_m = truncation_m.value_or(kTruncationVoxels * r.tsdf.voxel_size_m);
  return RunGuarded([&] {
    const std::optional<reconstruct::ThermalMethod> parsed_method = reconstruct::ParseThermalMethod(method);
    if (!parsed_method) {
      throw UsageError("--thermal-method: must be latest, mean, capped-mean, online or offline, got '" + method + "'");
    }
    t.method = *parsed_method;
    t.scene_correction.frame_offset = scene_correction == "frame" || scene_correction == "both";
    t.scene_correction.pixel_offset = scene_correction == "pixel" || scene_correction == "both";
    ThrowIfInvalid(o.Check());
    const ReconstructCommandResult result = RunReconstruction(o, common.quiet);
    if (!common.quiet) std::cout << FormatReconstructSummary(result) << std::flush;
    return kExitOk;
  });
}

}  // namespace hw::cli
