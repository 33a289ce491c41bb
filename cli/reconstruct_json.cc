#include "cli/reconstruct_json.h"

#include <algorithm>
#include <vector>

#include "cli/reconstruct_thermal.h"
#include "core/json.h"
#include "core/strings.h"

namespace hw::cli {

namespace {

using core::JsonArray;
using core::JsonNumber;
using core::JsonObject;
using reconstruct::FrameRecord;
using reconstruct::FrameStatus;

std::string SettingsJson(const ReconstructCommandOptions& o) {
  const auto& r = o.reconstruction;
  JsonObject tsdf, depth, icp, raycast, mesh, all;
  tsdf.Number("voxel_size_m", r.tsdf.voxel_size_m)
      .Number("truncation_m", r.tsdf.truncation_m)
      .Number("truncation_noise_sigmas", r.tsdf.truncation_noise_sigmas)
      .Number("noise_base_m", r.tsdf.noise.base_m)
      .Number("noise_quadratic_per_m", r.tsdf.noise.quadratic_per_m)
      .Number("noise_reference_m", r.tsdf.noise.reference_m)
      .Number("max_weight", r.tsdf.max_weight)
      .Bool("coarse_far", r.tsdf.coarse_far);
  depth.Int("bilateral_radius_px", r.depth.bilateral_radius_px)
      .Number("bilateral_sigma_px", r.depth.bilateral_sigma_px)
      .Number("bilateral_sigma_depth_m", r.depth.bilateral_sigma_depth_m)
      .Number("edge_jump_fraction", r.depth.edge_jump_fraction)
      .Int("num_levels", r.depth.num_levels);
  icp.Add("iterations", core::StringPrintf("[%d, %d, %d]", r.icp.iterations[0], r.icp.iterations[1],
                                           r.icp.iterations[2]))
      .Number("max_distance_m", r.icp.max_distance_m)
      .Number("min_distance_m", r.icp.min_distance_m)
      .Number("max_normal_angle_deg", r.icp.max_normal_angle_deg)
      .Number("huber_m", r.icp.huber_m)
      .Number("noise_reference_depth_m", r.icp.noise_reference_depth_m)
      .Number("noise_gate_sigmas", r.icp.noise_gate_sigmas)
      .Number("min_inlier_fraction", r.icp.min_inlier_fraction)
      .Int("min_inliers", r.icp.min_inliers)
      .Number("max_condition", r.icp.max_condition)
      .Number("max_residual_m", r.icp.max_residual_m)
      .Number("max_jump_m", r.icp.max_jump_m)
      .Number("max_jump_deg", r.icp.max_jump_deg)
      .Number("photometric_weight", r.icp.photometric_weight)
      .Bool("photometric_offset", r.icp.photometric_offset);
  raycast.Number("step_fraction", r.raycast.step_fraction)
      .Bool("band_steps", r.raycast.band_steps)
      .Int("level", r.raycast_level)
      .Int("interval", r.raycast_interval)
      .Bool("integrate_between_raycasts", r.integrate_between_raycasts)
      .Number("reuse_max_correction_m", r.reuse_max_correction_m)
      .Number("reuse_max_correction_deg", r.reuse_max_correction_deg)
      .Number("reuse_max_motion_m", r.reuse_max_motion_m)
      .Number("reuse_max_motion_deg", r.reuse_max_motion_deg)
      .Number("integrate_max_motion_m", r.integrate_max_motion_m)
      .Number("integrate_max_motion_deg", r.integrate_max_motion_deg)
      .Number("reuse_lead", r.reuse_lead);
  JsonObject dynamic, keyframes, prealign;
  prealign.Int("iterations", r.prealign.iterations)
      .Number("blur_sigma_px", r.prealign.blur_sigma_px)
      .Number("max_rotation_deg", r.prealign.max_rotation_deg)
      .Number("min_correction_deg", r.prealign.min_correction_deg)
      .Number("huber", r.prealign.huber)
      .Int("min_pixels", r.prealign.min_pixels)
      .Int("scales", r.prealign.scales)
      .Number("max_depth_misfit_ratio", r.prealign.max_depth_misfit_ratio);
  dynamic.Number("margin_m", r.dynamic.margin_m).Number("margin_fraction", r.dynamic.margin_fraction);
  keyframes.Int("candidates", r.keyframes.candidates)
      .Number("min_distance_m", r.keyframes.min_distance_m)
      .Number("min_angle_deg", r.keyframes.min_angle_deg)
      .Int("descriptor_width", r.keyframes.descriptor_width)
      .Number("max_distance", r.keyframes.max_distance);
  mesh.Number("min_weight", r.mesh.min_weight)
      .Int("min_component_triangles", r.mesh.min_component_triangles)
      .Number("min_component_area_fraction", r.mesh.min_component_area_fraction);
  all.Number("min_depth_m", r.min_depth_m)
      .Number("max_depth_m", r.max_depth_m)
      .Bool("integrate_colour", r.integrate_colour)
      .Number("min_valid_depth_fraction", r.min_valid_depth_fraction)
      .Number("relocalisation_widening", r.relocalisation_widening)
      .Number("relocalisation_max_conflict", r.relocalisation_max_conflict)
      .Number("max_residual_ratio", r.max_residual_ratio)
      .Number("max_condition_ratio", r.max_condition_ratio)
      .Number("basin_check_m", r.basin_check_m)
      .Bool("drop_unconstrained", r.drop_unconstrained)
      .Int("num_threads", r.num_threads)
      .Bool("start_at_groundtruth", o.scan.start_at_groundtruth)
      .Bool("prepare_ahead", o.scan.prepare_ahead)
      .Bool("regularise_stamps", o.regularise_stamps)
      .Number("stamp_window_s", o.stamps.window_s)
      .String("poses", o.poses_path.string())
      .Int("first_frame", o.scan.first_frame)
      .Int("max_frames", o.scan.max_frames)
      .Add("tsdf", tsdf.str())
      .Add("depth", depth.str())
      .Add("icp", icp.str())
      .Add("raycast", raycast.str())
      .Add("dynamic", dynamic.str())
      .Add("keyframes", keyframes.str())
      .Add("prealign", prealign.str())
      .Add("mesh", mesh.str());
  return all.str();
}

std::string FrameJson(const FrameRecord& f, int depth_index) {
  JsonObject o;
  o.Int("depth_frame", depth_index)
      .Number("timestamp_s", f.timestamp_s)
      .String("status", reconstruct::FrameStatusName(f.status))
      .Bool("fused", f.fused)
      .Bool("integrated", f.integrated)
      .Bool("coloured", f.coloured)
      .Int("dynamic_pixels", f.dynamic_pixels)
      .Int("carved_points", f.carved_points)
      .Number("valid_depth_fraction", f.valid_depth_fraction)
      .Number("model_conflict", f.model_conflict);
  if (f.status == FrameStatus::kTracked || f.status == FrameStatus::kRecovered ||
      f.status == FrameStatus::kLost || f.status == FrameStatus::kUnconstrained) {
    o.String("icp", reconstruct::IcpStatusName(f.icp_status))
        .Int("inliers", f.inliers)
        .Int("valid_points", f.valid_points)
        .Number("residual_rms_m", f.residual_rms_m)
        .Number("condition", f.condition)
        .Int("held_directions", f.held_directions)
        .Bool("depth_alone", f.depth_alone)
        .Number("basin_m", f.basin_m)
        .Bool("unconstrained", f.unconstrained)
        .String("icp_start", f.keyframe >= 0 ? "keyframe" : f.from_last_pose ? "last_pose" : "prediction")
        .Int("keyframe", f.keyframe)
        .Bool("widened_gate", f.widened_gate)
        .Int("iterations", f.iterations)
        .Int("conflict_rejections", f.conflict_rejections)
        .Number("photometric_offset", f.photometric_offset)
        .Number("prealign_deg", f.prealign_deg)
        .Bool("prealign_rejected_by_depth", f.prealign_rejected_by_depth)
        .Number("correction_m", f.correction_m)
        .Number("correction_deg", f.correction_deg);
  }
  o.Int("blocks", static_cast<int64_t>(f.blocks))
      .Int("blocks_updated", f.blocks_updated)
      .Int("blocks_coarse", f.blocks_coarse)
      .Number("prepare_ms", f.prepare_ms)
      .Number("prepare_ahead_ms", f.prepare_ahead_ms)
      .Number("track_ms", f.track_ms)
      .Number("integrate_ms", f.integrate_ms)
      .Number("raycast_ms", f.raycast_ms);
  return o.str();
}

std::string ErrorStatsJson(const reconstruct::ErrorStats& e) {
  JsonObject o;
  o.Number("rmse", e.rmse).Number("mean", e.mean).Number("median", e.median).Number("std", e.std)
      .Number("min", e.min).Number("max", e.max).Int("count", e.count);
  return o.str();
}

}  // namespace

std::string StampFitJson(const core::StampFit& f) {
  return JsonObject()
      .Bool("regularised", f.applied)
      .String("reason", f.reason)
      .Number("period_s", f.period_s)
      .Number("jitter_s", f.jitter_s)
      .Number("time_std_s", f.time_std_s)
      .Number("max_shift_s", f.max_shift_s)
      .Int("outliers", f.outliers)
      .Int("empty_slots", f.empty_slots)
      .Int("segments", f.segments)
      .Int("unfitted", f.unfitted)
      .str();
}

std::string ReconstructReportJson(const ReconstructCommandOptions& options, const core::Scan& scan,
                                  const ReconstructCommandResult& r,
                                  const reconstruct::Reconstruction& reconstruction,
                                  const reconstruct::ScanReconstruction& run,
                                  const reconstruct::ThermalFusion* thermal) {
  JsonObject summary, timings, memory, mesh, input;
  input.String("scan", scan.folder().string())
      .String("rig", scan.rig_path().string())
      .Int("depth_frames", r.depth_frames)
      .String("depth_correction", r.depth_correction.empty() ? "none" : "rig.yaml, " + r.depth_correction);
  summary.Int("fused", r.fused).Int("tracked", r.tracked).Int("recovered", r.recovered)
      .Int("posed", r.posed).Int("unposed", r.unposed).Int("held", r.held)
      .Int("widened", r.widened)
      .Int("relocalisations_rejected", r.relocalisations_rejected)
      .Int("prealign_rejected_by_depth", r.prealign_rejected_by_depth)
      .Int("keyframes", r.keyframes)
      .Int("recovered_from_keyframe", r.recovered_from_keyframe)
      .Int("lost", r.lost).Int("no_depth", r.no_depth).Int("missing", r.missing)
      .Int("coloured", r.coloured)
      .Int("tracked_depth_only", r.tracked_depth_only)
      .Int("basin_checked", r.basin_checked)
      .Int("unconstrained", r.unconstrained)
      .Int("unconstrained_not_fused", r.unconstrained_not_fused)
      .Number("median_basin_m", r.median_basin_m)
      .Int("integrated", r.integrated)
      .Int("blocks_updated", r.blocks_updated)
      .Int("blocks_coarse", r.blocks_coarse)
      .Int("dynamic_frames", r.dynamic_frames)
      .Int("dynamic_pixels", static_cast<int64_t>(r.dynamic_pixels))
      .Int("carved_frames", r.carved_frames)
      .Int("carved_points", static_cast<int64_t>(r.carved_points));
  const double processed = std::max<size_t>(1, reconstruction.frames().size());
  timings.Number("load_s", r.load_seconds)
      .Number("process_s", r.process_seconds)
      .Number("mesh_s", r.mesh_seconds)
      .Number("total_s", r.total_seconds)
      .Number("frames_per_s", processed / std::max(r.process_seconds, 1e-9))
      .Number("mean_prepare_ms", r.prepare_ms)
      .Number("mean_prepare_ahead_ms", r.prepare_ahead_ms)
      .Number("mean_track_ms", r.track_ms)
      .Number("mean_integrate_ms", r.integrate_ms)
      .Number("mean_raycast_ms", r.raycast_ms)
      .Int("raycasts", r.raycasts);
  memory.Int("peak_rss_bytes", static_cast<int64_t>(r.peak_rss_bytes))
      .Int("volume_bytes", static_cast<int64_t>(r.volume_bytes))
      .Int("blocks", static_cast<int64_t>(r.blocks));
  mesh.Int("vertices", static_cast<int64_t>(r.vertices))
      .Int("faces", static_cast<int64_t>(r.faces))
      .Number("area_m2", r.area_m2)
      .Int("components", r.mesh_stats.components)
      .Int("components_removed", r.mesh_stats.components_removed)
      .Int("triangles_removed", r.mesh_stats.triangles_removed);
  std::vector<std::string> frames, warnings;
  for (size_t i = 0; i < reconstruction.frames().size(); ++i) {
    frames.push_back(FrameJson(reconstruction.frames()[i], run.depth_frame_index[i]));
  }
  for (const std::string& w : r.warnings) warnings.push_back(core::JsonString(w));
  // Each stream's frame clock (core/frame_clock.h): whether its stamps were replaced by
  // fitted exposure times, and what the fit measured.
  JsonObject stamps;
  for (const core::Stream stream : core::kAllStreams) {
    if (scan.NumFrames(stream) > 0) stamps.Add(core::StreamName(stream), StampFitJson(scan.StampRegularisation(stream)));
  }
  input.Add("stamps", stamps.str());
  JsonObject all;
  all.String("command", "heatwave reconstruct")
      .Add("input", input.str())
      .Add("settings", SettingsJson(options))
      .Add("summary", summary.str())
      .Add("timings", timings.str())
      .Add("memory", memory.str())
      .Add("mesh", mesh.str());
  if (r.evaluation) {
    JsonObject eval;
    eval.Int("associated_pairs", r.evaluation->associated_pairs)
        .Add("ate_m", ErrorStatsJson(r.evaluation->ate_m))
        .Add("rpe_m", ErrorStatsJson(r.evaluation->rpe_m))
        .Add("rpe_deg", ErrorStatsJson(r.evaluation->rpe_deg));
    if (r.surface) {
      // The distances' figures, world frame or registered.
      const auto add_stats = [](JsonObject& o, const reconstruct::SurfaceDistanceStats& d) {
        o.Int("beyond_search", d.beyond_search)
            .Number("median_m", d.median_m)
            .Number("mean_m", d.mean_m)
            .Number("rms_m", d.rms_m)
            .Number("p90_m", d.p90_m)
            .Number("max_m", d.max_m);
      };
      JsonObject surface;
      surface.Int("vertices", r.surface->points).Number("search_radius_m", kSurfaceSearchM);
      add_stats(surface, *r.surface);
      if (r.surface_registered && r.registration) {
        JsonObject registered;
        registered.Number("rotation_deg", r.registration->rotation_deg)
            .Number("translation_m", r.registration->translation_m)
            .Int("iterations", r.registration->iterations)
            .Bool("converged", r.registration->converged)
            .Int("correspondences", r.registration->correspondences)
            .Int("constrained_directions", r.registration->constrained_directions);
        add_stats(registered, *r.surface_registered);
        surface.Add("registered", registered.str());
      }
      eval.Add("surface_to_truth", surface.str());
    }
    all.Add("groundtruth_evaluation", eval.str());
  }
  if (thermal) all.Add("thermal", ThermalJson(*thermal, *r.thermal));
  all.Add("warnings", JsonArray(warnings, "  ")).Add("frames", JsonArray(frames, "  "));
  return all.str() + "\n";
}

}  // namespace hw::cli
