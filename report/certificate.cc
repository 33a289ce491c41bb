#include "report/certificate.h"

#include <cmath>

#include "core/atomic_file.h"
#include "core/json.h"
#include "core/strings.h"
#include "report/html_report.h"
#include "report/pdf_layout.h"
#include "report/pdf_report.h"

namespace hw::report {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

using Tint = std::optional<std::array<std::uint8_t, 3>>;
constexpr std::array<std::uint8_t, 3> kGreen{46, 160, 67};
constexpr std::array<std::uint8_t, 3> kRed{205, 45, 40};
constexpr std::array<std::uint8_t, 3> kGrey{150, 150, 150};

Tint StatusTint(PartStatus s) {
  return s == PartStatus::kPassed ? Tint(kGreen) : s == PartStatus::kNotRun ? Tint(kGrey) : Tint(kRed);
}

std::string Number(double v) { return std::isfinite(v) ? StringPrintf("%.5g", v) : "—"; }
std::string WithUnit(double v, const std::string& unit) { return Number(v) + (unit.empty() ? "" : " " + unit); }
std::string OptionalJson(const std::optional<double>& v) { return v ? core::JsonNumber(*v) : "null"; }

int PassedChecks(const CertificatePart& p) {
  int n = 0;
  for (const CertificateCheck& c : p.checks) n += c.pass;
  return n;
}

std::string VerdictLine(const Certificate& c) {
  if (c.verdict == "PASS") return "PASS — every check of every part passed";
  std::string failed, missing;
  for (const CertificatePart& p : c.parts) {
    if (p.status == PartStatus::kFailed || p.status == PartStatus::kError) failed += (failed.empty() ? "" : ", ") + p.id;
    if (p.status == PartStatus::kNotRun) missing += (missing.empty() ? "" : ", ") + p.id;
  }
  std::string line = c.verdict + " —";
  if (!failed.empty()) line += " failed: " + failed + ";";
  if (!missing.empty()) line += " not run: " + missing + ";";
  line.pop_back();
  return line;
}

}  // namespace

std::string PartStatusName(PartStatus status) {
  switch (status) {
    case PartStatus::kPassed: return "PASS";
    case PartStatus::kFailed: return "FAIL";
    case PartStatus::kError: return "ERROR";
    case PartStatus::kNotRun: return "NOT RUN";
  }
  return "?";
}

std::string CertificateVerdict(const std::vector<CertificatePart>& parts) {
  bool failed = false, missing = parts.empty();
  for (const CertificatePart& p : parts) {
    failed |= p.status == PartStatus::kFailed || p.status == PartStatus::kError;
    missing |= p.status == PartStatus::kNotRun;
  }
  return failed ? "FAIL" : missing ? "INCOMPLETE" : "PASS";
}

std::string CertificateJson(const Certificate& c) {
  core::JsonObject ids;
  for (const auto& [key, value] : c.ids) ids.String(key, value);
  std::vector<std::string> parts;
  for (const CertificatePart& p : c.parts) {
    std::vector<std::string> checks, images;
    for (const CertificateCheck& q : p.checks) {
      checks.push_back(core::JsonObject()
                           .String("check", q.name)
                           .String("what", q.what)
                           .Number("measured", q.measured)
                           .String("comparison", q.comparison)
                           .Number("threshold", q.threshold)
                           .String("unit", q.unit)
                           .String("verdict", q.pass ? "PASS" : "FAIL")
                           .str());
    }
    for (const CertificateImage& im : p.images) {
      images.push_back(core::JsonObject().String("path", im.path).String("caption", im.caption).str());
    }
    parts.push_back(core::JsonObject()
                        .String("part", p.id)
                        .String("title", p.title)
                        .String("verdict", PartStatusName(p.status))
                        .String("note", p.note)
                        .Add("checks", core::JsonArray(checks, "      "))
                        .Add("images", core::JsonArray(images, "      "))
                        .Number("seconds", p.seconds)
                        .str());
  }
  std::vector<std::string> rig;
  for (const RigQuantity& q : c.rig) {
    rig.push_back(core::JsonObject()
                      .String("quantity", q.name)
                      .Number("value", q.value)
                      .Add("sigma", OptionalJson(q.sigma))
                      .String("unit", q.unit)
                      .String("source", q.source)
                      .str());
  }
  core::JsonObject root;
  root.Int("version", 1).String("command", "heatwave calibrate bench");
  root.String("verdict", c.verdict).String("verdict_is", VerdictLine(c));
  root.String("software", c.software).String("date_utc", c.created_utc);
  root.String("session", c.session).String("qa_profile", c.profile).Add("ids", ids.str());
  root.Add("parts", core::JsonArray(parts, "  "));
  root.Add("rig", core::JsonObject()
                      .String("file", c.rig_file)
                      .String("sigma_is", "1 sigma, from the part's estimate")
                      .Add("quantities", core::JsonArray(rig, "    "))
                      .str());
  if (!c.truth.empty()) {
    std::vector<std::string> rows;
    for (const TruthRow& t : c.truth) {
      rows.push_back(core::JsonObject()
                         .String("quantity", t.name)
                         .Number("calibrated", t.value)
                         .Number("truth", t.truth)
                         .Number("error", t.value - t.truth)
                         .Add("sigma", OptionalJson(t.sigma))
                         .Add("error_in_sigmas", t.sigma && *t.sigma > 0 ? core::JsonNumber((t.value - t.truth) / *t.sigma) : "null")
                         .String("unit", t.unit)
                         .str());
    }
    root.Add("fixture_truth_check",
             core::JsonObject()
                 .String("is", "a FIXTURE check, not QA: the calibrated rig against the synthetic session's true rig; it "
                               "does not enter the verdict")
                 .String("truth", c.truth_file)
                 .Add("quantities", core::JsonArray(rows, "    "))
                 .str());
  }
  return root.str() + "\n";
}

Document CertificateDocument(const Certificate& c, const fs::path& folder) {
  Document doc;
  doc.cover.title = "Calibration certificate: " + c.verdict;  // the banner: the verdict first
  doc.cover.subtitle = VerdictLine(c);
  std::string rig_serial;
  for (const auto& [key, value] : c.ids) {
    if (key == "rig_serial") rig_serial = value;
  }
  doc.cover.facts.rows = {{"Verdict", c.verdict}};
  for (const auto& [key, value] : c.ids) doc.cover.facts.rows.push_back({key, value});
  doc.cover.facts.rows.push_back({"Software", c.software});
  doc.cover.facts.rows.push_back({"Date (UTC)", c.created_utc});
  doc.cover.facts.rows.push_back({"Session", c.session});
  doc.cover.facts.rows.push_back({"QA profile", c.profile});
  Table& summary = doc.cover.summary;
  summary.header = {"Part", "Verdict", "Checks passed", "Time"};
  summary.numeric = {false, false, true, true};
  for (const CertificatePart& p : c.parts) {
    const bool ran = p.status == PartStatus::kPassed || p.status == PartStatus::kFailed;
    summary.rows.push_back({p.title, PartStatusName(p.status),
                            ran ? StringPrintf("%d of %zu", PassedChecks(p), p.checks.size()) : "—",
                            ran ? StringPrintf("%.2f s", p.seconds) : "—"});
    summary.tint_srgb8.push_back(StatusTint(p.status));
    summary.row_links.push_back(p.id);
  }
  summary.caption = "Overall: " + VerdictLine(c) + ".";
  doc.author = "heatwave calibrate bench";
  doc.subject = "Calibration certificate" + (rig_serial.empty() ? "" : " of rig " + rig_serial);
  doc.keywords = "calibration, certificate, intrinsics, depth correction, extrinsics, latency";
  doc.creator = c.software;
  doc.created_utc = c.created_utc;
  doc.footer = "Calibration certificate" + (rig_serial.empty() ? "" : " · " + rig_serial) + " · " + c.verdict;

  Section verdict{1, "verdict", "Verdict", {}, false};
  verdict.blocks.push_back(Paragraph{VerdictLine(c) + ".", c.verdict == "PASS" ? Paragraph::Style::kBody : Paragraph::Style::kWarning});
  verdict.blocks.push_back(Paragraph{"PASS only when every part of the bench ran and every check met its threshold. "
                                     "INCOMPLETE: parts were not run; the rig is not certified.",
                                     Paragraph::Style::kNote});
  doc.sections.push_back(verdict);

  for (const CertificatePart& p : c.parts) {
    Section s{1, p.id, p.title + " — " + PartStatusName(p.status), {}, false};
    if (!p.note.empty()) {
      s.blocks.push_back(Paragraph{p.note, p.status == PartStatus::kPassed || p.status == PartStatus::kFailed
                                               ? Paragraph::Style::kBody
                                               : Paragraph::Style::kWarning});
    }
    if (!p.checks.empty()) {
      Table t;
      t.header = {"Check", "What", "Measured", "Threshold", "Verdict"};
      t.numeric = {false, false, true, true, false};
      for (const CertificateCheck& q : p.checks) {
        t.rows.push_back({q.name, q.what, WithUnit(q.measured, q.unit), q.comparison + " " + WithUnit(q.threshold, q.unit),
                          q.pass ? "PASS" : "FAIL"});
        t.tint_srgb8.push_back(q.pass ? Tint(kGreen) : Tint(kRed));
      }
      t.caption = StringPrintf("%d of %zu checks passed; outputs in %s/.", PassedChecks(p), p.checks.size(), p.id.c_str());
      s.blocks.push_back(t);
    }
    if (!p.images.empty()) {
      FigureGrid grid;
      grid.columns = 2;
      for (const CertificateImage& im : p.images) {
        const fs::path png = folder / im.path;
        const pdf::PixelSize size = pdf::ProbePng(png);
        grid.figures.push_back(Figure{png, size.width, size.height, im.caption, std::nullopt});
      }
      s.blocks.push_back(grid);
    }
    doc.sections.push_back(s);
  }

  Section rig{1, "rig", "Calibrated rig", {}, false};
  if (!c.rig.empty()) {
    Table t;
    t.header = {"Quantity", "Value", "1 sigma", "Source"};
    t.numeric = {false, true, true, false};
    for (const RigQuantity& q : c.rig) {
      t.rows.push_back({q.name, WithUnit(q.value, q.unit), q.sigma ? WithUnit(*q.sigma, q.unit) : "—", q.source});
    }
    t.caption = "The rig written to " + c.rig_file + " (cameras as in rig.yaml; sigma from each part's estimate).";
    rig.blocks.push_back(t);
  } else {
    rig.blocks.push_back(Paragraph{"No rig was calibrated.", Paragraph::Style::kWarning});
  }
  doc.sections.push_back(rig);

  if (!c.truth.empty()) {
    Section truth{1, "truth", "Fixture check against the session's truth (not QA)", {}, false};
    truth.blocks.push_back(Paragraph{"The session is synthetic: " + c.truth_file +
                                         " is the rig that rendered it. This comparison tests the bench itself; it is "
                                         "not a QA check and does not enter the verdict.",
                                     Paragraph::Style::kNote});
    Table t;
    t.header = {"Quantity", "Calibrated", "Truth", "Error", "Error / sigma"};
    t.numeric = {false, true, true, true, true};
    for (const TruthRow& r : c.truth) {
      t.rows.push_back({r.name, WithUnit(r.value, r.unit), WithUnit(r.truth, r.unit), WithUnit(r.value - r.truth, r.unit),
                        r.sigma && *r.sigma > 0 ? StringPrintf("%+.2f", (r.value - r.truth) / *r.sigma) : "—"});
    }
    truth.blocks.push_back(t);
    doc.sections.push_back(truth);
  }
  return doc;
}

std::vector<std::string> WriteCertificate(const Certificate& c, const fs::path& folder) {
  const Document doc = CertificateDocument(c, folder);
  core::WriteFileAtomically(folder / "certificate.json", CertificateJson(c));
  WriteHtml(doc, folder / "certificate.html");
  WritePdf(doc, folder / "certificate.pdf");
  return {"certificate.json", "certificate.html", "certificate.pdf"};
}

}  // namespace hw::report
