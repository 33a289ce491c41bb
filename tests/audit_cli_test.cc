// End-to-end tests of `heatwave audit` and `heatwave report`: the whole chain on a synthetic
// scan, the PDF read back with poppler-utils, determinism, markup in the job file, and what
// bad inputs do (one clear line, no half-written report).
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include <unistd.h>

#include "core/atomic_file.h"
#include "reconstruct/reconstruct_test_support.h"
#include "report/browser_check.h"
#include "report/report_model.h"
#include "report/report_test_support.h"
#include "report/screenshot_test_support.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::FreshPath;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) { return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args); }

std::string Read(const fs::path& path) { return hw::core::ReadFile(path, uint64_t{1} << 30); }

bool HavePoppler() { return std::system("command -v pdftotext >/dev/null 2>&1 && command -v pdffonts >/dev/null 2>&1") == 0; }

// A job whose free text is full of markup, script and PDF syntax: all of it must print as text.
const std::string kHostileJob =
    "version: 1\n"
    "reference: \"R-1 <b>bold</b>\"\n"
    "client: {name: \"<script>document.documentElement.dataset.hwInjected=1</script>ACME & Sons\"}\n"
    "site: {name: \"Site ) ( \\\\ %PDF-1.4\"}\n"
    "inspection: {date: 2026-11-30, inspector: {name: \"A. Inspector\"}}\n"
    "conditions: {emissivity: 0.9, reflected_c: 19.5}\n"
    "notes: \"</p><img src=x onerror=alert(1)><p> 100% sure\"\n";

fs::path ThermalScan() {
  hw::fixtures::SynthScanOptions o = hw::reconstruct::test::TestScanOptions();
  o.write_thermal = true;
  return hw::reconstruct::test::CachedScan("smooth-thermal", o);
}

TEST(AuditCli, AuditsAScanEndToEnd) {
  const fs::path folder = TestFolder();
  hw::core::WriteFileAtomically(folder / "job.yaml", kHostileJob);
  const fs::path out = folder / "audit";
  const Result r = Heatwave("audit " + ThermalScan().string() + " --job " + (folder / "job.yaml").string() + " --out " +
                            out.string() + " --voxel-size 0.01 --3d-max-faces 5000");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* name : {"model.ply", "trajectory.txt", "reconstruct.json", "analyze.json", "images", "report.html",
                           "report.pdf"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  EXPECT_FALSE(fs::exists(out / ".heatwave-run"));
  EXPECT_NE(r.output.find("[1/3] reconstruct"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("[3/3] report"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Audit      " + out.string()), std::string::npos) << r.output;
  // The on-site emissivity and reflected temperature replaced the rig's.
  EXPECT_NE(Read(out / "reconstruct.json").find("on-site values: 0.900 everywhere, reflected 19.50"), std::string::npos);
  const std::string html = Read(out / "report.html");
  EXPECT_EQ(html.find("<script>document"), std::string::npos);
  EXPECT_NE(html.find("&lt;script&gt;document.documentElement.dataset.hwInjected=1&lt;/script&gt;ACME &amp; Sons"),
            std::string::npos);
  EXPECT_EQ(html.find("<img src=x"), std::string::npos);
  // The scan's record says that frame selection skipped thermal frames (a client reading
  // "8 of 24 fused" alone would ask where the rest went).
  EXPECT_NE(html.find(" fused (the sharpest of each 0.09 s), "), std::string::npos);
  if (!HavePoppler()) GTEST_SKIP() << "poppler-utils not installed (scripts/install-deps.sh installs them)";
  const Result text = hw::test::RunCommand("pdftotext -enc UTF-8 " + (out / "report.pdf").string() + " -");
  ASSERT_EQ(text.exit_code, 0) << text.output;
  EXPECT_NE(text.output.find("<script>document.documentElement.dataset.hwInjected=1</script>ACME & Sons"),
            std::string::npos);
  EXPECT_NE(text.output.find("Site ) ( \\ %PDF-1.4"), std::string::npos);
  EXPECT_NE(text.output.find("</p><img src=x onerror=alert(1)><p> 100% sure"), std::string::npos);
}

TEST(AuditCli, ReportIsByteIdenticalAndCarriesTheAnalysisNumbers) {
  const fs::path folder = TestFolder();
  const hw::report::test::PlateAnalysis plate = hw::report::test::MakePlateAnalysis(folder);
  hw::core::WriteFileAtomically(folder / "job.yaml", kHostileJob);
  const std::string base = "report " + (folder / "analysis").string() + " --job " + (folder / "job.yaml").string() +
                           " --model " + plate.model_ply.string() + " --3d-max-faces 2000 -q --out ";
  const Result a = Heatwave(base + (folder / "a").string());
  ASSERT_EQ(a.exit_code, 0) << a.output;
  const Result b = Heatwave(base + (folder / "b").string());
  ASSERT_EQ(b.exit_code, 0) << b.output;
  EXPECT_TRUE(Read(folder / "a" / "report.pdf") == Read(folder / "b" / "report.pdf")) << "PDF bytes differ";
  EXPECT_TRUE(Read(folder / "a" / "report.html") == Read(folder / "b" / "report.html")) << "HTML bytes differ";
  // Writing again over an existing report needs --overwrite.
  const Result again = Heatwave(base + (folder / "a").string());
  EXPECT_EQ(again.exit_code, 2) << again.output;
  EXPECT_NE(again.output.find("pass --overwrite"), std::string::npos) << again.output;

  if (!HavePoppler()) GTEST_SKIP() << "poppler-utils not installed (scripts/install-deps.sh installs them)";
  const fs::path pdf = folder / "a" / "report.pdf";
  const Result text = hw::test::RunCommand("pdftotext -enc UTF-8 -layout " + pdf.string() + " -");
  ASSERT_EQ(text.exit_code, 0) << text.output;
  const hw::analyze::Spot& spot = plate.result.detection->spots.at(0);
  for (const std::string& cell :
       {hw::report::FormatCelsius(spot.peak_c), hw::report::FormatArea(spot.area_m2, spot.area_sigma_m2),
        hw::report::FormatLength(spot.length_m, spot.length_sigma_m), std::string("Hot and cold spots")}) {
    EXPECT_NE(text.output.find(cell), std::string::npos) << cell << "\n" << text.output;
  }
  // Every font embedded: pdffonts prints "name type encoding emb sub uni object ID" rows.
  const Result fonts = hw::test::RunCommand("pdffonts " + pdf.string());
  ASSERT_EQ(fonts.exit_code, 0) << fonts.output;
  int rows = 0;
  std::istringstream lines(fonts.output);
  std::string line;
  for (int i = 0; std::getline(lines, line); ++i) {
    if (i < 2 || line.empty()) continue;
    ++rows;
    EXPECT_NE(line.find(" yes "), std::string::npos) << "not embedded: " << line;
  }
  EXPECT_GT(rows, 0) << fonts.output;
  const Result info = hw::test::RunCommand("pdfinfo " + pdf.string());
  EXPECT_NE(info.output.find("A4"), std::string::npos) << info.output;
  EXPECT_NE(info.output.find("CreationDate:    Mon Nov 30 00:00:00 2026"), std::string::npos)
      << "the creation date comes from the job, not the clock\n" << info.output;
}

// The whole report opened in headless Chromium with the network blocked: the 3D view
// renders with no Content-Security-Policy violation, its canvas is not blank, and the
// hostile job's script never ran.
TEST(AuditCli, ReportOpensOfflineInChromiumWith3dView) {
  if (access("/usr/bin/chromium", X_OK) != 0) {
    GTEST_SKIP() << "/usr/bin/chromium absent: install it with scripts/install-deps.sh";
  }
  const fs::path folder = TestFolder();
  const hw::report::test::PlateAnalysis plate = hw::report::test::MakePlateAnalysis(folder);
  hw::core::WriteFileAtomically(folder / "job.yaml", kHostileJob);
  const Result r = Heatwave("report " + (folder / "analysis").string() + " --job " + (folder / "job.yaml").string() +
                            " --model " + plate.model_ply.string() + " --no-pdf -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const hw::report::BrowserResult page =
      hw::report::OpenInHeadlessChromium(folder / "analysis" / "report.html", 1000, 800, 90, "view=full");
  ASSERT_TRUE(page.available) << page.reason;
  EXPECT_EQ(page.exit_code, 0) << page.reason;
  EXPECT_NE(page.dom.find("data-hw-viewer=\"rendered\""), std::string::npos) << page.dom.substr(0, 400);
  EXPECT_EQ(page.dom.find("data-hw-csp-violations"), std::string::npos) << "the page tried a forbidden request";
  EXPECT_EQ(page.dom.find("data-hw-injected"), std::string::npos) << "the job file's script ran";
  // The markup is in the page as text (serialised back escaped), in the cover and the footer.
  EXPECT_NE(page.dom.find("&lt;script&gt;document.documentElement.dataset.hwInjected=1&lt;/script&gt;ACME &amp; Sons"),
            std::string::npos);
  EXPECT_NE(page.dom.find("&lt;/p&gt;&lt;img src=x onerror=alert(1)&gt;&lt;p&gt; 100% sure"), std::string::npos);
  ASSERT_FALSE(page.screenshot_png.empty()) << page.reason;
  // Opened full-window (#view=full), the 3D view fills the screenshot. An empty canvas is
  // flat (variance ≈ 0); the plate on the iron palette with its hot disc is not.
  EXPECT_GT(hw::report::test::GreyVariance(page.screenshot_png, 0, 0, 1000, 800), 100.0);
  fs::remove_all(page.screenshot_png.parent_path());
}

TEST(AuditCli, BadInputsAreOneLineAndLeaveNoReport) {
  const fs::path folder = TestFolder();
  const hw::report::test::PlateAnalysis plate = hw::report::test::MakePlateAnalysis(folder);
  const fs::path analysis = folder / "analysis";
  // A job with a misspelt key: named with its line; nothing written.
  hw::core::WriteFileAtomically(folder / "typo.yaml", "version: 1\nclinet: {name: X}\n");
  Result r = Heatwave("report " + analysis.string() + " --job " + (folder / "typo.yaml").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output, "error: " + (folder / "typo.yaml").string() + ": top level: unknown key 'clinet' (line 2)\n");
  EXPECT_FALSE(fs::exists(analysis / "report.html"));
  r = Heatwave("audit " + ThermalScan().string() + " --job " + (folder / "typo.yaml").string() + " --out " +
               (folder / "never").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_FALSE(fs::exists(folder / "never"));
  // A wrong type.
  hw::core::WriteFileAtomically(folder / "type.yaml", hw::report::test::TestJob().title.empty() ? "" :
      "version: 1\nclient: {name: C}\nsite: {name: S}\ninspection: {date: 2026-11-30, inspector: {name: I}}\n"
      "conditions: {ambient_c: warm}\n");
  r = Heatwave("report " + analysis.string() + " --job " + (folder / "type.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("conditions.ambient_c: must be a number, got 'warm' (line 5)"), std::string::npos) << r.output;

  hw::core::WriteFileAtomically(folder / "job.yaml", kHostileJob);
  const std::string job = " --job " + (folder / "job.yaml").string();
  // An analyze.json missing a field.
  std::string json = Read(analysis / "analyze.json");
  const size_t at = json.find("\"area_sigma_m2\"");
  ASSERT_NE(at, std::string::npos);
  json.replace(at, 15, "\"area_sigma\"");
  const fs::path broken = folder / "broken";
  fs::create_directories(broken);
  fs::copy(analysis / "images", broken / "images", fs::copy_options::recursive);
  hw::core::WriteFileAtomically(broken / "analyze.json", json);
  r = Heatwave("report " + broken.string() + job);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.output, "error: " + (broken / "analyze.json").string() + ": spots[0].area_sigma_m2: missing\n");
  EXPECT_FALSE(fs::exists(broken / "report.html"));
  EXPECT_FALSE(fs::exists(broken / "report.pdf"));
  // A model without temperature.
  hw::core::PlyMesh ply = hw::core::ReadPly(plate.model_ply);
  ply.RemoveProperty("temperature_c");
  hw::core::WritePly(folder / "cold.ply", ply);
  ASSERT_EQ(Heatwave("analyze " + (folder / "cold.ply").string() + " --out " + (folder / "cold").string() + " --no-images -q")
                .exit_code,
            0);
  r = Heatwave("report " + (folder / "cold").string() + job);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("the model has no temperature"), std::string::npos) << r.output;
  // --out is a file.
  hw::core::WriteFileAtomically(folder / "file", "x");
  r = Heatwave("report " + analysis.string() + job + " --out " + (folder / "file").string());
  EXPECT_EQ(r.exit_code, 1);
  // One error line, the last (progress lines may come before it), naming the file.
  const size_t error_at = r.output.find("error: ");
  ASSERT_NE(error_at, std::string::npos) << r.output;
  EXPECT_NE(r.output.find((folder / "file").string(), error_at), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find('\n', error_at), r.output.size() - 1) << r.output;
  r = Heatwave("audit " + ThermalScan().string() + job + " --out " + (folder / "file").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output.rfind("error: ", 0), 0u) << r.output;  // before any stage: no progress line
  EXPECT_NE(r.output.find((folder / "file").string()), std::string::npos) << r.output;
  // A non-empty audit folder without --overwrite, and bad options.
  r = Heatwave("audit " + ThermalScan().string() + job + " --out " + analysis.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("pass --overwrite"), std::string::npos) << r.output;
  r = Heatwave("audit " + ThermalScan().string() + job + " --out " + (folder / "x").string() + " --voxel-size 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_FALSE(fs::exists(folder / "x"));
}

}  // namespace
