#include "report/report_model.h"

#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/strings.h"
#include "report/report_test_support.h"
#include "tests/support.h"

namespace hw::report {
namespace {

namespace fs = std::filesystem;

const Table* FindTable(const Section& s) {
  for (const Block& b : s.blocks) {
    if (const auto* t = std::get_if<Table>(&b)) return t;
  }
  return nullptr;
}

const Section* FindSection(const Document& doc, const std::string& anchor) {
  for (const Section& s : doc.sections) {
    if (s.anchor == anchor) return &s;
  }
  return nullptr;
}

std::string ErrorOf(const ReportInputs& in) {
  try {
    BuildDocument(in);
  } catch (const core::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ReportModelTest, Formatting) {
  EXPECT_EQ(FormatWithSigma(0.6704, 0.0096, 100, "cm"), "67.04 ± 0.96 cm");
  EXPECT_EQ(FormatWithSigma(0.6704, 0.012, 100, "cm"), "67.0 ± 1.2 cm");
  EXPECT_EQ(FormatWithSigma(0.024866, 0.0036816, 1e4, "cm²"), "249 ± 37 cm²");
  EXPECT_EQ(FormatArea(0.024866, 0.0036816), "249 ± 37 cm²");
  EXPECT_EQ(FormatArea(1.234, 0.05), "1.234 ± 0.050 m²");  // two significant digits of σ
  EXPECT_EQ(FormatLength(1.5, std::nan("")), "1.5 m");
  EXPECT_EQ(FormatCelsius(27.849), "27.8 °C");
  EXPECT_EQ(FormatCelsius(std::nan("")), "—");
}

TEST(ReportModelTest, BuildsEverySectionFromARealAnalysis) {
  const fs::path folder = hw::test::TestFolder();
  const test::PlateAnalysis plate = test::MakePlateAnalysis(folder);
  ASSERT_TRUE(plate.result.detection);
  ASSERT_EQ(plate.result.detection->spots.size(), 1u);
  const analyze::Spot& spot = plate.result.detection->spots[0];
  ReportInputs in;
  in.analyze_json = plate.analyze_json;
  in.model_ply = plate.model_ply;
  in.job = test::TestJob();
  const Document doc = BuildDocument(in);

  EXPECT_EQ(doc.cover.subtitle, "Plant room 2 — ACME Ltd");
  EXPECT_EQ(doc.created_utc, "2026-12-01T09:30:00Z");
  EXPECT_EQ(doc.footer, "Report HW-TEST-7 · ACME Ltd · Plant room 2");
  ASSERT_TRUE(doc.cover.hero);
  EXPECT_TRUE(doc.cover.hero->key);
  // Summary by severity: the one hot spot in its band, and the total.
  int hot_total = 0;
  for (const auto& row : doc.cover.summary.rows) {
    if (row[0] == "Total") hot_total = std::stoi(row[2]);
  }
  EXPECT_EQ(hot_total, 1);

  const Section* spots = FindSection(doc, "spots");
  ASSERT_NE(spots, nullptr);
  const Table* table = FindTable(*spots);
  ASSERT_NE(table, nullptr);
  ASSERT_EQ(table->rows.size(), 1u);
  EXPECT_EQ(table->rows[0][0], spot.id);
  EXPECT_EQ(table->rows[0][3], FormatCelsius(spot.peak_c));
  EXPECT_EQ(table->rows[0][5], FormatArea(spot.area_m2, spot.area_sigma_m2));
  EXPECT_EQ(table->rows[0][6], FormatLength(spot.length_m, spot.length_sigma_m));
  EXPECT_EQ(table->row_links[0], "spot-h1");
  // π (0.1 m)² = 314 cm²: the text shows the analysis' measurement.
  EXPECT_NEAR(spot.area_m2, M_PI * 0.01, 0.05 * M_PI * 0.01);

  const Section* detail = FindSection(doc, "spot-h1");
  ASSERT_NE(detail, nullptr);
  EXPECT_EQ(detail->level, 2);
  bool close_ups = false;
  for (const Block& b : detail->blocks) {
    if (const auto* g = std::get_if<FigureGrid>(&b)) close_ups = g->figures.size() == 4;
  }
  EXPECT_TRUE(close_ups);
  const Section* overview = FindSection(doc, "overview");
  ASSERT_NE(overview, nullptr);
  const auto& grid = std::get<FigureGrid>(overview->blocks[1]);
  ASSERT_EQ(grid.figures.size(), 4u);
  EXPECT_FALSE(grid.figures[1].key);  // the colour view has no colour bar
  ASSERT_TRUE(grid.figures[3].key);
  EXPECT_EQ(grid.figures[3].key->mode, analyze::ViewMode::kHighlight);

  ASSERT_TRUE(doc.model_view);
  ASSERT_EQ(doc.model_view->markers.size(), 1u);
  EXPECT_EQ(doc.model_view->markers[0].anchor, "spot-h1");
  EXPECT_LT(doc.model_view->markers[0].position_in_world.norm(), 0.1);  // the peak is on the disc
  for (const char* anchor : {"summary", "inspection", "equipment", "scan", "method", "disclaimer"}) {
    EXPECT_NE(FindSection(doc, anchor), nullptr) << anchor;
  }
}

// A spot measured with a coarse thermal image: its detail says how many pixels across it was
// and that it is under-resolved, and the analysis' warning is in the report.
TEST(ReportModelTest, SpotDetailGivesTheThermalResolution) {
  const fs::path folder = hw::test::TestFolder();
  for (const double footprint_m : {0.1, 0.005}) {
    const test::PlateAnalysis plate = test::MakePlateAnalysis(folder / std::to_string(footprint_m), footprint_m);
    ReportInputs in;
    in.analyze_json = plate.analyze_json;
    in.model_ply = plate.model_ply;
    in.job = test::TestJob();
    const Document doc = BuildDocument(in);
    ASSERT_EQ(plate.result.detection->spots.size(), 1u);
    const double width_px = plate.result.detection->spots[0].width_px;
    EXPECT_NEAR(width_px, 0.2 / footprint_m, 0.02 / footprint_m);  // the 20 cm disc
    const Section* detail = FindSection(doc, "spot-h1");
    ASSERT_NE(detail, nullptr);
    std::string resolution;
    for (const Block& b : detail->blocks) {
      if (const auto* kv = std::get_if<KeyValues>(&b)) {
        for (const auto& row : kv->rows) {
          if (row.first == "Thermal resolution") resolution = row.second;
        }
      }
    }
    bool warned = false;
    for (const Section& s : doc.sections) {
      for (const Block& b : s.blocks) {
        if (const auto* p = std::get_if<Paragraph>(&b)) warned |= p->text.find("under-resolved") != std::string::npos;
      }
    }
    if (footprint_m > 0.05) {
      EXPECT_EQ(resolution, core::StringPrintf("%.1f", width_px) +
                                " thermal pixels across (one pixel covers 100.0 mm of the surface); under-resolved: "
                                "the peak and ΔT read low and the size high");
      EXPECT_TRUE(warned);
    } else {
      EXPECT_EQ(resolution, core::StringPrintf("%.1f", width_px) + " thermal pixels across (one pixel covers 5.0 mm of the surface)");
      EXPECT_FALSE(warned);
    }
  }
}

// The reflection check's verdict is in the spot's detail: the disc seen head-on from 1.5 m
// is no reflection at 50 °C (warmer than a person), and is one when people may look 60 °C.
TEST(ReportModelTest, SpotDetailGivesTheReflectionCheck) {
  const fs::path folder = hw::test::TestFolder();
  for (const double operator_max_c : {37.0, 60.0}) {
    const test::PlateAnalysis plate = test::MakePlateAnalysis(folder / std::to_string(operator_max_c), std::nan(""),
                                                              Eigen::Vector3d(0, 0, 1.5), operator_max_c);
    ReportInputs in;
    in.analyze_json = plate.analyze_json;
    in.model_ply = plate.model_ply;
    in.job = test::TestJob();
    const Document doc = BuildDocument(in);
    const Section* detail = FindSection(doc, "spot-h1");
    ASSERT_NE(detail, nullptr);
    std::string check, action;
    for (const Block& b : detail->blocks) {
      if (const auto* kv = std::get_if<KeyValues>(&b)) {
        for (const auto& row : kv->rows) {
          if (row.first == "Reflection check") check = row.second;
          if (row.first == "Suggested action") action = row.second;
        }
      }
    }
    // The disc's faces are 0-3.8° from head-on (atan(10 cm / 1.5 m)), 2.5° on the area's mean.
    if (operator_max_c < 50) {
      EXPECT_EQ(check, "seen 3° from head-on; the mirror direction meets nothing as warm as the spot: not flagged as a reflection");
      EXPECT_EQ(action.find("Verify first"), std::string::npos) << action;
    } else {
      EXPECT_EQ(check, "seen 3° from head-on; over 100 % of the spot the mirror direction returns to the thermographer: "
                       "possibly a reflection — re-image from another angle before acting");
      EXPECT_EQ(action.find("Verify first: possibly the thermographer's own reflection"), 0u) << action;
    }
    // The summary says so (or not), and the method describes the check.
    const Section* summary = FindSection(doc, "summary");
    const Section* method = FindSection(doc, "method");
    ASSERT_NE(summary, nullptr);
    ASSERT_NE(method, nullptr);
    const auto text_of = [](const Section& section) {
      std::string text;
      for (const Block& b : section.blocks) {
        if (const auto* p = std::get_if<Paragraph>(&b)) text += p->text;
      }
      return text;
    };
    EXPECT_EQ(text_of(*summary).find("1 of them (H1) may be a reflection") != std::string::npos, operator_max_c > 50)
        << text_of(*summary);
    EXPECT_NE(text_of(*method).find("checked for reflections"), std::string::npos);
  }
  // Without view vectors, no row.
  const test::PlateAnalysis plain = test::MakePlateAnalysis(folder / "plain");
  ReportInputs in;
  in.analyze_json = plain.analyze_json;
  in.model_ply = plain.model_ply;
  in.job = test::TestJob();
  const Document doc = BuildDocument(in);
  const Section* detail = FindSection(doc, "spot-h1");
  ASSERT_NE(detail, nullptr);
  for (const Block& b : detail->blocks) {
    if (const auto* kv = std::get_if<KeyValues>(&b)) {
      for (const auto& row : kv->rows) EXPECT_NE(row.first, "Reflection check");
    }
  }
}

TEST(ReportModelTest, BadAnalysisFilesNameFileAndField) {
  const fs::path folder = hw::test::TestFolder();
  const test::PlateAnalysis plate = test::MakePlateAnalysis(folder);
  ReportInputs in;
  in.job = test::TestJob();
  in.analyze_json = folder / "missing.json";
  EXPECT_NE(ErrorOf(in).find("missing.json"), std::string::npos);

  std::string json = core::ReadFile(plate.analyze_json, 1 << 26);
  auto write_variant = [&](const std::string& from, const std::string& to) {
    std::string text = json;
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
    in.analyze_json = folder / "analysis" / "variant.json";
    core::WriteFileAtomically(in.analyze_json, text);
    return ErrorOf(in);
  };
  EXPECT_EQ(write_variant("\"area_m2\": ", "\"area_x\": "),
            (folder / "analysis" / "variant.json").string() + ": mesh.area_m2: missing");
  EXPECT_NE(write_variant("\"peak_c\": ", "\"peak_c\": \"hot\", \"x\": ").find("spots[0].peak_c: must be a number, got string"),
            std::string::npos);
  EXPECT_NE(write_variant("\"has_temperature\": true", "\"has_temperature\": false").find("the model has no temperature"),
            std::string::npos);
  EXPECT_NE(write_variant("{", "[").find("not valid JSON"), std::string::npos);
  EXPECT_NE(write_variant("\"file\": \"images/", "\"file\": \"../../etc/").find("must be a path inside the analysis folder"), std::string::npos);
  // An image listed but gone.
  in.analyze_json = plate.analyze_json;
  fs::remove(folder / "analysis" / plate.result.images[0].file);
  EXPECT_NE(ErrorOf(in).find("missing: analyze.json lists this image"), std::string::npos);
}

}  // namespace
}  // namespace hw::report
