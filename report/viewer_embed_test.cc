#include "report/viewer_embed.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "analyze/srgb.h"
#include "report/browser_check.h"
#include "report/screenshot_test_support.h"

namespace hw::report {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A UV sphere of radius 0.5 m centred at (0, 0, 2) (in front of a camera at the origin),
// `rings` × `segments` quads; temperature 15 °C at the bottom to 35 °C at the top, colour
// a green→magenta gradient along x, and the vertices of the first segment column unobserved.
analyze::ThermalMesh Sphere(int rings, int segments, bool with_nan = true) {
  analyze::ThermalMesh mesh;
  const Eigen::Vector3d centre(0, 0, 2);
  for (int r = 0; r <= rings; ++r) {
    const double theta = std::numbers::pi * r / rings;
    for (int s = 0; s <= segments; ++s) {
      const double phi = 2 * std::numbers::pi * s / segments;
      const Eigen::Vector3d n(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      mesh.points_in_world.push_back(centre + 0.5 * n);
      mesh.normals.push_back(n);
      mesh.temperature_c.push_back(with_nan && s == 0 ? kNaN : 25 + 10 * n.z());
      const auto u = static_cast<float>((n.x() + 1) / 2);
      mesh.colour_linear.emplace_back(1 - u, u, 0.8f * (1 - u));
    }
  }
  const auto index = [segments](int r, int s) { return r * (segments + 1) + s; };
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      if (r > 0) mesh.faces.emplace_back(index(r, s), index(r + 1, s), index(r, s + 1));
      if (r + 1 < rings) mesh.faces.emplace_back(index(r, s + 1), index(r + 1, s), index(r + 1, s + 1));
    }
  }
  return mesh;
}

ModelView View() {
  ModelView view;
  view.palette = analyze::Palette::kIron;
  view.span = {15, 35};
  view.band_low_c = 20;
  view.band_high_c = 30;
  return view;
}

std::array<uint8_t, 3> Srgb8(const Eigen::Vector3f& linear) {
  return {analyze::LinearToSrgb8(linear[0]), analyze::LinearToSrgb8(linear[1]), analyze::LinearToSrgb8(linear[2])};
}

std::array<uint8_t, 3> ColourOf(const ViewerMesh& encoded, int mode, size_t v) {
  const auto& c = encoded.colours_srgb8[static_cast<size_t>(mode)];
  return {c[v * 3], c[v * 3 + 1], c[v * 3 + 2]};
}

TEST(ViewerOptions, CheckNamesTheField) {
  EXPECT_EQ(ViewerOptions{}.Check(), "");
  ViewerOptions o;
  o.max_faces = 10;
  EXPECT_NE(o.Check().find("max_faces"), std::string::npos);
  o = {};
  o.max_error_fraction = 0;
  EXPECT_NE(o.Check().find("max_error_fraction"), std::string::npos);
  o = {};
  o.height_px = 5000;
  EXPECT_NE(o.Check().find("height_px"), std::string::npos);
}

TEST(EncodeViewerMesh, SmallMeshIsKeptWhole) {
  const analyze::ThermalMesh mesh = Sphere(12, 24);
  const ViewerMesh encoded = EncodeViewerMesh(mesh, View());
  EXPECT_EQ(encoded.faces_in, mesh.NumFaces());
  EXPECT_EQ(encoded.indices.size(), mesh.faces.size() * 3);
  // Every vertex a face uses is kept (the poles' seam copies of the first column are
  // not), and positions survive quantisation to within half a step of the box.
  std::vector<bool> used(mesh.points_in_world.size(), false);
  for (const Eigen::Vector3i& f : mesh.faces) used[static_cast<size_t>(f[0])] = used[static_cast<size_t>(f[1])] = used[static_cast<size_t>(f[2])] = true;
  ASSERT_EQ(encoded.source_vertex.size(), static_cast<size_t>(std::count(used.begin(), used.end(), true)));
  const Eigen::Vector3d extent = encoded.box_max - encoded.box_min;
  for (size_t v = 0; v < encoded.positions_q.size(); ++v) {
    const Eigen::Vector3d& p = mesh.points_in_world[static_cast<size_t>(encoded.source_vertex[v])];
    for (int c = 0; c < 3; ++c) {
      const double back = encoded.box_min[c] + encoded.positions_q[v][static_cast<size_t>(c)] / 65535.0 * extent[c];
      EXPECT_NEAR(back, p[c], extent[c] / 65535.0);
    }
  }
}

TEST(EncodeViewerMesh, DecimatesToAtMostMaxFaces) {
  const analyze::ThermalMesh mesh = Sphere(100, 200);  // 39 800 faces
  ViewerOptions options;
  options.max_faces = 2000;
  const ViewerMesh encoded = EncodeViewerMesh(mesh, View(), options);
  const size_t faces = encoded.indices.size() / 3;
  EXPECT_LE(faces, 2000u);
  EXPECT_GT(faces, 500u);  // not collapsed to nothing
  for (const uint32_t i : encoded.indices) ASSERT_LT(i, encoded.positions_q.size());
  // Compacted: every kept vertex is used.
  std::vector<bool> used(encoded.positions_q.size(), false);
  for (const uint32_t i : encoded.indices) used[i] = true;
  EXPECT_EQ(std::count(used.begin(), used.end(), false), 0);
}

TEST(EncodeViewerMesh, ModeColoursAreThoseOfTheImages) {
  const analyze::ThermalMesh mesh = Sphere(12, 24);
  const ModelView view = View();
  const ViewerMesh encoded = EncodeViewerMesh(mesh, view);
  int checked_outside = 0, checked_inside = 0;
  for (size_t v = 0; v < encoded.source_vertex.size(); ++v) {
    const auto source = static_cast<size_t>(encoded.source_vertex[v]);
    const double t = mesh.temperature_c[source];
    if (std::isnan(t)) continue;
    const double t01 = (t - 15) / 20;
    const Eigen::Vector3f colour = mesh.colour_linear[source];
    const Eigen::Vector3f thermal = analyze::PaletteColour(analyze::Palette::kIron, false, t01);
    EXPECT_EQ(ColourOf(encoded, 0, v), Srgb8(thermal));
    EXPECT_EQ(ColourOf(encoded, 1, v), Srgb8(colour));
    const float luminance = 0.2126f * colour[0] + 0.7152f * colour[1] + 0.0722f * colour[2];
    EXPECT_EQ(ColourOf(encoded, 2, v), Srgb8(analyze::IhColour(t01, luminance)));
    const bool outside = t < 20 || t > 30;
    EXPECT_EQ(ColourOf(encoded, 3, v), Srgb8(outside ? thermal : colour));
    (outside ? checked_outside : checked_inside) += 1;
    EXPECT_EQ(encoded.unobserved[v], 0);
  }
  EXPECT_GT(checked_outside, 10);
  EXPECT_GT(checked_inside, 10);
  // A known temperature, end to end: the top pole is 35 °C, the iron palette's white end.
  const auto top = static_cast<size_t>(std::find(encoded.source_vertex.begin(), encoded.source_vertex.end(), 1) -
                                       encoded.source_vertex.begin());
  ASSERT_LT(top, encoded.source_vertex.size());
  EXPECT_EQ(ColourOf(encoded, 0, top), Srgb8(analyze::PaletteColour(analyze::Palette::kIron, false, 1.0)));
}

TEST(EncodeViewerMesh, UnobservedTemperatureIsTheHatchGrey) {
  const analyze::ThermalMesh mesh = Sphere(12, 24);
  const ViewerMesh encoded = EncodeViewerMesh(mesh, View());
  const uint8_t grey = analyze::LinearToSrgb8(analyze::SrgbToLinear(0.62f));
  // The hatch's base, i.e. UnobservedHatchGrey away from its lines.
  EXPECT_EQ(grey, analyze::LinearToSrgb8(analyze::UnobservedHatchGrey(4, 0, 8)));
  int unobserved = 0;
  for (size_t v = 0; v < encoded.source_vertex.size(); ++v) {
    if (!std::isnan(mesh.temperature_c[static_cast<size_t>(encoded.source_vertex[v])])) continue;
    ++unobserved;
    EXPECT_EQ(encoded.unobserved[v], 255);
    for (const int mode : {0, 2, 3}) EXPECT_EQ(ColourOf(encoded, mode, v), (std::array<uint8_t, 3>{grey, grey, grey}));
    EXPECT_EQ(ColourOf(encoded, 1, v), Srgb8(mesh.colour_linear[static_cast<size_t>(encoded.source_vertex[v])]));
  }
  EXPECT_GT(unobserved, 5);
}

constexpr const char* kInjection =
    "</script><script>window.hwInjected=1;document.documentElement.dataset.hwInjected='1'</script><!--";

ModelView ViewWithMarkers() {
  ModelView view = View();
  Marker hot;
  hot.label = kInjection;
  hot.anchor = "spot-h1\"><script>document.documentElement.dataset.hwInjected='2'</script>";
  hot.position_in_world = {0, 0, 2.5};
  hot.normal_in_world = {0, 0, 1};
  view.markers.push_back(hot);
  Marker cold = hot;
  cold.label = "C1 <b>&amp;</b>";
  cold.anchor = "spot-c1";
  cold.hot = false;
  cold.position_in_world = {0, 0, 1.5};
  cold.normal_in_world = {0, 0, -1};
  view.markers.push_back(cold);
  return view;
}

TEST(ViewerHtml, StringsCannotCloseTheScript) {
  ViewerStats stats;
  const std::string html = ViewerHtml(Sphere(12, 24), ViewWithMarkers(), {}, &stats);
  EXPECT_EQ(html.find("<script>window.hwInjected"), std::string::npos);
  EXPECT_EQ(html.find("<b>"), std::string::npos);
  EXPECT_NE(html.find("\\u003c/script\\u003e\\u003cscript\\u003ewindow.hwInjected"), std::string::npos);
  // Exactly the fragment's own elements: meta, data, bundle.
  size_t scripts = 0;
  for (size_t at = html.find("<script"); at != std::string::npos; at = html.find("<script", at + 1)) ++scripts;
  size_t closes = 0;
  for (size_t at = html.find("</script"); at != std::string::npos; at = html.find("</script", at + 1)) ++closes;
  EXPECT_EQ(scripts, 3u);
  EXPECT_EQ(closes, 3u);
  EXPECT_NE(html.find("@media print{.hw-viewer{display:none}}"), std::string::npos);
  EXPECT_EQ(stats.faces_in, stats.faces_out);
  EXPECT_EQ(stats.embedded_bytes, static_cast<int64_t>(html.size()));
  // The bundle keeps three.js's licence.
  EXPECT_NE(html.find("Copyright \xC2\xA9 2010-2026 three.js authors"), std::string::npos);
}

// The fragment in a minimal page with the report's CSP, opened in headless Chromium: the
// view renders with no CSP violation, the screenshot shows the model, and the marker label
// and anchor that try to inject a script stay text.
TEST(ViewerHtml, RendersInHeadlessChromium) {
  if (access("/usr/bin/chromium", X_OK) != 0) {
    GTEST_SKIP() << "/usr/bin/chromium absent: install it with scripts/install-deps.sh";
  }
  const std::filesystem::path folder = std::filesystem::temp_directory_path() /
                                       ("hw-viewer-test-" + std::to_string(getpid()));
  std::filesystem::create_directories(folder);
  const std::filesystem::path page = folder / "page.html";
  {
    std::ofstream out(page);
    out << "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><meta http-equiv=\"Content-Security-Policy\" content=\""
        << ViewerContentSecurityPolicy() << "\"><title>t</title></head><body style=\"margin:0\">"
        << ViewerHtml(Sphere(40, 80), ViewWithMarkers()) << "</body></html>\n";
  }
  const BrowserResult result = OpenInHeadlessChromium(page, 800, 600, 60);
  ASSERT_TRUE(result.available) << result.reason;
  EXPECT_EQ(result.exit_code, 0) << result.reason;
  EXPECT_NE(result.dom.find("data-hw-viewer=\"rendered\""), std::string::npos) << result.dom.substr(0, 400);
  EXPECT_EQ(result.dom.find("data-hw-csp-violations"), std::string::npos) << "CSP violations reported";
  EXPECT_EQ(result.dom.find("data-hw-injected"), std::string::npos) << "a label's script ran";
  EXPECT_NE(result.dom.find("data-mode=\"thermal\" aria-pressed=\"true\""), std::string::npos);
  ASSERT_FALSE(result.screenshot_png.empty()) << result.reason;
  // The canvas spans the page's top 560 px; a flat page has variance 0, the grey
  // background alone too: the lit sphere's palette gives a large one.
  const double variance = test::GreyVariance(result.screenshot_png, 0, 40, 800, 560);
  EXPECT_GT(variance, 100.0);
  std::filesystem::remove_all(result.screenshot_png.parent_path());
  std::filesystem::remove_all(folder);
}

TEST(OpenInHeadlessChromium, MissingPageIsReportedWithoutRunningTheBrowser) {
  const BrowserResult result = OpenInHeadlessChromium("/nonexistent/page.html", 320, 240, 5);
  EXPECT_FALSE(result.available);
  EXPECT_NE(result.reason.find("/nonexistent/page.html"), std::string::npos) << result.reason;
  EXPECT_TRUE(result.screenshot_png.empty());
}

}  // namespace
}  // namespace hw::report
