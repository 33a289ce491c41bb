#include "calibrate/qa_profile.h"

#include <cmath>
#include <utility>

#include "core/atomic_file.h"
#include "core/json.h"
#include "core/option_check.h"
#include "core/strings.h"
#include "core/yaml_reader.h"

namespace hw::calibrate {

std::string QaProfile::Check() const {
  if (min_views < 3 || min_views > 10000) return core::OptionFail("min_views", min_views, "in [3, 10000]");
  if (!(max_rms_px > 0 && max_rms_px <= 100)) return core::OptionFail("max_rms_px", max_rms_px, "in (0, 100] px");
  if (!(max_worst_px > 0 && max_worst_px <= 1000)) return core::OptionFail("max_worst_px", max_worst_px, "in (0, 1000] px");
  if (!(max_view_rms_px > 0 && max_view_rms_px <= 100)) {
    return core::OptionFail("max_view_rms_px", max_view_rms_px, "in (0, 100] px");
  }
  if (!(max_outlier_fraction >= 0 && max_outlier_fraction <= 1)) {
    return core::OptionFail("max_outlier_fraction", max_outlier_fraction, "in [0, 1]");
  }
  if (!(min_coverage >= 0 && min_coverage <= 1)) return core::OptionFail("min_coverage", min_coverage, "in [0, 1]");
  if (!(max_uncertainty_px > 0 && max_uncertainty_px <= 100)) {
    return core::OptionFail("max_uncertainty_px", max_uncertainty_px, "in (0, 100] px");
  }
  if (!(uncertainty_range_m > 0 && uncertainty_range_m <= 1e4)) {
    return core::OptionFail("uncertainty_range_m", uncertainty_range_m, "in (0, 1e4] m");
  }
  return "";
}

QaCheck MakeQaCheck(std::string name, std::string what, double measured, double threshold, bool at_most,
                    std::string unit) {
  QaCheck c{std::move(name), std::move(what), measured, threshold, at_most, std::move(unit), false};
  c.pass = std::isfinite(measured) && (at_most ? measured <= threshold : measured >= threshold);
  return c;
}

std::vector<QaCheck> EvaluateQa(const QaProfile& p, const QaMeasurements& m) {
  return {
      MakeQaCheck("views", "accepted views", static_cast<double>(m.views), static_cast<double>(p.min_views), false,
                  "views"),
      MakeQaCheck("rms_px", "RMS residual (norm per corner)", m.rms_px, p.max_rms_px, true, "px"),
      MakeQaCheck("worst_px", "largest inlier residual", m.worst_px, p.max_worst_px, true, "px"),
      MakeQaCheck("view_rms_px", "worst view's RMS residual", m.max_view_rms_px, p.max_view_rms_px, true, "px"),
      MakeQaCheck("outlier_fraction", "corners rejected as outliers", m.outlier_fraction, p.max_outlier_fraction,
                  true, ""),
      MakeQaCheck("coverage", "image cells (8 x 6) observed", m.coverage, p.min_coverage, false, ""),
      MakeQaCheck("uncertainty_px",
                  core::StringPrintf("worst projection uncertainty (1 sigma) at %g m over the observed cells",
                                     p.uncertainty_range_m),
                  m.max_uncertainty_px, p.max_uncertainty_px, true, "px"),
  };
}

std::string QaChecksJson(const std::vector<QaCheck>& checks) {
  std::vector<std::string> items;
  for (const QaCheck& q : checks) {
    items.push_back(core::JsonObject()
                        .String("check", q.name)
                        .String("what", q.what)
                        .Number("measured", q.measured)
                        .String("comparison", q.at_most ? "<=" : ">=")
                        .Number("threshold", q.threshold)
                        .String("unit", q.unit)
                        .String("verdict", q.pass ? "PASS" : "FAIL")
                        .str());
  }
  return core::JsonArray(items, "  ");
}

bool AllPass(const std::vector<QaCheck>& checks) {
  for (const QaCheck& c : checks) {
    if (!c.pass) return false;
  }
  return true;
}

std::string FailedCheckNames(const std::vector<QaCheck>& checks) {
  std::string failed;
  for (const QaCheck& q : checks) {
    if (!q.pass) failed += (failed.empty() ? "" : ", ") + q.name;
  }
  return failed;
}

std::string FormatQaCheck(const QaCheck& c) {
  const std::string unit = c.unit.empty() ? "" : " " + c.unit;
  return core::StringPrintf("%s  %-17s %8.4g%s %s %g%s  %s", c.pass ? "PASS" : "FAIL", c.name.c_str(), c.measured,
                            unit.c_str(), c.at_most ? "<=" : ">=", c.threshold, unit.c_str(), c.what.c_str());
}

QaProfile ParseQaProfile(const std::string& yaml_text, const std::filesystem::path& path_for_errors) {
  const core::YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  reader.CheckVersion(root, 1);
  const core::YamlReader::Fields f =
      reader.Mapping(root, "", {"version", "min_views", "max_rms_px", "max_worst_px", "max_view_rms_px",
                                "max_outlier_fraction", "min_coverage", "max_uncertainty_px", "uncertainty_range_m"});
  QaProfile p;
  if (f.Has("min_views")) p.min_views = reader.Integer(f.Required("min_views"), "min_views");
  auto number = [&](const char* key, double* out) {
    if (f.Has(key)) *out = reader.Number(f.Required(key), key);
  };
  number("max_rms_px", &p.max_rms_px);
  number("max_worst_px", &p.max_worst_px);
  number("max_view_rms_px", &p.max_view_rms_px);
  number("max_outlier_fraction", &p.max_outlier_fraction);
  number("min_coverage", &p.min_coverage);
  number("max_uncertainty_px", &p.max_uncertainty_px);
  number("uncertainty_range_m", &p.uncertainty_range_m);
  if (const std::string problem = p.Check(); !problem.empty()) reader.FailCheck(root, "", problem);
  return p;
}

QaProfile ReadQaProfile(const std::filesystem::path& path) {
  return ParseQaProfile(core::ReadFile(path, core::kMaxConfigFileBytes), path);
}

}  // namespace hw::calibrate
