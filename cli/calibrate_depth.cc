#include "cli/calibrate_depth.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>

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

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

// Depth error at 3 m (mm) of an inverse-depth offset (1/m): z²·δ.
constexpr double kMmAt3mPerUnit = 9e3;

std::string NumberArray(const std::vector<double>& values) {
  std::string out = "[";
  for (size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + core::JsonNumber(values[i]);
  return out + "]";
}

std::string IntArray(const std::vector<int>& values) {
  std::string out = "[";
  for (size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + std::to_string(values[i]);
  return out + "]";
}

std::string FrameJson(const calibrate::DepthPlaneFit& f) {
  core::JsonObject o;
  o.Int("frame", f.frame).Number("timestamp_s", f.timestamp_s).Bool("used", f.used);
  if (!f.used) return o.String("skipped_because", f.skipped_because).str();
  return o.Int("samples", f.samples)
      .Int("inliers", f.inliers)
      .Number("distance_m", f.distance_m)
      .Number("tilt_deg", f.tilt_deg)
      .Number("sigma_per_m", f.sigma_per_m)
      .Number("rms_before_mm", f.rms_before_mm)
      .Number("rms_after_mm", f.rms_after_mm)
      .str();
}

std::string DepthJson(const DepthCommandOptions& o, const DepthCommandResult& r) {
  const calibrate::DepthCorrectionResult& e = r.estimate;
  const core::DepthCorrection& c = e.correction;
  core::JsonObject root;
  root.Int("version", 1).String("command", "heatwave calibrate depth");
  root.String("scan", o.scan.string());
  root.String("model",
              "1/z_true = 1/z_measured - offset(x, y): offset_per_m at the nodes of an nx x ny grid over "
              "the ray's normalised coordinates x = X/Z, y = Y/Z, bilinear (rig.yaml depth_correction)");
  root.String("unobservable",
              "an affine offset a + b x + c y maps planes to planes: the estimate has none over its nodes "
              "(the depth scale and tilt it stands for are left as they were)");
  root.Add("grid", core::JsonObject()
                       .Int("nx", c.nx)
                       .Int("ny", c.ny)
                       .Add("x_range", NumberArray({c.x_range[0], c.x_range[1]}))
                       .Add("y_range", NumberArray({c.y_range[0], c.y_range[1]}))
                       .str());
  root.Add("offset_per_m", NumberArray(c.offset_per_m));
  root.Add("sigma_per_m", NumberArray(e.sigma_per_m));
  root.Add("node_samples", IntArray(e.node_samples));
  root.Add("summary", core::JsonObject()
                          .Int("frames", static_cast<int>(e.frames.size()))
                          .Int("frames_used", e.frames_used)
                          .Int("samples_used", e.samples_used)
                          .Number("distance_min_m", e.distance_min_m)
                          .Number("distance_max_m", e.distance_max_m)
                          .Number("rms_before_mm", e.rms_before_mm)
                          .Number("rms_after_mm", e.rms_after_mm)
                          .Number("field_rms_mm_at_3m", e.field_rms_mm_at_3m)
                          .Number("max_sigma_mm_at_3m", e.max_sigma_mm_at_3m)
                          .Number("coverage", e.coverage)
                          .str());
  std::vector<std::string> frames;
  for (const calibrate::DepthPlaneFit& f : e.frames) frames.push_back(FrameJson(f));
  root.Add("frames", core::JsonArray(frames, "  "));
  std::vector<std::string> warnings;
  for (const std::string& w : e.warnings) warnings.push_back(core::JsonString(w));
  root.Add("warnings", core::JsonArray(warnings, "  "));
  root.Add("options", core::JsonObject()
                          .Int("nx", o.fit.nx)
                          .Int("ny", o.fit.ny)
                          .Int("pixel_step", o.fit.pixel_step)
                          .Number("min_depth_m", o.fit.min_depth_m)
                          .Number("max_depth_m", o.fit.max_depth_m)
                          .Number("ransac_threshold_per_m", o.fit.ransac_threshold_per_m)
                          .Number("inlier_sigmas", o.fit.inlier_sigmas)
                          .Int("iterations", o.fit.iterations)
                          .Number("min_plane_fraction", o.fit.min_plane_fraction)
                          .Number("smoothness_sigma_per_m", o.fit.smoothness_sigma_per_m)
                          .Int("max_frames", o.fit.max_frames)
                          .str());
  root.Add("qa", calibrate::QaChecksJson(r.checks)).String("verdict", r.pass ? "PASS" : "FAIL");
  root.Number("read_s", r.read_seconds).Number("total_s", r.seconds);
  return root.str() + "\n";
}

std::vector<double> MmAt3m(const std::vector<double>& per_m) {
  std::vector<double> mm(per_m.size());
  std::transform(per_m.begin(), per_m.end(), mm.begin(), [](double v) { return kMmAt3mPerUnit * v; });
  return mm;
}

}  // namespace

std::string DepthCommandOptions::Check() const {
  if (scan.empty()) return "--scan: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (!(max_sigma_mm > 0 && max_sigma_mm <= 1000)) return core::OptionFail("--max-sigma-mm", max_sigma_mm, "in (0, 1000] mm");
  if (!core::InRange(min_coverage, 0, 1)) return core::OptionFail("--min-coverage", min_coverage, "in [0, 1]");
  const std::string problem = fit.Check();
  if (problem.empty()) return "";
  // Name the flag where the option has one.
  for (const auto& [field, flag] : {std::pair{"nx", "--nx"}, {"ny", "--ny"}, {"nx*ny", "--nx*--ny"},
                                    {"pixel_step", "--step"}, {"max_frames", "--max-frames"}}) {
    const std::string prefix = std::string(field) + ":";
    if (problem.rfind(prefix, 0) == 0) return flag + problem.substr(std::string(field).size());
  }
  return problem;
}

DepthCommandResult CalibrateDepth(const DepthCommandOptions& o, bool quiet) {
  const auto start = std::chrono::steady_clock::now();
  DepthCommandResult r;
  core::ScanOptions scan_options;
  scan_options.rig_path = o.rig_path;
  const core::Scan scan = core::Scan::Open(o.scan, scan_options);
  r.rig_in = scan.rig();
  {
    std::unique_ptr<core::ProgressBar> bar;  // the total is known at the first frame
    r.estimate = calibrate::CalibrateDepthCorrection(scan, r.rig_in.depth, o.fit, [&](int done, int total) {
      if (!bar) bar = std::make_unique<core::ProgressBar>("read depth", total, "frames", quiet);
      bar->Set(done);
      if (done == total) {
        r.read_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      }
    });
  }
  const calibrate::DepthCorrectionResult& e = r.estimate;
  r.rig_out = r.rig_in;
  r.rig_out.depth_correction = e.correction;
  r.checks.push_back(calibrate::MakeQaCheck("sigma_mm_at_3m", "largest node uncertainty (1 sigma) as depth at 3 m",
                                            e.max_sigma_mm_at_3m, o.max_sigma_mm, true, "mm"));
  r.checks.push_back(calibrate::MakeQaCheck("coverage", "fraction of grid nodes backed by 50 plane samples",
                                            e.coverage, o.min_coverage, false, ""));
  r.pass = calibrate::AllPass(r.checks);

  core::OutputFolder folder(o.out_folder, "heatwave calibrate depth");
  if (!folder.IsEmpty()) {
    if (!o.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + o.out_folder.string() +
                       ": folder is not empty; pass --overwrite to replace the calibration in it");
    }
    folder.Remove({"depth_correction.json", "rig.yaml", "diagnostics/field.png", "diagnostics/sigma.png"});
  }
  fs::create_directories(o.out_folder / "diagnostics");
  const std::vector<double> field_mm = MmAt3m(e.correction.offset_per_m);
  const std::vector<double> sigma_mm = MmAt3m(e.sigma_per_m);
  const double field_max = *std::max_element(field_mm.begin(), field_mm.end(),
                                              [](double a, double b) { return std::abs(a) < std::abs(b); });
  core::WriteImageAtomically(
      o.out_folder / "diagnostics" / "field.png",
      calibrate::DrawNodeField(e.correction, field_mm, r.rig_in.depth, true, std::abs(field_max),
                               "depth correction as depth error at 3 m, mm (red: reads far)"));
  core::WriteImageAtomically(
      o.out_folder / "diagnostics" / "sigma.png",
      calibrate::DrawNodeField(e.correction, sigma_mm, r.rig_in.depth, false,
                               std::max(o.max_sigma_mm, e.max_sigma_mm_at_3m),
                               "uncertainty (1 sigma) as depth at 3 m, mm"));
  core::WriteRig(o.out_folder / "rig.yaml", r.rig_out);
  r.written = {"diagnostics/field.png", "diagnostics/sigma.png", "rig.yaml", "depth_correction.json"};
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  core::WriteFileAtomically(o.out_folder / "depth_correction.json", DepthJson(o, r));
  folder.Commit();
  return r;
}

std::string FormatDepthSummary(const DepthCommandResult& r, const fs::path& out_folder) {
  const calibrate::DepthCorrectionResult& e = r.estimate;
  std::string out;
  out += StringPrintf("Planes     %d of %zu frames, %d samples, seen from %.2f to %.2f m\n", e.frames_used,
                      e.frames.size(), e.samples_used, e.distance_min_m, e.distance_max_m);
  out += StringPrintf("Residual   %.2f mm RMS before, %.2f mm after (depth to each frame's plane)\n", e.rms_before_mm,
                      e.rms_after_mm);
  out += StringPrintf("Field      %d x %d nodes, %.2f mm RMS as depth at 3 m; largest 1 sigma %.2f mm; "
                      "%.0f %% of nodes covered\n",
                      e.correction.nx, e.correction.ny, e.field_rms_mm_at_3m, e.max_sigma_mm_at_3m, 100 * e.coverage);
  out += "           1/z_true = 1/z_measured - offset(x, y); its affine part (depth scale, tilt) is not observable\n";
  for (const std::string& w : e.warnings) out += "Warning    " + w + "\n";
  if (r.rig_in.depth_correction) out += "           the rig's earlier depth_correction is replaced\n";
  return out + FormatQaAndWritten(r.pass, r.checks, r.written, out_folder, r.seconds);
}

DepthSubcommand::DepthSubcommand(CLI::App& calibrate) {
  app_ = calibrate.add_subcommand("depth",
                                  "the depth camera's systematic error (rig.yaml depth_correction) from a flat wall seen "
                                  "from near to far");
  AddCommonOptions(*app_, common_);
  app_->add_option("--scan", options_.scan, "scan folder whose depth frames see a flat wall (heatwave synth --session depth-wall)")
      ->required();
  app_->add_option("--rig", options_.rig_path, "rig.yaml to start from (its depth_correction is replaced); default: the scan's");
  app_->add_option("--out", options_.out_folder, "output folder")->required();
  app_->add_flag("--overwrite", options_.overwrite, "replace an earlier calibration in --out");
  app_->add_option("--nx", options_.fit.nx, "grid nodes across the image, [2, 256]")->capture_default_str();
  app_->add_option("--ny", options_.fit.ny, "grid nodes down the image, [2, 256]")->capture_default_str();
  app_->add_option("--step", options_.fit.pixel_step, "use every N-th pixel along rows and columns, [1, 64]")
      ->capture_default_str();
  app_->add_option("--max-frames", options_.fit.max_frames, "use at most N frames, evenly spread (0: all)")
      ->capture_default_str();
  app_->add_option("--max-sigma-mm", options_.max_sigma_mm, "QA: largest accepted node 1-sigma, as depth at 3 m, mm")
      ->capture_default_str();
  app_->add_option("--min-coverage", options_.min_coverage, "QA: smallest accepted fraction of covered nodes, [0, 1]")
      ->capture_default_str();
}

bool DepthSubcommand::Chosen() const { return app_->parsed(); }

int DepthSubcommand::Run() {
  return RunGuarded([&] {
    ThrowIfInvalid(options_.Check());
    const DepthCommandResult result = CalibrateDepth(options_, common_.quiet);
    if (!common_.quiet) std::cout << FormatDepthSummary(result, options_.out_folder) << std::flush;
    if (!result.pass) {
      PrintError("the depth calibration failed QA: " + calibrate::FailedCheckNames(result.checks) +
                 " (depth_correction.json has every check)");
      return kExitFailure;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
