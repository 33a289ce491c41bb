#pragma once

// The QA profile of the calibration bench (qa.yaml): the thresholds a camera's calibration
// must meet, and the PASS/FAIL verdict of each check with the measured value beside its
// threshold — what manufacturing QA files and what the certificate of part 2 shows.

#include <filesystem>
#include <string>
#include <vector>

namespace hw::calibrate {

struct QaProfile {
  int min_views = 10;                 // accepted views, [3, 10000]
  double max_rms_px = 0.5;            // RMS of the corners' residual norms (mrcal's figure), px, (0, 100]
  double max_worst_px = 2.0;          // largest inlier residual (2D norm), px, (0, 1000]
  double max_view_rms_px = 1.0;       // worst view's RMS, as max_rms_px, px, (0, 100]
  double max_outlier_fraction = 0.05; // corners rejected as outliers, [0, 1]
  double min_coverage = 0.5;          // fraction of the image's 8 × 6 cells holding a corner, [0, 1]
  double max_uncertainty_px = 0.5;    // worst projection uncertainty (1σ) over the covered cells, px, (0, 100]
  double uncertainty_range_m = 2.0;   // distance of the points whose projection is checked, m, (0, 1e4]

  // "" or "<key>: must be ..., got ..." (keys as in qa.yaml).
  std::string Check() const;
};

// What a calibration measured, for the checks.
struct QaMeasurements {
  int views = 0;
  double rms_px = 0, worst_px = 0, max_view_rms_px = 0, outlier_fraction = 0, coverage = 0;
  double max_uncertainty_px = 0;
};

struct QaCheck {
  std::string name;       // "rms_px", the qa.yaml key it is checked against without max_/min_
  std::string what;       // one line: "RMS residual per coordinate"
  double measured = 0;
  double threshold = 0;
  bool at_most = true;    // pass when measured <= threshold (else >=)
  std::string unit;       // "px", "", "views"
  bool pass = false;
};

// A check with its verdict: pass when measured <= threshold (at_most) or >= threshold; NaN
// never passes.
QaCheck MakeQaCheck(std::string name, std::string what, double measured, double threshold, bool at_most,
                    std::string unit);
// Every check of `profile` on `m`, in qa.yaml's order. NaN measured values fail.
std::vector<QaCheck> EvaluateQa(const QaProfile& profile, const QaMeasurements& m);
// True when every check passed.
bool AllPass(const std::vector<QaCheck>& checks);
// "PASS  rms_px  0.182 px <= 0.5 px  RMS residual per coordinate" — one line per check.
std::string FormatQaCheck(const QaCheck& check);
// The checks as a JSON array of objects {check, what, measured, comparison, threshold,
// unit, verdict}, as the bench's JSON files hold them.
std::string QaChecksJson(const std::vector<QaCheck>& checks);
// The names of the failed checks, ", "-separated ("" when all pass).
std::string FailedCheckNames(const std::vector<QaCheck>& checks);

// qa.yaml, strict (unknown key, wrong type, value out of range: one line naming key and
// line). Absent keys keep the defaults above. Throws core::InputError.
QaProfile ParseQaProfile(const std::string& yaml_text, const std::filesystem::path& path_for_errors);
QaProfile ReadQaProfile(const std::filesystem::path& path);

}  // namespace hw::calibrate
