#include "report/pdf_layout.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <utility>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include "analyze/palette.h"
#include "analyze/srgb.h"
#include "core/atomic_file.h"
#include "core/error.h"

namespace hw::report::pdf {
namespace {

constexpr double kPangoScale = PANGO_SCALE;

// OpenImageIO's message, always draining the global error (it prints pending ones at exit).
template <typename T>
std::string OiioError(T* io) {
  std::string message = io ? io->geterror() : std::string();
  const std::string global = OIIO::geterror();
  if (message.empty()) message = global;
  return message.empty() ? "unknown error" : message;
}

struct DecodedPng {
  int width = 0, height = 0, channels = 0;
  bool sixteen_bit = false;
  // Encoded values at the file's depth (no conversion on the way in): 8-bit in bytes8,
  // 16-bit in bytes16; width · height · channels.
  std::vector<uint8_t> bytes8;
  std::vector<uint16_t> bytes16;
};

// Opens (and with `pixels`, decodes) a PNG through OpenImageIO from memory: the file is read
// by core::ReadFile, which refuses FIFOs, devices and oversized files.
DecodedPng DecodePng(const std::filesystem::path& png, bool pixels) {
  const std::string bytes = core::ReadFile(png, core::kMaxFrameFileBytes);
  OIIO::Filesystem::IOMemReader reader(bytes.data(), bytes.size());
  std::unique_ptr<OIIO::ImageInput> input = OIIO::ImageInput::create("image.png", true, nullptr, &reader);
  if (!input) throw core::InputError(png, "not a readable PNG: " + OiioError<OIIO::ImageInput>(nullptr));
  const OIIO::ImageSpec& spec = input->spec();
  DecodedPng out;
  out.width = spec.width;
  out.height = spec.height;
  out.channels = spec.nchannels;
  out.sixteen_bit = spec.format.size() > 1;
  if (out.width <= 0 || out.height <= 0 || out.channels < 1 || out.channels > 4) {
    throw core::InputError(png, "unsupported PNG layout (" + std::to_string(out.channels) + " channels)");
  }
  if (pixels) {
    const size_t count = static_cast<size_t>(out.width) * static_cast<size_t>(out.height) * static_cast<size_t>(out.channels);
    bool ok = false;
    if (out.sixteen_bit) {
      out.bytes16.resize(count);
      ok = input->read_image(0, 0, 0, out.channels, OIIO::TypeDesc::UINT16, out.bytes16.data());
    } else {
      out.bytes8.resize(count);
      ok = input->read_image(0, 0, 0, out.channels, OIIO::TypeDesc::UINT8, out.bytes8.data());
    }
    if (!ok) throw core::InputError(png, "corrupt PNG: " + OiioError(input.get()));
  }
  input->close();
  OiioError(input.get());
  return out;
}

std::string EncodeJpeg(const std::filesystem::path& png, const std::vector<unsigned char>& rgb,
                       int width, int height, int quality) {
  std::unique_ptr<OIIO::ImageOutput> output = OIIO::ImageOutput::create("jpg");
  if (!output) throw core::InputError(png, "no JPEG encoder: " + OiioError<OIIO::ImageOutput>(nullptr));
  // Only the pixels and the quality: no metadata of the source (dates) reaches the PDF.
  OIIO::ImageSpec spec(width, height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("Compression", "jpeg:" + std::to_string(quality));
  std::vector<unsigned char> bytes;
  OIIO::Filesystem::IOVecOutput memory(bytes);
  if (!output->set_ioproxy(&memory) || !output->open("image.jpg", spec) ||
      !output->write_image(OIIO::TypeDesc::UINT8, rgb.data()) || !output->close()) {
    throw core::InputError(png, "cannot encode as JPEG: " + OiioError(output.get()));
  }
  OiioError(output.get());
  return std::string(bytes.begin(), bytes.end());
}

// Resampling weights from n_in samples to n_out (<= n_in): a tent as wide as two destination
// pixels, so every source pixel contributes (anti-aliased for any reduction); the identity
// when n_out == n_in.
struct Taps {
  std::vector<int> first;       // n_out: first source index
  std::vector<std::vector<float>> weights;  // n_out: normalized weights from `first`
};
Taps TentTaps(int n_in, int n_out) {
  Taps taps;
  const double scale = static_cast<double>(n_in) / n_out;  // source pixels per destination pixel
  for (int o = 0; o < n_out; ++o) {
    const double centre = (o + 0.5) * scale;  // in source pixel units
    const int lo = std::max(0, static_cast<int>(std::floor(centre - scale)));
    const int hi = std::min(n_in - 1, static_cast<int>(std::ceil(centre + scale)));
    std::vector<float> w;
    double sum = 0;
    for (int i = lo; i <= hi; ++i) {
      const double d = std::abs(i + 0.5 - centre) / scale;
      const double weight = std::max(0.0, 1 - d);
      w.push_back(static_cast<float>(weight));
      sum += weight;
    }
    for (float& x : w) x = static_cast<float>(static_cast<double>(x) / sum);
    taps.first.push_back(lo);
    taps.weights.push_back(std::move(w));
  }
  return taps;
}

}  // namespace

void SetColour(cairo_t* cr, const Rgb& c, double alpha) { cairo_set_source_rgba(cr, c.r, c.g, c.b, alpha); }

LayoutPtr Text::Make(const std::string& text, const Style& style, double width_pt,
                     PangoAlignment align) const {
  LayoutPtr layout(pango_cairo_create_layout(cr_), g_object_unref);
  PangoFontDescription* font = pango_font_description_new();
  pango_font_description_set_family(font, family_.c_str());
  pango_font_description_set_absolute_size(font, style.size_pt * kPangoScale);
  pango_font_description_set_weight(font, style.bold ? PANGO_WEIGHT_BOLD : PANGO_WEIGHT_NORMAL);
  pango_font_description_set_style(font, style.italic ? PANGO_STYLE_ITALIC : PANGO_STYLE_NORMAL);
  pango_layout_set_font_description(layout.get(), font);
  pango_font_description_free(font);
  if (width_pt > 0) {
    pango_layout_set_width(layout.get(), static_cast<int>(width_pt * kPangoScale));
    pango_layout_set_wrap(layout.get(), PANGO_WRAP_WORD_CHAR);
    pango_layout_set_alignment(layout.get(), align);
  }
  // Text, never markup: '<', '&' from a job file print as themselves.
  pango_layout_set_text(layout.get(), text.c_str(), static_cast<int>(text.size()));
  return layout;
}

double Text::Width(PangoLayout* layout) {
  PangoRectangle logical;
  pango_layout_get_extents(layout, nullptr, &logical);
  return logical.width / kPangoScale;
}

double Text::Height(PangoLayout* layout) {
  PangoRectangle logical;
  pango_layout_get_extents(layout, nullptr, &logical);
  return logical.height / kPangoScale;
}

double Text::LastLineWidth(PangoLayout* layout) {
  const int count = pango_layout_get_line_count(layout);
  if (count == 0) return 0;
  PangoRectangle logical;
  pango_layout_line_get_extents(pango_layout_get_line_readonly(layout, count - 1), nullptr, &logical);
  return logical.width / kPangoScale;
}

void Show(cairo_t* cr, PangoLayout* layout, double x, double y, const Rgb& colour) {
  SetColour(cr, colour);
  cairo_move_to(cr, x, y);
  pango_cairo_show_layout(cr, layout);
}

std::vector<LayoutLine> Lines(PangoLayout* layout) {
  std::vector<LayoutLine> lines;
  PangoLayoutIter* iter = pango_layout_get_iter(layout);
  int index = 0;
  do {
    int top = 0, bottom = 0;
    pango_layout_iter_get_line_yrange(iter, &top, &bottom);
    lines.push_back({index++, top / kPangoScale, (bottom - top) / kPangoScale});
  } while (pango_layout_iter_next_line(iter));
  pango_layout_iter_free(iter);
  return lines;
}

void ShowLine(cairo_t* cr, PangoLayout* layout, const LayoutLine& line, double x, double y,
              const Rgb& colour) {
  PangoLayoutIter* iter = pango_layout_get_iter(layout);
  for (int i = 0; i < line.index; ++i) pango_layout_iter_next_line(iter);
  PangoRectangle logical;
  pango_layout_iter_get_line_extents(iter, nullptr, &logical);
  const double baseline = pango_layout_iter_get_baseline(iter) / kPangoScale;
  PangoLayoutLine* layout_line = pango_layout_iter_get_line_readonly(iter);
  SetColour(cr, colour);
  cairo_move_to(cr, x + logical.x / kPangoScale, y + baseline - line.top);
  pango_cairo_show_layout_line(cr, layout_line);
  pango_layout_iter_free(iter);
}

std::vector<Page> Paginate(const std::vector<Unit>& units, std::map<std::string, int>* anchor_pages) {
  std::vector<Page> pages(1);
  double y = kBodyTop;
  bool fresh = true;  // nothing but a repeated table header on the page yet
  const double page_height = kBodyBottom - kBodyTop;
  auto place = [&](const Unit& unit, bool repeated) {
    if (!fresh) y += unit.space_before;
    pages.back().push_back({&unit, y});
    y += unit.height;
    if (!repeated) fresh = false;
    if (!unit.anchor.empty() && anchor_pages) (*anchor_pages)[unit.anchor] = static_cast<int>(pages.size());
  };
  auto new_page = [&](const Unit& next) {
    pages.emplace_back();
    y = kBodyTop;
    fresh = true;
    if (next.repeat_header) place(*next.repeat_header, true);
  };
  for (size_t i = 0; i < units.size(); ++i) {
    const Unit& unit = units[i];
    if (unit.page_break_before && !pages.back().empty()) new_page(unit);
    // The keep-with-next chain starting here moves to a new page as a whole when it does not
    // fit but would fit on an empty page.
    double chain = unit.height;
    for (size_t j = i; j + 1 < units.size() && units[j].keep_with_next && !units[j + 1].page_break_before; ++j) {
      chain += units[j + 1].space_before + units[j + 1].height;
    }
    const double space = fresh ? 0 : unit.space_before;
    if (!fresh && y + space + chain > kBodyBottom && chain <= page_height) {
      new_page(unit);
    } else if (!fresh && y + space + unit.height > kBodyBottom) {
      new_page(unit);
    }
    place(unit, false);
  }
  return pages;
}

PixelSize ProbePng(const std::filesystem::path& png) {
  const DecodedPng header = DecodePng(png, false);
  return {header.width, header.height};
}

EmbeddedImage LoadForPdf(const std::filesystem::path& png, int max_width_px, int jpeg_quality) {
  assert(max_width_px > 0);
  const DecodedPng decoded = DecodePng(png, true);
  const int channels = decoded.channels;
  const bool alpha = channels == 2 || channels == 4;
  const int colour_channels = channels >= 3 ? 3 : 1;
  std::vector<float> to_linear(decoded.sixteen_bit ? 65536 : 256);
  for (size_t i = 0; i < to_linear.size(); ++i) {
    to_linear[i] = analyze::SrgbToLinear(static_cast<float>(i) / static_cast<float>(to_linear.size() - 1));
  }
  const float alpha_scale = 1.0f / static_cast<float>(to_linear.size() - 1);
  // Linear light of channel c of source pixel p, composited over white: resampling averages
  // light, not encoded values.
  auto linear = [&](size_t p, int c) {
    const size_t base = p * static_cast<size_t>(channels);
    const auto value = [&](size_t i) -> size_t { return decoded.sixteen_bit ? decoded.bytes16[i] : decoded.bytes8[i]; };
    const float v = to_linear[value(base + static_cast<size_t>(colour_channels == 3 ? c : 0))];
    if (!alpha) return v;
    const float a = static_cast<float>(value(base + static_cast<size_t>(channels - 1))) * alpha_scale;
    return v * a + (1 - a);
  };

  const int width = std::min(max_width_px, decoded.width);
  const int height = width == decoded.width
                         ? decoded.height
                         : std::max(1, static_cast<int>(std::lround(static_cast<double>(decoded.height) * width / decoded.width)));
  // Separable tent resampling: rows to the new width (linear floats), then columns straight
  // to 8-bit sRGB.
  const Taps across = TentTaps(decoded.width, width), down = TentTaps(decoded.height, height);
  const size_t row_floats = static_cast<size_t>(width) * 3;
  std::vector<float> rows(row_floats * static_cast<size_t>(decoded.height));
  for (int y = 0; y < decoded.height; ++y) {
    float* out = rows.data() + static_cast<size_t>(y) * row_floats;
    const size_t row_start = static_cast<size_t>(y) * static_cast<size_t>(decoded.width);
    for (int x = 0; x < width; ++x) {
      const std::vector<float>& w = across.weights[static_cast<size_t>(x)];
      const size_t first = row_start + static_cast<size_t>(across.first[static_cast<size_t>(x)]);
      for (int c = 0; c < 3; ++c) {
        float sum = 0;
        for (size_t k = 0; k < w.size(); ++k) sum += w[k] * linear(first + k, c);
        out[static_cast<size_t>(x) * 3 + static_cast<size_t>(c)] = sum;
      }
    }
  }
  std::vector<unsigned char> srgb8(row_floats * static_cast<size_t>(height));
  std::vector<float> sum(row_floats);
  for (int y = 0; y < height; ++y) {
    const std::vector<float>& w = down.weights[static_cast<size_t>(y)];
    std::fill(sum.begin(), sum.end(), 0.0f);
    for (size_t k = 0; k < w.size(); ++k) {
      const float* in = rows.data() + (static_cast<size_t>(down.first[static_cast<size_t>(y)]) + k) * row_floats;
      for (size_t i = 0; i < row_floats; ++i) sum[i] += w[k] * in[i];
    }
    unsigned char* out = srgb8.data() + static_cast<size_t>(y) * row_floats;
    for (size_t i = 0; i < row_floats; ++i) out[i] = analyze::LinearToSrgb8(sum[i]);
  }
  const std::string jpeg = EncodeJpeg(png, srgb8, width, height, jpeg_quality);

  EmbeddedImage image;
  image.width = width;
  image.height = height;
  image.jpeg_bytes = jpeg.size();
  image.surface.reset(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height), cairo_surface_destroy);
  if (cairo_surface_status(image.surface.get()) != CAIRO_STATUS_SUCCESS) {
    throw core::InputError(png, "image too large for Cairo");
  }
  // The pixels stand in for the JPEG wherever Cairo cannot use it (it can in a PDF).
  cairo_surface_flush(image.surface.get());
  unsigned char* data = cairo_image_surface_get_data(image.surface.get());
  const int stride = cairo_image_surface_get_stride(image.surface.get());
  for (int y = 0; y < height; ++y) {
    auto* row = reinterpret_cast<uint32_t*>(data + static_cast<ptrdiff_t>(y) * stride);
    for (int x = 0; x < width; ++x) {
      const unsigned char* p = srgb8.data() + (static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)) * 3;
      row[x] = 0xff000000u | (uint32_t{p[0]} << 16) | (uint32_t{p[1]} << 8) | uint32_t{p[2]};
    }
  }
  cairo_surface_mark_dirty(image.surface.get());
  auto* mime = static_cast<unsigned char*>(std::malloc(jpeg.size()));
  assert(mime);
  std::memcpy(mime, jpeg.data(), jpeg.size());
  cairo_surface_set_mime_data(image.surface.get(), CAIRO_MIME_TYPE_JPEG, mime, jpeg.size(), std::free, mime);
  // The same image at the same size placed twice (the cover's hero again in a section) is
  // embedded once.
  const std::string id = png.string() + "@" + std::to_string(width);
  auto* unique = static_cast<unsigned char*>(std::malloc(id.size()));
  assert(unique);
  std::memcpy(unique, id.data(), id.size());
  cairo_surface_set_mime_data(image.surface.get(), CAIRO_MIME_TYPE_UNIQUE_ID, unique, id.size(), std::free, unique);
  return image;
}

namespace {

constexpr double kKeyBarHeight = 7;
constexpr double kKeyTickLength = 2.5;
constexpr Text::Style kKeyLabel{6.5, false, false};
// The band on a highlighting bar: a neutral grey standing for "visible colour here".
constexpr Rgb kBandGrey{0.62, 0.62, 0.62};

Rgb ToSrgb(const Eigen::Vector3f& linear) {
  return {analyze::LinearToSrgb(linear.x()), analyze::LinearToSrgb(linear.y()), analyze::LinearToSrgb(linear.z())};
}

Rgb KeyColour(const ColourKey& key, double t) {
  if (key.mode == analyze::ViewMode::kIhMapping) return ToSrgb(analyze::IhColour(t, 1.0f));
  return ToSrgb(analyze::PaletteColour(key.palette, key.inverted, t));
}

}  // namespace

double ColourKeyHeight(const Text& text) {
  const LayoutPtr label = text.Make("0123456789", kKeyLabel);
  return kKeyBarHeight + kKeyTickLength + 1 + Text::Height(label.get());
}

void DrawColourKey(cairo_t* cr, const Text& text, const ColourKey& key, double x, double y, double width) {
  assert(key.mode != analyze::ViewMode::kColour);
  assert(key.span.max_c > key.span.min_c);
  const LayoutPtr unit = text.Make(key.unit, kKeyLabel);
  const double unit_width = Text::Width(unit.get());
  const double bar_width = std::max(10.0, width - unit_width - 4);

  // Stops every 1/64 of the bar (the palettes are piecewise linear in sRGB between more
  // distant control points, so this follows them closely); in highlighting mode the band
  // is a grey segment with hard edges.
  std::vector<std::pair<double, Rgb>> stops;
  auto add_palette = [&](double from, double to) {
    const int n = std::max(2, static_cast<int>(std::ceil(64 * (to - from))));
    for (int k = 0; k <= n; ++k) {
      const double t = from + (to - from) * k / n;
      stops.push_back({t, KeyColour(key, t)});
    }
  };
  if (key.mode == analyze::ViewMode::kHighlight && key.band_high_c > key.band_low_c) {
    const double low = key.span.Normalize(key.band_low_c), high = key.span.Normalize(key.band_high_c);
    if (low > 0) add_palette(0, low);
    stops.push_back({low, kBandGrey});
    stops.push_back({high, kBandGrey});
    if (high < 1) add_palette(high, 1);
  } else {
    add_palette(0, 1);
  }
  cairo_pattern_t* gradient = cairo_pattern_create_linear(x, 0, x + bar_width, 0);
  for (const auto& [t, c] : stops) cairo_pattern_add_color_stop_rgb(gradient, t, c.r, c.g, c.b);
  cairo_rectangle(cr, x, y, bar_width, kKeyBarHeight);
  cairo_set_source(cr, gradient);
  cairo_fill(cr);
  cairo_pattern_destroy(gradient);
  cairo_set_line_width(cr, 0.4);
  SetColour(cr, kSoft);
  cairo_rectangle(cr, x, y, bar_width, kKeyBarHeight);
  cairo_stroke(cr);
  Show(cr, unit.get(), x + bar_width + 4, y + (kKeyBarHeight - Text::Height(unit.get())) / 2, kSoft);

  // Tick labels, as many as fit without crowding.
  const double span_width = key.span.max_c - key.span.min_c;
  const int target = std::max(2, static_cast<int>(bar_width / 42));
  const double step = analyze::NiceStep(span_width, target);
  for (double value : analyze::NiceTicks(key.span, target)) {
    const double tx = x + bar_width * key.span.Normalize(value);
    cairo_move_to(cr, tx, y + kKeyBarHeight);
    cairo_line_to(cr, tx, y + kKeyBarHeight + kKeyTickLength);
    SetColour(cr, kSoft);
    cairo_stroke(cr);
    const LayoutPtr label = text.Make(analyze::FormatTick(value, step), kKeyLabel);
    const double w = Text::Width(label.get());
    const double lx = std::clamp(tx - w / 2, x, x + bar_width - w);
    Show(cr, label.get(), lx, y + kKeyBarHeight + kKeyTickLength + 1, kInk);
  }
}

}  // namespace hw::report::pdf
