// heatwave scan-info: validates a scan folder and summarises its streams.
#include "cli/scan_info.h"

#include <algorithm>
#include <cassert>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli/command.h"
#include "cli/reconstruct_json.h"
#include "core/json.h"
#include "core/progress.h"
#include "core/strings.h"

namespace hw::cli {

using core::JsonArray;
using core::JsonNumber;
using core::JsonObject;

namespace {

// At most this many unloadable frames are listed in the text report.
constexpr size_t kMaxListedProblems = 20;

}  // namespace

std::string ScanInfoOptions::Check() const {
  if (scan_folder.empty()) return "scan_folder: must be given";
  if (max_association_dt_s &&
      !(std::isfinite(*max_association_dt_s) && *max_association_dt_s > 0)) {
    return "max_association_dt_s (--max-dt): must be > 0, got " +
           std::to_string(*max_association_dt_s);
  }
  if (!(std::isfinite(gap_factor) && gap_factor > 1)) {
    return "gap_factor (--gap-factor): must be > 1, got " + std::to_string(gap_factor);
  }
  if (threads < 0) return "threads (--threads): must be >= 0, got " + std::to_string(threads);
  return "";
}

ScanInfoReport InspectScan(const ScanInfoOptions& options) {
  assert(options.Check().empty());
  core::ScanOptions scan_options;
  scan_options.rig_path = options.rig_path;
  scan_options.max_association_dt_s = options.max_association_dt_s;
  scan_options.gap_factor = options.gap_factor;
  const core::Scan scan = core::Scan::Open(options.scan_folder, scan_options);

  ScanInfoReport report;
  report.summary = core::SummarizeScan(scan);
  for (const core::StreamSummary& st : report.summary.streams) {
    if (st.frames == 0) continue;
    std::vector<double> stamps;
    for (const core::IndexEntry& e : scan.Entries(st.stream)) stamps.push_back(e.timestamp_s);
    report.clocks[static_cast<size_t>(st.stream)] = core::RegulariseStamps(stamps);
  }
  report.total_frames = core::TotalFrames(scan);
  if (options.check_frames) {
    core::ProgressBar progress("frames", report.total_frames, "frames", options.quiet);
    report.frame_problems = core::CheckFrames(
        scan, [&] { progress.Advance(); }, options.threads);
    progress.Finish();
    report.frames_checked = true;
  }
  return report;
}

std::string FormatScanInfo(const ScanInfoReport& report) {
  const core::ScanSummary& s = report.summary;
  std::string out;
  out += "Scan     " + s.folder.string() + "\n";
  out += "Rig      " + s.rig_path.string() + core::StringPrintf("  (depth_scale %g units/m)\n", s.depth_scale);
  out += "\n";
  out += core::StringPrintf("%-8s %6s  %-17s %8s %8s %5s %9s %8s %9s\n", "Stream", "Frames", "Start (s)",
                "Span (s)", "Rate Hz", "Gaps", "Longest s", "Missing", "Offset s");
  std::string pairing;
  for (const core::StreamSummary& st : s.streams) {
    const std::string name = core::StreamName(st.stream);
    if (!st.has_index) {
      out += core::StringPrintf("%-8s %6s  no %s.txt\n", name.c_str(), "-", name.c_str());
      continue;
    }
    out += core::StringPrintf("%-8s %6d  %-17.6f %8.3f %8.2f %5d %9.4f %8d %+9.4f\n", name.c_str(), st.frames,
                  st.start_s, st.span_s, st.median_rate_hz, st.gaps, st.largest_interval_s,
                  st.missing_files, st.time_offset_s);
    if (st.stream != core::Stream::kDepth) {
      pairing += core::StringPrintf("Paired   %d of %d depth frames have a %s frame within %.4f s\n",
                        st.associated_depth_frames, s.streams[0].frames, name.c_str(),
                        st.max_association_dt_s);
    }
  }
  out += pairing;
  for (const core::StreamSummary& st : s.streams) {
    if (st.frames == 0) continue;
    const core::StampFit& f = report.clocks[static_cast<size_t>(st.stream)];
    out += "Clock    " + core::StreamName(st.stream) +
           (f.applied ? core::StringPrintf(" %.2f Hz, jitter %.2f ms: exposure times fitted (±%.2f ms, %lld empty slots)",
                                           1 / f.period_s, 1e3 * f.jitter_s, 1e3 * f.time_std_s,
                                           static_cast<long long>(f.empty_slots))
                      : ": stamps used as they are (" + f.reason + ")") +
           "\n";
  }
  out += "\n";
  out += core::StringPrintf("%-8s %-8s %-10s %9s %9s %4s %13s %15s\n", "Camera", "Model", "Size", "fx", "fy",
                "Dist", "Baseline (m)", "Rotation (deg)");
  for (const core::CameraSummary& c : s.cameras) {
    const bool reference = c.name == "depth";
    out += core::StringPrintf("%-8s %-8s %-10s %9.2f %9.2f %4d %13s %15s\n", c.name.c_str(), c.model.c_str(),
                  (std::to_string(c.width) + "x" + std::to_string(c.height)).c_str(), c.fx, c.fy,
                  c.distortion_coefficients, reference ? "-" : core::StringPrintf("%.4f", c.baseline_m).c_str(),
                  reference ? "-" : core::StringPrintf("%.3f", c.rotation_deg).c_str());
  }
  if (s.thermal_settings) {
    const core::ThermalSettings& t = *s.thermal_settings;
    out += core::StringPrintf(
        "Thermal  apparent °C = %g x raw %c %g; band %g-%g µm; NETD %g K\n"
        "         scene defaults: emissivity %g, reflected apparent temperature %g °C\n",
        t.raw_scale, t.raw_offset < 0 ? '-' : '+', std::abs(t.raw_offset), t.spectral_band_um[0],
        t.spectral_band_um[1], t.netd_k, t.emissivity, t.reflected_c);
  }
  out += "\n";
  if (s.has_groundtruth) {
    out +=
        core::StringPrintf("Ground truth  %d poses over %.3f s\n", s.groundtruth_poses, s.groundtruth_span_s);
  } else {
    out += "Ground truth  none\n";
  }
  out += core::StringPrintf("FFC events    %d\n", s.ffc_events);
  if (!s.warnings.empty()) {
    out += core::StringPrintf("\nWarnings (%zu):\n", s.warnings.size());
    for (const std::string& w : s.warnings) out += "  " + w + "\n";
  }
  if (report.frames_checked) {
    if (report.frame_problems.empty()) {
      out += core::StringPrintf("\nFrames   all %d frames load\n", report.total_frames);
    } else {
      out += core::StringPrintf("\nFrames   %zu of %d frames cannot be loaded:\n", report.frame_problems.size(),
                    report.total_frames);
      for (size_t i = 0; i < report.frame_problems.size() && i < kMaxListedProblems; ++i) {
        out += "  " + report.frame_problems[i].message + "\n";
      }
      if (report.frame_problems.size() > kMaxListedProblems) {
        out += core::StringPrintf("  ... and %zu more\n", report.frame_problems.size() - kMaxListedProblems);
      }
    }
  }
  out += "\n";
  if (report.frame_problems.empty()) {
    out += s.warnings.empty() ? "OK: valid scan\n"
                              : core::StringPrintf("OK: valid scan, %zu warning(s)\n", s.warnings.size());
  } else {
    out += "FAILED: some frames cannot be loaded\n";
  }
  return out;
}

std::string FormatScanInfoJson(const ScanInfoReport& report) {
  const core::ScanSummary& s = report.summary;
  std::vector<std::string> streams;
  for (const core::StreamSummary& st : s.streams) {
    JsonObject o;
    o.String("name", core::StreamName(st.stream))
        .Bool("has_index", st.has_index)
        .Int("frames", st.frames)
        .Number("start_s", st.start_s)
        .Number("end_s", st.end_s)
        .Number("span_s", st.span_s)
        .Number("median_rate_hz", st.median_rate_hz)
        .Int("gaps", st.gaps)
        .Number("largest_interval_s", st.largest_interval_s)
        .Int("missing_files", st.missing_files)
        .Number("time_offset_s", st.time_offset_s);
    if (st.stream != core::Stream::kDepth) {
      o.Int("associated_depth_frames", st.associated_depth_frames)
          .Number("max_association_dt_s", st.max_association_dt_s);
    }
    if (st.frames > 0) {
      const core::StampFit& f = report.clocks[static_cast<size_t>(st.stream)];
      o.Add("clock", StampFitJson(f));
    }
    streams.push_back(o.str());
  }
  std::vector<std::string> cameras;
  for (const core::CameraSummary& c : s.cameras) {
    cameras.push_back(JsonObject()
                          .String("name", c.name)
                          .String("model", c.model)
                          .Int("width", c.width)
                          .Int("height", c.height)
                          .Number("fx", c.fx)
                          .Number("fy", c.fy)
                          .Int("distortion_coefficients", c.distortion_coefficients)
                          .Number("baseline_m", c.baseline_m)
                          .Number("rotation_deg", c.rotation_deg)
                          .Number("time_offset_s", c.time_offset_s)
                          .str());
  }
  std::vector<std::string> warnings;
  for (const std::string& w : s.warnings) warnings.push_back(core::JsonString(w));
  std::vector<std::string> problems;
  for (const core::FrameProblem& p : report.frame_problems) {
    problems.push_back(JsonObject()
                           .String("stream", core::StreamName(p.stream))
                           .Int("index", p.index)
                           .String("path", p.path.string())
                           .String("message", p.message)
                           .str());
  }
  std::string out = "{\n";
  out += "  \"valid\": " + std::string(report.frame_problems.empty() ? "true" : "false") + ",\n";
  out += "  \"folder\": " + core::JsonString(s.folder.string()) + ",\n";
  out += "  \"rig_path\": " + core::JsonString(s.rig_path.string()) + ",\n";
  out += "  \"depth_scale\": " + JsonNumber(s.depth_scale) + ",\n";
  out += "  \"streams\": " + JsonArray(streams, "  ") + ",\n";
  out += "  \"cameras\": " + JsonArray(cameras, "  ") + ",\n";
  if (s.thermal_settings) {
    const core::ThermalSettings& t = *s.thermal_settings;
    out += "  \"thermal\": " +
           JsonObject()
               .Number("raw_scale", t.raw_scale)
               .Number("raw_offset", t.raw_offset)
               .Add("spectral_band_um", "[" + JsonNumber(t.spectral_band_um[0]) + ", " +
                                            JsonNumber(t.spectral_band_um[1]) + "]")
               .Number("netd_k", t.netd_k)
               .Number("emissivity", t.emissivity)
               .Number("reflected_c", t.reflected_c)
               .str() +
           ",\n";
  }
  out += "  \"groundtruth_poses\": " +
         (s.has_groundtruth ? std::to_string(s.groundtruth_poses) : std::string("null")) + ",\n";
  out += "  \"groundtruth_span_s\": " +
         (s.has_groundtruth ? JsonNumber(s.groundtruth_span_s) : std::string("null")) + ",\n";
  out += "  \"ffc_events\": " + std::to_string(s.ffc_events) + ",\n";
  out += "  \"warnings\": " + JsonArray(warnings, "  ") + ",\n";
  out += "  \"total_frames\": " + std::to_string(report.total_frames) + ",\n";
  out += "  \"frames_checked\": " + std::string(report.frames_checked ? "true" : "false") + ",\n";
  out += "  \"frame_problems\": " + JsonArray(problems, "  ") + "\n";
  out += "}\n";
  return out;
}

int RunScanInfo(int argc, char** argv) {
  CLI::App app(
      "Validate a scan folder (scan-format.md) and summarise it: streams (frames, time span, "
      "rate, gaps, missing files, pairing with depth), rig, ground truth, warnings.\n"
      "Exit code 0: valid scan (warnings allowed); 1: invalid scan, or with --check-frames "
      "frames that cannot be loaded; 2: bad usage.",
      "heatwave scan-info");
  ScanInfoOptions options;
  CommonOptions common;
  double max_dt_s = 0;
  app.add_option("scan", options.scan_folder, "scan folder")->required();
  app.add_option("--rig", options.rig_path,
                 "rig.yaml to use instead of SCAN/rig.yaml (e.g. for a TUM RGB-D sequence)");
  CLI::Option* max_dt_option = app.add_option(
      "--max-dt", max_dt_s,
      "largest |dt| in seconds pairing depth with rgb/thermal frames (default: half the median "
      "frame period of the slower stream)");
  app.add_option("--gap-factor", options.gap_factor,
                 "report intervals longer than this many median frame periods as gaps")
      ->capture_default_str();
  app.add_flag("--check-frames", options.check_frames,
               "decode every frame and report those that cannot be loaded");
  app.add_option("--threads", options.threads, "threads for --check-frames (0: all cores)")
      ->capture_default_str();
  app.add_flag("--json", options.json, "print the report as JSON on stdout (also with --quiet)");
  AddCommonOptions(app, common);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  options.quiet = common.quiet;
  if (max_dt_option->count() > 0) options.max_association_dt_s = max_dt_s;

  return RunGuarded([&] {
    ThrowIfInvalid(options.Check());
    const ScanInfoReport report = InspectScan(options);
    if (options.json) {
      std::cout << FormatScanInfoJson(report) << std::flush;
    } else if (!options.quiet) {
      std::cout << FormatScanInfo(report) << std::flush;
    }
    if (!report.frame_problems.empty()) {
      PrintError(std::to_string(report.frame_problems.size()) + " of " +
                 std::to_string(report.total_frames) +
                 " frames cannot be loaded; first: " + report.frame_problems[0].message);
      return kExitFailure;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
