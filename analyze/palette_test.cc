#include "analyze/palette.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "analyze/srgb.h"

namespace hw::analyze {
namespace {

float Luminance(const Eigen::Vector3f& linear) {
  return 0.2126f * linear[0] + 0.7152f * linear[1] + 0.0722f * linear[2];
}

void ExpectSrgb8(const Eigen::Vector3f& linear, int r, int g, int b) {
  EXPECT_EQ(LinearToSrgb8(linear[0]), r);
  EXPECT_EQ(LinearToSrgb8(linear[1]), g);
  EXPECT_EQ(LinearToSrgb8(linear[2]), b);
}

TEST(PaletteTest, EndpointsAreTheControlPoints) {
  ExpectSrgb8(PaletteColour(Palette::kIron, false, 0), 0, 0, 0);
  ExpectSrgb8(PaletteColour(Palette::kIron, false, 1), 255, 255, 255);
  ExpectSrgb8(PaletteColour(Palette::kGrey, false, 0), 0, 0, 0);
  ExpectSrgb8(PaletteColour(Palette::kGrey, false, 1), 255, 255, 255);
  ExpectSrgb8(PaletteColour(Palette::kRainbow, false, 0), 0, 0, 90);
  ExpectSrgb8(PaletteColour(Palette::kRainbow, false, 1), 220, 0, 0);
  ExpectSrgb8(PaletteColour(Palette::kDiverging, false, 0), 33, 102, 172);
  ExpectSrgb8(PaletteColour(Palette::kDiverging, false, 0.5), 247, 247, 247);
  ExpectSrgb8(PaletteColour(Palette::kDiverging, false, 1), 178, 24, 43);
  // Interior stop of iron, and clamping outside [0, 1].
  ExpectSrgb8(PaletteColour(Palette::kIron, false, 0.75), 250, 150, 0);
  ExpectSrgb8(PaletteColour(Palette::kIron, false, -3), 0, 0, 0);
  ExpectSrgb8(PaletteColour(Palette::kIron, false, 7), 255, 255, 255);
}

TEST(PaletteTest, GreyIsTInSrgb) {
  // Half way is sRGB 0.5 → 128, i.e. linear 0.214, not linear 0.5.
  for (double t : {0.1, 0.5, 0.9}) {
    const Eigen::Vector3f c = PaletteColour(Palette::kGrey, false, t);
    EXPECT_NEAR(LinearToSrgb(c[0]), t, 1e-6);
    EXPECT_EQ(c[0], c[1]);
    EXPECT_EQ(c[1], c[2]);
  }
}

TEST(PaletteTest, IronAndGreyLuminanceRiseMonotonically) {
  for (Palette palette : {Palette::kIron, Palette::kGrey}) {
    float previous = -1;
    for (int i = 0; i <= 1000; ++i) {
      const float y = Luminance(PaletteColour(palette, false, i / 1000.0));
      EXPECT_GT(y, previous) << PaletteName(palette) << " at t = " << i / 1000.0;
      previous = y;
    }
  }
}

TEST(PaletteTest, InvertedIsReversed) {
  for (Palette palette : {Palette::kIron, Palette::kRainbow, Palette::kGrey, Palette::kDiverging}) {
    for (double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
      EXPECT_EQ(PaletteColour(palette, true, t), PaletteColour(palette, false, 1 - t))
          << PaletteName(palette) << " t=" << t;
    }
  }
}

TEST(PaletteTest, DivergingIsSymmetricInLuminance) {
  // Equal changes either side of 0 read as equally strong: the ColorBrewer RdBu stops
  // mirror each other's lightness within a few percent.
  for (double d : {0.1, 0.25, 0.4, 0.5}) {
    const float below = Luminance(PaletteColour(Palette::kDiverging, false, 0.5 - d));
    const float above = Luminance(PaletteColour(Palette::kDiverging, false, 0.5 + d));
    EXPECT_NEAR(below, above, 0.35f * std::max(below, above)) << d;
  }
  // White in the middle, blue below, red above.
  const Eigen::Vector3f cold = PaletteColour(Palette::kDiverging, false, 0.2);
  const Eigen::Vector3f hot = PaletteColour(Palette::kDiverging, false, 0.8);
  EXPECT_GT(cold[2], cold[0]);
  EXPECT_GT(hot[0], hot[2]);
}

TEST(PaletteTest, ParsePalette) {
  struct Case {
    const char* name;
    Palette palette;
    bool inverted;
  };
  for (const Case& c : {Case{"iron", Palette::kIron, false}, Case{"rainbow", Palette::kRainbow, false},
                        Case{"grey", Palette::kGrey, false}, Case{"diverging", Palette::kDiverging, false},
                        Case{"iron-inverted", Palette::kIron, true},
                        Case{"diverging-inverted", Palette::kDiverging, true}}) {
    const auto parsed = ParsePalette(c.name);
    ASSERT_TRUE(parsed.has_value()) << c.name;
    EXPECT_EQ(parsed->palette, c.palette);
    EXPECT_EQ(parsed->inverted, c.inverted);
    EXPECT_EQ(PaletteName(c.palette, c.inverted), c.name);
  }
  for (const char* bad : {"", "Iron", "gray", "-inverted", "iron-inverted-inverted", "iron ", "inverted"}) {
    EXPECT_FALSE(ParsePalette(bad).has_value()) << bad;
  }
}

TEST(PaletteTest, IhColourHueAndValue) {
  // t = 0: hue 240° (pure blue), t = 1: hue 0° (pure red), t = 0.5: hue 120° (green);
  // the largest sRGB channel is the encoded intensity.
  const float intensity = 0.2f;
  const float v = LinearToSrgb(intensity);
  const Eigen::Vector3f cold = IhColour(0, intensity);
  EXPECT_FLOAT_EQ(LinearToSrgb(cold[2]), v);
  EXPECT_FLOAT_EQ(cold[0], 0);
  EXPECT_FLOAT_EQ(cold[1], 0);
  const Eigen::Vector3f hot = IhColour(1, intensity);
  EXPECT_FLOAT_EQ(LinearToSrgb(hot[0]), v);
  EXPECT_FLOAT_EQ(hot[1] + hot[2], 0);
  const Eigen::Vector3f mid = IhColour(0.5, intensity);
  EXPECT_FLOAT_EQ(LinearToSrgb(mid[1]), v);
  EXPECT_FLOAT_EQ(mid[0] + mid[2], 0);
}

TEST(PaletteTest, AutoSpanPercentilesIgnoreNaN) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  // 0..100 in steps of 1 plus non-finite values: the 5th and 95th percentiles are 5 and 95.
  std::vector<float> values;
  for (int i = 100; i >= 0; --i) values.push_back(static_cast<float>(i));
  values.insert(values.begin() + 10, {nan, inf, -inf, nan});
  const Span span = AutoSpan(values, 5, 95);
  EXPECT_DOUBLE_EQ(span.min_c, 5);
  EXPECT_DOUBLE_EQ(span.max_c, 95);
  // Interpolated between order statistics: {10, 20}, 25th percentile = 12.5.
  EXPECT_DOUBLE_EQ(AutoSpan({20, nan, 10}, 25, 100).min_c, 12.5);
  // Uniform: widened to 0.1 about the value.
  const Span flat = AutoSpan({21, 21, nan}, 0, 100);
  EXPECT_NEAR(flat.min_c, 20.95, 1e-12);
  EXPECT_NEAR(flat.max_c, 21.05, 1e-12);
  // Nothing finite.
  const Span none = AutoSpan({nan, nan}, 1, 99);
  EXPECT_EQ(none.min_c, 0);
  EXPECT_EQ(none.max_c, 1);
  const Span symmetric = SymmetricAutoSpan({-1, 0, 3}, 0, 100);
  EXPECT_DOUBLE_EQ(symmetric.min_c, -3);
  EXPECT_DOUBLE_EQ(symmetric.max_c, 3);
}

TEST(PaletteTest, SpanNormalize) {
  const Span span{20, 30};
  EXPECT_DOUBLE_EQ(span.Normalize(22.5), 0.25);
  EXPECT_DOUBLE_EQ(span.Normalize(10), 0);
  EXPECT_DOUBLE_EQ(span.Normalize(40), 1);
  EXPECT_TRUE(std::isnan(span.Normalize(std::numeric_limits<double>::quiet_NaN())));
}

TEST(PaletteTest, NiceStepsAndTicks) {
  EXPECT_DOUBLE_EQ(NiceStep(10, 5), 2);
  EXPECT_DOUBLE_EQ(NiceStep(10, 6), 2);    // 1.67 → 2
  EXPECT_DOUBLE_EQ(NiceStep(10, 4), 2.5);  // 2.5
  EXPECT_DOUBLE_EQ(NiceStep(10, 3), 5);    // 3.33 → 5
  EXPECT_DOUBLE_EQ(NiceStep(0.7, 6), 0.2);  // 0.117 → 0.2
  EXPECT_DOUBLE_EQ(NiceStep(300, 4), 100);  // 75 → 100

  const std::vector<double> ticks = NiceTicks(Span{18.3, 31.7}, 6);  // step 2.5 (13.4/6 = 2.23)
  ASSERT_EQ(ticks.size(), 5u);
  EXPECT_DOUBLE_EQ(ticks.front(), 20);
  EXPECT_DOUBLE_EQ(ticks.back(), 30);
  const std::vector<double> exact = NiceTicks(Span{-5, 5}, 5);  // step 2: −4 … 4
  ASSERT_EQ(exact.size(), 5u);
  EXPECT_DOUBLE_EQ(exact.front(), -4);
  EXPECT_FALSE(std::signbit(exact[2]));
  EXPECT_EQ(NiceTicks(Span{0, 10}, 5).size(), 6u);  // ends included

  EXPECT_EQ(FormatTick(22.5, 2.5), "22.5");
  EXPECT_EQ(FormatTick(20, 2.5), "20.0");
  EXPECT_EQ(FormatTick(20, 2), "20");
  EXPECT_EQ(FormatTick(0.25, 0.25), "0.25");
  EXPECT_EQ(FormatTick(-4, 2), "\u22124");
  EXPECT_EQ(FormatTick(-0.0001, 1), "0");
}

}  // namespace
}  // namespace hw::analyze
