#include "report/pdf_report.h"

#include <cairo.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "report/pdf_layout.h"
#include "tests/support.h"

namespace hw::report {
namespace {

namespace fs = std::filesystem;

bool HavePoppler() { return test::RunCommand("pdftotext -v").exit_code == 0; }

#define REQUIRE_POPPLER() \
  if (!HavePoppler()) GTEST_SKIP() << "pdftotext (poppler-utils) is not installed"

// A w × h PNG: a diagonal gradient with a bright disc, so the JPEG has something to encode.
fs::path WritePng(const fs::path& folder, const std::string& name, int w, int h, double hue) {
  cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h);
  cairo_t* cr = cairo_create(surface);
  cairo_pattern_t* gradient = cairo_pattern_create_linear(0, 0, w, h);
  cairo_pattern_add_color_stop_rgb(gradient, 0, 0.1, 0.0, 0.3 + 0.5 * hue);
  cairo_pattern_add_color_stop_rgb(gradient, 1, 1.0, 0.6 * hue, 0.1);
  cairo_set_source(cr, gradient);
  cairo_paint(cr);
  cairo_pattern_destroy(gradient);
  cairo_set_source_rgb(cr, 1, 1, 0.8);
  cairo_arc(cr, w * 0.6, h * 0.4, h * 0.15, 0, 2 * M_PI);
  cairo_fill(cr);
  cairo_destroy(cr);
  const fs::path path = folder / name;
  EXPECT_EQ(cairo_surface_write_to_png(surface, path.c_str()), CAIRO_STATUS_SUCCESS);
  cairo_surface_destroy(surface);
  return path;
}

ColourKey Key(analyze::ViewMode mode) {
  ColourKey key;
  key.mode = mode;
  key.span = {17.0, 39.1};
  key.band_low_c = 20;
  key.band_high_c = 30;
  return key;
}

Table SpotTable(int rows) {
  Table t;
  t.header = {"Spot", "Kind", "Peak", "ΔT", "Area"};
  t.numeric = {false, false, true, true, true};
  for (int r = 0; r < rows; ++r) {
    char peak[32], delta[32], area[32];
    std::snprintf(peak, sizeof(peak), "%.1f °C", 30.0 + r * 0.1);
    std::snprintf(delta, sizeof(delta), "+%.2f K", 1.0 + r * 0.01);
    std::snprintf(area, sizeof(area), "%.3f m²", 0.01 * (r + 1));
    t.rows.push_back({"H" + std::to_string(r + 1), r % 2 ? "cold spot" : "hot spot", peak, delta, area});
    t.tint_srgb8.push_back(r % 3 == 0 ? std::optional<std::array<std::uint8_t, 3>>({220, 60, 40}) : std::nullopt);
    t.row_links.push_back(r < 2 ? "spot-h" + std::to_string(r + 1) : "");
  }
  t.caption = "Spots by severity.";
  return t;
}

Document MakeDocument(const fs::path& folder) {
  Document doc;
  doc.cover.title = "Infrared thermography inspection report";
  doc.cover.subtitle = "Plant room 2, ACME Ltd";
  doc.cover.facts.rows = {{"Client", "ACME Ltd"}, {"Date", "2 December 2026"}, {"Inspector", "J. Smith\nLevel II"}};
  const fs::path thermal = WritePng(folder, "thermal.png", 160, 120, 0.2);
  const fs::path colour = WritePng(folder, "colour.png", 160, 120, 0.8);
  doc.cover.hero = Figure{thermal, 160, 120, "Overview, thermal", Key(analyze::ViewMode::kThermal)};
  doc.cover.summary = SpotTable(2);
  doc.author = "J. Smith";
  doc.subject = "ACME Ltd — Plant room 2";
  doc.keywords = "thermography, ASTM E1934";
  doc.creator = "heatwave test";
  doc.created_utc = "2026-12-02T10:00:00Z";
  doc.footer = "Report HW-0142 · ACME Ltd";

  Section intro{1, "intro", "Introduction", {}, false};
  intro.blocks.push_back(Paragraph{"The inspection covered the plant room.\nA second line.", Paragraph::Style::kBody});
  intro.blocks.push_back(Paragraph{"Emissivity assumed 0.95.", Paragraph::Style::kNote});
  intro.blocks.push_back(Paragraph{"Two hot spots need attention.", Paragraph::Style::kWarning});
  intro.blocks.push_back(KeyValues{{{"Camera", "FLIR-like 160×120"}, {"Ambient", "21.3 °C"}}});
  doc.sections.push_back(intro);

  Section findings{1, "findings", "Findings overview", {}, true};
  findings.blocks.push_back(SpotTable(3));
  FigureGrid grid;
  grid.columns = 2;
  grid.figures = {Figure{thermal, 160, 120, "Thermal", Key(analyze::ViewMode::kThermal)},
                  Figure{colour, 160, 120, "Colour", std::nullopt},
                  Figure{thermal, 160, 120, "IH", Key(analyze::ViewMode::kIhMapping)},
                  Figure{colour, 160, 120, "Highlight", Key(analyze::ViewMode::kHighlight)}};
  grid.caption = "Overview from the front.";
  findings.blocks.push_back(grid);
  doc.sections.push_back(findings);

  for (int s = 1; s <= 2; ++s) {
    Section spot{2, "spot-h" + std::to_string(s), "H" + std::to_string(s) + " hot spot detail", {}, false};
    spot.blocks.push_back(KeyValues{{{"Peak", "38.4 °C"}, {"Severity", "probable"}}});
    spot.blocks.push_back(FigureGrid{{Figure{thermal, 160, 120, "Close-up", Key(analyze::ViewMode::kThermal)}}, 2, ""});
    doc.sections.push_back(spot);
  }
  Section method{1, "method", "Method and standards", {}, false};
  method.blocks.push_back(Paragraph{std::string(60, 'x') + " end of method.", Paragraph::Style::kBody});
  doc.sections.push_back(method);
  return doc;
}

std::vector<std::string> PdfPages(const fs::path& pdf) {
  const test::CommandResult r = test::RunCommand("pdftotext -layout '" + pdf.string() + "' -");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::string> pages;
  std::stringstream in(r.output);
  std::string page;
  while (std::getline(in, page, '\f')) pages.push_back(page);
  if (!pages.empty() && pages.back().find_first_not_of(" \n") == std::string::npos) pages.pop_back();
  return pages;
}

std::string ReadAll(const fs::path& path) {
  return core::ReadFile(path, uint64_t{1} << 30);
}

// The value of `field` in pdfinfo's output ("Title:    value"), or "<absent>".
std::string InfoField(const std::string& output, const std::string& field) {
  std::smatch m;
  if (std::regex_search(output, m, std::regex("(^|\n)" + field + ": +([^\n]*)"))) return m[2];
  return "<absent>";
}

// 1-based page of the first page from `from` (1-based) whose text contains `needle`; 0 if none.
int PageOf(const std::vector<std::string>& pages, const std::string& needle, int from = 1) {
  for (size_t p = static_cast<size_t>(from - 1); p < pages.size(); ++p) {
    if (pages[p].find(needle) != std::string::npos) return static_cast<int>(p) + 1;
  }
  return 0;
}

// Pagination alone: a heading chain moves to the next page rather than end one, a table
// row that starts a page brings its header, space_before vanishes at a page top.
TEST(PdfPaginate, KeepsHeadingsWithContentAndRepeatsHeaders) {
  const double body = pdf::kBodyBottom - pdf::kBodyTop;
  std::vector<pdf::Unit> units;
  auto add = [&](double h, double space = 0) -> pdf::Unit& {
    units.push_back(pdf::Unit{});
    units.back().height = h;
    units.back().space_before = space;
    return units.back();
  };
  add(body - 50);                            // 0: fills most of page 1
  pdf::Unit& heading = add(20, 10);          // 1: fits (30 pt) but its content does not
  heading.keep_with_next = true;
  heading.anchor = "h";
  add(40, 5);                                // 2: first line of the content
  pdf::Unit& header = add(15, 10);           // 3: a table header
  header.keep_with_next = true;
  auto repeat = std::make_shared<pdf::Unit>();
  repeat->height = 15;
  for (int r = 0; r < 60; ++r) add(15).repeat_header = repeat;  // 4..63
  std::map<std::string, int> anchors;
  const std::vector<pdf::Page> pages = pdf::Paginate(units, &anchors);
  ASSERT_GE(pages.size(), 3u);
  ASSERT_EQ(pages[0].size(), 1u);            // the heading left page 1 with its content
  EXPECT_EQ(anchors.at("h"), 2);
  EXPECT_EQ(pages[1][0].unit, &units[1]);
  EXPECT_DOUBLE_EQ(pages[1][0].y, pdf::kBodyTop);  // no space_before at the top
  EXPECT_EQ(pages[1][1].unit, &units[2]);
  EXPECT_EQ(pages[2][0].unit, repeat.get());  // the continuation starts with the header
  EXPECT_EQ(pages[2][1].unit->repeat_header, repeat);
  size_t placed = 0;
  for (const pdf::Page& page : pages) {
    for (const pdf::Placed& p : page) {
      EXPECT_LE(p.y + p.unit->height, pdf::kBodyBottom + 1e-9);
      if (p.unit != repeat.get()) ++placed;
    }
  }
  EXPECT_EQ(placed, units.size());
}

TEST(PdfReport, OptionsCheck) {
  EXPECT_EQ(PdfOptions{}.Check(), "");
  PdfOptions o;
  o.dpi = 50;
  EXPECT_NE(o.Check().find("dpi"), std::string::npos);
  o = {};
  o.jpeg_quality = 101;
  EXPECT_NE(o.Check().find("jpeg_quality"), std::string::npos);
  o = {};
  o.font_family = "";
  EXPECT_NE(o.Check().find("font_family"), std::string::npos);
}

TEST(PdfReport, PdfInfoMetadataOutlineAndDestinations) {
  REQUIRE_POPPLER();
  const fs::path folder = test::TestFolder();
  const fs::path pdf = folder / "report.pdf";
  const PdfStats stats = WritePdf(MakeDocument(folder), pdf);
  EXPECT_EQ(stats.figures, 7);  // hero + 4 + 2 close-ups
  EXPECT_EQ(stats.bytes, static_cast<int64_t>(fs::file_size(pdf)));
  const test::CommandResult info = test::RunCommand("pdfinfo '" + pdf.string() + "'");
  ASSERT_EQ(info.exit_code, 0) << info.output;
  EXPECT_EQ(InfoField(info.output, "Pages"), std::to_string(stats.pages));
  EXPECT_EQ(InfoField(info.output, "Title"), "Infrared thermography inspection report");
  EXPECT_EQ(InfoField(info.output, "Author"), "J. Smith");
  EXPECT_EQ(InfoField(info.output, "Subject"), "ACME Ltd — Plant room 2");
  EXPECT_EQ(InfoField(info.output, "Keywords"), "thermography, ASTM E1934");
  EXPECT_EQ(InfoField(info.output, "Creator"), "heatwave test");
  EXPECT_EQ(InfoField(info.output, "Page size"), "595.28 x 841.89 pts (A4)");
  // The dates are doc.created_utc, not the clock.
  EXPECT_EQ(InfoField(info.output, "CreationDate"), "Wed Dec  2 10:00:00 2026 UTC");
  EXPECT_EQ(InfoField(info.output, "ModDate"), "Wed Dec  2 10:00:00 2026 UTC");
  // Named destinations for every section anchor.
  const test::CommandResult dests = test::RunCommand("pdfinfo -dests '" + pdf.string() + "'");
  ASSERT_EQ(dests.exit_code, 0) << dests.output;
  for (const char* anchor : {"intro", "findings", "spot-h1", "spot-h2", "method"}) {
    EXPECT_NE(dests.output.find(std::string("\"") + anchor + "\""), std::string::npos) << anchor << "\n" << dests.output;
  }
  // The outline: three top-level items, the two spots nested under "2 Findings overview".
  const std::string raw = ReadAll(pdf);
  EXPECT_NE(raw.find("/Type /Outlines"), std::string::npos);
  EXPECT_NE(raw.find("(2.1 H1 hot spot detail)"), std::string::npos);
  EXPECT_NE(raw.find("/DCTDecode"), std::string::npos);  // images embedded as JPEG
  // Links: 5 TOC entries + 2 linked rows in each of the two spot tables.
  size_t links = 0;
  for (size_t at = raw.find("/Subtype /Link"); at != std::string::npos; at = raw.find("/Subtype /Link", at + 1)) ++links;
  EXPECT_EQ(links, 9u);
}

TEST(PdfReport, TextTableRowsContentsAndFooter) {
  REQUIRE_POPPLER();
  const fs::path folder = test::TestFolder();
  const fs::path pdf = folder / "report.pdf";
  const PdfStats stats = WritePdf(MakeDocument(folder), pdf);
  const std::vector<std::string> pages = PdfPages(pdf);
  ASSERT_EQ(static_cast<int>(pages.size()), stats.pages);
  // Table rows keep their exact formatted numbers, cells in order on one line.
  EXPECT_TRUE(std::regex_search(pages[0], std::regex(R"(H1 +hot spot +30\.0 °C +\+1\.00 K +0\.010 m²)"))) << pages[0];
  EXPECT_TRUE(std::regex_search(pages[0], std::regex(R"(H2 +cold spot +30\.1 °C +\+1\.01 K +0\.020 m²)")));
  EXPECT_NE(pages[0].find("Infrared thermography"), std::string::npos);
  EXPECT_NE(pages[0].find("Plant room 2, ACME Ltd"), std::string::npos);
  EXPECT_EQ(pages[0].find("Page 1 of"), std::string::npos);  // no footer on the cover
  // Contents on page 2: every entry's page number is where its heading is.
  ASSERT_NE(pages[1].find("Contents"), std::string::npos);
  EXPECT_NE(pages[1].find("Page 2 of " + std::to_string(stats.pages)), std::string::npos) << pages[1];
  EXPECT_NE(pages[1].find("Report HW-0142 · ACME Ltd"), std::string::npos);
  const std::vector<std::pair<std::string, std::string>> entries = {
      {"1", "Introduction"}, {"2", "Findings overview"}, {"2.1", "H1 hot spot detail"},
      {"2.2", "H2 hot spot detail"}, {"3", "Method and standards"}};
  int previous = 3;
  for (const auto& [number, title] : entries) {
    std::smatch m;
    const std::regex line(number + R"( +)" + title + R"( +(\d+)\n)");
    ASSERT_TRUE(std::regex_search(pages[1], m, line)) << title << "\n" << pages[1];
    const int heading_page = PageOf(pages, title, 3);  // after the cover and contents
    EXPECT_EQ(std::stoi(m[1]), heading_page) << title;
    EXPECT_GE(heading_page, previous);
    previous = heading_page;
  }
  // "Findings overview" has new_page: it starts a page of its own (after the introduction).
  EXPECT_GT(PageOf(pages, "Findings overview", 3), PageOf(pages, "Introduction", 3));
  EXPECT_NE(pages.back().find("Page " + std::to_string(stats.pages) + " of " + std::to_string(stats.pages)),
            std::string::npos);
}

TEST(PdfReport, EveryFontEmbedded) {
  REQUIRE_POPPLER();
  const fs::path folder = test::TestFolder();
  const fs::path pdf = folder / "report.pdf";
  WritePdf(MakeDocument(folder), pdf);
  const test::CommandResult fonts = test::RunCommand("pdffonts '" + pdf.string() + "'");
  ASSERT_EQ(fonts.exit_code, 0) << fonts.output;
  // Columns from the dashed separator line: name, type, encoding, emb, ...
  std::stringstream in(fonts.output);
  std::string line, separator;
  std::vector<std::string> rows;
  while (std::getline(in, line)) {
    if (line.rfind("----", 0) == 0) {
      separator = line;
    } else if (!separator.empty() && !line.empty()) {
      rows.push_back(line);
    }
  }
  ASSERT_FALSE(separator.empty()) << fonts.output;
  ASSERT_GE(rows.size(), 2u) << fonts.output;  // regular and bold at least
  std::vector<size_t> starts = {0};
  for (size_t i = 1; i < separator.size(); ++i) {
    if (separator[i - 1] == ' ' && separator[i] == '-') starts.push_back(i);
  }
  ASSERT_GE(starts.size(), 4u);
  for (const std::string& row : rows) {
    ASSERT_GT(row.size(), starts[3] + 3);
    EXPECT_EQ(row.substr(starts[3], 3), "yes") << row;
  }
}

TEST(PdfReport, MarkupAndPdfSyntaxInTextPrintLiterally) {
  REQUIRE_POPPLER();
  const fs::path folder = test::TestFolder();
  const fs::path pdf = folder / "report.pdf";
  const std::string hostile = "<b>&amp;</script><script>alert(1)</script> 50% \\ ( ) %PDF";
  Document doc = MakeDocument(folder);
  doc.cover.title = hostile;
  doc.author = hostile;
  doc.sections[0].title = hostile;
  doc.sections[0].blocks.push_back(Paragraph{hostile, Paragraph::Style::kBody});
  doc.sections[0].blocks.push_back(Table{{"A", hostile}, {{"x", hostile}}, {false, false}, {}, hostile, {}});
  WritePdf(doc, pdf);
  const test::CommandResult info = test::RunCommand("pdfinfo '" + pdf.string() + "'");
  ASSERT_EQ(info.exit_code, 0) << info.output;
  EXPECT_EQ(InfoField(info.output, "Title"), hostile);
  EXPECT_EQ(InfoField(info.output, "Author"), hostile);
  const test::CommandResult text = test::RunCommand("pdftotext '" + pdf.string() + "' -");
  ASSERT_EQ(text.exit_code, 0);
  size_t count = 0;
  for (size_t at = text.output.find(hostile); at != std::string::npos; at = text.output.find(hostile, at + 1)) ++count;
  // Cover title, contents entry, heading, paragraph, table cell, caption, page headers.
  EXPECT_GE(count, 6u) << text.output;
}

TEST(PdfReport, ImagesResampledToDpiAndEmbeddedAsJpeg) {
  REQUIRE_POPPLER();
  const fs::path folder = test::TestFolder();
  Document doc = MakeDocument(folder);
  const fs::path big = WritePng(folder, "big.png", 1600, 1200, 0.5);
  doc.sections[0].blocks.push_back(FigureGrid{{Figure{big, 1600, 1200, "Big", std::nullopt}}, 1, ""});
  PdfOptions options;
  options.dpi = 150;
  const fs::path pdf = folder / "report.pdf";
  WritePdf(doc, pdf, options);
  const test::CommandResult list = test::RunCommand("pdfimages -list '" + pdf.string() + "'");
  ASSERT_EQ(list.exit_code, 0) << list.output;
  // The full-width figure (481.9 pt) at 150 ppi: 1004 pixels wide, not 1600; every image a
  // JPEG; the 160 × 120 images are not enlarged.
  EXPECT_TRUE(std::regex_search(list.output, std::regex(R"(image +1004 +753 +rgb +3 +8 +jpeg)"))) << list.output;
  EXPECT_EQ(list.output.find(" 1600 "), std::string::npos);
  EXPECT_TRUE(std::regex_search(list.output, std::regex(R"(image +160 +120 +rgb +3 +8 +jpeg)")));
  std::stringstream in(list.output);
  std::string line;
  int images = 0;
  while (std::getline(in, line)) {
    if (!std::regex_search(line, std::regex(R"(^ +\d+ +\d+ +image )"))) continue;
    ++images;
    EXPECT_NE(line.find(" jpeg "), std::string::npos) << line;
  }
  EXPECT_GE(images, 6);
}

TEST(PdfReport, IdenticalInputsGiveIdenticalBytes) {
  const fs::path folder = test::TestFolder();
  Document doc = MakeDocument(folder);
  WritePdf(doc, folder / "a.pdf");
  WritePdf(doc, folder / "b.pdf");
  const std::string a = ReadAll(folder / "a.pdf");
  ASSERT_GT(a.size(), 1000u);
  EXPECT_TRUE(a == ReadAll(folder / "b.pdf"));
  doc.created_utc = "2026-12-03T10:00:00Z";
  WritePdf(doc, folder / "c.pdf");
  const std::string c = ReadAll(folder / "c.pdf");
  EXPECT_FALSE(a == c);
  EXPECT_EQ(a.find("20261203"), std::string::npos);
  EXPECT_NE(c.find("20261203"), std::string::npos);
}

TEST(PdfReport, LongTableSplitsWithHeaderRepeated) {
  REQUIRE_POPPLER();
  const fs::path folder = test::TestFolder();
  const fs::path pdf = folder / "report.pdf";
  Document doc = MakeDocument(folder);
  Section all{1, "all-spots", "All spots", {SpotTable(120)}, true};
  doc.sections.push_back(all);
  const PdfStats stats = WritePdf(doc, pdf);
  const std::vector<std::string> pages = PdfPages(pdf);
  ASSERT_EQ(static_cast<int>(pages.size()), stats.pages);
  const int first = PageOf(pages, "All spots", 3);
  const int last = PageOf(pages, "H120 ");
  ASSERT_GT(first, 0);
  ASSERT_GT(last, first) << "120 rows should take more than one page";
  int rows_seen = 0;
  for (int p = first; p <= last; ++p) {
    const std::string& page = pages[static_cast<size_t>(p - 1)];
    EXPECT_TRUE(std::regex_search(page, std::regex(R"(Spot +Kind +Peak +ΔT +Area)"))) << "page " << p << "\n" << page;
    for (int r = 1; r <= 120; ++r) {
      if (std::regex_search(page, std::regex("\\bH" + std::to_string(r) + " +(hot|cold) spot"))) ++rows_seen;
    }
  }
  EXPECT_EQ(rows_seen, 120);
}

TEST(PdfReport, MissingOrCorruptPngIsInputErrorAndLeavesNoFile) {
  const fs::path folder = test::TestFolder();
  const fs::path out = folder / "out" / "report.pdf";
  fs::create_directories(out.parent_path());
  Document doc = MakeDocument(folder);
  const fs::path missing = folder / "missing.png";
  std::get<FigureGrid>(doc.sections[1].blocks[1]).figures[1].png = missing;
  try {
    WritePdf(doc, out);
    FAIL() << "no InputError";
  } catch (const core::InputError& e) {
    EXPECT_EQ(e.path(), missing);
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_TRUE(fs::is_empty(out.parent_path()));

  const fs::path corrupt = folder / "corrupt.png";
  std::string bytes = ReadAll(folder / "colour.png");
  bytes.resize(bytes.size() / 2);  // truncated: the header reads, the pixels do not
  std::ofstream(corrupt, std::ios::binary) << bytes;
  std::get<FigureGrid>(doc.sections[1].blocks[1]).figures[1].png = corrupt;
  try {
    WritePdf(doc, out);
    FAIL() << "no InputError";
  } catch (const core::InputError& e) {
    EXPECT_EQ(e.path(), corrupt) << e.what();
  }
  EXPECT_TRUE(fs::is_empty(out.parent_path()));
}

TEST(PdfReport, UnwritablePathIsOutputError) {
  const fs::path folder = test::TestFolder();
  std::ofstream(folder / "file") << "x";
  EXPECT_THROW(WritePdf(MakeDocument(folder), folder / "file" / "report.pdf"), core::OutputError);
}

// The demo analysis's real images (1280 × 960), when the demo has been built: a cover with a
// hero, a 2 × 2 overview grid with keys and 30 figures in all. Prints size and time; with
// HW_PDF_DEMO_OUT set, also writes the PDF there for a look.
TEST(PdfReport, RealDemoImages) {
  const fs::path images = fs::path(HW_SOURCE_DIR) / ".." / "main" / "build" / "demo" / "analysis" / "images";
  if (!fs::exists(images / "overview-1-thermal.png")) GTEST_SKIP() << "no demo images at " << images;
  const fs::path folder = test::TestFolder();
  Document doc = MakeDocument(folder);
  ColourKey thermal = Key(analyze::ViewMode::kThermal);
  thermal.span = {18.0, 36.5};
  ColourKey ih = thermal, highlight = thermal;
  ih.mode = analyze::ViewMode::kIhMapping;
  highlight.mode = analyze::ViewMode::kHighlight;
  highlight.band_low_c = 21;
  highlight.band_high_c = 28;
  auto figure = [&](const std::string& view, const std::string& mode) {
    const fs::path png = images / (view + "-" + mode + ".png");
    std::optional<ColourKey> key;
    if (mode == "thermal") key = thermal;
    if (mode == "ih") key = ih;
    if (mode == "highlight") key = highlight;
    return Figure{png, 1280, 960, view + ", " + mode + (key ? ", 18.0–36.5 °C" : ""), key};
  };
  doc.cover.hero = figure("overview-1", "thermal");
  doc.sections[1].blocks[1] = FigureGrid{{figure("overview-1", "thermal"), figure("overview-1", "colour"),
                                          figure("overview-1", "ih"), figure("overview-1", "highlight")},
                                         2, "Overview 1 in the four modes."};
  for (const std::string view : {"overview-2", "top", "H1"}) {
    Section s{2, "view-" + std::to_string(doc.sections.size()), "View " + view, {}, false};
    s.blocks.push_back(Paragraph{"The " + view + " view in the four modes.", Paragraph::Style::kBody});
    FigureGrid grid{{}, 2, ""};
    for (const char* mode : {"thermal", "colour", "ih", "highlight"}) grid.figures.push_back(figure(view, mode));
    s.blocks.push_back(grid);
    doc.sections.push_back(s);
  }
  // 30 figures: 1 + 4 + 2 + 3 · 4 = 19 so far; eleven more single close-ups in a 4-column grid.
  FigureGrid small{{}, 4, "Close-ups."};
  for (int i = 0; i < 11; ++i) small.figures.push_back(figure(i % 2 ? "H1" : "top", i % 3 ? "thermal" : "ih"));
  doc.sections.back().blocks.push_back(small);
  const fs::path pdf = folder / "demo.pdf";
  const PdfStats stats = WritePdf(doc, pdf);
  EXPECT_EQ(stats.figures, 30);
  std::printf("demo PDF: %d pages, %d figures, %.2f MB, %.2f s\n", stats.pages, stats.figures,
              static_cast<double>(stats.bytes) / 1e6, stats.seconds);
  EXPECT_LT(stats.bytes, 12'000'000);
  if (const char* out = std::getenv("HW_PDF_DEMO_OUT")) fs::copy_file(pdf, out, fs::copy_options::overwrite_existing);
}

}  // namespace
}  // namespace hw::report
