#pragma once

// Thermal palettes (temperature → colour) and the temperature span they are stretched over.
// Colours are linear RGB in [0, 1] (see analyze/srgb.h): views blend, shade and average in
// linear light and encode to sRGB only when writing 8-bit pixels.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace hw::analyze {

enum class Palette {
  kIron,       // black → indigo → purple → red → orange → yellow → white (luminance rises)
  kRainbow,    // navy → blue → cyan → green → yellow → orange → red (hue sweep)
  kGrey,       // black → white, even steps in sRGB (perceptually even)
  kDiverging,  // blue → white → red, symmetric about t = 0.5, for before/after differences
};

// Colour of `palette` at t01 ∈ [0, 1] (clamped; NaN asserts), linear RGB in [0, 1].
// `inverted` reverses the palette (t → 1 − t). Iron, rainbow and diverging are defined by
// control points in sRGB (the way thermal camera LUTs are published), interpolated in sRGB
// and decoded to linear; grey is t in sRGB, decoded.
Eigen::Vector3f PaletteColour(Palette palette, bool inverted, double t01);

// IH mapping (Moghadam & Vidas, HeatWave): colour of a surface at t01 ∈ [0, 1] (clamped)
// of the temperature span with visible intensity `intensity_linear` (linear light, [0, 1]):
// HSV taken in sRGB with hue 240° · (1 − t01) (blue cold → red hot), saturation 1 and
// value = sRGB encoding of the intensity, then decoded to linear RGB. The largest sRGB
// channel is thus the encoded intensity, the hue the temperature. IhColour(t, 1) is the
// colour bar of IH views.
Eigen::Vector3f IhColour(double t01, float intensity_linear);

struct PaletteChoice {
  Palette palette = Palette::kIron;
  bool inverted = false;
};
// "iron", "rainbow", "grey", "diverging", each optionally with the suffix "-inverted"
// ("iron-inverted"); nullopt for anything else.
std::optional<PaletteChoice> ParsePalette(std::string_view name);
// The name ParsePalette accepts for a choice, e.g. "rainbow-inverted".
std::string PaletteName(Palette palette, bool inverted = false);

// The temperatures (°C; K for differences) mapped to the palette's ends.
struct Span {
  double min_c = 0;
  double max_c = 1;
  // (value − min_c) / (max_c − min_c), clamped to [0, 1]; NaN stays NaN. Asserts
  // max_c > min_c.
  double Normalize(double value_c) const;
};

// The span from the `low_percentile` to the `high_percentile` (both in [0, 100], low <
// high; asserted) of the finite values (NaN and ±Inf ignored), percentiles interpolated
// linearly between order statistics. A span narrower than 0.1 (a uniform surface) is
// widened symmetrically to 0.1, so the palette stays defined. With no finite value, returns
// {0, 1}: nothing will be coloured with it.
Span AutoSpan(const std::vector<float>& values, double low_percentile, double high_percentile);

// AutoSpan made symmetric about 0 (±max(|min|, |max|)), for differences on the diverging
// palette, so that white means "no change".
Span SymmetricAutoSpan(const std::vector<float>& values, double low_percentile,
                       double high_percentile);

// A "nice" step for about `target_count` intervals over `range` (> 0): 1, 2, 2.5 or 5 ×
// 10^k, the smallest of those ≥ range / target_count. target_count ≥ 1.
double NiceStep(double range, int target_count);

// Tick values for a colour bar over `span`: the multiples of NiceStep(span width,
// target_count) inside the span (inclusive, with a tolerance of 1e-9 of the width), in
// increasing order; at least two for any span, since NiceStep ≤ width / target_count.
std::vector<double> NiceTicks(const Span& span, int target_count = 6);

// Tick label with as many decimals as `step` needs (step 0.5 → "21.5", step 2 → "22",
// step 0.25 → "21.25"); "−" (U+2212) for negative values, never "-0".
std::string FormatTick(double value, double step);

}  // namespace hw::analyze
