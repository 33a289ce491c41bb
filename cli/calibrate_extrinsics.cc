#include "cli/calibrate_extrinsics.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <numbers>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "calibrate/diagnostics.h"
#include "cli/calibrate.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/json.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/scan.h"
#include "core/strings.h"
#include "core/trajectory.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

const char* MethodName(ExtrinsicsMethod m) {
  switch (m) {
    case ExtrinsicsMethod::kAuto:
      return "auto";
    case ExtrinsicsMethod::kTarget:
      return "target";
    case ExtrinsicsMethod::kTargetless:
      return "targetless";
  }
  return "?";
}

// A camera's corner residuals (projected − observed) as arrows, per still.
cv::Mat ResidualScatter(const core::CameraModel& camera, const std::vector<calibrate::ResidualSample>& samples,
                        int stills) {
  std::vector<std::vector<Eigen::Vector2d>> corners(stills), residuals(stills);
  std::vector<std::vector<bool>> outlier(stills);
  for (const calibrate::ResidualSample& s : samples) {
    corners[s.still].push_back(s.pixel);
    residuals[s.still].push_back(-s.residual);  // DrawResidualField draws observed − projected
    outlier[s.still].push_back(false);
  }
  return calibrate::DrawResidualField(camera.width, camera.height, corners, residuals, outlier, 20.0);
}

// Histogram of the plate points' distances to their fitted plane (mm) with the normal density
// of σ (the points' white σ and the cells' correlated σ in quadrature); 640 × 400.
cv::Mat PlaneHistogram(const std::vector<calibrate::ResidualSample>& samples, double sigma_m) {
  const int width = 640, height = 400, margin = 40, bins = 60;
  cv::Mat out(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const double range_mm = std::max(4 * 1e3 * sigma_m, 1e-3);
  std::vector<int> counts(bins, 0);
  for (const calibrate::ResidualSample& s : samples) {
    const int b = static_cast<int>(std::floor((1e3 * s.residual.x() + range_mm) / (2 * range_mm) * bins));
    if (b >= 0 && b < bins) ++counts[b];
  }
  const int peak = std::max(1, *std::max_element(counts.begin(), counts.end()));
  const double bin_w = (width - 2.0 * margin) / bins;
  for (int b = 0; b < bins; ++b) {
    const double h = (height - 2.0 * margin) * counts[b] / peak;
    cv::rectangle(out, cv::Point2d(margin + b * bin_w, height - margin - h),
                  cv::Point2d(margin + (b + 1) * bin_w - 1, height - margin), cv::Scalar(180, 130, 70), cv::FILLED);
  }
  // The normal density of σ scaled to the histogram's area.
  const double n = static_cast<double>(samples.size()), width_mm = 2 * range_mm / bins, s_mm = 1e3 * sigma_m;
  cv::Point2d last;
  for (int x = margin; x <= width - margin; ++x) {
    const double v = -range_mm + 2 * range_mm * (x - margin) / (width - 2.0 * margin);
    const double density = n * width_mm * std::exp(-0.5 * v * v / (s_mm * s_mm)) / (s_mm * std::sqrt(2 * std::numbers::pi));
    const cv::Point2d p(x, height - margin - (height - 2.0 * margin) * density / peak);
    if (x > margin) cv::line(out, last, p, cv::Scalar(0, 0, 220), 2, cv::LINE_AA);
    last = p;
  }
  cv::putText(out, StringPrintf("depth points to plate plane, mm (%zu points); red: normal, sigma %.2f mm (white + correlated)", samples.size(), s_mm),
              cv::Point(margin, 24), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  for (int t = -4; t <= 4; t += 2) {
    const double x = margin + (width - 2.0 * margin) * (t + 4) / 8.0;
    cv::putText(out, StringPrintf("%.1f", t * s_mm), cv::Point2d(x - 12, height - margin + 20), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return out;
}

std::string ExtrinsicsJsonFile(const ExtrinsicsCommandOptions& o, const ExtrinsicsCommandResult& r,
                               const calibrate::TargetExtrinsicsResult* target,
                               const calibrate::TargetlessResult* targetless) {
  core::JsonObject root;
  root.Int("version", 1).String("command", "heatwave calibrate extrinsics");
  root.String("scan", o.scan.string()).String("method", r.method);
  root.String("parameterisation",
              "depth_from_camera = (R, t); covariance of [omega (rad), rotation applied on the left about the depth "
              "frame's axes; delta_t (m), additive in the depth frame]");
  std::vector<std::string> estimates;
  for (const calibrate::ExtrinsicsEstimate& e : r.estimates) estimates.push_back(calibrate::ExtrinsicsJson(e));
  root.Add("estimates", core::JsonArray(estimates, "  "));
  if (target) {
    std::vector<std::string> stills;
    for (const calibrate::TargetExtrinsicsStill& s : target->stills) {
      stills.push_back(core::JsonObject()
                           .Int("depth_frame", s.depth_frame)
                           .Int("thermal_frame", s.thermal_frame)
                           .Int("rgb_frame", s.rgb_frame)
                           .Int("thermal_corners", s.thermal_corners)
                           .Int("rgb_corners", s.rgb_corners)
                           .Int("plane_points", s.plane_points)
                           .Bool("used", s.used)
                           .String("reason", s.reason)
                           .str());
    }
    root.Add("target", core::JsonObject()
                           .Int("stills_used", target->stills_used)
                           .Number("sigma_thermal_px", target->sigma_thermal_px)
                           .Number("sigma_rgb_px", target->sigma_rgb_px)
                           .Number("sigma_plane_m", target->sigma_plane_m)
                           .Number("sigma_cell_m", target->sigma_cell_m)
                           .Number("sigma_still_offset_m", target->sigma_still_offset_m)
                           .Number("sigma_still_tilt_rad", target->sigma_still_tilt_rad)
                           .Number("thermal_edge_shift_m", target->thermal_edge_shift_m)
                           .Number("rgb_edge_shift_m", target->rgb_edge_shift_m)
                           .Number("target_thickness_m", target->target_thickness_m)
                           .Int("plane_points", target->plane_points)
                           .Number("plane_rms_m", target->plane_rms_m)
                           .Number("depth_model_bowl_per_m", target->depth_model.y())
                           .Add("depth_model_affine_per_m",
                                core::JsonArray({core::JsonNumber(target->depth_model[0]),
                                                 core::JsonNumber(target->depth_model[2]),
                                                 core::JsonNumber(target->depth_model[3])}))
                           .Add("depth_model_affine_sigma_per_m",
                                core::JsonArray({core::JsonNumber(std::sqrt(target->depth_model_covariance(0, 0))),
                                                 core::JsonNumber(std::sqrt(target->depth_model_covariance(2, 2))),
                                                 core::JsonNumber(std::sqrt(target->depth_model_covariance(3, 3)))}))
                           .Number("depth_model_bowl_sigma_per_m", std::sqrt(target->depth_model_covariance(1, 1)))
                           .Number("depth_affine_prior_sigma_per_m", target->depth_affine_sigma_per_m)
                           .Add("depth_affine_folded_into_rig_per_m",
                                core::JsonArray({core::JsonNumber(r.depth_affine_folded_per_m[0]),
                                                 core::JsonNumber(r.depth_affine_folded_per_m[1]),
                                                 core::JsonNumber(r.depth_affine_folded_per_m[2])}))
                           .Number("detect_s", target->detect_seconds)
                           .Number("solve_s", target->solve_seconds)
                           .Add("stills", core::JsonArray(stills, "    "))
                           .str());
  }
  if (targetless) {
    const calibrate::TargetlessResult& t = *targetless;
    std::vector<std::string> frames;
    for (const calibrate::TargetlessFrameStats& f : t.frames) {
      frames.push_back(core::JsonObject()
                           .Int("thermal_frame", f.thermal_index)
                           .Int("depth_frame", f.depth_index)
                           .Number("dt_s", f.dt_s)
                           .Int("lines_3d", f.lines_3d)
                           .Int("lines_2d", f.lines_2d)
                           .Int("matches", f.matches)
                           .str());
    }
    std::vector<std::string> cost, matches;
    for (double c : t.cost_per_iteration) cost.push_back(core::JsonNumber(c));
    for (int m : t.matches_per_iteration) matches.push_back(std::to_string(m));
    root.Add("targetless", core::JsonObject()
                               .Bool("used_trajectory", t.used_trajectory)
                               .String("trajectory", o.trajectory.string())
                               .Int("matches", t.matches)
                               .Number("inlier_fraction", t.inlier_fraction)
                               .Number("robust_sigma_px", t.robust_sigma_px)
                               .Number("edge_offset_px", t.edge_offset_px)
                               .Number("edge_offset_sigma_px", t.edge_offset_sigma_px)
                               .Number("sigma_inflation", o.targetless.alignment.sigma_inflation)
                               .Add("cost_per_iteration", core::JsonArray(cost))
                               .Add("matches_per_iteration", core::JsonArray(matches))
                               .Add("frames", core::JsonArray(frames, "    "))
                               .str());
  }
  root.Add("settings", core::JsonObject()
                           .String("rig", o.rig_path.empty() ? (o.scan / "rig.yaml").string() : o.rig_path.string())
                           .Number("max_rotation_sigma_deg", o.max_rotation_sigma_deg)
                           .Number("max_translation_sigma_mm", o.max_translation_sigma_mm)
                           .Int("min_stills", o.target.min_stills)
                           .Bool("depth_model", o.target.depth_model)
                           .Bool("depth_affine", o.target.depth_affine)
                           .Number("depth_affine_sigma_per_m", o.target.depth_affine_sigma_per_m)
                           .Number("huber_sigmas", o.target.huber_sigmas)
                           .Int("reweight_iterations", o.target.reweight_iterations)
                           .str());
  root.Add("qa", calibrate::QaChecksJson(r.checks)).String("verdict", r.pass ? "PASS" : "FAIL");
  root.Number("total_s", r.seconds);
  return root.str() + "\n";
}

}  // namespace

std::string ExtrinsicsCommandOptions::Check() const {
  if (scan.empty()) return "--scan: must be given";
  if (out_folder.empty()) return "--out: must be given";
  // 0: the method's default.
  if (!(max_rotation_sigma_deg >= 0 && max_rotation_sigma_deg <= 90)) {
    return core::OptionFail("--max-rotation-sigma-deg", max_rotation_sigma_deg, "in (0, 90] degrees");
  }
  if (!(max_translation_sigma_mm >= 0 && max_translation_sigma_mm <= 1000)) {
    return core::OptionFail("--max-translation-sigma-mm", max_translation_sigma_mm, "in (0, 1000] mm");
  }
  if (const std::string problem = targetless.Check(); !problem.empty()) return problem;
  return target.Check();
}

ExtrinsicsCommandResult CalibrateExtrinsics(const ExtrinsicsCommandOptions& o, bool quiet) {
  const auto start = std::chrono::steady_clock::now();
  ExtrinsicsCommandResult r;
  ExtrinsicsMethod method = o.method;
  if (method == ExtrinsicsMethod::kAuto) {
    method = fs::exists(o.scan / "target.yaml") ? ExtrinsicsMethod::kTarget : ExtrinsicsMethod::kTargetless;
  }
  r.method = MethodName(method);
  if (method == ExtrinsicsMethod::kTarget && !o.trajectory.empty()) {
    throw UsageError("--trajectory: applies to --method targetless only (the target method uses stills)");
  }
  core::ScanOptions scan_options;
  scan_options.rig_path = o.rig_path;
  const core::Scan scan = core::Scan::Open(o.scan, scan_options);
  r.rig_in = scan.rig();
  r.rig_out = r.rig_in;

  // The method's estimate and its diagnostic images (name → image, in diagnostics/).
  std::vector<std::pair<std::string, cv::Mat>> images;
  std::optional<calibrate::TargetExtrinsicsResult> target_result;
  std::optional<calibrate::TargetlessResult> targetless_result;
  if (method == ExtrinsicsMethod::kTarget) {
    const core::Target target = core::ReadTarget(o.scan / "target.yaml");
    calibrate::TargetExtrinsicsResult& t = target_result.emplace();
    {
      core::ProgressBar bar("detect", scan.NumFrames(core::Stream::kDepth), "stills", quiet);
      t = calibrate::EstimateTargetExtrinsics(scan, target, o.target, [&](int done, int) { bar.Set(done); });
    }
    r.estimates = {t.thermal, t.rgb};
    r.detect_seconds = t.detect_seconds;
    r.notes.push_back(StringPrintf("Stills     %d of %zu used; corners sigma thermal %.3f px, rgb %.3f px; plate %d points, "
                                   "sigma %.2f mm white, %.2f mm per %.0f mm cell; depth bowl %+.4f /m, affine %+.4f %+.4f %+.4f /m",
                                   t.stills_used, t.stills.size(), t.sigma_thermal_px, t.sigma_rgb_px, t.plane_points,
                                   1e3 * t.sigma_plane_m, 1e3 * t.sigma_cell_m, 1e3 * o.target.plane_cell_m,
                                   t.depth_model[1], t.depth_model[0], t.depth_model[2], t.depth_model[3]));
    r.rig_out.depth_from_rgb = t.rgb.depth_from_camera;
    if (o.fold_depth_affine && t.depth_affine_sigma_per_m > 0 && r.rig_out.depth_correction) {
      const Eigen::Vector4d& m = t.depth_model;
      const Eigen::Vector4d sigma = t.depth_model_covariance.diagonal().cwiseSqrt();
      // A term is folded when the stills, not its prior, determine it: its posterior σ at
      // most a third of the prior's (the data's information ≥ 8× the prior's). Else the
      // estimate is mostly the prior's pull to 0 plus noise (the 10 small stills of the test
      // session: scale σ 0.8 of the prior's, and folding it made the field's affine part
      // 14 % worse). A plate seen at 0.65–1.2 m measures the scale well (full session:
      // 0.15 of the prior's), the tilts hardly (0.48, 0.51).
      const auto measured = [&](int k) { return sigma[k] <= t.depth_affine_sigma_per_m / 3; };
      const Eigen::Vector3d folded(measured(0) ? m[0] : 0, measured(2) ? m[2] : 0, measured(3) ? m[3] : 0);
      core::DepthCorrection& correction = *r.rig_out.depth_correction;
      correction.AddAffine(folded[0], folded[1], folded[2]);
      // Recorded as measured (accumulating over runs: a second run measures what is left).
      if (folded != Eigen::Vector3d::Zero()) {
        std::array<double, 3> total = correction.plate_affine_per_m.value_or(std::array<double, 3>{0, 0, 0});
        for (int i = 0; i < 3; ++i) total[i] += folded[i];
        correction.plate_affine_per_m = total;
      }
      if (const std::string bad = correction.Check(); !bad.empty()) {
        throw core::InputError(o.scan, "the depth error's affine part measured on the plate does not fit rig.yaml's "
                                       "depth_correction (" + bad + "): check the depth camera and target.yaml");
      }
      r.depth_affine_folded_per_m = folded;
      const auto said = [&](int k) { return measured(k) ? "folded" : "not measured: left"; };
      // z²·a: what the scale term moves a depth of 3 m by.
      r.notes.push_back(StringPrintf("Depth      affine part of the depth error (no wall shows it), on the plate: scale "
                                     "%+.5f +- %.5f /m (%+.1f +- %.1f mm at 3 m; %s), tilt x %+.5f +- %.5f (%s), "
                                     "y %+.5f +- %.5f /m (%s); prior sigma %.5f /m",
                                     m[0], sigma[0], 9e3 * m[0], 9e3 * sigma[0], said(0), m[2], sigma[2], said(2), m[3],
                                     sigma[3], said(3), t.depth_affine_sigma_per_m));
    }
    const int stills = static_cast<int>(t.stills.size());
    images = {{"thermal_residuals.png", ResidualScatter(*r.rig_in.thermal, t.thermal_residuals, stills)},
              {"rgb_residuals.png", ResidualScatter(*r.rig_in.rgb, t.rgb_residuals, stills)},
              {"plane_residuals.png", PlaneHistogram(t.plane_residuals, std::hypot(t.sigma_plane_m, t.sigma_cell_m))}};
  } else {
    std::optional<core::Trajectory> world_from_depth;
    if (!o.trajectory.empty()) {
      world_from_depth = core::ReadTumTrajectory(o.trajectory);
      // Two poses at least to interpolate between; fewer is a bad file, not a bad scan.
      if (world_from_depth->size() < 2) {
        throw core::InputError(o.trajectory, "needs at least 2 poses to interpolate, has " +
                                                 std::to_string(world_from_depth->size()));
      }
    }
    calibrate::TargetlessResult& t = targetless_result.emplace();
    {
      // The number of frames is known once the solver has paired them: the bar starts then.
      std::unique_ptr<core::ProgressBar> bar;
      t = calibrate::EstimateTargetlessExtrinsics(scan, world_from_depth, o.targetless, [&](int done, int total) {
        if (!bar) bar = std::make_unique<core::ProgressBar>("lines", total, "frames", quiet);
        bar->Set(done);
      });
    }
    r.estimates = {t.estimate};
    r.notes.push_back(StringPrintf("Frames     %zu thermal frames%s; %d line matches, %.0f %% inliers, robust sigma "
                                   "%.3f px; occlusion edge offset %+.2f +- %.2f depth px",
                                   t.frames.size(), t.used_trajectory ? " on the trajectory" : " (nearest depth frames)",
                                   t.matches, 100 * t.inlier_fraction, t.robust_sigma_px, t.edge_offset_px,
                                   t.edge_offset_sigma_px));
    // The frame with the most matches, and the first used one: the fit where it is best
    // constrained, and an arbitrary one.
    int best = 0;
    for (size_t i = 0; i < t.frames.size(); ++i) {
      if (t.frames[i].matches > t.frames[best].matches) best = static_cast<int>(i);
    }
    images = {{"lines_best.png", calibrate::DrawTargetlessDiagnostic(scan, t, best, o.targetless)},
              {"lines_first.png", calibrate::DrawTargetlessDiagnostic(scan, t, 0, o.targetless)}};
  }
  r.rig_out.depth_from_thermal = r.estimates.front().depth_from_camera;
  const double max_rotation_sigma_deg =
      o.max_rotation_sigma_deg > 0 ? o.max_rotation_sigma_deg : (method == ExtrinsicsMethod::kTarget ? 0.1 : 0.5);
  const double max_translation_sigma_mm =
      o.max_translation_sigma_mm > 0 ? o.max_translation_sigma_mm : (method == ExtrinsicsMethod::kTarget ? 2.0 : 10.0);
  for (const calibrate::ExtrinsicsEstimate& e : r.estimates) {
    r.checks.push_back(calibrate::MakeQaCheck(e.camera + "_rotation_sigma_deg",
                                              e.camera + " rotation uncertainty, largest axis (1 sigma)",
                                              e.RotationSigmaDeg().maxCoeff(), max_rotation_sigma_deg, true, "deg"));
    r.checks.push_back(calibrate::MakeQaCheck(e.camera + "_translation_sigma_mm",
                                              e.camera + " translation uncertainty, largest axis (1 sigma)",
                                              e.TranslationSigmaMm().maxCoeff(), max_translation_sigma_mm, true, "mm"));
  }
  r.pass = calibrate::AllPass(r.checks);

  // Every file either method writes, so that --overwrite also clears the other method's.
  const std::vector<std::string> outputs = {
      "extrinsics.json",           "rig.yaml",
      "diagnostics/thermal_residuals.png", "diagnostics/rgb_residuals.png",
      "diagnostics/plane_residuals.png",   "diagnostics/lines_best.png",
      "diagnostics/lines_first.png"};
  core::OutputFolder folder(o.out_folder, "heatwave calibrate extrinsics");
  if (!folder.IsEmpty()) {
    if (!o.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + o.out_folder.string() +
                       ": folder is not empty; pass --overwrite to replace the calibration in it");
    }
    folder.Remove(outputs);
  }
  fs::create_directories(o.out_folder / "diagnostics");
  for (const auto& [name, image] : images) {
    core::WriteImageAtomically(o.out_folder / "diagnostics" / name, image);
    r.written.push_back("diagnostics/" + name);
  }
  core::WriteRig(o.out_folder / "rig.yaml", r.rig_out);
  r.written.push_back("rig.yaml");
  r.written.push_back("extrinsics.json");
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  core::WriteFileAtomically(o.out_folder / "extrinsics.json",
                            ExtrinsicsJsonFile(o, r, target_result ? &*target_result : nullptr,
                                               targetless_result ? &*targetless_result : nullptr));
  folder.Commit();
  return r;
}

std::string FormatExtrinsicsSummary(const ExtrinsicsCommandResult& r, const fs::path& out_folder) {
  std::string out = StringPrintf("Method     %s\n", r.method.c_str());
  for (const std::string& note : r.notes) out += note + "\n";
  for (const calibrate::ExtrinsicsEstimate& e : r.estimates) {
    const core::Rigid3d& before = e.camera == "thermal" ? r.rig_in.depth_from_thermal : r.rig_in.depth_from_rgb;
    const Eigen::Vector3d t_mm = 1e3 * e.depth_from_camera.translation;
    const Eigen::Vector3d rs = e.RotationSigmaDeg(), ts = e.TranslationSigmaMm();
    out += StringPrintf("%-10s t = [%+.2f %+.2f %+.2f] mm (1 sigma %.2f %.2f %.2f), rotation 1 sigma %.3f %.3f %.3f deg; "
                        "moved %.3f deg, %.2f mm from rig.yaml; RMS %.3f %s\n",
                        e.camera.c_str(), t_mm.x(), t_mm.y(), t_mm.z(), ts.x(), ts.y(), ts.z(), rs.x(), rs.y(), rs.z(),
                        calibrate::RotationErrorDeg(before, e.depth_from_camera),
                        calibrate::TranslationErrorMm(before, e.depth_from_camera), e.rms_residual,
                        e.residual_unit.c_str());
  }
  out += "           sigmas about / along the depth camera's x, y, z axes\n";
  return out + FormatQaAndWritten(r.pass, r.checks, r.written, out_folder, r.seconds);
}

ExtrinsicsSubcommand::ExtrinsicsSubcommand(CLI::App& calibrate) {
  app_ = calibrate.add_subcommand("extrinsics",
                                  "depth_from_thermal and depth_from_rgb: from stills of a heated square_grid seen by all "
                                  "three cameras (target), or from a scan of a scene (targetless)");
  AddCommonOptions(*app_, common_);
  app_->add_option("--scan", options_.scan, "scan folder (with target.yaml for the target method)")->required();
  app_->add_option("--rig", options_.rig_path,
                   "rig.yaml to start from (calibrated intrinsics; its extrinsics are the first guess and are "
                   "replaced); default: the scan's");
  app_->add_option("--out", options_.out_folder, "output folder")->required();
  app_->add_flag("--overwrite", options_.overwrite, "replace an earlier calibration in --out");
  app_->add_option("--method", method_, "target, targetless, or auto: target when the scan has target.yaml")
      ->check(CLI::IsMember({"auto", "target", "targetless"}))
      ->capture_default_str();
  app_->add_option("--max-rotation-sigma-deg", options_.max_rotation_sigma_deg,
                   "QA: largest accepted 1-sigma rotation uncertainty about any axis, degrees; default: 0.1 with a "
                   "target, 0.5 targetless");
  app_->add_option("--max-translation-sigma-mm", options_.max_translation_sigma_mm,
                   "QA: largest accepted 1-sigma translation uncertainty along any axis, mm; default: 2 with a "
                   "target, 10 targetless");
  app_->add_flag("--keep-depth-correction{false}", options_.fold_depth_affine,
                 "target: write rig.yaml's depth_correction as read (default: fold in the depth error's affine "
                 "part measured on the plate)");
  app_->add_option("--min-stills", options_.target.min_stills, "target: stills needed in each camera")
      ->capture_default_str();
  app_->add_option("--trajectory", options_.trajectory,
                   "targetless: world_from_depth of the scan, TUM format (heatwave reconstruct's trajectory.txt), "
                   "to bring each depth frame's lines to the thermal frame's time; default: nearest depth frames only");
  app_->add_option("--max-frames", options_.targetless.max_frames,
                   "targetless: at most this many thermal frames, evenly spread")
      ->capture_default_str();
}

bool ExtrinsicsSubcommand::Chosen() const { return app_->parsed(); }

int ExtrinsicsSubcommand::Run() {
  return RunGuarded([&] {
    options_.method = method_ == "target"       ? ExtrinsicsMethod::kTarget
                      : method_ == "targetless" ? ExtrinsicsMethod::kTargetless
                                                : ExtrinsicsMethod::kAuto;
    ThrowIfInvalid(options_.Check());
    const ExtrinsicsCommandResult result = CalibrateExtrinsics(options_, common_.quiet);
    if (!common_.quiet) std::cout << FormatExtrinsicsSummary(result, options_.out_folder) << std::flush;
    if (!result.pass) {
      PrintError("the extrinsic calibration failed QA: " + calibrate::FailedCheckNames(result.checks) +
                 " (extrinsics.json has every check)");
      return kExitFailure;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
