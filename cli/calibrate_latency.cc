#include "cli/calibrate_latency.h"

#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <tuple>

#include "cli/calibrate.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/json.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/scan.h"
#include "core/scan_writer.h"
#include "core/strings.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

std::string TrackJson(const calibrate::BlobTrack& t) {
  return core::JsonObject()
      .Int("frames", t.frames)
      .Int("frames_with_blob", t.frames - t.missing)
      .Int("frames_missing", t.missing)
      .Number("motion_px", t.motion_px)
      .Number("noise", t.noise)
      .String("noise_unit", t.stream == core::Stream::kDepth ? "m"
                            : t.stream == core::Stream::kRgb ? "linear luma"
                                                             : "band radiance W/(m^2 sr)")
      .str();
}

std::string PairJson(const calibrate::PairOffset& p) {
  return core::JsonObject()
      .String("reference", p.reference)
      .String("other", p.other)
      .Number("offset_s", p.offset_s)
      .Number("sigma_s", p.sigma_s)
      .Number("sigma_fit_s", p.sigma_fit_s)
      .Number("sigma_bootstrap_s", p.sigma_bootstrap_s)
      .Number("coarse_offset_s", p.coarse_offset_s)
      .Number("peak_correlation", p.peak_correlation)
      .Number("second_peak_correlation", p.second_peak_correlation)
      .Number("gain", p.gain)
      .Number("bias", p.bias)
      .Number("residual_rms", p.residual_rms)
      .Int("samples", p.samples)
      .Number("effective_samples", p.effective_samples)
      .Int("bootstrap_block", p.bootstrap_block)
      .str();
}

std::string LatencyJson(const LatencyCommandOptions& o, const LatencyCommandResult& r) {
  const calibrate::LatencyResult& e = r.estimate;
  core::JsonObject root;
  root.Int("version", 1).String("command", "heatwave calibrate latency");
  root.String("scan", o.scan.string());
  root.String("sign_convention",
              "t_depth_clock = t_stream + time_offset_s (scan-format.md); a pair's offset_s: t_reference_clock = "
              "t_other_clock + offset_s");
  root.String("thermal_lag",
              "the thermal offset is the effective one (images aligned to the scene they show): it includes the "
              "microbolometer's lag");
  root.Add("time_offset_s", core::JsonObject()
                                .Number("rgb", e.rgb.offset_s)
                                .Number("thermal", e.thermal.offset_s)
                                .Number("rgb_sigma", e.rgb.sigma_s)
                                .Number("thermal_sigma", e.thermal.sigma_s)
                                .str());
  root.Add("time_offset_s_before",
           core::JsonObject().Number("rgb", r.rig_in.rgb_time_offset_s).Number("thermal", r.rig_in.thermal_time_offset_s).str());
  root.Add("pairs", core::JsonObject()
                        .Add("depth_rgb", PairJson(e.rgb))
                        .Add("depth_thermal", PairJson(e.thermal))
                        .Add("rgb_thermal", PairJson(e.thermal_rgb))
                        .str());
  root.Number("closure_s", e.closure_s)
      .Number("closure_sigma_s", e.closure_sigma_s)
      .String("closure_is", "rgb_thermal offset - (thermal - rgb offsets): 0 when the three pairs agree");
  root.Add("streams", core::JsonObject()
                          .Add("depth", TrackJson(e.depth_track))
                          .Add("rgb", TrackJson(e.rgb_track))
                          .Add("thermal", TrackJson(e.thermal_track))
                          .str());
  root.Add("motion_axis", StringPrintf("[%s, %s]", core::JsonNumber(e.motion_axis.x()).c_str(),
                                       core::JsonNumber(e.motion_axis.y()).c_str()));
  root.Add("options", core::JsonObject()
                          .Number("max_offset_s", o.latency.max_offset_s)
                          .Number("coarse_step_s", o.latency.coarse_step_s)
                          .Number("threshold_sigmas", o.latency.threshold_sigmas)
                          .Int("background_frames", o.latency.background_frames)
                          .Int("bootstrap_samples", o.latency.bootstrap_samples)
                          .str());
  root.Add("qa", calibrate::QaChecksJson(r.checks)).String("verdict", r.pass ? "PASS" : "FAIL");
  root.Number("estimate_s", e.seconds).Number("total_s", r.seconds);
  return root.str() + "\n";
}

}  // namespace

std::string LatencyCommandOptions::Check() const {
  if (scan.empty()) return "--scan: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (!(max_sigma_ms > 0 && max_sigma_ms <= 1000)) return core::OptionFail("--max-sigma-ms", max_sigma_ms, "in (0, 1000] ms");
  return latency.Check();
}

LatencyCommandResult CalibrateLatency(const LatencyCommandOptions& o, bool quiet) {
  const auto start = std::chrono::steady_clock::now();
  LatencyCommandResult r;
  core::ScanOptions scan_options;
  scan_options.rig_path = o.rig_path;
  const core::Scan scan = core::Scan::Open(o.scan, scan_options);
  r.rig_in = scan.rig();
  {
    std::unique_ptr<core::ProgressBar> bar;  // the total is known at the first frame
    r.estimate = calibrate::EstimateLatency(scan, o.latency, [&](int done, int total) {
      if (!bar) bar = std::make_unique<core::ProgressBar>("track blob", total, "frames", quiet);
      bar->Set(done);
      if (done == total) r.track_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    });
  }
  const calibrate::LatencyResult& e = r.estimate;
  r.rig_out = r.rig_in;
  r.rig_out.rgb_time_offset_s = core::RoundToMicroseconds(e.rgb.offset_s);
  r.rig_out.thermal_time_offset_s = core::RoundToMicroseconds(e.thermal.offset_s);
  for (const auto& [name, stream, pair] : {std::tuple{"rgb_sigma_ms", "rgb", &e.rgb}, std::tuple{"thermal_sigma_ms", "thermal", &e.thermal}}) {
    r.checks.push_back(calibrate::MakeQaCheck(name, std::string(stream) + " clock offset uncertainty (1 sigma)",
                                              1e3 * pair->sigma_s, o.max_sigma_ms, true, "ms"));
  }
  r.pass = calibrate::AllPass(r.checks);

  core::OutputFolder folder(o.out_folder, "heatwave calibrate latency");
  if (!folder.IsEmpty()) {
    if (!o.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + o.out_folder.string() + ": folder is not empty; pass --overwrite to replace the calibration in it");
    }
    folder.Remove({"latency.json", "rig.yaml", "diagnostics/signals.png"});
  }
  fs::create_directories(o.out_folder / "diagnostics");
  core::WriteImageAtomically(o.out_folder / "diagnostics" / "signals.png", calibrate::DrawLatencySignals(e));
  core::WriteRig(o.out_folder / "rig.yaml", r.rig_out);
  r.written = {"diagnostics/signals.png", "rig.yaml", "latency.json"};
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  core::WriteFileAtomically(o.out_folder / "latency.json", LatencyJson(o, r));
  folder.Commit();
  return r;
}

std::string FormatLatencySummary(const LatencyCommandResult& r, const fs::path& out_folder) {
  const calibrate::LatencyResult& e = r.estimate;
  std::string out;
  out += StringPrintf("Blob       depth %d/%d frames, rgb %d/%d, thermal %d/%d (motion %.1f / %.1f / %.1f px RMS)\n",
                      e.depth_track.frames - e.depth_track.missing, e.depth_track.frames,
                      e.rgb_track.frames - e.rgb_track.missing, e.rgb_track.frames,
                      e.thermal_track.frames - e.thermal_track.missing, e.thermal_track.frames, e.depth_track.motion_px,
                      e.rgb_track.motion_px, e.thermal_track.motion_px);
  auto line = [&](const char* label, const calibrate::PairOffset& p, double before) {
    out += StringPrintf("%-10s %+9.3f ms  (1 sigma %.3f ms: fit %.3f, bootstrap %.3f; r = %.3f; rig.yaml had %+.3f ms)\n",
                        label, 1e3 * p.offset_s, 1e3 * p.sigma_s, 1e3 * p.sigma_fit_s, 1e3 * p.sigma_bootstrap_s,
                        p.peak_correlation, 1e3 * before);
  };
  line("rgb", e.rgb, r.rig_in.rgb_time_offset_s);
  line("thermal", e.thermal, r.rig_in.thermal_time_offset_s);
  out += StringPrintf("Closure    rgb->thermal %+.3f ms vs thermal - rgb %+.3f ms: %+.3f ms (1 sigma %.3f)\n",
                      1e3 * e.thermal_rgb.offset_s, 1e3 * (e.thermal.offset_s - e.rgb.offset_s), 1e3 * e.closure_s,
                      1e3 * e.closure_sigma_s);
  out += "           time_offset_s: t_depth_clock = t_stream + offset; thermal includes the bolometer lag\n";
  return out + FormatQaAndWritten(r.pass, r.checks, r.written, out_folder, r.seconds);
}

LatencySubcommand::LatencySubcommand(CLI::App& calibrate) {
  app_ = calibrate.add_subcommand("latency",
                                  "clock offsets of rgb and thermal against depth, from an object waved in front of a "
                                  "still background");
  AddCommonOptions(*app_, common_);
  app_->add_option("--scan", options_.scan, "scan folder with depth, rgb and thermal streams")->required();
  app_->add_option("--rig", options_.rig_path, "rig.yaml to start from (its offsets are replaced); default: the scan's");
  app_->add_option("--out", options_.out_folder, "output folder")->required();
  app_->add_flag("--overwrite", options_.overwrite, "replace an earlier calibration in --out");
  app_->add_option("--max-sigma-ms", options_.max_sigma_ms, "QA: largest accepted 1-sigma uncertainty of an offset, ms")
      ->capture_default_str();
  app_->add_option("--max-offset", options_.latency.max_offset_s, "searched offsets: +- this, s")->capture_default_str();
}

bool LatencySubcommand::Chosen() const { return app_->parsed(); }

int LatencySubcommand::Run() {
  return RunGuarded([&] {
    ThrowIfInvalid(options_.Check());
    const LatencyCommandResult result = CalibrateLatency(options_, common_.quiet);
    if (!common_.quiet) std::cout << FormatLatencySummary(result, options_.out_folder) << std::flush;
    if (!result.pass) {
      PrintError("the latency calibration failed QA: " + calibrate::FailedCheckNames(result.checks) + " (latency.json has every check)");
      return kExitFailure;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
