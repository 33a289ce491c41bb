#include "cli/audit.h"

#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>

#include "analyze/analyze_config.h"
#include "cli/analyze.h"
#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/scan.h"
#include "core/strings.h"
#include "report/job.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// The files an audit writes; what --overwrite replaces.
const std::vector<std::string> kAuditEntries = {"model.ply", "trajectory.txt", "reconstruct.json", "images",
                                                "analyze.json", "report.html", "report.pdf"};

void AddReportOptions(CLI::App& app, report::ReportWriteOptions& o) {
  app.add_flag_callback("--no-html", [&o] { o.html = false; }, "do not write report.html");
  app.add_flag_callback("--no-pdf", [&o] { o.pdf = false; }, "do not write report.pdf");
  app.add_flag_callback("--no-3d", [&o] { o.model_view = false; }, "report.html without the interactive 3D view");
  app.add_option("--3d-max-faces", o.viewer.max_faces, "triangles of the model embedded in report.html")
      ->capture_default_str();
  app.add_option("--pdf-dpi", o.pdf_options.dpi, "resolution of the PDF's images at their printed size")
      ->capture_default_str();
}

report::ReportInputs MakeReportInputs(const fs::path& folder, const report::Job& job, const fs::path& reconstruct_json,
                                      const fs::path& model_ply, const fs::path& rig) {
  report::ReportInputs in;
  in.analyze_json = folder / "analyze.json";
  in.reconstruct_json = reconstruct_json;
  in.model_ply = model_ply;
  in.rig_yaml = rig;
  in.job = job;
  in.creator = std::string("heatwave ") + HW_VERSION;
  return in;
}

report::ReportWriteResult WriteReportWithBar(const report::ReportInputs& in, const fs::path& out,
                                            const report::ReportWriteOptions& options, bool quiet) {
  std::unique_ptr<core::ProgressBar> bar;
  report::ReportWriteResult r = report::WriteReport(in, out, options, [&](int done, int total) {
    if (!bar) bar = std::make_unique<core::ProgressBar>("report", total, "steps", quiet);
    bar->Set(done);
  });
  return r;
}

std::string ReportLines(const report::ReportWriteResult& r) {
  std::string out;
  std::string by;
  for (const auto& [name, n] : r.spots_by_severity) by += core::StringPrintf("%s%d %s", by.empty() ? "" : ", ", n, name.c_str());
  out += core::StringPrintf("Spots      %d%s%s\n", r.spots, by.empty() ? "" : ": ", by.c_str());
  if (!r.html_path.empty()) {
    out += core::StringPrintf("HTML       %s  %.1f MB, %d images", r.html_path.c_str(), r.html.bytes / 1e6, r.html.images);
    if (r.viewer.faces_out > 0) {
      out += core::StringPrintf("; 3D view %d of %d triangles (%.1f MB)", r.viewer.faces_out, r.viewer.faces_in,
                                r.viewer.embedded_bytes / 1e6);
    }
    out += "\n";
  }
  if (!r.pdf_path.empty()) {
    out += core::StringPrintf("PDF        %s  %.1f MB, %d pages, %d figures\n", r.pdf_path.c_str(), r.pdf.bytes / 1e6,
                              r.pdf.pages, r.pdf.figures);
  }
  return out;
}

}  // namespace

std::string AuditCommandOptions::Check() const {
  if (scan_folder.empty()) return "SCAN: must be given";
  if (job_path.empty()) return "--job: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (num_threads < 0 || num_threads > 256) return core::OptionFail("--threads", num_threads, "in [0, 256]");
  if (max_frames < 0) return core::OptionFail("--max-frames", max_frames, ">= 0");
  if (!(voxel_size_m >= 0.001 && voxel_size_m <= 0.1)) return core::OptionFail("--voxel-size", voxel_size_m, "in [0.001, 0.1] m");
  return report.Check();
}

AuditResult AuditCommand(const AuditCommandOptions& options, bool quiet) {
  const auto start = Clock::now();
  // Everything that can be wrong with the inputs is found before the first stage.
  const report::Job job = report::ReadJob(options.job_path);
  if (!job.analyze_config.empty()) analyze::ReadAnalyzeConfig(job.analyze_config);
  core::ScanOptions scan_options;
  scan_options.rig_path = options.rig_path;
  {
    const core::Scan scan = core::Scan::Open(options.scan_folder, scan_options);
    if (!scan.rig().thermal || scan.NumFrames(core::Stream::kThermal) == 0) {
      throw UsageError("SCAN " + options.scan_folder.string() +
                       ": has no thermal stream (or its rig no thermal camera): there is no temperature to audit");
    }
  }
  {
    core::OutputFolder folder(options.out_folder, "heatwave audit");
    if (!folder.IsEmpty()) {
      if (!options.overwrite) {
        folder.Abandon();
        throw UsageError("--out " + options.out_folder.string() +
                         ": folder is not empty; pass --overwrite to replace the audit in it");
      }
      folder.Remove(kAuditEntries);
    }
    folder.Abandon();
  }

  AuditResult result;
  {
    core::ProgressStage stage("[1/3]");
    const auto t0 = Clock::now();
    ReconstructCommandOptions r;
    r.scan_folder = options.scan_folder;
    r.out_folder = options.out_folder;
    r.rig_path = options.rig_path;
    r.overwrite = true;
    r.reconstruction.num_threads = options.num_threads;
    r.scan.max_frames = options.max_frames;
    r.reconstruction.tsdf.voxel_size_m = options.voxel_size_m;
    r.reconstruction.tsdf.truncation_m = kTruncationVoxels * options.voxel_size_m;
    if (!std::isnan(job.conditions.emissivity)) r.emissivity = job.conditions.emissivity;
    if (!std::isnan(job.conditions.reflected_c)) r.reflected_c = job.conditions.reflected_c;
    ThrowIfInvalid(r.Check());
    result.reconstruction = RunReconstruction(r, quiet);
    result.reconstruct_s = Since(t0);
  }
  {
    core::ProgressStage stage("[2/3]");
    const auto t0 = Clock::now();
    AnalyzeCommandOptions a;
    a.model_path = options.out_folder / "model.ply";
    a.out_folder = options.out_folder;
    a.config_path = job.analyze_config;
    a.overwrite = true;
    a.num_threads = options.num_threads;
    a.legends = false;  // the report draws vector colour bars and captions
    result.analysis = AnalyzeCommand(a, quiet);
    result.analyze_s = Since(t0);
  }
  {
    core::ProgressStage stage("[3/3]");
    const auto t0 = Clock::now();
    const fs::path rig = options.rig_path.empty() ? options.scan_folder / "rig.yaml" : options.rig_path;
    result.report = WriteReportWithBar(MakeReportInputs(options.out_folder, job, options.out_folder / "reconstruct.json",
                                                        options.out_folder / "model.ply", rig),
                                       options.out_folder, options.report, quiet);
    result.report_s = Since(t0);
  }
  result.total_s = Since(start);
  return result;
}

std::string FormatAuditSummary(const AuditResult& r) {
  const ReconstructCommandResult& rec = r.reconstruction;
  std::string out;
  out += core::StringPrintf("Reconstruct %d depth frames: %d fused, %d lost, %d missing; model %zu triangles, %.2f m2 (%.1f s)\n",
                            rec.depth_frames, rec.fused, rec.lost, rec.missing, rec.faces, rec.area_m2, r.reconstruct_s);
  if (rec.thermal) {
    out += core::StringPrintf("Temperature %d of %d thermal frames fused", rec.thermal->fused, rec.thermal->frames);
    if (rec.thermal->skipped > 0) {
      out += core::StringPrintf(" (%d skipped: the sharpest of each %g s fused)", rec.thermal->skipped,
                                rec.thermal->frame_interval_s);
    }
    out += core::StringPrintf("; %d vertices with temperature (%s)\n", rec.thermal->vertices_observed,
                              rec.thermal->method.c_str());
  }
  out += core::StringPrintf("Analyze    %.2f m2 with temperature, %.1f to %.1f C; %zu images (%.1f s)\n",
                            r.analysis.observed_area_m2, r.analysis.temperature_min_c, r.analysis.temperature_max_c,
                            r.analysis.images.size(), r.analyze_s);
  out += ReportLines(r.report);
  if (r.analysis.detection) {
    std::string ids;
    int n = 0;
    for (const analyze::Spot& s : r.analysis.detection->spots) {
      if (!s.possible_reflection) continue;
      ids += (n++ ? ", " : "") + s.id;
    }
    if (n > 0) {
      out += core::StringPrintf("Verify     %d %s (%s): re-image from another angle\n", n,
                                n == 1 ? "spot may be a reflection" : "spots may be reflections", ids.c_str());
    }
  }
  std::vector<std::string> warnings = rec.warnings;
  warnings.insert(warnings.end(), r.analysis.warnings.begin(), r.analysis.warnings.end());
  if (!warnings.empty()) {
    out += core::StringPrintf("Warnings   %zu (in the report and the JSON files)\n", warnings.size());
    for (size_t i = 0; i < std::min<size_t>(4, warnings.size()); ++i) out += "  " + warnings[i] + "\n";
  }
  out += core::StringPrintf("Audit      %s in %.1f s (reconstruct %.1f, analyze %.1f, report %.1f)\n",
                            rec.out_folder.c_str(), r.total_s, r.reconstruct_s, r.analyze_s, r.report_s);
  return out;
}

std::string ReportCommandOptions::Check() const {
  if (folder.empty()) return "FOLDER: must be given";
  if (job_path.empty()) return "--job: must be given";
  return report.Check();
}

report::ReportWriteResult ReportCommand(const ReportCommandOptions& options, bool quiet) {
  const report::Job job = report::ReadJob(options.job_path);
  const fs::path out = options.out_folder.empty() ? options.folder : options.out_folder;
  auto present = [&](const fs::path& given, const char* name) {
    if (!given.empty()) return given;
    return fs::is_regular_file(options.folder / name) ? options.folder / name : fs::path();
  };
  for (const char* name : {"report.html", "report.pdf"}) {
    if (fs::exists(out / name) && !options.overwrite) {
      throw UsageError("--out " + out.string() + ": holds " + name + "; pass --overwrite to replace the report");
    }
  }
  return WriteReportWithBar(MakeReportInputs(options.folder, job, present(options.reconstruct_json, "reconstruct.json"),
                                             present(options.model_ply, "model.ply"), options.rig_path),
                            out, options.report, quiet);
}

int RunAudit(int argc, char** argv) {
  CLI::App app("Audit a scan: reconstruct it with temperature, find and measure hot and cold spots, write the "
               "HTML and PDF report.",
               "heatwave audit");
  AuditCommandOptions o;
  CommonOptions common;
  AddCommonOptions(app, common);
  app.add_option("scan", o.scan_folder, "scan folder (heatwave capture or synth)")->required();
  app.add_option("--job", o.job_path, "job.yaml: client, site, assets, inspector, conditions (README)")->required();
  app.add_option("--out", o.out_folder, "output folder: model, images, analyze.json, report.html, report.pdf")
      ->required();
  app.add_option("--rig", o.rig_path, "rig.yaml to use instead of the scan's");
  app.add_flag("--overwrite", o.overwrite, "replace an earlier audit in a non-empty --out");
  app.add_option("--threads", o.num_threads, "worker threads, 0 = all cores")->capture_default_str();
  app.add_option("--max-frames", o.max_frames, "depth frames to use, 0 = all")->capture_default_str();
  app.add_option("--voxel-size", o.voxel_size_m, "TSDF voxel side, m (larger for building-scale scans)")
      ->capture_default_str();
  AddReportOptions(app, o.report);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    const AuditResult result = AuditCommand(o, common.quiet);
    if (!common.quiet) std::cout << FormatAuditSummary(result) << std::flush;
    return kExitOk;
  });
}

int RunReport(int argc, char** argv) {
  CLI::App app("Write the HTML and PDF report of an audit or analysis folder (after editing job.yaml).",
               "heatwave report");
  ReportCommandOptions o;
  CommonOptions common;
  AddCommonOptions(app, common);
  app.add_option("folder", o.folder, "folder with analyze.json and images/ (heatwave audit or analyze --out)")
      ->required();
  app.add_option("--job", o.job_path, "job.yaml (README)")->required();
  app.add_option("--out", o.out_folder, "where report.html and report.pdf go; default: the folder");
  app.add_option("--reconstruction", o.reconstruct_json, "reconstruct.json; default: the folder's, if any");
  app.add_option("--model", o.model_ply, "model.ply for the 3D view; default: the folder's, if any");
  app.add_option("--rig", o.rig_path, "rig.yaml whose calibration the report shows");
  app.add_flag("--overwrite", o.overwrite, "replace an earlier report.html / report.pdf");
  AddReportOptions(app, o.report);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    const report::ReportWriteResult result = ReportCommand(o, common.quiet);
    if (!common.quiet) std::cout << ReportLines(result) << std::flush;
    return kExitOk;
  });
}

}  // namespace hw::cli
