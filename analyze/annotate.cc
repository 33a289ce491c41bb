#include "analyze/annotate.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <memory>
#include <utility>

#include <cairo.h>
#include <pango/pangocairo.h>

#include "analyze/srgb.h"

namespace hw::analyze {
namespace {

struct CairoDeleter {
  void operator()(cairo_t* cr) const { cairo_destroy(cr); }
  void operator()(cairo_surface_t* surface) const { cairo_surface_destroy(surface); }
  void operator()(cairo_font_options_t* options) const { cairo_font_options_destroy(options); }
  void operator()(PangoLayout* layout) const { g_object_unref(layout); }
  void operator()(PangoFontDescription* font) const { pango_font_description_free(font); }
};
using LayoutPtr = std::unique_ptr<PangoLayout, CairoDeleter>;

// Colours of the annotation, sRGB in [0, 1] (Cairo blends in sRGB: fine for thin overlays).
struct Rgb {
  double r, g, b;
};
constexpr Rgb kPanelText{0.92, 0.92, 0.92};
constexpr Rgb kPanelSoftText{0.72, 0.72, 0.72};
constexpr Rgb kTickLine{0.80, 0.80, 0.80};
constexpr Rgb kLabelText{1, 1, 1};
constexpr Rgb kHalo{0.05, 0.05, 0.05};
// The band on a highlighting bar: a neutral grey standing for "visible colour here".
constexpr Rgb kBandGrey{0.50, 0.50, 0.50};

void SetColour(cairo_t* cr, const Rgb& c, double alpha = 1) {
  cairo_set_source_rgba(cr, c.r, c.g, c.b, alpha);
}

// Text with one font, measured in whole pixels.
class TextMaker {
 public:
  TextMaker(cairo_t* cr, double font_px) : cr_(cr), font_px_(font_px) {
    std::unique_ptr<cairo_font_options_t, CairoDeleter> options(cairo_font_options_create());
    cairo_font_options_set_antialias(options.get(), CAIRO_ANTIALIAS_GRAY);
    cairo_font_options_set_hint_style(options.get(), CAIRO_HINT_STYLE_SLIGHT);
    cairo_font_options_set_hint_metrics(options.get(), CAIRO_HINT_METRICS_OFF);
    cairo_set_font_options(cr_, options.get());
  }

  // A layout of `text` at scale × the base size; wrapped (or ellipsized) to width_px when
  // width_px > 0.
  LayoutPtr Make(const std::string& text, double scale = 1, bool bold = false,
                 int width_px = -1, bool ellipsize = false) const {
    LayoutPtr layout(pango_cairo_create_layout(cr_));
    std::unique_ptr<PangoFontDescription, CairoDeleter> font(
        pango_font_description_from_string("DejaVu Sans, Sans"));
    pango_font_description_set_absolute_size(font.get(), font_px_ * scale * PANGO_SCALE);
    pango_font_description_set_weight(font.get(), bold ? PANGO_WEIGHT_SEMIBOLD : PANGO_WEIGHT_NORMAL);
    pango_layout_set_font_description(layout.get(), font.get());
    if (width_px > 0) {
      pango_layout_set_width(layout.get(), width_px * PANGO_SCALE);
      if (ellipsize) {
        pango_layout_set_ellipsize(layout.get(), PANGO_ELLIPSIZE_END);
      } else {
        pango_layout_set_wrap(layout.get(), PANGO_WRAP_WORD_CHAR);
      }
    }
    pango_layout_set_text(layout.get(), text.c_str(), -1);
    return layout;
  }

  static Eigen::Vector2d Size(PangoLayout* layout) {
    PangoRectangle logical;
    pango_layout_get_pixel_extents(layout, nullptr, &logical);
    return {logical.width, logical.height};
  }

  // Draws with the layout's top-left corner at (x, y).
  void Draw(PangoLayout* layout, double x, double y, const Rgb& colour, double alpha = 1) const {
    cairo_move_to(cr_, x, y);
    SetColour(cr_, colour, alpha);
    pango_cairo_show_layout(cr_, layout);
  }

  // Draws with a dark halo of width halo_px around the glyphs, readable on any colour.
  void DrawWithHalo(PangoLayout* layout, double x, double y, const Rgb& colour, double alpha,
                    double halo_px) const {
    cairo_save(cr_);
    cairo_move_to(cr_, x, y);
    pango_cairo_layout_path(cr_, layout);
    cairo_set_line_join(cr_, CAIRO_LINE_JOIN_ROUND);
    cairo_set_line_width(cr_, 2 * halo_px);
    SetColour(cr_, kHalo, 0.7);
    cairo_stroke(cr_);
    cairo_restore(cr_);
    Draw(layout, x, y, colour, alpha);
  }

 private:
  cairo_t* cr_;
  double font_px_;
};

void PutPixel(unsigned char* data, int stride, int x, int y, std::uint8_t r, std::uint8_t g,
              std::uint8_t b) {
  auto* pixel = reinterpret_cast<std::uint32_t*>(data + static_cast<ptrdiff_t>(y) * stride) + x;
  *pixel = (std::uint32_t{r} << 16) | (std::uint32_t{g} << 8) | std::uint32_t{b};
}

// Fills a rectangle of the surface pixel by pixel with colour(x, y) (linear light).
template <typename ColourFn>
void FillPixels(cairo_surface_t* surface, int x0, int y0, int width, int height, ColourFn colour) {
  cairo_surface_flush(surface);
  unsigned char* data = cairo_image_surface_get_data(surface);
  const int stride = cairo_image_surface_get_stride(surface);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const Eigen::Vector3f linear = colour(x, y);
      PutPixel(data, stride, x0 + x, y0 + y, LinearToSrgb8(linear[0]), LinearToSrgb8(linear[1]),
               LinearToSrgb8(linear[2]));
    }
  }
  cairo_surface_mark_dirty(surface);
}

struct Layout {
  double font_px = 12;
  int margin = 12;
  int title_h = 0;   // the title strip
  int panel_w = 0;   // the colour bar panel
  int panel_min_h = 0;
};

// Sizes of the colour bar panel's parts, from the text it holds.
struct BarGeometry {
  int bar_w = 0;
  int tick_len = 0;
  int gap = 0;
  int band_label_w = 0;  // left of the bar, for the band limits
  int tick_label_w = 0;
  int title_w = 0;       // wrap width of the bar title
};

BarGeometry MeasureBar(const TextMaker& text, const ColourBar& bar, double font_px,
                       const std::vector<double>& ticks, double step) {
  BarGeometry g;
  g.bar_w = static_cast<int>(std::lround(font_px * 1.4));
  g.tick_len = static_cast<int>(std::lround(font_px * 0.45));
  g.gap = static_cast<int>(std::lround(font_px * 0.35));
  for (double tick : ticks) {
    g.tick_label_w = std::max(g.tick_label_w, static_cast<int>(TextMaker::Size(
                                                  text.Make(FormatTick(tick, step)).get())[0]));
  }
  if (bar.band) {
    for (double limit : {bar.band->min_c, bar.band->max_c}) {
      const LayoutPtr label = text.Make(FormatTick(limit, 0.1), 1, true);
      g.band_label_w = std::max(g.band_label_w,
                                static_cast<int>(TextMaker::Size(label.get())[0]) + g.tick_len + g.gap);
    }
  }
  g.title_w = static_cast<int>(std::lround(font_px * 7));
  return g;
}

void DrawColourBar(cairo_t* cr, cairo_surface_t* surface, const TextMaker& text,
                   const ColourBar& bar, const BarGeometry& g, const Layout& layout, int panel_x,
                   int panel_y, int panel_h) {
  const double font = layout.font_px;
  const int content_x = panel_x + layout.margin;
  double top = panel_y + layout.margin;
  if (!bar.title.empty()) {
    const int wrap_w = layout.panel_w - 2 * layout.margin;
    const LayoutPtr title = text.Make(bar.title, 0.85, false, wrap_w);
    text.Draw(title.get(), content_x, top, kPanelSoftText);
    top += TextMaker::Size(title.get())[1] + 0.25 * font;
  }
  const LayoutPtr units = text.Make(bar.units, 1.15, true);
  text.Draw(units.get(), content_x + g.band_label_w, top, kPanelText);
  top += TextMaker::Size(units.get())[1] + 0.9 * font;

  double bottom = panel_y + panel_h - layout.margin;
  const int key_h = static_cast<int>(std::lround(font * 1.1));
  if (bar.unobserved_key) bottom -= key_h + 0.9 * font;
  bottom -= 0.6 * font;  // half a tick label below the lowest tick

  const int bar_x = content_x + g.band_label_w;
  const int bar_top = static_cast<int>(std::lround(top));
  const int bar_h = std::max(2, static_cast<int>(std::lround(bottom)) - bar_top);
  const Span& span = bar.span;
  auto value_at_row = [&](double row_centre) {
    return span.max_c - (row_centre / bar_h) * (span.max_c - span.min_c);
  };
  const Eigen::Vector3f band_grey = Eigen::Vector3f::Constant(SrgbToLinear(static_cast<float>(kBandGrey.r)));
  FillPixels(surface, bar_x, bar_top, g.bar_w, bar_h, [&](int, int y) -> Eigen::Vector3f {
    const double value = value_at_row(y + 0.5);
    if (bar.band && value >= bar.band->min_c && value <= bar.band->max_c) return band_grey;
    const double t = span.Normalize(value);
    return bar.ih_hue ? IhColour(t, 1.0f) : PaletteColour(bar.palette, bar.inverted, t);
  });
  cairo_set_line_width(cr, 1);
  SetColour(cr, kTickLine);
  cairo_rectangle(cr, bar_x - 0.5, bar_top - 0.5, g.bar_w + 1, bar_h + 1);
  cairo_stroke(cr);

  auto row_of = [&](double value) {
    return bar_top + (span.max_c - std::clamp(value, span.min_c, span.max_c)) /
                         (span.max_c - span.min_c) * bar_h;
  };
  const std::vector<double> ticks = NiceTicks(span, std::clamp(bar_h / static_cast<int>(2.6 * font), 2, 10));
  const double step = ticks.size() > 1 ? ticks[1] - ticks[0] : span.max_c - span.min_c;
  for (double tick : ticks) {
    const double y = std::round(row_of(tick)) + 0.5;  // crisp 1-px lines
    cairo_move_to(cr, bar_x + g.bar_w, y);
    cairo_line_to(cr, bar_x + g.bar_w + g.tick_len, y);
    SetColour(cr, kTickLine);
    cairo_stroke(cr);
    const LayoutPtr label = text.Make(FormatTick(tick, step));
    text.Draw(label.get(), bar_x + g.bar_w + g.tick_len + g.gap,
              y - TextMaker::Size(label.get())[1] / 2, kPanelText);
  }
  if (bar.band) {
    for (double limit : {bar.band->min_c, bar.band->max_c}) {
      const double y = std::round(row_of(limit)) + 0.5;
      cairo_set_line_width(cr, 2);
      cairo_move_to(cr, bar_x - g.tick_len, y);
      cairo_line_to(cr, bar_x + g.bar_w, y);
      SetColour(cr, kLabelText);
      cairo_stroke(cr);
      const LayoutPtr label = text.Make(FormatTick(limit, 0.1), 1, true);
      const Eigen::Vector2d size = TextMaker::Size(label.get());
      text.Draw(label.get(), bar_x - g.tick_len - g.gap - size[0], y - size[1] / 2, kPanelText);
    }
    cairo_set_line_width(cr, 1);
  }
  if (bar.unobserved_key) {
    const int key_y = static_cast<int>(std::lround(panel_y + panel_h - layout.margin - key_h));
    FillPixels(surface, bar_x, key_y, g.bar_w, key_h, [&](int x, int y) -> Eigen::Vector3f {
      return Eigen::Vector3f::Constant(UnobservedHatchGrey(x, y, bar.hatch_period_px));
    });
    SetColour(cr, kTickLine);
    cairo_rectangle(cr, bar_x - 0.5, key_y - 0.5, g.bar_w + 1, key_h + 1);
    cairo_stroke(cr);
    const LayoutPtr label = text.Make("unobserved", 0.85);
    text.Draw(label.get(), bar_x + g.bar_w + g.tick_len + g.gap,
              key_y + key_h / 2.0 - TextMaker::Size(label.get())[1] / 2, kPanelSoftText);
  }
}

void DrawSpot(cairo_t* cr, const TextMaker& text, const SpotLabel& spot, double font,
              int image_x, int image_y, int image_w, int image_h) {
  const double x = image_x + spot.position_px[0];
  const double y = image_y + spot.position_px[1];
  const double radius = 0.6 * font;  // arm length: the crosshair reaches 1.25 radius
  const double alpha = spot.visible ? 1.0 : 0.75;
  cairo_save(cr);
  cairo_rectangle(cr, image_x, image_y, image_w, image_h);
  cairo_clip(cr);
  if (!spot.visible) {
    const double dash[] = {0.15 * font, 0.12 * font};
    cairo_set_dash(cr, dash, 2, 0);
  }
  // The marker: a spot-meter crosshair (four arms around an open centre, so the spot
  // itself stays visible) and a centre dot; a dark outline under a white line.
  cairo_new_path(cr);
  for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
    cairo_move_to(cr, x + dx * 0.35 * radius, y + dy * 0.35 * radius);
    cairo_line_to(cr, x + dx * 1.25 * radius, y + dy * 1.25 * radius);
  }
  cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
  cairo_set_line_width(cr, 0.3 * font);
  SetColour(cr, kHalo, 0.8);
  cairo_stroke_preserve(cr);
  cairo_set_line_width(cr, 0.12 * font);
  SetColour(cr, kLabelText, alpha);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  cairo_arc(cr, x, y, 0.1 * font, 0, 2 * M_PI);
  SetColour(cr, kLabelText, alpha);
  cairo_fill_preserve(cr);
  cairo_set_line_width(cr, 0.08 * font);
  SetColour(cr, kHalo, 0.8);
  cairo_stroke(cr);

  // The label right of the marker, or left when it would leave the image; inside the image.
  const LayoutPtr label = text.Make(spot.text, 0.95, spot.visible);  // hidden: regular weight
  const Eigen::Vector2d size = TextMaker::Size(label.get());
  const double pad = 0.25 * font;
  double text_x = x + 1.25 * radius + 0.3 * font;
  if (text_x + size[0] > image_x + image_w - pad) text_x = x - 1.25 * radius - 0.3 * font - size[0];
  text_x = std::max(image_x + pad, std::min(text_x, image_x + image_w - pad - size[0]));
  double text_y = y - size[1] / 2;
  text_y = std::max(image_y + pad, std::min(text_y, image_y + image_h - pad - size[1]));
  text.DrawWithHalo(label.get(), text_x, text_y, kLabelText, alpha, 0.2 * font);
  cairo_restore(cr);
}

}  // namespace

ImageRgb8 Annotate(const ImageRgb8& image, const Annotation& a) {
  assert(image.width > 0 && image.height > 0 &&
         image.rgb.size() == static_cast<size_t>(image.width) * static_cast<size_t>(image.height) * 3);
  Layout layout;
  layout.font_px = std::clamp(std::round(image.height / 48.0), 11.0, 26.0);
  layout.margin = static_cast<int>(std::lround(layout.font_px));

  // Text is measured on a scratch surface before the canvas size is known.
  std::unique_ptr<cairo_surface_t, CairoDeleter> scratch(
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, 1, 1));
  std::unique_ptr<cairo_t, CairoDeleter> scratch_cr(cairo_create(scratch.get()));
  const TextMaker measure(scratch_cr.get(), layout.font_px);

  if (!a.title.empty()) {
    const LayoutPtr title = measure.Make(a.title, 1.1, true);
    layout.title_h = static_cast<int>(std::lround(TextMaker::Size(title.get())[1] + layout.font_px));
  }
  BarGeometry bar_geometry;
  std::vector<double> ticks;
  double step = 1;
  if (a.colour_bar) {
    const ColourBar& bar = *a.colour_bar;
    assert(std::isfinite(bar.span.min_c) && bar.span.max_c > bar.span.min_c);
    assert(!bar.band || bar.band->max_c > bar.band->min_c);
    // Labels are measured for the densest tick set the bar can get.
    ticks = NiceTicks(bar.span, 10);
    step = ticks.size() > 1 ? ticks[1] - ticks[0] : 1;
    bar_geometry = MeasureBar(measure, bar, layout.font_px, ticks, step);
    const LayoutPtr units = measure.Make(bar.units, 1.15, true);
    const int ticks_w = bar_geometry.bar_w + bar_geometry.tick_len + bar_geometry.gap +
                        std::max(bar_geometry.tick_label_w,
                                 static_cast<int>(TextMaker::Size(measure.Make("unobserved", 0.85).get())[0]));
    const int content_w = std::max({bar_geometry.band_label_w + ticks_w,
                                    static_cast<int>(TextMaker::Size(units.get())[0]),
                                    bar.title.empty() ? 0 : bar_geometry.title_w});
    layout.panel_w = content_w + 2 * layout.margin;
    layout.panel_min_h = static_cast<int>(std::lround(layout.font_px * 14));
  }

  const int out_w = image.width + layout.panel_w;
  const int out_h = layout.title_h + std::max(image.height, layout.panel_min_h);
  std::unique_ptr<cairo_surface_t, CairoDeleter> surface(
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, out_w, out_h));
  assert(cairo_surface_status(surface.get()) == CAIRO_STATUS_SUCCESS);
  std::unique_ptr<cairo_t, CairoDeleter> cr(cairo_create(surface.get()));
  const TextMaker text(cr.get(), layout.font_px);

  cairo_set_source_rgb(cr.get(), a.panel_srgb8[0] / 255.0, a.panel_srgb8[1] / 255.0,
                       a.panel_srgb8[2] / 255.0);
  cairo_paint(cr.get());
  cairo_surface_flush(surface.get());
  {
    unsigned char* data = cairo_image_surface_get_data(surface.get());
    const int stride = cairo_image_surface_get_stride(surface.get());
    for (int y = 0; y < image.height; ++y) {
      for (int x = 0; x < image.width; ++x) {
        const std::uint8_t* p = image.At(x, y);
        PutPixel(data, stride, x, layout.title_h + y, p[0], p[1], p[2]);
      }
    }
  }
  cairo_surface_mark_dirty(surface.get());

  if (!a.title.empty()) {
    const LayoutPtr title = text.Make(a.title, 1.1, true, out_w - 2 * layout.margin, true);
    text.Draw(title.get(), layout.margin,
              (layout.title_h - TextMaker::Size(title.get())[1]) / 2, kPanelText);
  }
  if (a.colour_bar) {
    DrawColourBar(cr.get(), surface.get(), text, *a.colour_bar, bar_geometry, layout, image.width,
                  layout.title_h, out_h - layout.title_h);
  }
  for (const SpotLabel& spot : a.spots) {
    DrawSpot(cr.get(), text, spot, layout.font_px, 0, layout.title_h, image.width, image.height);
  }

  cairo_surface_flush(surface.get());
  ImageRgb8 out;
  out.width = out_w;
  out.height = out_h;
  out.rgb.resize(static_cast<size_t>(out_w) * static_cast<size_t>(out_h) * 3);
  const unsigned char* data = cairo_image_surface_get_data(surface.get());
  const int stride = cairo_image_surface_get_stride(surface.get());
  for (int y = 0; y < out_h; ++y) {
    const auto* row = reinterpret_cast<const std::uint32_t*>(data + static_cast<ptrdiff_t>(y) * stride);
    for (int x = 0; x < out_w; ++x) {
      std::uint8_t* p = out.rgb.data() + (static_cast<size_t>(y) * static_cast<size_t>(out_w) + static_cast<size_t>(x)) * 3;
      p[0] = static_cast<std::uint8_t>((row[x] >> 16) & 0xFF);
      p[1] = static_cast<std::uint8_t>((row[x] >> 8) & 0xFF);
      p[2] = static_cast<std::uint8_t>(row[x] & 0xFF);
    }
  }
  return out;
}

}  // namespace hw::analyze
