#include "analyze/annotate.h"

#include <algorithm>
#include <array>
#include <cstdlib>

#include <gtest/gtest.h>

#include "analyze/srgb.h"

namespace hw::analyze {
namespace {

constexpr std::array<int, 3> kFill = {60, 90, 120};

ImageRgb8 Uniform(int width, int height) {
  ImageRgb8 image;
  image.width = width;
  image.height = height;
  for (int i = 0; i < width * height; ++i) image.rgb.insert(image.rgb.end(), {60, 90, 120});
  return image;
}

std::array<int, 3> Pixel(const ImageRgb8& image, int x, int y) {
  const std::uint8_t* p = image.At(x, y);
  return {p[0], p[1], p[2]};
}

bool Near(const std::array<int, 3>& a, const std::array<int, 3>& b, int tolerance) {
  for (int c = 0; c < 3; ++c) {
    if (std::abs(a[c] - b[c]) > tolerance) return false;
  }
  return true;
}

std::array<int, 3> Srgb8(const Eigen::Vector3f& linear) {
  return {LinearToSrgb8(linear[0]), LinearToSrgb8(linear[1]), LinearToSrgb8(linear[2])};
}

bool Light(const std::array<int, 3>& p) { return p[0] > 180 && p[1] > 180 && p[2] > 180; }

Annotation WithBar() {
  Annotation a;
  a.title = "Wall, east side";
  ColourBar bar;
  bar.span = Span{20, 30};
  bar.title = "Surface temperature";
  a.colour_bar = bar;
  return a;
}

TEST(AnnotateTest, NothingToDrawLeavesTheImage) {
  const ImageRgb8 image = Uniform(64, 48);
  const ImageRgb8 out = Annotate(image, Annotation{});
  EXPECT_EQ(out.width, 64);
  EXPECT_EQ(out.height, 48);
  EXPECT_EQ(out.rgb, image.rgb);
}

TEST(AnnotateTest, ColourBarPanelGrowsTheImageAndHoldsThePaletteAndTicks) {
  const ImageRgb8 image = Uniform(240, 360);  // text 11 px (the minimum), bar ≈ 250 px
  const ImageRgb8 out = Annotate(image, WithBar());
  ASSERT_GT(out.width, 240 + 40);  // a bar, ticks and labels
  // The title strip on top: the image starts lower, unchanged.
  int title_h = 0;
  while (title_h < out.height && Pixel(out, 5, title_h) != kFill) ++title_h;
  EXPECT_GT(title_h, 10);
  EXPECT_EQ(out.height, 360 + title_h);
  EXPECT_EQ(Pixel(out, 10, title_h + 350), kFill);
  EXPECT_EQ(Pixel(out, 239, out.height - 1), kFill);
  // The title's text: light pixels in the strip.
  int title_text = 0;
  for (int y = 0; y < title_h; ++y) {
    for (int x = 0; x < 240; ++x) title_text += Light(Pixel(out, x, y));
  }
  EXPECT_GT(title_text, 20);

  // The bar: a panel column holding iron's orange (t = 0.75) above its purple (t = 0.28).
  const std::array<int, 3> orange = Srgb8(PaletteColour(Palette::kIron, false, 0.75));
  const std::array<int, 3> purple = Srgb8(PaletteColour(Palette::kIron, false, 0.28));
  int bar_x = -1, orange_y = -1, purple_y = -1;
  for (int x = 240; x < out.width && bar_x < 0; ++x) {
    int o = -1, p = -1;
    for (int y = 0; y < out.height; ++y) {
      if (o < 0 && Near(Pixel(out, x, y), orange, 6)) o = y;
      if (p < 0 && Near(Pixel(out, x, y), purple, 6)) p = y;
    }
    if (o >= 0 && p >= 0) {
      bar_x = x;
      orange_y = o;
      purple_y = p;
    }
  }
  ASSERT_GE(bar_x, 240) << "no palette column in the panel";
  EXPECT_LT(orange_y, purple_y);  // hot at the top
  // Span 20..30: t = 0.75 is 27.5 °C; the 0.28 point 22.8 °C; their rows are
  // (0.75 − 0.28) of the bar height apart, and the bar fits in the panel.
  EXPECT_GT(purple_y - orange_y, 0.3 * (out.height - title_h) * 0.47);

  // Tick labels: light text right of the bar in separate rows along the bar (its rows:
  // where the bar column is not the panel's colour).
  const std::array<int, 3> panel = {32, 32, 32};
  int bar_top = orange_y, bar_bottom = purple_y;
  while (Pixel(out, bar_x, bar_top - 1) != panel) --bar_top;
  while (Pixel(out, bar_x, bar_bottom + 1) != panel) ++bar_bottom;
  EXPECT_GT(bar_bottom - bar_top, 200);
  // A cluster: rows with light pixels, separated by ≥ 8 rows without (labels are ≈ 50 px
  // apart; the thin diagonal of an 11-px "2" leaves a few rows below the threshold).
  int clusters = 0;
  int gap = 1000;
  for (int y = bar_top; y <= bar_bottom; ++y) {
    bool light = false;
    for (int x = bar_x + 24; x < out.width; ++x) light = light || Light(Pixel(out, x, y));
    if (light && gap >= 8) ++clusters;
    gap = light ? 0 : gap + 1;
  }
  // NiceTicks over 20..30 for ≈ 250 px / (2.6 · 11 px) = 8 intervals: step 2, six labels
  // 20 … 30 (the two end labels half inside the bar's rows).
  EXPECT_EQ(clusters, 6);
}

TEST(AnnotateTest, HighlightBandAndUnobservedKeyAreDrawn) {
  Annotation a = WithBar();
  a.colour_bar->band = Span{22, 28};
  const ImageRgb8 out = Annotate(Uniform(240, 180), a);
  // The band is neutral grey on the bar: a run of (128, 128, 128) in some panel column.
  int band_pixels = 0, hatch_dark = 0;
  const int line = LinearToSrgb8(UnobservedHatchGrey(0, 0, 8));  // a hatch line pixel
  for (int x = 240; x < out.width; ++x) {
    for (int y = 0; y < out.height; ++y) {
      band_pixels += Pixel(out, x, y) == std::array<int, 3>{128, 128, 128};
      hatch_dark += Pixel(out, x, y) == std::array<int, 3>{line, line, line};
    }
  }
  EXPECT_GT(band_pixels, 100);
  EXPECT_GT(hatch_dark, 5);
}

TEST(AnnotateTest, SpotMarkerAndLabelStayInsideTheImage) {
  Annotation a;
  a.spots.push_back({Eigen::Vector2d(230.5, 90.5), "H1 78.3 °C", true});  // pixel (230, 90)
  const ImageRgb8 out = Annotate(Uniform(240, 180), a);
  ASSERT_EQ(out.width, 240);
  ASSERT_EQ(out.height, 180);
  // The marker's centre dot.
  EXPECT_TRUE(Light(Pixel(out, 230, 90)));
  // The label near the right edge was moved to the left of the marker, fully inside.
  int left_text = 0;
  for (int y = 70; y < 110; ++y) {
    for (int x = 120; x < 220; ++x) left_text += Light(Pixel(out, x, y));
  }
  EXPECT_GT(left_text, 40);
  // Away from the spot nothing changed.
  EXPECT_EQ(Pixel(out, 20, 20), kFill);
  EXPECT_EQ(Pixel(out, 230, 170), kFill);
}

TEST(AnnotateTest, HiddenSpotIsDimmer) {
  Annotation visible;
  visible.spots.push_back({Eigen::Vector2d(60, 60), "C1 12.0 °C", true});
  Annotation hidden = visible;
  hidden.spots[0].visible = false;
  auto brightest = [](const ImageRgb8& image) {
    int best = 0;
    for (std::uint8_t v : image.rgb) best = std::max<int>(best, v);
    return best;
  };
  EXPECT_EQ(brightest(Annotate(Uniform(240, 180), visible)), 255);
  EXPECT_LT(brightest(Annotate(Uniform(240, 180), hidden)), 240);
}

}  // namespace
}  // namespace hw::analyze
