#pragma once

// The calibration bench's certificate (`heatwave calibrate bench`): what was checked, with
// which result, on which rig, by which software and when — as certificate.json and, laid
// out by the report module (report/document.h), as a self-contained HTML page and a PDF.
// All three come from one Certificate, so they say the same thing. Plain structs: the
// bench fills them; nothing here knows how a calibration is computed.

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "report/document.h"

namespace hw::report {

// One QA check: measured against threshold.
struct CertificateCheck {
  std::string name;        // "rms_px"
  std::string what;        // "RMS residual (norm per corner)"
  double measured = 0;     // in `unit`
  std::string comparison;  // "<=" or ">=": pass when measured <comparison> threshold
  double threshold = 0;    // in `unit`
  std::string unit;        // "px", "ms", "views", "" (a fraction)
  bool pass = false;
};

// A diagnostic image of a part: an 8-bit PNG, relative to the certificate's folder (the
// JSON names it so; the HTML inlines it, the PDF embeds it).
struct CertificateImage {
  std::string path;     // e.g. "intrinsics-thermal/diagnostics/residuals.png"
  std::string caption;  // "Residuals"
};

enum class PartStatus {
  kPassed,  // run, every check passed
  kFailed,  // run, a check failed
  kError,   // could not be computed (error: why); no numbers
  kNotRun,  // its sub-folder is missing (--partial); no numbers
};
std::string PartStatusName(PartStatus status);  // "PASS", "FAIL", "ERROR", "NOT RUN"

struct CertificatePart {
  std::string id;      // "intrinsics-thermal": the session's and output's sub-folder
  std::string title;   // "Thermal camera intrinsics"
  PartStatus status = PartStatus::kNotRun;
  std::string note;    // kError: the error; kNotRun: what is missing; else a summary line
  std::vector<CertificateCheck> checks;
  std::vector<CertificateImage> images;
  double seconds = 0;  // wall time of the part
};

// One number of the calibrated rig with its 1σ uncertainty.
struct RigQuantity {
  std::string name;    // "thermal fx"
  double value = 0;    // in `unit`
  std::optional<double> sigma;  // 1σ, in `unit`; none when not estimated
  std::string unit;    // "px", "ms", "mm", "deg"
  std::string source;  // the part that calibrated it, or "nominal (not calibrated)"
};

// A calibrated number against a synthetic session's truth: a FIXTURE check (how well the
// bench recovers a known rig), never part of the QA verdict.
struct TruthRow {
  std::string name;       // "thermal fx"
  double value = 0, truth = 0;
  std::optional<double> sigma;
  std::string unit;
};

struct Certificate {
  // "PASS": every part ran and passed; "FAIL": a check failed or a part could not be
  // computed; "INCOMPLETE": parts were not run (--partial) and none of those run failed.
  std::string verdict;
  std::string software;     // "heatwave 0.13.0"
  std::string created_utc;  // ISO 8601 UTC, "2026-12-02T17:00:00Z"
  std::string session;      // the session folder as given
  std::string profile;      // the QA profile: its path, or "defaults"
  std::vector<std::pair<std::string, std::string>> ids;  // ("rig_serial", "HW-R-0042"), ...
  std::vector<CertificatePart> parts;                     // in bench order
  std::string rig_file = "rig.yaml";                      // the final rig, relative
  std::vector<RigQuantity> rig;
  std::vector<TruthRow> truth;  // empty: the session has no truth/rig.yaml
  std::string truth_file;       // the truth compared with, as given
};

// The verdict of `parts` as Certificate::verdict defines it.
std::string CertificateVerdict(const std::vector<CertificatePart>& parts);

// certificate.json: every field above; each check as {check, what, measured, comparison,
// threshold, unit, verdict}; non-finite numbers as null.
std::string CertificateJson(const Certificate& certificate);

// The certificate as a report document: the verdict on the cover with the parts' table,
// one section per part (checks, images), the rig, the truth comparison. Image paths are
// resolved against `folder` (the certificate's folder). Throws core::InputError for an
// image that is not a readable PNG.
Document CertificateDocument(const Certificate& certificate, const std::filesystem::path& folder);

// Writes folder/certificate.{json,html,pdf} atomically; returns the files written
// (relative names). Throws as CertificateDocument, WriteHtml and WritePdf.
std::vector<std::string> WriteCertificate(const Certificate& certificate, const std::filesystem::path& folder);

}  // namespace hw::report
