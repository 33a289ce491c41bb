#include "report/certificate.h"

#include <cairo.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"

namespace hw::report {
namespace {

namespace fs = std::filesystem;

bool HavePoppler() { return test::RunCommand("pdftotext -v").exit_code == 0; }

void WritePng(const fs::path& path, int w, int h) {
  fs::create_directories(path.parent_path());
  cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h);
  cairo_t* cr = cairo_create(surface);
  cairo_set_source_rgb(cr, 0.2, 0.4, 0.8);
  cairo_paint(cr);
  cairo_destroy(cr);
  ASSERT_EQ(cairo_surface_write_to_png(surface, path.c_str()), CAIRO_STATUS_SUCCESS);
  cairo_surface_destroy(surface);
}

CertificateCheck Check(const std::string& name, double measured, double threshold, const std::string& unit) {
  return {name, "what " + name, measured, "<=", threshold, unit, measured <= threshold};
}

// Three parts: one passes, one fails a check, one was not run.
Certificate MakeCertificate(const fs::path& folder) {
  WritePng(folder / "intrinsics-thermal" / "diagnostics" / "residuals.png", 64, 48);
  Certificate c;
  c.software = "heatwave 9.9.9";
  c.created_utc = "2026-12-02T17:00:00Z";
  c.session = "/data/session-42";
  c.profile = "defaults";
  c.ids = {{"rig_serial", "HW-R-0042"}, {"thermal_serial", "TH-17"}};
  CertificatePart thermal{"intrinsics-thermal", "Thermal camera intrinsics", PartStatus::kPassed, "opencv5 from 20 views", {}, {}, 1.25};
  thermal.checks = {Check("rms_px", 0.0731, 0.5, "px"), Check("uncertainty_px", 0.321, 0.5, "px")};
  thermal.images = {{"intrinsics-thermal/diagnostics/residuals.png", "Residuals"}};
  CertificatePart latency{"latency", "Clock offsets", PartStatus::kFailed, "", {}, {}, 0.5};
  latency.checks = {Check("rgb_sigma_ms", 4.656, 2, "ms"), Check("thermal_sigma_ms", 1.5, 2, "ms")};
  CertificatePart colour{"intrinsics-rgb", "Colour camera intrinsics", PartStatus::kNotRun,
                         "missing: /data/session-42/intrinsics-rgb", {}, {}, 0};
  c.parts = {thermal, colour, latency};
  c.verdict = CertificateVerdict(c.parts);
  c.rig = {{"thermal fx", 148.37, 0.21, "px", "intrinsics-thermal"}, {"rgb fx", 258.8, std::nullopt, "px", "nominal (not calibrated)"}};
  c.truth = {{"thermal fx", 148.37, 148.5, 0.21, "px"}};
  c.truth_file = "/data/session-42/truth/rig.yaml";
  return c;
}

TEST(Certificate, VerdictFailDominatesIncomplete) {
  CertificatePart pass{"a", "A", PartStatus::kPassed, "", {}, {}, 0};
  CertificatePart fail{"b", "B", PartStatus::kFailed, "", {}, {}, 0};
  CertificatePart error{"c", "C", PartStatus::kError, "", {}, {}, 0};
  CertificatePart missing{"d", "D", PartStatus::kNotRun, "", {}, {}, 0};
  EXPECT_EQ(CertificateVerdict({pass, pass}), "PASS");
  EXPECT_EQ(CertificateVerdict({pass, missing}), "INCOMPLETE");
  EXPECT_EQ(CertificateVerdict({pass, missing, fail}), "FAIL");
  EXPECT_EQ(CertificateVerdict({pass, error}), "FAIL");
  EXPECT_EQ(CertificateVerdict({}), "INCOMPLETE");  // nothing run certifies nothing
}

TEST(Certificate, JsonHasEveryCheckAndTheTruthApart) {
  const fs::path folder = test::TestFolder();
  const Certificate c = MakeCertificate(folder);
  const std::string json = CertificateJson(c);
  EXPECT_NE(json.find("\"verdict\": \"FAIL\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"verdict_is\": \"FAIL — failed: latency; not run: intrinsics-rgb\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"software\": \"heatwave 9.9.9\""), std::string::npos);
  EXPECT_NE(json.find("\"date_utc\": \"2026-12-02T17:00:00Z\""), std::string::npos);
  EXPECT_NE(json.find("\"rig_serial\": \"HW-R-0042\""), std::string::npos);
  EXPECT_NE(json.find("{\"check\": \"rgb_sigma_ms\", \"what\": \"what rgb_sigma_ms\", \"measured\": 4.656, \"comparison\": "
                      "\"<=\", \"threshold\": 2, \"unit\": \"ms\", \"verdict\": \"FAIL\"}"),
            std::string::npos)
      << json;
  for (const char* name : {"rms_px", "uncertainty_px", "thermal_sigma_ms"}) {
    EXPECT_NE(json.find("\"check\": \"" + std::string(name) + "\""), std::string::npos) << name;
  }
  EXPECT_NE(json.find("\"verdict\": \"NOT RUN\""), std::string::npos);
  EXPECT_NE(json.find("\"sigma\": null"), std::string::npos);  // a nominal value has no sigma
  EXPECT_NE(json.find("\"fixture_truth_check\": {\"is\": \"a FIXTURE check, not QA"), std::string::npos);
  EXPECT_NE(json.find("\"truth\": 148.5, \"error\": -0.1"), std::string::npos) << json;
}

TEST(Certificate, HtmlAndPdfSayTheSame) {
  const fs::path folder = test::TestFolder();
  const Certificate c = MakeCertificate(folder);
  const std::vector<std::string> written = WriteCertificate(c, folder);
  ASSERT_EQ(written.size(), 3u);
  const std::string html = core::ReadFile(folder / "certificate.html", 1 << 24);
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);  // the residual image inline
  EXPECT_EQ(html.find("residuals.png\""), std::string::npos);         // not linked
  for (const CertificatePart& p : c.parts) {
    for (const CertificateCheck& q : p.checks) EXPECT_NE(html.find(q.name), std::string::npos) << q.name;
  }
  for (const char* text : {"FAIL — failed: latency; not run: intrinsics-rgb", "HW-R-0042", "heatwave 9.9.9",
                           "2026-12-02T17:00:00Z", "4.656 ms", "NOT RUN", "not QA", "nominal (not calibrated)"}) {
    EXPECT_NE(html.find(text), std::string::npos) << text;
  }
  if (!HavePoppler()) GTEST_SKIP() << "pdftotext (poppler-utils) is not installed";
  const test::CommandResult pdf = test::RunCommand("pdftotext '" + (folder / "certificate.pdf").string() + "' -");
  ASSERT_EQ(pdf.exit_code, 0) << pdf.output;
  for (const char* text : {"Calibration certificate", "HW-R-0042", "heatwave 9.9.9", "rms_px", "uncertainty_px",
                           "rgb_sigma_ms", "thermal_sigma_ms", "4.656 ms", "NOT RUN", "Fixture check", "148.37 px"}) {
    EXPECT_NE(pdf.output.find(text), std::string::npos) << text << "\n" << pdf.output;
  }
}

TEST(Certificate, AMissingImageIsAnInputError) {
  const fs::path folder = test::TestFolder();
  Certificate c = MakeCertificate(folder);
  c.parts[0].images.push_back({"nothing.png", "Nothing"});
  EXPECT_THROW(CertificateDocument(c, folder), core::InputError);
}

}  // namespace
}  // namespace hw::report
