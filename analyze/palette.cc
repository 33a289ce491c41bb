#include "analyze/palette.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <span>

#include "analyze/srgb.h"

namespace hw::analyze {
namespace {

// A control point: position in [0, 1] and an 8-bit sRGB colour.
struct Stop {
  double t;
  std::array<int, 3> srgb8;
};

// Iron ("ironbow"), the usual thermography palette: black through indigo, purple, crimson,
// orange and yellow to white, after the published LUTs of handheld thermal cameras. The
// stops are chosen so that relative luminance rises monotonically (a hotter surface is
// never drawn darker), which the tests check.
constexpr std::array<Stop, 8> kIron = {{
    {0.00, {0, 0, 0}},
    {0.12, {30, 10, 110}},
    {0.28, {110, 10, 155}},
    {0.45, {195, 30, 110}},
    {0.60, {235, 80, 25}},
    {0.75, {250, 150, 0}},
    {0.90, {255, 220, 60}},
    {1.00, {255, 255, 255}},
}};

// Rainbow: a hue sweep blue → red with a dark navy start so the cold end is not mistaken
// for the background.
constexpr std::array<Stop, 7> kRainbow = {{
    {0.00, {0, 0, 90}},
    {0.14, {0, 0, 255}},
    {0.32, {0, 200, 255}},
    {0.50, {0, 230, 80}},
    {0.68, {255, 240, 0}},
    {0.84, {255, 128, 0}},
    {1.00, {220, 0, 0}},
}};

// Blue–white–red after ColorBrewer's RdBu (Brewer, colorbrewer2.org), symmetric about 0.5.
constexpr std::array<Stop, 7> kDiverging = {{
    {0.0, {33, 102, 172}},
    {1.0 / 6, {103, 169, 207}},
    {2.0 / 6, {209, 229, 240}},
    {0.5, {247, 247, 247}},
    {4.0 / 6, {253, 219, 199}},
    {5.0 / 6, {239, 138, 98}},
    {1.0, {178, 24, 43}},
}};

Eigen::Vector3f FromStops(std::span<const Stop> stops, double t) {
  size_t i = 1;
  while (i + 1 < stops.size() && t > stops[i].t) ++i;
  const Stop& a = stops[i - 1];
  const Stop& b = stops[i];
  const double w = std::clamp((t - a.t) / (b.t - a.t), 0.0, 1.0);
  Eigen::Vector3f linear;
  for (int c = 0; c < 3; ++c) {
    const double encoded = ((1 - w) * a.srgb8[c] + w * b.srgb8[c]) / 255.0;
    linear[c] = SrgbToLinear(static_cast<float>(encoded));
  }
  return linear;
}

// HSV → RGB (all in [0, 1], hue in degrees [0, 360)).
Eigen::Vector3f HsvToRgb(float hue_deg, float saturation, float value) {
  const float h = std::fmod(std::max(hue_deg, 0.0f), 360.0f) / 60.0f;
  const float c = value * saturation;
  const float x = c * (1 - std::abs(std::fmod(h, 2.0f) - 1));
  const float m = value - c;
  Eigen::Vector3f rgb;
  switch (static_cast<int>(h)) {
    case 0: rgb = {c, x, 0}; break;
    case 1: rgb = {x, c, 0}; break;
    case 2: rgb = {0, c, x}; break;
    case 3: rgb = {0, x, c}; break;
    case 4: rgb = {x, 0, c}; break;
    default: rgb = {c, 0, x}; break;
  }
  return rgb + Eigen::Vector3f::Constant(m);
}


constexpr std::string_view kInvertedSuffix = "-inverted";

}  // namespace

Eigen::Vector3f PaletteColour(Palette palette, bool inverted, double t01) {
  assert(!std::isnan(t01));
  double t = std::clamp(t01, 0.0, 1.0);
  if (inverted) t = 1 - t;
  switch (palette) {
    case Palette::kIron:
      return FromStops(kIron, t);
    case Palette::kRainbow:
      return FromStops(kRainbow, t);
    case Palette::kDiverging:
      return FromStops(kDiverging, t);
    case Palette::kGrey:
      break;
  }
  return Eigen::Vector3f::Constant(SrgbToLinear(static_cast<float>(t)));
}

Eigen::Vector3f IhColour(double t01, float intensity_linear) {
  assert(!std::isnan(t01));
  const auto t = static_cast<float>(std::clamp(t01, 0.0, 1.0));
  const Eigen::Vector3f encoded = HsvToRgb(240.0f * (1 - t), 1.0f, LinearToSrgb(intensity_linear));
  return {SrgbToLinear(encoded[0]), SrgbToLinear(encoded[1]), SrgbToLinear(encoded[2])};
}

std::optional<PaletteChoice> ParsePalette(std::string_view name) {
  PaletteChoice choice;
  if (name.size() > kInvertedSuffix.size() && name.ends_with(kInvertedSuffix)) {
    choice.inverted = true;
    name.remove_suffix(kInvertedSuffix.size());
  }
  if (name == "iron") {
    choice.palette = Palette::kIron;
  } else if (name == "rainbow") {
    choice.palette = Palette::kRainbow;
  } else if (name == "grey") {
    choice.palette = Palette::kGrey;
  } else if (name == "diverging") {
    choice.palette = Palette::kDiverging;
  } else {
    return std::nullopt;
  }
  return choice;
}

std::string PaletteName(Palette palette, bool inverted) {
  std::string name;
  switch (palette) {
    case Palette::kIron: name = "iron"; break;
    case Palette::kRainbow: name = "rainbow"; break;
    case Palette::kGrey: name = "grey"; break;
    case Palette::kDiverging: name = "diverging"; break;
  }
  if (inverted) name += kInvertedSuffix;
  return name;
}

double Span::Normalize(double value_c) const {
  assert(max_c > min_c);
  if (std::isnan(value_c)) return value_c;
  return std::clamp((value_c - min_c) / (max_c - min_c), 0.0, 1.0);
}

namespace {

// Percentile p ∈ [0, 100] of sorted values, linear between order statistics.
double Percentile(const std::vector<float>& sorted, double p) {
  const double position = p / 100.0 * static_cast<double>(sorted.size() - 1);
  const auto below = static_cast<size_t>(std::floor(position));
  const size_t above = std::min(below + 1, sorted.size() - 1);
  const double w = position - static_cast<double>(below);
  return (1 - w) * double{sorted[below]} + w * double{sorted[above]};
}

constexpr double kMinSpanWidth = 0.1;

}  // namespace

Span AutoSpan(const std::vector<float>& values, double low_percentile, double high_percentile) {
  assert(low_percentile >= 0 && high_percentile <= 100 && low_percentile < high_percentile);
  std::vector<float> finite;
  finite.reserve(values.size());
  for (float v : values) {
    if (std::isfinite(v)) finite.push_back(v);
  }
  if (finite.empty()) return Span{0, 1};
  std::sort(finite.begin(), finite.end());
  Span span{Percentile(finite, low_percentile), Percentile(finite, high_percentile)};
  if (span.max_c - span.min_c < kMinSpanWidth) {
    const double centre = 0.5 * (span.min_c + span.max_c);
    span = Span{centre - 0.5 * kMinSpanWidth, centre + 0.5 * kMinSpanWidth};
  }
  return span;
}

Span SymmetricAutoSpan(const std::vector<float>& values, double low_percentile,
                       double high_percentile) {
  const Span span = AutoSpan(values, low_percentile, high_percentile);
  const double half = std::max(std::abs(span.min_c), std::abs(span.max_c));
  return Span{-half, half};
}

double NiceStep(double range, int target_count) {
  assert(range > 0 && std::isfinite(range) && target_count >= 1);
  const double raw = range / target_count;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double mantissa : {1.0, 2.0, 2.5, 5.0, 10.0}) {
    // The tolerance keeps 10/5 = 2 at 2 rather than jumping to 2.5 on rounding noise.
    if (mantissa * decade >= raw * (1 - 1e-12)) return mantissa * decade;
  }
  return 10 * decade;
}

std::vector<double> NiceTicks(const Span& span, int target_count) {
  const double width = span.max_c - span.min_c;
  assert(width > 0);
  const double step = NiceStep(width, target_count);
  const double tolerance = 1e-9 * width;
  std::vector<double> ticks;
  for (double k = std::ceil((span.min_c - tolerance) / step);; k += 1) {
    const double value = k * step;
    if (value > span.max_c + tolerance) break;
    ticks.push_back(value == 0 ? 0.0 : value);  // no −0
  }
  return ticks;
}

std::string FormatTick(double value, double step) {
  int decimals = 0;
  // Smallest number of decimals that shows multiples of `step` exactly (up to 6).
  while (decimals < 6 && std::abs(step * std::pow(10.0, decimals) -
                                  std::round(step * std::pow(10.0, decimals))) >
                             1e-6 * step * std::pow(10.0, decimals)) {
    ++decimals;
  }
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, std::abs(value));
  std::string text = buffer;
  const bool all_zero = text.find_first_not_of("0.") == std::string::npos;
  if (value < 0 && !all_zero) text = "\u2212" + text;
  return text;
}

}  // namespace hw::analyze
