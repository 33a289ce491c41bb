#pragma once

// The analyzer's images from a render's samples (analyze/render.h): every sample is
// coloured (thermal palette, visible colour, IH mapping, thermal highlighting), the samples
// of a pixel are averaged in linear light (anti-aliasing without darkened edges) and the
// mean is encoded to 8-bit sRGB. Surface whose temperature is unobserved (NaN) is drawn as
// a neutral grey diagonal hatch in every mode that shows temperature, never as a
// temperature.

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "analyze/palette.h"
#include "analyze/render.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

enum class ViewMode {
  kThermal,    // palette(temperature) × shading
  kColour,     // visible colour × shading (grey when the mesh has no colour)
  kIhMapping,  // hue from temperature, intensity from the visible texture (HeatWave paper)
  kHighlight,  // visible colour, palette where the temperature is outside the normal band
};
// "thermal", "colour" (or "color"), "ih" (or "ih-mapping"), "highlight"; nullopt otherwise.
std::optional<ViewMode> ParseViewMode(std::string_view name);
// "thermal", "colour", "ih", "highlight".
std::string ViewModeName(ViewMode mode);

struct ViewStyle {
  ViewMode mode = ViewMode::kThermal;
  Palette palette = Palette::kIron;
  bool inverted = false;  // palette reversed (cold = bright)
  // Field values (°C; K for differences) mapped to the palette's ends (IH: to hues 240°
  // and 0°); values outside are clamped to the end colours. Finite, min_c < max_c.
  Span span;
  // kHighlight: the normal band, °C; the palette overrides the visible colour only where
  // the temperature is below band_low_c or above band_high_c. Finite, low < high (checked
  // in that mode only).
  double band_low_c = std::numeric_limits<double>::quiet_NaN();
  double band_high_c = std::numeric_limits<double>::quiet_NaN();
  // Shading = ambient + diffuse · |cos incidence| (a headlight at the camera): a mild
  // relief cue that keeps palette colours readable. Each in [0, 1], sum in (0, 1] (1: a
  // surface seen head-on shows the palette colour exactly).
  double ambient = 0.7;
  double diffuse = 0.3;
  // Pixels no sample hit: 8-bit sRGB.
  std::array<std::uint8_t, 3> background_srgb8 = {48, 48, 48};
  // Period of the unobserved-surface hatch, pixels along x, in [3, 64].
  int hatch_period_px = 8;

  // "" or "field: must be ..., got ...".
  std::string Check() const;
};

// An 8-bit sRGB image, row-major, 3 bytes a pixel (R, G, B).
struct ImageRgb8 {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  // width · height · 3

  const std::uint8_t* At(int x, int y) const {
    return rgb.data() + (static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)) * 3;
  }
};

// Linear-light colour of the unobserved hatch at pixel (x, y) before shading: a mid grey
// with darker anti-aliased diagonal lines (R = G = B). Exposed for the colour bar's key
// and for tests.
float UnobservedHatchGrey(int x, int y, int period_px);

// The image of `samples` (a render of `mesh`) in `style`. `field_c` is per vertex (the
// mesh's temperature_c in °C, or a difference in K), interpolated at each sample over the
// face's finite vertices (NaN when they carry less than half the barycentric weight; see
// InterpolateAtSample in analyze/render.h); it may be empty in kColour mode. Asserts
// style.Check() == "", field_c.size() == mesh.NumVertices() in the temperature modes, the
// buffer's sizes and faces valid for the mesh.
//   thermal:   palette(span(T)) · shading
//   colour:    colour_linear · shading (0.5 linear grey without colour)
//   IH:        HSV in sRGB with hue = 240° · (1 − span(T)) (blue cold, red hot), saturation
//              1, value = sRGB encoding of (luminance(colour_linear) · shading); so the
//              largest sRGB channel carries the visible intensity and the hue the
//              temperature. Luminance = Rec. 709 weights on linear RGB.
//   highlight: colour view; palette(span(T)) · shading where T < band_low_c or T >
//              band_high_c.
// NaN temperature: UnobservedHatchGrey · shading (thermal, IH, highlight). Misses:
// background.
ImageRgb8 ComposeView(const ThermalMesh& mesh, const SampleBuffer& samples,
                      const std::vector<double>& field_c, const ViewStyle& style);

// Per pixel, the mean of the field over the pixel's samples where it is finite (same
// interpolation as ComposeView); NaN where no sample has one (a miss or unobserved
// surface). Row-major, width · height, the raw data for EXR/TIFF.
std::vector<float> TemperatureImage(const ThermalMesh& mesh, const SampleBuffer& samples,
                                    const std::vector<double>& field_c);

}  // namespace hw::analyze
