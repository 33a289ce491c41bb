#pragma once

// Annotation of the analyzer's images with Cairo and Pango: the colour bar (every thermal
// image carries its scale and units), spot markers with labels, and a title line.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/palette.h"
#include "analyze/views.h"

namespace hw::analyze {

// The scale of a thermal image, drawn in a panel to the right of the image, hot at the
// top.
struct ColourBar {
  Palette palette = Palette::kIron;
  bool inverted = false;
  // true for IH views: the bar shows the hue scale (IhColour(t, 1)) instead of `palette`.
  bool ih_hue = false;
  Span span;                 // the view's span (°C, or K for differences); min < max
  std::string units = "°C";  // shown above the bar: "°C" or "K"
  std::string title;         // e.g. "Surface temperature"; wrapped to the panel's width
  // Highlighting views: the normal band (°C); drawn on the bar in neutral grey (inside it
  // the image shows the visible colour) with its limits labelled on the bar's left.
  std::optional<Span> band;
  // A hatched swatch under the bar labelled "unobserved" (the view's NaN drawing).
  bool unobserved_key = true;
  int hatch_period_px = 8;  // as ViewStyle::hatch_period_px
};

// A spot's marker and label.
struct SpotLabel {
  // Where the spot is, image coordinates of the input image (pixels, continuous; pixel
  // (0, 0)'s centre at (0.5, 0.5)).
  Eigen::Vector2d position_px = Eigen::Vector2d::Zero();
  std::string text;  // e.g. "H1 78.3 °C"
  // false: the spot is hidden from this camera (behind other surface): drawn with a
  // dashed marker and dimmed text, so that a reader does not look for it on the surface.
  bool visible = true;
};

struct Annotation {
  std::string title;  // a line above the image; none when empty
  std::optional<ColourBar> colour_bar;
  std::vector<SpotLabel> spots;
  // The added panels (title strip, bar panel), 8-bit sRGB; text is drawn light on it.
  std::array<std::uint8_t, 3> panel_srgb8 = {32, 32, 32};
};

// The annotated image: `image` with a title strip on top (when a.title is set; the image
// grows in height) and the colour bar panel on its right (when a.colour_bar is set; the
// image grows in width), spot markers and labels drawn over the image, with a dark halo
// so they read on any background, and kept inside the image. Text size follows the image
// height (1/48 of it, 11 to 26 px). Asserts a non-empty image and a valid span/band.
ImageRgb8 Annotate(const ImageRgb8& image, const Annotation& a);

}  // namespace hw::analyze
