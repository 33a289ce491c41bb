#pragma once

// heatwave audit: the whole job in one command — scan → reconstruct (with temperature) →
// analyze → report — into one folder, with one progress display and one summary.
// heatwave report: the report alone, from an audit or analysis folder (re-issue after
// editing job.yaml). heatwave demo: a bundled synthetic scan rendered and audited.

#include <filesystem>
#include <string>

#include "analyze/analyzer.h"
#include "cli/reconstruct.h"
#include "report/report_writer.h"

namespace hw::cli {

struct AuditCommandOptions {
  std::filesystem::path scan_folder;
  std::filesystem::path job_path;    // job.yaml (report/job.h; README "Audit reports")
  std::filesystem::path out_folder;
  std::filesystem::path rig_path;    // "" = the scan's rig.yaml
  bool overwrite = false;            // replace an earlier audit's files in out_folder
  int num_threads = 0;               // 0 = all cores
  int max_frames = 0;                // depth frames used, 0 = all
  double voxel_size_m = 0.005;       // TSDF voxel side, m (truncation: 4 voxels)
  report::ReportWriteOptions report;

  std::string Check() const;
};

struct AuditResult {
  ReconstructCommandResult reconstruction;
  analyze::AnalyzeResult analysis;
  report::ReportWriteResult report;
  double reconstruct_s = 0, analyze_s = 0, report_s = 0, total_s = 0;
};

// Runs the three stages into options.out_folder: model.ply, trajectory.txt,
// reconstruct.json, images/, analyze.json, report.html, report.pdf. The job file and the
// analysis config are read, and the folder checked, before any stage starts. Throws
// core::InputError (a bad job, config, scan or frame), core::OutputError, UsageError (a
// non-empty --out without overwrite; a scan without thermal stream: nothing to audit).
AuditResult AuditCommand(const AuditCommandOptions& options, bool quiet);

// The one-screen summary.
std::string FormatAuditSummary(const AuditResult& result);

struct ReportCommandOptions {
  std::filesystem::path folder;      // holds analyze.json (an audit or analysis folder)
  std::filesystem::path job_path;
  std::filesystem::path out_folder;  // "" = folder
  std::filesystem::path reconstruct_json;  // "" = folder/reconstruct.json when present
  std::filesystem::path model_ply;         // "" = folder/model.ply when present
  std::filesystem::path rig_path;          // "" = none
  bool overwrite = false;
  report::ReportWriteOptions report;

  std::string Check() const;
};

// Writes report.html / report.pdf from an existing analysis. Throws as AuditCommand.
report::ReportWriteResult ReportCommand(const ReportCommandOptions& options, bool quiet);

// The demo's job.yaml and analyze.yaml, written next to the demo scan as examples.
std::string DemoJobYaml();
std::string DemoAnalyzeYaml();

}  // namespace hw::cli
