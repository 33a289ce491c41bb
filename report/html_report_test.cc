#include "report/html_report.h"

#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/strings.h"
#include "report/report_model.h"
#include "report/report_test_support.h"
#include "tests/support.h"

namespace hw::report {
namespace {

namespace fs = std::filesystem;

size_t Count(const std::string& haystack, const std::string& needle) {
  size_t n = 0;
  for (size_t at = haystack.find(needle); at != std::string::npos; at = haystack.find(needle, at + 1)) ++n;
  return n;
}

TEST(HtmlReportTest, Base64MatchesRfc4648) {
  EXPECT_EQ(core::Base64(""), "");
  EXPECT_EQ(core::Base64("f"), "Zg==");
  EXPECT_EQ(core::Base64("fo"), "Zm8=");
  EXPECT_EQ(core::Base64("foo"), "Zm9v");
  EXPECT_EQ(core::Base64("foob"), "Zm9vYg==");
  EXPECT_EQ(core::Base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(core::Base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(core::Base64(std::string("\xff\xfe\x00", 3)), "//4A");
}

TEST(HtmlReportTest, EscapesMarkupAndInvalidUtf8) {
  EXPECT_EQ(HtmlEscape("<script>alert('x')</script> & \"q\""),
            "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;");
  EXPECT_EQ(HtmlEscape("25 °C ± 1\nµm"), "25 °C ± 1\nµm");
  EXPECT_EQ(HtmlEscape("a\x01" "b\x7f"), "ab");
  EXPECT_EQ(HtmlEscape("\xc0\xaf"), "\xEF\xBF\xBD\xEF\xBF\xBD");      // overlong '/'
  EXPECT_EQ(HtmlEscape("\xed\xa0\x80"), "\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD");  // surrogate
  EXPECT_EQ(HtmlEscape("x\xe2\x82"), "x\xEF\xBF\xBD\xEF\xBF\xBD");    // truncated
}

TEST(HtmlReportTest, SelfContainedPageWithEverySectionAndNoInjection) {
  const fs::path folder = hw::test::TestFolder();
  const test::PlateAnalysis plate = test::MakePlateAnalysis(folder);
  ReportInputs in;
  in.analyze_json = plate.analyze_json;
  in.job = test::TestJob();
  in.job.client.name = "<script>window.hwInjected=1</script>ACME & Sons \"Ltd\"";
  in.job.notes = "</p><img src=x onerror=alert(1)><p>";
  const Document doc = BuildDocument(in);
  const fs::path html_path = folder / "report.html";
  const HtmlStats stats = WriteHtml(doc, html_path);
  const std::string html = core::ReadFile(html_path, 1 << 28);
  EXPECT_EQ(stats.bytes, static_cast<int64_t>(html.size()));

  // No script at all without a 3D view, and nothing the job file said became markup.
  EXPECT_EQ(Count(html, "<script"), 0u);
  EXPECT_EQ(Count(html, "<img src=x"), 0u);
  EXPECT_GT(Count(html, "&lt;script&gt;window.hwInjected=1&lt;/script&gt;ACME &amp; Sons &quot;Ltd&quot;"), 0u);
  EXPECT_EQ(Count(html, "&lt;/p&gt;&lt;img src=x onerror=alert(1)&gt;&lt;p&gt;"), 1u);
  // Self-contained: every image a data: URI, no URL to fetch, a CSP forbidding requests.
  EXPECT_EQ(Count(html, "src=\"data:image/png;base64,"), static_cast<size_t>(stats.images));
  EXPECT_EQ(Count(html, " src=\""), static_cast<size_t>(stats.images));
  EXPECT_EQ(Count(html, "http://"), 0u);
  EXPECT_EQ(Count(html, "https://"), 0u);
  EXPECT_EQ(Count(html, "url("), 0u);
  EXPECT_NE(html.find("Content-Security-Policy\" content=\"default-src &#39;none&#39;"), std::string::npos);
  // Every image of the analysis (overviews and the plan view in four modes, the close-ups)
  // and the cover's hero.
  EXPECT_EQ(stats.images, static_cast<int>(plate.result.images.size()) + 1);
  // Every section has its id, and every TOC link and table link a target.
  for (const Section& s : doc.sections) EXPECT_EQ(Count(html, "id=\"" + s.anchor + "\""), 1u) << s.anchor;
  const std::regex link("href=\"#([a-z0-9-]+)\"");
  int links = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), link); it != std::sregex_iterator(); ++it, ++links) {
    EXPECT_EQ(Count(html, "id=\"" + (*it)[1].str() + "\""), 1u) << (*it)[1].str();
  }
  EXPECT_GE(links, static_cast<int>(doc.sections.size()) + 2);  // TOC + summary and spot tables
  // The spot's numbers as the model formatted them.
  const analyze::Spot& spot = plate.result.detection->spots.at(0);
  EXPECT_NE(html.find(HtmlEscape(FormatArea(spot.area_m2, spot.area_sigma_m2))), std::string::npos);
  // Colour bars: a gradient and a last tick with the unit.
  EXPECT_GE(Count(html, "linear-gradient(to right,"), 7u);
  EXPECT_GE(Count(html, " °C</span>"), 7u);
}

TEST(HtmlReportTest, UnreadableFigureIsAnInputErrorAndNoFile) {
  const fs::path folder = hw::test::TestFolder();
  Document doc;
  doc.cover.title = "t";
  Section s;
  s.anchor = "a";
  s.title = "A";
  FigureGrid grid;
  Figure f;
  f.png = folder / "not-a-png.png";
  core::WriteFileAtomically(f.png, "GIF89a");
  grid.figures.push_back(f);
  s.blocks.push_back(grid);
  doc.sections.push_back(s);
  try {
    WriteHtml(doc, folder / "report.html");
    FAIL() << "no error";
  } catch (const core::InputError& e) {
    EXPECT_EQ(std::string(e.what()), f.png.string() + ": not a PNG file");
  }
  EXPECT_FALSE(fs::exists(folder / "report.html"));
}

}  // namespace
}  // namespace hw::report
