#pragma once

// Building blocks of the PDF writer (report/pdf_report.h): Pango text, the unbreakable
// units a document is cut into and their pagination, images embedded as JPEG, and vector
// colour bars. Internal to report/; units are PDF points (1/72 in), y down from the page's
// top edge.

#include <cairo.h>
#include <pango/pangocairo.h>

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "report/document.h"

namespace hw::report::pdf {

// A4 portrait and the body frame between the header and footer lines.
inline constexpr double kPageWidth = 595.28;
inline constexpr double kPageHeight = 841.89;
inline constexpr double kMarginX = 56.69;  // 20 mm left and right
inline constexpr double kBodyTop = 68;
inline constexpr double kBodyBottom = kPageHeight - 62;
inline constexpr double kBodyWidth = kPageWidth - 2 * kMarginX;

// sRGB in [0, 1] (Cairo blends in sRGB; fine for flat fills and thin lines).
struct Rgb {
  double r = 0, g = 0, b = 0;
};
inline constexpr Rgb kInk{0.13, 0.15, 0.17};         // body text
inline constexpr Rgb kAccent{0.10, 0.27, 0.43};      // headings, header row, rules
inline constexpr Rgb kSoft{0.40, 0.43, 0.46};        // notes, captions, labels
inline constexpr Rgb kHairline{0.80, 0.82, 0.84};    // table and list separators
inline constexpr Rgb kZebra{0.955, 0.962, 0.970};    // alternate table rows
inline constexpr Rgb kLink{0.05, 0.33, 0.62};        // linked table cells
inline constexpr Rgb kAmber{0.86, 0.56, 0.05};       // warning box border
inline constexpr Rgb kAmberFill{1.0, 0.965, 0.88};   // warning box background
inline constexpr Rgb kWhite{1, 1, 1};
void SetColour(cairo_t* cr, const Rgb& c, double alpha = 1);

using LayoutPtr = std::shared_ptr<PangoLayout>;

// Pango layouts in one font family, measured in points on the PDF surface's context (the
// context that draws them: no hinting, so measured and drawn sizes agree).
class Text {
 public:
  Text(cairo_t* cr, std::string family) : cr_(cr), family_(std::move(family)) {}
  struct Style {
    double size_pt = 9.5;
    bool bold = false;
    bool italic = false;
  };
  // `text` set as text (never markup); wrapped at width_pt when > 0, aligned within it.
  LayoutPtr Make(const std::string& text, const Style& style, double width_pt = -1,
                 PangoAlignment align = PANGO_ALIGN_LEFT) const;
  static double Width(PangoLayout* layout);   // logical width, pt
  static double Height(PangoLayout* layout);  // logical height, pt
  // The logical width of the layout's last line, pt.
  static double LastLineWidth(PangoLayout* layout);

 private:
  cairo_t* cr_;
  std::string family_;
};
// Draws `layout` with its top-left at (x, y).
void Show(cairo_t* cr, PangoLayout* layout, double x, double y, const Rgb& colour);

// One line of a layout: its top and height within the layout, pt.
struct LayoutLine {
  int index = 0;
  double top = 0;
  double height = 0;
};
std::vector<LayoutLine> Lines(PangoLayout* layout);
// Draws line `line` of `layout` with the line's top at y (x is the layout's left edge).
void ShowLine(cairo_t* cr, PangoLayout* layout, const LayoutLine& line, double x, double y,
              const Rgb& colour);

// The unbreakable piece pagination works with: a heading, a line of text, a table row, a
// row of figures. draw(cr, x, y) draws it with its top-left at (x, y) of the body frame.
struct Unit {
  double height = 0;         // pt
  double space_before = 0;   // pt; dropped at the top of a page
  bool keep_with_next = false;
  bool page_break_before = false;
  std::string anchor;        // a section heading's anchor: its page number is recorded
  std::shared_ptr<const Unit> repeat_header;  // table rows: drawn first on a continuation page
  std::function<void(cairo_t* cr, double x, double y)> draw;
};
struct Placed {
  const Unit* unit = nullptr;
  double y = 0;
};
using Page = std::vector<Placed>;

// Places `units` in order on pages of the body frame [kBodyTop, kBodyBottom]. A unit goes
// to a new page when it does not fit or has page_break_before; a chain of keep_with_next
// units moves as a whole when it fits on one page; a table row that starts a page gets its
// header first. Records each anchor's 1-based page in *anchor_pages. `units` must outlive
// the pages.
std::vector<Page> Paginate(const std::vector<Unit>& units, std::map<std::string, int>* anchor_pages);

// Size of a PNG from its header. Throws core::InputError(png, reason) when the file is
// missing, not a regular file or not a PNG.
struct PixelSize {
  int width = 0, height = 0;
};
PixelSize ProbePng(const std::filesystem::path& png);

// A PNG ready for a PDF: resampled in linear light (tent filter) to at most max_width_px wide
// (never enlarged), alpha composited over white, as an RGB24 Cairo surface carrying its
// JPEG encoding as mime data, so that the PDF embeds the JPEG (DCTDecode) and not the
// pixels. Throws core::InputError(png, reason) when the file cannot be read or decoded.
struct EmbeddedImage {
  std::shared_ptr<cairo_surface_t> surface;
  int width = 0, height = 0;
  size_t jpeg_bytes = 0;
};
EmbeddedImage LoadForPdf(const std::filesystem::path& png, int max_width_px, int jpeg_quality);

// Height of a horizontal colour key (bar, ticks and their labels), pt.
double ColourKeyHeight(const Text& text);
// Draws `key` as a horizontal bar over [x, x + width] with its top at y: a linear gradient
// sampled from the palette (sRGB-encoded from analyze's linear colours), tick labels from
// analyze::NiceTicks, the unit at the bar's right end. kHighlight: neutral grey inside the
// normal band. Asserts key.mode != kColour and a valid span.
void DrawColourKey(cairo_t* cr, const Text& text, const ColourKey& key, double x, double y,
                   double width);

}  // namespace hw::report::pdf
