#include "analyze/views.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "analyze/srgb.h"

namespace hw::analyze {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// One triangle; vertex temperatures 20, 30, 40 °C; span 20..40.
ThermalMesh Triangle(bool with_colour = false) {
  ThermalMesh mesh;
  mesh.points_in_world = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  mesh.faces = {{0, 1, 2}};
  mesh.temperature_c = {20, 30, 40};
  if (with_colour) mesh.colour_linear.assign(3, Eigen::Vector3f::Constant(0.3f));
  return mesh;
}

// A width × height buffer of misses with `spp` samples a pixel.
SampleBuffer Misses(int width, int height, int spp = 1) {
  SampleBuffer b;
  b.width = width;
  b.height = height;
  b.samples_per_pixel = spp;
  const size_t n = static_cast<size_t>(width * height * spp);
  b.face.assign(n, -1);
  b.bary_u.assign(n, 0);
  b.bary_v.assign(n, 0);
  b.depth_m.assign(n, std::numeric_limits<float>::infinity());
  b.cos_incidence.assign(n, 0);
  return b;
}

void Hit(SampleBuffer* b, int x, int y, int s, float u, float v, float cos_incidence = 1) {
  const size_t i = b->Index(x, y, s);
  b->face[i] = 0;
  b->bary_u[i] = u;
  b->bary_v[i] = v;
  b->depth_m[i] = 1;
  b->cos_incidence[i] = cos_incidence;
}

ViewStyle Style(ViewMode mode) {
  ViewStyle style;
  style.mode = mode;
  style.span = Span{20, 40};
  style.ambient = 1;  // shading 1 unless a test sets otherwise
  style.diffuse = 0;
  style.background_srgb8 = {0, 0, 0};
  return style;
}

std::array<int, 3> Pixel(const ImageRgb8& image, int x, int y) {
  const std::uint8_t* p = image.At(x, y);
  return {p[0], p[1], p[2]};
}

std::array<int, 3> Encode(const Eigen::Vector3f& linear) {
  return {LinearToSrgb8(linear[0]), LinearToSrgb8(linear[1]), LinearToSrgb8(linear[2])};
}

TEST(ViewsTest, ThermalIsThePaletteAtTheInterpolatedTemperature) {
  const ThermalMesh mesh = Triangle();
  SampleBuffer b = Misses(2, 2);
  Hit(&b, 0, 0, 0, 0.25f, 0.5f);         // 0.25·20 + 0.25·30 + 0.5·40 = 32.5 → t = 0.625
  Hit(&b, 1, 1, 0, 0.25f, 0.5f, 0.6f);   // same, shaded
  ViewStyle style = Style(ViewMode::kThermal);
  ImageRgb8 image = ComposeView(mesh, b, mesh.temperature_c, style);
  ASSERT_EQ(image.width, 2);
  ASSERT_EQ(image.height, 2);
  EXPECT_EQ(Pixel(image, 0, 0), Encode(PaletteColour(Palette::kIron, false, 0.625)));
  EXPECT_EQ(Pixel(image, 1, 0), (std::array<int, 3>{0, 0, 0}));  // miss: background
  // Shading 0.5 + 0.5 · 0.6 = 0.8 multiplies linear light.
  style.ambient = 0.5;
  style.diffuse = 0.5;
  style.palette = Palette::kRainbow;
  image = ComposeView(mesh, b, mesh.temperature_c, style);
  EXPECT_EQ(Pixel(image, 1, 1), Encode(0.8f * PaletteColour(Palette::kRainbow, false, 0.625)));
  EXPECT_EQ(Pixel(image, 0, 0), Encode(PaletteColour(Palette::kRainbow, false, 0.625)));
}

TEST(ViewsTest, ThermalMatchesThePaletteWithinOneLevelAtAnyTemperature) {
  // The view tabulates the palette; at temperatures off the table's grid the colour is
  // still the palette's to within one 8-bit level (rounding at a level boundary).
  const ThermalMesh mesh = Triangle();
  SampleBuffer b = Misses(997, 1);
  for (int x = 0; x < 997; ++x) Hit(&b, x, 0, 0, 0, static_cast<float>(x) / 996);  // 20..40 °C
  for (Palette palette : {Palette::kIron, Palette::kRainbow, Palette::kDiverging}) {
    ViewStyle style = Style(ViewMode::kThermal);
    style.palette = palette;
    const ImageRgb8 image = ComposeView(mesh, b, mesh.temperature_c, style);
    for (int x = 0; x < 997; ++x) {
      const std::array<int, 3> expected = Encode(PaletteColour(palette, false, x / 996.0));
      const std::array<int, 3> got = Pixel(image, x, 0);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(got[c], expected[c], 1) << PaletteName(palette) << " x=" << x;
    }
  }
}

TEST(ViewsTest, ColourModeShowsTheVisibleColourOrGrey) {
  ThermalMesh mesh = Triangle(true);
  mesh.colour_linear[2] = Eigen::Vector3f(0.9f, 0.1f, 0.5f);
  SampleBuffer b = Misses(2, 1);
  Hit(&b, 0, 0, 0, 0.25f, 0.5f);
  const ImageRgb8 image = ComposeView(mesh, b, {}, Style(ViewMode::kColour));
  EXPECT_EQ(Pixel(image, 0, 0), Encode(0.5f * Eigen::Vector3f::Constant(0.3f) +
                                       0.5f * Eigen::Vector3f(0.9f, 0.1f, 0.5f)));
  const ImageRgb8 grey = ComposeView(Triangle(false), b, {}, Style(ViewMode::kColour));
  EXPECT_EQ(Pixel(grey, 0, 0), Encode(Eigen::Vector3f::Constant(0.5f)));
}

TEST(ViewsTest, IhMappingHueFromTemperatureIntensityFromTexture) {
  const ThermalMesh mesh = Triangle(true);  // grey texture, luminance 0.3
  SampleBuffer b = Misses(3, 2);
  Hit(&b, 0, 0, 0, 0, 0);  // vertex 0: 20 °C → hue 240° (blue)
  Hit(&b, 1, 0, 0, 1, 0);  // vertex 1: 30 °C → hue 120° (green)
  Hit(&b, 2, 0, 0, 0, 1);  // vertex 2: 40 °C → hue 0° (red)
  Hit(&b, 0, 1, 0, 0, 1, 0.0f);  // 40 °C seen at grazing angle: shading = ambient
  ViewStyle style = Style(ViewMode::kIhMapping);
  style.ambient = 0.5;
  style.diffuse = 0.5;
  const ImageRgb8 image = ComposeView(mesh, b, mesh.temperature_c, style);
  const int v = LinearToSrgb8(0.3f);
  EXPECT_EQ(Pixel(image, 0, 0), (std::array<int, 3>{0, 0, v}));
  EXPECT_EQ(Pixel(image, 1, 0), (std::array<int, 3>{0, v, 0}));
  EXPECT_EQ(Pixel(image, 2, 0), (std::array<int, 3>{v, 0, 0}));
  // Intensity = luminance · shading: 0.3 · 0.5.
  EXPECT_EQ(Pixel(image, 0, 1), (std::array<int, 3>{LinearToSrgb8(0.15f), 0, 0}));
}

TEST(ViewsTest, HighlightOverridesOnlyOutsideTheBand) {
  ThermalMesh mesh = Triangle(true);
  SampleBuffer b = Misses(2, 2);
  Hit(&b, 0, 0, 0, 0, 0);  // 20 °C: below the band
  Hit(&b, 1, 0, 0, 1, 0);  // 30 °C: inside
  Hit(&b, 0, 1, 0, 0, 1);  // 40 °C: above
  ViewStyle style = Style(ViewMode::kHighlight);
  style.band_low_c = 25;
  style.band_high_c = 35;
  const ImageRgb8 image = ComposeView(mesh, b, mesh.temperature_c, style);
  EXPECT_EQ(Pixel(image, 0, 0), Encode(PaletteColour(Palette::kIron, false, 0)));
  EXPECT_EQ(Pixel(image, 1, 0), Encode(Eigen::Vector3f::Constant(0.3f)));
  EXPECT_EQ(Pixel(image, 0, 1), Encode(PaletteColour(Palette::kIron, false, 1)));
  EXPECT_EQ(Pixel(image, 1, 1), (std::array<int, 3>{0, 0, 0}));
  // Band edges belong to the band.
  style.band_low_c = 20;
  style.band_high_c = 40;
  const ImageRgb8 all_normal = ComposeView(mesh, b, mesh.temperature_c, style);
  EXPECT_EQ(Pixel(all_normal, 0, 0), Encode(Eigen::Vector3f::Constant(0.3f)));
  EXPECT_EQ(Pixel(all_normal, 0, 1), Encode(Eigen::Vector3f::Constant(0.3f)));
}

TEST(ViewsTest, UnobservedIsHatchedNeverAPaletteColour) {
  ThermalMesh mesh = Triangle(true);
  mesh.temperature_c[0] = kNaN;
  SampleBuffer b = Misses(3, 1);
  Hit(&b, 0, 0, 0, 0.1f, 0.1f);  // vertex 0 carries 0.8: unobserved
  Hit(&b, 1, 0, 0, 0.4f, 0.4f);  // vertex 0 carries 0.2: (0.4·30 + 0.4·40) / 0.8 = 35
  Hit(&b, 2, 0, 0, 0.25f, 0.25f);  // exactly half on finite vertices: still observed, 35
  for (ViewMode mode : {ViewMode::kThermal, ViewMode::kIhMapping, ViewMode::kHighlight}) {
    ViewStyle style = Style(mode);
    style.band_low_c = 0;
    style.band_high_c = 1;  // everything observed is outside the band
    const ImageRgb8 image = ComposeView(mesh, b, mesh.temperature_c, style);
    const int grey = LinearToSrgb8(UnobservedHatchGrey(0, 0, style.hatch_period_px));
    EXPECT_EQ(Pixel(image, 0, 0), (std::array<int, 3>{grey, grey, grey})) << ViewModeName(mode);
    if (mode != ViewMode::kIhMapping) {
      EXPECT_EQ(Pixel(image, 1, 0), Encode(PaletteColour(Palette::kIron, false, 0.75)));
      EXPECT_EQ(Pixel(image, 2, 0), Encode(PaletteColour(Palette::kIron, false, 0.75)));
    }
  }
  // The colour view does not show temperature: no hatch.
  const ImageRgb8 colour = ComposeView(mesh, b, mesh.temperature_c, Style(ViewMode::kColour));
  EXPECT_EQ(Pixel(colour, 0, 0), Encode(Eigen::Vector3f::Constant(0.3f)));
}

TEST(ViewsTest, HatchHasLinesAndGaps) {
  // Along a row, one period holds both the line (darker) and the base grey.
  float darkest = 1, lightest = 0;
  for (int x = 0; x < 8; ++x) {
    darkest = std::min(darkest, UnobservedHatchGrey(x, 3, 8));
    lightest = std::max(lightest, UnobservedHatchGrey(x, 3, 8));
  }
  EXPECT_EQ(LinearToSrgb8(darkest), std::lround(0.40 * 255));
  EXPECT_EQ(LinearToSrgb8(lightest), std::lround(0.62 * 255));
  EXPECT_EQ(UnobservedHatchGrey(2, 5, 8), UnobservedHatchGrey(10, 5, 8));  // periodic
}

TEST(ViewsTest, AntiAliasingAveragesInLinearLight) {
  const ThermalMesh mesh = Triangle();
  SampleBuffer b = Misses(1, 1, 2);
  Hit(&b, 0, 0, 0, 0, 1);  // 40 °C: white on the grey palette
  ViewStyle style = Style(ViewMode::kThermal);
  style.palette = Palette::kGrey;  // background black
  const ImageRgb8 image = ComposeView(mesh, b, mesh.temperature_c, style);
  // Half white, half black: linear 0.5 → sRGB 188, not the 128 of averaging encoded values.
  EXPECT_EQ(Pixel(image, 0, 0), (std::array<int, 3>{188, 188, 188}));
}

TEST(ViewsTest, TemperatureImageMeansFiniteSamples) {
  ThermalMesh mesh = Triangle();
  mesh.temperature_c[0] = kNaN;
  SampleBuffer b = Misses(3, 1, 2);
  Hit(&b, 0, 0, 0, 0.4f, 0.4f);  // 35
  Hit(&b, 0, 0, 1, 0, 1);        // 40 (the other sample of pixel 0 — mean 37.5)
  Hit(&b, 1, 0, 0, 1, 0);        // 30, and a miss
  Hit(&b, 2, 0, 0, 0.1f, 0.1f);  // unobserved, and a miss
  const std::vector<float> t = TemperatureImage(mesh, b, mesh.temperature_c);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_FLOAT_EQ(t[0], 37.5f);
  EXPECT_FLOAT_EQ(t[1], 30.0f);
  EXPECT_TRUE(std::isnan(t[2]));
}

TEST(ViewsTest, StyleCheckNamesFieldAndValue) {
  ViewStyle style;
  EXPECT_EQ(style.Check(), "");  // kThermal: the band is not needed
  style.mode = ViewMode::kHighlight;
  EXPECT_EQ(style.Check(), "band_low_c: must be finite, got nan");
  style.band_low_c = 40;
  style.band_high_c = 30;
  EXPECT_EQ(style.Check(), "band_high_c: must be > band_low_c (40), got 30");
  style.band_high_c = 45;
  EXPECT_EQ(style.Check(), "");
  style.span = Span{30, 30};
  EXPECT_EQ(style.Check(), "span.max_c: must be > span.min_c (30), got 30");
  style.span = Span{20, 30};
  style.ambient = 0.8;
  EXPECT_EQ(style.Check(), "ambient + diffuse: must be in (0, 1], got 1.1000000000000001");
  style.ambient = -0.1;
  EXPECT_EQ(style.Check(), "ambient: must be in [0, 1], got -0.10000000000000001");
  style.ambient = 0.7;
  style.hatch_period_px = 2;
  EXPECT_EQ(style.Check(), "hatch_period_px: must be in [3, 64], got 2");
}

TEST(ViewsTest, ViewModeNames) {
  for (ViewMode mode : {ViewMode::kThermal, ViewMode::kColour, ViewMode::kIhMapping, ViewMode::kHighlight}) {
    EXPECT_EQ(ParseViewMode(ViewModeName(mode)), mode);
  }
  EXPECT_EQ(ParseViewMode("color"), ViewMode::kColour);
  EXPECT_EQ(ParseViewMode("ih-mapping"), ViewMode::kIhMapping);
  EXPECT_FALSE(ParseViewMode("Thermal").has_value());
  EXPECT_FALSE(ParseViewMode("").has_value());
}

}  // namespace
}  // namespace hw::analyze
