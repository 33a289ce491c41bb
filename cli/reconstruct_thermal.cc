#include "cli/reconstruct_thermal.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/json.h"
#include "core/radiometry.h"
#include "core/strings.h"
#include "reconstruct/emissivity_map.h"
#include "reconstruct/mesh_query.h"

namespace hw::cli {

namespace {

namespace fs = std::filesystem;
using core::JsonArray;
using core::JsonObject;
using reconstruct::ThermalMethod;

// Truth emissivities are matched to model points within this distance of the truth surface
// (the model is mm to cm off it; farther, the point is not on a surface the truth knows).
constexpr double kTruthEmissivitySearchM = 0.05;

}  // namespace

std::unique_ptr<reconstruct::ThermalFusion> MakeThermalFusion(const ReconstructCommandOptions& options,
                                                              const core::Scan& scan,
                                                              std::vector<std::string>& warnings,
                                                              std::string& emissivity_source) {
  if (!options.thermal) return nullptr;
  core::Rig rig = scan.rig();
  if (rig.thermal_settings && options.emissivity) rig.thermal_settings->emissivity = *options.emissivity;
  if (rig.thermal_settings && options.reflected_c) rig.thermal_settings->reflected_c = *options.reflected_c;
  if (!rig.thermal || !rig.thermal_settings) {
    if (scan.NumFrames(core::Stream::kThermal) > 0) {
      warnings.push_back("the rig has no thermal camera: the thermal frames are ignored and the model has no temperature");
    }
    return nullptr;
  }
  if (scan.NumFrames(core::Stream::kThermal) == 0) {
    warnings.push_back("the scan has no thermal frames: the model is written without temperature");
    return nullptr;
  }
  reconstruct::EmissivityMap emissivity(*rig.thermal_settings);
  emissivity_source = core::StringPrintf("%s: %.3f everywhere, reflected %.2f °C",
                                         options.emissivity || options.reflected_c ? "on-site values" : "rig.yaml",
                                         rig.thermal_settings->emissivity, rig.thermal_settings->reflected_c);
  if (!options.emissivity_path.empty()) {
    emissivity = reconstruct::EmissivityMap::Read(options.emissivity_path, *rig.thermal_settings);
    emissivity_source = core::StringPrintf("%s: %d regions", options.emissivity_path.c_str(), emissivity.num_regions());
  } else if (options.emissivity_from_truth) {
    const fs::path truth_path = scan.folder() / "truth" / "scene.ply";
    // The truth mesh, kept alive by the lookup; each query takes the closest truth point's
    // triangle and, of its vertices, the one the point is nearest (no blending of materials
    // across a patch border).
    struct Truth {
      reconstruct::TemperatureTruth mesh;
      std::unique_ptr<reconstruct::TriangleGrid> grid;
    };
    auto truth = std::make_shared<Truth>();
    truth->mesh = reconstruct::ReadTemperatureTruth(truth_path);
    if (truth->mesh.emissivity.empty()) throw core::InputError(truth_path, "has no emissivity property");
    truth->grid = std::make_unique<reconstruct::TriangleGrid>(truth->mesh.vertices, truth->mesh.faces,
                                                              kTruthEmissivitySearchM);
    emissivity = reconstruct::EmissivityMap::FromLookup(
        *rig.thermal_settings, [truth](const Eigen::Vector3f& p, reconstruct::SurfaceEmissivity& out) {
          const auto closest = truth->grid->FindClosest(p.cast<double>(), kTruthEmissivitySearchM);
          if (!closest) return false;
          int corner = 0;
          closest->on_face.weights.maxCoeff(&corner);
          const int vertex = truth->mesh.faces[closest->face][corner];
          out.emissivity = truth->mesh.emissivity[vertex];
          // The truth stores no law; the fixtures' low-emissivity patches are bare metal, and
          // only a metal's Fresnel index reaches below MaxMetalNormalEmissivity.
          out.law = out.emissivity <= core::MaxMetalNormalEmissivity() ? core::EmissivityLaw::kMetal
                                                                      : core::EmissivityLaw::kDielectric;
          out.region = vertex;
          return true;
        });
    emissivity_source = "truth/scene.ply (per vertex; metal below " +
                        core::StringPrintf("%.2f", core::MaxMetalNormalEmissivity()) + ")";
  }
  reconstruct::ThermalFusionOptions fusion_options = options.thermal_fusion;
  fusion_options.min_depth_m = options.reconstruction.min_depth_m;
  fusion_options.max_depth_m = options.reconstruction.max_depth_m;
  fusion_options.num_threads = options.reconstruction.num_threads;
  // A frame between two depth poses is bridged as given poses are (three depth periods).
  fusion_options.max_pose_gap_s = std::max(fusion_options.max_pose_gap_s, reconstruct::PoseGapLimitS(scan));
  return std::make_unique<reconstruct::ThermalFusion>(rig, fusion_options, std::move(emissivity),
                                                      scan.ffc_timestamps_s());
}

void SummarizeThermal(const reconstruct::ThermalFusion& fusion, const reconstruct::ScanReconstruction& run,
                      const core::Scan& scan, ThermalCommandResult& r) {
  using reconstruct::ThermalFrameStatus;
  r.frames = scan.NumFrames(core::Stream::kThermal);
  r.missing = run.thermal_missing_frames;
  r.after_end = run.thermal_after_end;
  r.seconds = run.thermal_seconds;
  r.load_seconds = run.thermal_load_seconds;
  r.finish_seconds = run.thermal_finish_seconds;
  for (const reconstruct::ThermalFrameRecord& f : fusion.frames()) {
    r.fused += f.status == ThermalFrameStatus::kFused;
    r.frozen += f.status == ThermalFrameStatus::kFrozen;
    r.no_pose += f.status == ThermalFrameStatus::kNoPose;
    r.no_surface += f.status == ThermalFrameStatus::kNoSurface;
    r.skipped += f.status == ThermalFrameStatus::kSkipped;
    assert(f.status != ThermalFrameStatus::kHeld);  // ReconstructScan flushes
    r.rays += f.rays;
    r.hits += f.hits;
    r.rays_fused += f.fused;
    r.rays_occluded += f.occluded;
    r.mirror_traced += f.mirror_traced;
    r.mirror_operator += f.mirror_operator;
    r.mirror_surface += f.mirror_surface;
    r.occluded_frames += f.occluded > 0;
    r.live_depth_frames += f.live_depth;
    if (f.status == ThermalFrameStatus::kFused) {
      r.raycast_ms += f.raycast_ms;
      r.reflect_ms += f.reflect_ms;
      r.fuse_ms += f.fuse_ms;
      r.offset_estimated += f.offset_estimated;
      r.offset_min_k = std::min(r.offset_min_k, f.offset_correction_k);
      r.offset_max_k = std::max(r.offset_max_k, f.offset_correction_k);
      r.pixel_offset_rms_k = f.pixel_offset_rms_k;
    }
  }
  r.frame_interval_s = fusion.options().frame_interval_s;
  r.background = fusion.options().background && r.frame_interval_s > 0;
  r.scene_correction = fusion.options().scene_correction.frame_offset || fusion.options().scene_correction.pixel_offset;
  if (r.fused > 0) {
    r.raycast_ms /= r.fused;
    r.reflect_ms /= r.fused;
    r.fuse_ms /= r.fused;
  }
  r.regions = fusion.NumRegions();
  r.observations = fusion.NumObservations();
  r.observations_dropped = fusion.NumObservationsDropped();
  r.memory_bytes = fusion.MemoryBytes();
  r.offline_rejected = fusion.OfflineRejected();
  r.method = reconstruct::ThermalMethodName(fusion.options().method);
}

void AddTemperatureProperties(const reconstruct::PointTemperatures& t, const std::vector<Eigen::Vector3f>& positions,
                              const reconstruct::EmissivityMap& emissivity, core::PlyMesh& ply) {
  const auto to_double = [](const auto& v) { return std::vector<double>(v.begin(), v.end()); };
  ply.AddProperty("temperature_c", core::PlyType::kFloat32, to_double(t.surface_c));
  // The normal emissivity temperature_c was corrected with (NaN where unobserved): analyze
  // does not take a spot on a low-emissivity surface for a measurement.
  std::vector<double> used(positions.size(), std::numeric_limits<double>::quiet_NaN());
  for (size_t i = 0; i < positions.size(); ++i) {
    if (t.views[i] > 0) used[i] = emissivity.At(positions[i]).emissivity;
  }
  ply.AddProperty("temperature_emissivity", core::PlyType::kFloat32, std::move(used));
  ply.AddProperty("temperature_apparent_c", core::PlyType::kFloat32, to_double(t.apparent_c));
  ply.AddProperty("temperature_confidence", core::PlyType::kFloat32, to_double(t.confidence));
  ply.AddProperty("temperature_views", core::PlyType::kUInt16, to_double(t.views));
  ply.AddProperty("temperature_std_c", core::PlyType::kFloat32, to_double(t.std_c));
  ply.AddProperty("temperature_footprint_m", core::PlyType::kFloat32, to_double(t.footprint_m));
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> component(t.view_m.size());
    for (size_t i = 0; i < component.size(); ++i) component[i] = static_cast<double>(t.view_m[i][axis]);
    ply.AddProperty(std::string("temperature_view_") + "xyz"[axis], core::PlyType::kFloat32, std::move(component));
  }
}

void EvaluateThermalMethods(const reconstruct::ThermalFusion& fusion,
                            const std::vector<Eigen::Vector3f>& model_vertices_in_model,
                            const std::vector<Eigen::Vector3f>& model_vertices_in_truth,
                            const std::vector<Eigen::Vector3i>& faces, const reconstruct::TemperatureTruth& truth,
                            ThermalCommandResult& result) {
  std::optional<reconstruct::TemperatureComparison> comparison;
  // The plain mean first: its confidence per vertex, the mean of all its region's views', is
  // the view quality every method is also scored by; its estimate is kept for its turn.
  // Its footprints (over all views, whatever the method) set the resolved subset's balls.
  std::vector<double> quality, mean_estimate, footprint_m;
  {
    const reconstruct::PointTemperatures mean = fusion.Sample(model_vertices_in_model, ThermalMethod::kMean);
    quality.reserve(mean.confidence.size());
    for (size_t i = 0; i < mean.confidence.size(); ++i) {
      quality.push_back(mean.views[i] > 0 ? static_cast<double>(mean.confidence[i]) : std::nan(""));
    }
    mean_estimate.assign(mean.surface_c.begin(), mean.surface_c.end());
    footprint_m.assign(mean.footprint_m.begin(), mean.footprint_m.end());
  }
  for (ThermalMethod method : reconstruct::kThermalMethods) {
    std::vector<double> estimate;
    if (method == ThermalMethod::kMean) {
      estimate = std::move(mean_estimate);
    } else {
      const reconstruct::PointTemperatures t = fusion.Sample(model_vertices_in_model, method);
      estimate.assign(t.surface_c.begin(), t.surface_c.end());
    }
    if (!comparison) {
      comparison = reconstruct::CompareTemperatures(model_vertices_in_truth, faces, estimate, truth,
                                                    reconstruct::TemperatureErrorOptions{}, footprint_m);
    }
    const reconstruct::TemperatureErrorStats stats = reconstruct::TemperatureErrors(*comparison, estimate);
    result.evaluation.emplace_back(method, stats);
    result.evaluation_by_view_quality.push_back(
        reconstruct::TemperatureErrorsByViewQuality(*comparison, stats, estimate, quality));
  }
}

std::string ThermalJson(const reconstruct::ThermalFusion& fusion, const ThermalCommandResult& r) {
  const reconstruct::ThermalFusionOptions& o = fusion.options();
  const reconstruct::ThermalConfidenceOptions& c = o.confidence;
  JsonObject confidence, offline, settings, summary, timings;
  confidence.Number("motion_power", c.motion_power)
      .Number("distortion_power", c.distortion_power)
      .Number("angle_power", c.angle_power)
      .Number("distance_power", c.distance_power)
      .Number("operating_power", c.operating_power)
      .Number("integration_time_s", c.integration_time_s)
      .Number("motion_blur_px", c.motion_blur_px)
      .Number("distortion_px", c.distortion_px)
      .Number("max_angle_deg", c.max_angle_deg)
      .Number("reference_distance_m", c.reference_distance_m)
      .Number("ffc_settle_s", c.ffc_settle_s)
      .Number("ffc_ramp_s", c.ffc_ramp_s)
      .Number("drift_onset_s", c.drift_onset_s)
      .Number("drift_time_s", c.drift_time_s);
  offline.Number("outlier_sigmas", o.offline.outlier_sigmas).Number("min_sigma_k", o.offline.min_sigma_k);
  const reconstruct::SceneCorrectionOptions& sc = o.scene_correction;
  JsonObject scene;
  scene.Bool("frame_offset", sc.frame_offset)
      .Bool("pixel_offset", sc.pixel_offset)
      .Int("max_pair_shift_px", sc.max_pair_shift_px)
      .Int("min_reference_views", sc.min_reference_views)
      .Number("max_reference_std_k", sc.max_reference_std_k)
      .Number("max_residual_k", sc.max_residual_k)
      .Int("min_reference_rays", sc.min_reference_rays)
      .Number("pixel_rate", sc.pixel_rate)
      .Number("max_pixel_offset_k", sc.max_pixel_offset_k);
  const reconstruct::ThermalReflectionOptions& ro = o.reflections;
  JsonObject reflections;
  reflections.Bool("trace", ro.trace)
      .Number("min_specular_weight", ro.min_specular_weight)
      .Number("max_distance_m", ro.max_distance_m)
      .Bool("operator_body", ro.operator_body)
      .Number("operator_apparent_c", ro.operator_apparent_c)
      .Number("operator_distance_m", ro.operator_distance_m)
      .Number("operator_offset_down_m", ro.operator_offset_down_m)
      .Number("operator_half_width_m", ro.operator_half_width_m)
      .Number("operator_half_height_m", ro.operator_half_height_m);
  settings.String("method", reconstruct::ThermalMethodName(o.method))
      .String("emissivity", r.emissivity)
      .Number("recency_bias", o.recency_bias)
      .Number("capped_mean_max_weight", o.capped_mean_max_weight)
      .Number("min_ray_confidence", o.min_ray_confidence)
      .Int("edge_radius_px", o.edge_radius_px)
      .Number("occlusion_margin_m", o.occlusion_margin_m)
      .Number("occlusion_margin_fraction", o.occlusion_margin_fraction)
      .Number("vignetting", o.vignetting)
      .Number("max_pose_gap_s", o.max_pose_gap_s)
      .Bool("keep_observations", o.keep_observations)
      .Int("max_views_per_region", o.max_views_per_region)
      .Number("frame_interval_s", o.frame_interval_s)
      .Bool("background", o.background)
      .Add("scene_correction", scene.str())
      .Add("reflections", reflections.str())
      .Add("confidence", confidence.str())
      .Add("offline", offline.str());
  summary.Int("frames", r.frames)
      .Int("fused", r.fused)
      .Int("frozen", r.frozen)
      .Int("no_pose", r.no_pose)
      .Int("no_surface", r.no_surface)
      .Int("skipped", r.skipped)
      .Int("missing", r.missing)
      .Int("after_end", r.after_end)
      .Int("rays", r.rays)
      .Int("hits", r.hits)
      .Int("rays_fused", r.rays_fused)
      .Int("rays_occluded", r.rays_occluded)
      .Int("occluded_frames", r.occluded_frames)
      .Int("mirror_traced", r.mirror_traced)
      .Int("mirror_operator", r.mirror_operator)
      .Int("mirror_surface", r.mirror_surface)
      .Int("live_depth_frames", r.live_depth_frames)
      .Number("fraction_fused", r.rays > 0 ? static_cast<double>(r.rays_fused) / r.rays : 0)
      .Int("regions", static_cast<int64_t>(r.regions))
      .Int("observations", static_cast<int64_t>(r.observations))
      .Int("observations_dropped", static_cast<int64_t>(r.observations_dropped))
      .Int("offline_rejected", r.offline_rejected)
      .Int("vertices_with_temperature", r.vertices_observed)
      .Int("offset_estimated_frames", r.offset_estimated)
      .Number("offset_min_k", r.offset_min_k)
      .Number("offset_max_k", r.offset_max_k)
      .Number("pixel_offset_rms_k", r.pixel_offset_rms_k)
      .Int("memory_bytes", static_cast<int64_t>(r.memory_bytes));
  timings.Number("fusion_s", r.seconds)
      .Number("load_s", r.load_seconds)
      .Number("offline_s", r.finish_seconds)
      .Number("mean_raycast_ms", r.raycast_ms)
      .Number("mean_reflect_ms", r.reflect_ms)
      .Number("mean_fuse_ms", r.fuse_ms);
  JsonObject all;
  all.Add("settings", settings.str()).Add("summary", summary.str()).Add("timings", timings.str());
  if (!r.evaluation.empty()) {
    std::vector<std::string> methods;
    for (size_t k = 0; k < r.evaluation.size(); ++k) {
      const auto& [method, e] = r.evaluation[k];
      std::vector<std::string> classes;
      if (k < r.evaluation_by_view_quality.size()) {
        for (const reconstruct::ViewQualityClass& q : r.evaluation_by_view_quality[k]) {
          JsonObject j;
          j.Number("confidence_from", q.quality_from)
              .Number("confidence_to", q.quality_to)
              .Int("compared", q.compared)
              .Number("rmse_k", q.rmse_k)
              .Number("rmse_affine_k", q.rmse_affine_k);
          classes.push_back(j.str());
        }
      }
      JsonObject m;
      m.String("method", reconstruct::ThermalMethodName(method))
          .Int("vertices", e.vertices)
          .Int("observed", e.observed)
          .Int("compared", e.compared)
          .Int("compared_uniform", e.compared_uniform)
          .Number("rmse_k", e.rmse_k)
          .Number("p95_abs_k", e.p95_abs_k)
          .Number("mean_k", e.mean_k)
          .Number("max_abs_k", e.max_abs_k)
          .Number("rmse_uniform_k", e.rmse_uniform_k)
          .Number("p95_abs_uniform_k", e.p95_abs_uniform_k)
          .Number("mean_uniform_k", e.mean_uniform_k)
          .Number("affine_gain", e.affine_gain)
          .Number("affine_offset_k", e.affine_offset_k)
          .Number("rmse_affine_k", e.rmse_affine_k)
          .Number("p95_abs_affine_k", e.p95_abs_affine_k)
          .Int("compared_resolved", e.compared_resolved)
          .Number("rmse_resolved_affine_k", e.rmse_resolved_affine_k)
          .Number("p95_abs_resolved_affine_k", e.p95_abs_resolved_affine_k)
          .Int("compared_low_emissivity", e.compared_low_emissivity)
          .Number("rmse_low_emissivity_k", e.rmse_low_emissivity_k)
          .Number("mean_low_emissivity_k", e.mean_low_emissivity_k)
          .Add("by_view_quality", JsonArray(classes, "      "));
      methods.push_back(m.str());
    }
    all.Add("truth_evaluation", JsonArray(methods, "    "));
  }
  std::vector<std::string> frames;
  for (const reconstruct::ThermalFrameRecord& f : fusion.frames()) {
    JsonObject j;
    j.Int("thermal_frame", f.index)
        .Number("timestamp_s", f.timestamp_s)
        .Number("depth_clock_s", f.depth_clock_s)
        .String("status", reconstruct::ThermalFrameStatusName(f.status))
        .Number("time_since_ffc_s", f.time_since_ffc_s)
        .Number("linear_speed_mps", f.linear_speed_mps)
        .Number("angular_speed_dps", f.angular_speed_dps)
        .Number("frame_confidence", f.frame_confidence)
        .Int("rays", f.rays)
        .Int("hits", f.hits)
        .Int("fused", f.fused)
        .Int("low_confidence", f.low_confidence)
        .Int("no_normal", f.no_normal)
        .Int("depth_edge", f.depth_edge)
        .Int("occluded", f.occluded)
        .Bool("live_depth", f.live_depth)
        .Int("no_surface_temperature", f.no_surface_temperature)
        .Int("mirror_traced", f.mirror_traced)
        .Int("mirror_operator", f.mirror_operator)
        .Int("mirror_surface", f.mirror_surface)
        .Number("mean_confidence", f.mean_confidence)
        .Int("regions_updated", f.regions_updated)
        .Int("pair_rays", f.pair_rays)
        .Int("pair_shift_px", f.pair_shift_px)
        .Int("reference_rays", f.reference_rays)
        .Bool("offset_estimated", f.offset_estimated)
        .Number("offset_correction_k", f.offset_correction_k)
        .Number("pixel_offset_rms_k", f.pixel_offset_rms_k)
        .Number("raycast_ms", f.raycast_ms)
        .Number("reflect_ms", f.reflect_ms)
        .Number("fuse_ms", f.fuse_ms);
    frames.push_back(j.str());
  }
  all.Add("frames", JsonArray(frames, "  "));
  return all.str();
}

std::string FormatThermalSummary(const ThermalCommandResult& r) {
  std::string out = core::StringPrintf(
      "Thermal    %d frames: %d fused, %d frozen (shutter), %d without pose, %d after the last depth pose, "
      "%d missing; %.0f %% of rays fused; %.1f ms/frame (raycast %.1f, reflections %.1f, fuse %.1f%s)\n",
      r.frames, r.fused, r.frozen, r.no_pose, r.after_end, r.missing,
      r.rays > 0 ? 100.0 * r.rays_fused / r.rays : 0.0, r.raycast_ms + r.reflect_ms + r.fuse_ms, r.raycast_ms,
      r.reflect_ms, r.fuse_ms,
      r.background ? " beside the depth pipeline" : "");
  if (r.skipped > 0) {
    out += core::StringPrintf("           %d skipped: of the frames within %g s only the most confident (least "
                              "blurred) is fused (--thermal-frame-interval)\n",
                              r.skipped, r.frame_interval_s);
  }
  out += core::StringPrintf("           %d vertices with temperature (%s), %zu regions, %.1f MB", r.vertices_observed,
                            r.method.c_str(), r.regions, r.memory_bytes / 1e6);
  if (r.observations_dropped > 0) {
    out += core::StringPrintf(" (%zu least confident views dropped)", r.observations_dropped);
  }
  out += "; emissivity: " + r.emissivity + "\n";
  if (r.occluded_frames > 0) {
    out += core::StringPrintf(
        "           %lld rays of %d frames not fused: behind something the depth camera saw nearer at the time "
        "(a person walking by; --thermal-occlusion-margin)\n",
        static_cast<long long>(r.rays_occluded), r.occluded_frames);
  }
  if (r.mirror_traced > 0) {
    out += core::StringPrintf(
        "           reflections: %lld mirror rays traced; of the fused, %lld met the operator, %lld a surface with a "
        "temperature, the rest the room (--thermal-reflections)\n",
        static_cast<long long>(r.mirror_traced), static_cast<long long>(r.mirror_operator),
        static_cast<long long>(r.mirror_surface));
  }
  if (r.scene_correction) {
    out += core::StringPrintf(
        "           scene correction: offset measured on %d frames (once per shutter event), offsets %+.2f to %+.2f K, "
        "pixel offsets %.3f K RMS\n",
        r.offset_estimated, r.offset_min_k, r.offset_max_k, r.pixel_offset_rms_k);
  }
  if (!r.evaluation.empty()) {
    out += "           vs truth/scene.ply (K)   all: RMSE    p95   bias | uniform: RMSE    p95   bias | "
           "camera gain/offset removed: RMSE    p95 | emissivity < 0.5: RMSE   bias\n";
    for (const auto& [method, e] : r.evaluation) {
      out += core::StringPrintf("           %-12s           %6.3f %6.3f %6.3f |          %6.3f %6.3f %6.3f |"
                                "                             %6.3f %6.3f |                 %6.3f %6.3f\n",
                                reconstruct::ThermalMethodName(method).c_str(), e.rmse_k, e.p95_abs_k, e.mean_k,
                                e.rmse_uniform_k, e.p95_abs_uniform_k, e.mean_uniform_k, e.rmse_affine_k,
                                e.p95_abs_affine_k, e.rmse_low_emissivity_k, e.mean_low_emissivity_k);
    }
    if (r.evaluation.front().second.compared_resolved > 0) {
      // The same vertices for every method (the plain mean's footprints).
      out += core::StringPrintf("           resolved subset (%d vertices: uniform within %g thermal pixels), "
                                "gain/offset removed, RMSE:",
                                r.evaluation.front().second.compared_resolved,
                                reconstruct::TemperatureErrorOptions{}.resolved_footprints);
      for (const auto& [method, e] : r.evaluation) {
        out += core::StringPrintf(" %s %.3f", reconstruct::ThermalMethodName(method).c_str(), e.rmse_resolved_affine_k);
      }
      out += "\n";
    }
    if (!r.evaluation_by_view_quality.empty()) {
      // The classes are the same vertices for every method (the plain mean's confidence).
      const auto& c = r.evaluation_by_view_quality.front();
      out += core::StringPrintf(
          "           by view quality, uniform subset, gain/offset removed (mean confidence of the views: "
          "%.2f-%.2f | %.2f-%.2f | %.2f-%.2f)\n",
          c[0].quality_from, c[0].quality_to, c[1].quality_from, c[1].quality_to, c[2].quality_from, c[2].quality_to);
      for (size_t k = 0; k < r.evaluation_by_view_quality.size() && k < r.evaluation.size(); ++k) {
        const auto& q = r.evaluation_by_view_quality[k];
        out += core::StringPrintf("           %-12s           worst third %6.3f | middle %6.3f | best third %6.3f\n",
                                  reconstruct::ThermalMethodName(r.evaluation[k].first).c_str(), q[0].rmse_affine_k,
                                  q[1].rmse_affine_k, q[2].rmse_affine_k);
      }
    }
  }
  return out;
}

}  // namespace hw::cli
