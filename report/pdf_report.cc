#include "report/pdf_report.h"

#include <cairo-pdf.h>
#include <cairo.h>
#include <pango/pangocairo.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/option_check.h"
#include "report/pdf_layout.h"

namespace hw::report {
namespace {

using pdf::LayoutPtr;
using pdf::Rgb;
using pdf::Text;
using pdf::Unit;

// Type sizes, pt.
constexpr Text::Style kBody{9.5, false, false};
constexpr Text::Style kBodyBold{9.5, true, false};
constexpr Text::Style kNote{8.5, false, false};
constexpr Text::Style kCaption{8, false, true};
constexpr Text::Style kTable{8.5, false, false};
constexpr Text::Style kTableHeader{8.5, true, false};
constexpr Text::Style kHeading1{15, true, false};
constexpr Text::Style kHeading2{11.5, true, false};
constexpr Text::Style kTocTitle{18, true, false};
constexpr Text::Style kToc1{10, true, false};
constexpr Text::Style kToc2{9.5, false, false};
constexpr Text::Style kPageLine{7.5, false, false};
constexpr Text::Style kCoverTitle{24, true, false};
constexpr Text::Style kCoverSubtitle{13, false, false};

constexpr double kBlockGap = 8;      // between blocks of a section, pt
constexpr double kCellPadX = 4;      // table cell padding, pt
constexpr double kCellPadY = 2.6;
constexpr double kFigureGap = 12;    // between figures of a grid row, pt
constexpr double kWarningPad = 6;    // inside the warning box, pt
constexpr double kWarningStripe = 3;

// "YYYY-MM-DDThh:mm:ss" with an optional "Z" or ±hh:mm: what cairo_pdf_surface_set_metadata
// accepts for dates.
std::string PdfDate(const std::string& iso_utc) {
  static const std::regex kIso(R"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(Z|[+-]\d{2}:\d{2})?)");
  return std::regex_match(iso_utc, kIso) ? iso_utc : "1970-01-01T00:00:00Z";
}

// Cuts a Document into pagination units, drawing into a PDF surface's context.
class Builder {
 public:
  Builder(cairo_t* cr, cairo_surface_t* surface, const Document& doc, const PdfOptions& options)
      : cr_(cr), surface_(surface), doc_(doc), options_(options), text_(cr, options.font_family) {}

  void Build() {
    BuildCover();
    BuildContents();
    int major = 0, minor = 0;
    bool first = true;
    for (const Section& section : doc_.sections) {
      assert(section.level == 1 || section.level == 2);
      std::string number;
      if (section.level == 1) {
        number = std::to_string(++major);
        minor = 0;
      } else {
        number = std::to_string(major) + "." + std::to_string(++minor);
      }
      Heading(section, number, first || section.new_page);
      first = false;
      for (const Block& block : section.blocks) {
        std::visit([&](const auto& b) { Add(b); }, block);
      }
    }
  }

  // Lays out and draws every page; returns the page count.
  int Draw() {
    pages_ = pdf::Paginate(units_, &anchor_pages_);
    const int count = static_cast<int>(pages_.size());
    for (int p = 0; p < count; ++p) {
      DecoratePage(p + 1, count);
      for (const pdf::Placed& placed : pages_[static_cast<size_t>(p)]) placed.unit->draw(cr_, pdf::kMarginX, placed.y);
      cairo_show_page(cr_);
    }
    return count;
  }

  int figures() const { return figures_; }

 private:
  Unit& Push(double height, std::function<void(cairo_t*, double, double)> draw, double space_before = 0) {
    Unit unit;
    unit.height = height;
    unit.space_before = space_before;
    unit.draw = std::move(draw);
    units_.push_back(std::move(unit));
    return units_.back();
  }

  // ---- Cover, contents, headings ----

  void BuildCover() {
    const double w = pdf::kBodyWidth;
    const LayoutPtr title = text_.Make(doc_.cover.title, kCoverTitle, w);
    const LayoutPtr subtitle = text_.Make(doc_.cover.subtitle, kCoverSubtitle, w);
    const double title_h = Text::Height(title.get());
    const double subtitle_h = doc_.cover.subtitle.empty() ? 0 : Text::Height(subtitle.get()) + 4;
    const size_t first = units_.size();
    Push(24 + title_h + subtitle_h + 12, [=](cairo_t* cr, double x, double y) {
      pdf::Show(cr, title.get(), x, y + 24, pdf::kAccent);
      if (subtitle_h > 0) pdf::Show(cr, subtitle.get(), x, y + 24 + title_h + 4, pdf::kSoft);
      pdf::SetColour(cr, pdf::kAccent);
      cairo_rectangle(cr, x, y + 24 + title_h + subtitle_h + 8, w, 1.2);
      cairo_fill(cr);
    });
    if (!doc_.cover.facts.rows.empty()) Add(doc_.cover.facts, 14);
    const size_t before_hero = units_.size();
    if (!doc_.cover.summary.header.empty()) Add(doc_.cover.summary);
    if (doc_.cover.hero) {
      // The hero takes the height the rest of the cover leaves, so the cover is one page.
      double used = 0;
      for (size_t i = first; i < units_.size(); ++i) used += units_[i].height + units_[i].space_before;
      // Besides the image: its colour key and a one-line caption.
      const double under_image = pdf::ColourKeyHeight(text_) + 4 + 2 * kCaption.size_pt + 8;
      const double budget = pdf::kBodyBottom - pdf::kBodyTop - used - 2 * kBlockGap - 6 - under_image;
      const double max_image_h = std::max(budget, 0.35 * (pdf::kBodyBottom - pdf::kBodyTop));
      std::vector<Unit> summary(units_.begin() + static_cast<std::ptrdiff_t>(before_hero), units_.end());
      units_.resize(before_hero);
      FigureGrid hero;
      hero.figures.push_back(*doc_.cover.hero);
      hero.columns = 1;
      AddGrid(hero, max_image_h, 14);
      for (Unit& unit : summary) units_.push_back(std::move(unit));
    }
  }

  void BuildContents() {
    std::vector<const Section*> entries;
    for (const Section& s : doc_.sections) entries.push_back(&s);
    if (entries.empty()) return;
    const LayoutPtr title = text_.Make("Contents", kTocTitle);
    Unit& head = Push(Text::Height(title.get()) + 14, [=](cairo_t* cr, double x, double y) {
      pdf::Show(cr, title.get(), x, y, pdf::kAccent);
    });
    head.page_break_before = true;
    const double w = pdf::kBodyWidth;
    int major = 0, minor = 0;
    int parent = CAIRO_PDF_OUTLINE_ROOT;
    for (const Section* s : entries) {
      const bool top = s->level == 1;
      const std::string number = top ? std::to_string(++major) : std::to_string(major) + "." + std::to_string(++minor);
      if (top) minor = 0;
      const double indent = top ? 0 : 24;
      const double number_w = top ? 24 : 30;
      const Text::Style style = top ? kToc1 : kToc2;
      const LayoutPtr num = text_.Make(number, style);
      const LayoutPtr name = text_.Make(s->title, style, w - indent - number_w - 40);
      const double h = Text::Height(name.get());
      const std::string anchor = s->anchor;
      Push(h + 2, [=, this](cairo_t* cr, double x, double y) {
        const auto found = anchor_pages_.find(anchor);
        assert(found != anchor_pages_.end());
        const LayoutPtr page = text_.Make(std::to_string(found->second), style);
        const double page_w = Text::Width(page.get());
        pdf::Show(cr, num.get(), x + indent, y, top ? pdf::kAccent : pdf::kInk);
        pdf::Show(cr, name.get(), x + indent + number_w, y, top ? pdf::kAccent : pdf::kInk);
        pdf::Show(cr, page.get(), x + w - page_w, y, pdf::kInk);
        // Dot leader from the title's last line to the page number.
        const double lead_from = x + indent + number_w + Text::LastLineWidth(name.get()) + 6;
        const double lead_to = x + w - page_w - 6;
        if (lead_to > lead_from) {
          const double baseline = y + h - 3;
          const double dots[] = {0, 3};
          cairo_save(cr);
          cairo_set_dash(cr, dots, 2, 0);
          cairo_set_line_cap(cr, CAIRO_LINE_CAP_ROUND);
          cairo_set_line_width(cr, 0.7);
          pdf::SetColour(cr, pdf::kSoft);
          cairo_move_to(cr, lead_from, baseline);
          cairo_line_to(cr, lead_to, baseline);
          cairo_stroke(cr);
          cairo_restore(cr);
        }
        Link(cr, anchor, x, y, w, h + 2);
      }, top ? 7 : 1.5);
      // The outline: level 2 nested under its level 1.
      const std::string outline_title = number + " " + s->title;
      const std::string dest = "dest='" + anchor + "'";
      const int id = cairo_pdf_surface_add_outline(surface_, top ? CAIRO_PDF_OUTLINE_ROOT : parent,
                                                   outline_title.c_str(), dest.c_str(),
                                                   top ? CAIRO_PDF_OUTLINE_FLAG_OPEN : static_cast<cairo_pdf_outline_flags_t>(0));
      if (top) parent = id;
    }
  }

  void Heading(const Section& section, const std::string& number, bool new_page) {
    const bool top = section.level == 1;
    const Text::Style style = top ? kHeading1 : kHeading2;
    const double w = pdf::kBodyWidth;
    const LayoutPtr num = text_.Make(number, style);
    const double number_w = Text::Width(num.get()) + (top ? 10 : 8);
    const LayoutPtr title = text_.Make(section.title, style, w - number_w);
    const double h = Text::Height(title.get());
    assert(ValidAnchor(section.anchor));
    const std::string dest = "name='" + section.anchor + "'";
    Unit& unit = Push(h + (top ? 9 : 6), [=](cairo_t* cr, double x, double y) {
      cairo_tag_begin(cr, CAIRO_TAG_DEST, dest.c_str());
      pdf::Show(cr, num.get(), x, y, pdf::kAccent);
      pdf::Show(cr, title.get(), x + number_w, y, pdf::kAccent);
      cairo_tag_end(cr, CAIRO_TAG_DEST);
      pdf::SetColour(cr, top ? pdf::kAccent : pdf::kHairline);
      cairo_rectangle(cr, x, y + h + 3, w, top ? 0.8 : 0.5);
      cairo_fill(cr);
    }, top ? 20 : 12);
    unit.keep_with_next = true;
    unit.page_break_before = new_page;
    unit.anchor = section.anchor;
  }

  // Anchors go into Cairo's attribute strings ('...'): document.h promises [a-z0-9-].
  static bool ValidAnchor(const std::string& anchor) {
    return !anchor.empty() && std::all_of(anchor.begin(), anchor.end(), [](char c) {
      return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-';
    });
  }

  static void Link(cairo_t* cr, const std::string& anchor, double x, double y, double w, double h) {
    assert(ValidAnchor(anchor));
    char rect[160];
    std::snprintf(rect, sizeof(rect), "rect=[%.2f %.2f %.2f %.2f] ", x, y, w, h);
    const std::string attributes = rect + ("dest='" + anchor + "'");
    cairo_tag_begin(cr, CAIRO_TAG_LINK, attributes.c_str());
    cairo_tag_end(cr, CAIRO_TAG_LINK);
  }

  // ---- Blocks ----

  void Add(const Paragraph& paragraph) {
    const bool warning = paragraph.style == Paragraph::Style::kWarning;
    const bool note = paragraph.style == Paragraph::Style::kNote;
    const double inset = warning ? kWarningStripe + 2 * kWarningPad : 0;
    const double w = pdf::kBodyWidth;
    const LayoutPtr layout = text_.Make(paragraph.text, note ? kNote : kBody, w - inset);
    const std::vector<pdf::LayoutLine> lines = pdf::Lines(layout.get());
    const Rgb colour = note ? pdf::kSoft : pdf::kInk;
    // One unit per line, so that long paragraphs flow across pages; the first two and the
    // last two lines stay together (no orphans or widows). A warning's box is drawn piecewise.
    for (size_t i = 0; i < lines.size(); ++i) {
      const bool first = i == 0, last = i + 1 == lines.size();
      const double pad_top = warning && first ? kWarningPad : 0;
      const double pad_bottom = warning && last ? kWarningPad : 0;
      const pdf::LayoutLine line = lines[i];
      Unit& unit = Push(line.height + pad_top + pad_bottom, [=](cairo_t* cr, double x, double y) {
        const double h = line.height + pad_top + pad_bottom;
        if (warning) {
          pdf::SetColour(cr, pdf::kAmberFill);
          cairo_rectangle(cr, x, y, w, h);
          cairo_fill(cr);
          pdf::SetColour(cr, pdf::kAmber);
          cairo_rectangle(cr, x, y, kWarningStripe, h);
          cairo_fill(cr);
          cairo_set_line_width(cr, 0.6);
          cairo_move_to(cr, x + w, y);
          cairo_line_to(cr, x + w, y + h);
          if (first) {
            cairo_move_to(cr, x, y);
            cairo_line_to(cr, x + w, y);
          }
          if (last) {
            cairo_move_to(cr, x, y + h);
            cairo_line_to(cr, x + w, y + h);
          }
          cairo_stroke(cr);
        }
        pdf::ShowLine(cr, layout.get(), line, x + (warning ? kWarningStripe + kWarningPad : 0), y + pad_top, colour);
      }, first ? kBlockGap : 0);
      unit.keep_with_next = lines.size() > 1 && (i == 0 || i + 2 == lines.size());
    }
  }

  void Add(const KeyValues& kv, double space_before = kBlockGap) {
    const double w = pdf::kBodyWidth;
    double label_w = 0;
    for (const auto& [label, value] : kv.rows) {
      label_w = std::max(label_w, Text::Width(text_.Make(label, kBodyBold).get()));
    }
    label_w = std::min(label_w + 14, 0.38 * w);
    for (size_t i = 0; i < kv.rows.size(); ++i) {
      const LayoutPtr label = text_.Make(kv.rows[i].first, kBodyBold, label_w - 10);
      const LayoutPtr value = text_.Make(kv.rows[i].second, kBody, w - label_w);
      const double h = std::max(Text::Height(label.get()), Text::Height(value.get())) + 6;
      Push(h, [=](cairo_t* cr, double x, double y) {
        pdf::Show(cr, label.get(), x, y + 3, pdf::kSoft);
        pdf::Show(cr, value.get(), x + label_w, y + 3, pdf::kInk);
        pdf::SetColour(cr, pdf::kHairline);
        cairo_rectangle(cr, x, y + h - 0.4, w, 0.4);
        cairo_fill(cr);
      }, i == 0 ? space_before : 0);
    }
  }

  // Column widths, as an HTML table lays them out: natural widths when they fit (the spare
  // width spread in proportion); otherwise every column keeps at least its widest word
  // (numeric columns their whole text: numbers never wrap) and the columns share what is
  // left in proportion to how much wrapping saves them.
  std::vector<double> ColumnWidths(const Table& table) const {
    const size_t n = table.header.size();
    std::vector<double> natural(n, 0), least(n, 0);
    auto widest_word = [&](const std::string& text, const Text::Style& style) {
      double widest = 0;
      size_t start = 0;
      while (start <= text.size()) {
        size_t end = text.find_first_of(" \n", start);
        if (end == std::string::npos) end = text.size();
        if (end > start) widest = std::max(widest, Text::Width(text_.Make(text.substr(start, end - start), style).get()));
        start = end + 1;
      }
      return widest;
    };
    for (size_t c = 0; c < n; ++c) {
      natural[c] = Text::Width(text_.Make(table.header[c], kTableHeader).get());
      least[c] = widest_word(table.header[c], kTableHeader);
      for (const auto& row : table.rows) {
        natural[c] = std::max(natural[c], Text::Width(text_.Make(row[c], kTable).get()));
        least[c] = std::max(least[c], table.numeric[c] ? natural[c] : widest_word(row[c], kTable));
      }
      const double pad = 2 * kCellPadX + (c == 0 && !table.tint_srgb8.empty() ? 10 : 0);
      natural[c] += pad;
      least[c] = std::min(natural[c], least[c] + pad);
    }
    const double w = pdf::kBodyWidth;
    double total = 0, total_least = 0;
    for (size_t c = 0; c < n; ++c) total += natural[c], total_least += least[c];
    std::vector<double> widths = natural;
    if (total <= w) {
      for (double& x : widths) x += (w - total) * x / total;
    } else if (total_least >= w) {
      for (size_t c = 0; c < n; ++c) widths[c] = least[c] * w / total_least;
    } else {
      const double share = (w - total_least) / (total - total_least);
      for (size_t c = 0; c < n; ++c) widths[c] = least[c] + (natural[c] - least[c]) * share;
    }
    return widths;
  }

  void Add(const Table& table) {
    const size_t n = table.header.size();
    assert(n > 0 && table.numeric.size() == n);
    assert(table.tint_srgb8.empty() || table.tint_srgb8.size() == table.rows.size());
    assert(table.row_links.empty() || table.row_links.size() == table.rows.size());
    const std::vector<double> widths = ColumnWidths(table);
    const double w = pdf::kBodyWidth;
    const bool tinted = !table.tint_srgb8.empty();
    auto make_cells = [&](const std::vector<std::string>& cells, const Text::Style& style, double* height) {
      assert(cells.size() == n);
      std::vector<LayoutPtr> layouts;
      *height = 0;
      for (size_t c = 0; c < n; ++c) {
        const double inner = widths[c] - 2 * kCellPadX - (c == 0 && tinted ? 10 : 0);
        layouts.push_back(text_.Make(cells[c], style, inner, table.numeric[c] ? PANGO_ALIGN_RIGHT : PANGO_ALIGN_LEFT));
        *height = std::max(*height, Text::Height(layouts.back().get()));
      }
      *height += 2 * kCellPadY;
      return layouts;
    };
    double header_h = 0;
    const std::vector<LayoutPtr> header = make_cells(table.header, kTableHeader, &header_h);
    auto draw_header = [=](cairo_t* cr, double x, double y) {
      pdf::SetColour(cr, pdf::kAccent);
      cairo_rectangle(cr, x, y, w, header_h);
      cairo_fill(cr);
      double cx = x;
      for (size_t c = 0; c < n; ++c) {
        pdf::Show(cr, header[c].get(), cx + kCellPadX + (c == 0 && tinted ? 10 : 0), y + kCellPadY, pdf::kWhite);
        cx += widths[c];
      }
    };
    Unit& head = Push(header_h, draw_header, kBlockGap);
    head.keep_with_next = !table.rows.empty();
    auto repeat = std::make_shared<Unit>(head);
    repeat->keep_with_next = false;
    repeat->space_before = 0;
    for (size_t r = 0; r < table.rows.size(); ++r) {
      double h = 0;
      const std::vector<LayoutPtr> cells = make_cells(table.rows[r], kTable, &h);
      const std::optional<std::array<std::uint8_t, 3>> tint = tinted ? table.tint_srgb8[r] : std::nullopt;
      const std::string link = table.row_links.empty() ? std::string() : table.row_links[r];
      const bool zebra = r % 2 == 1;
      Unit& row = Push(h, [=](cairo_t* cr, double x, double y) {
        if (zebra) {
          pdf::SetColour(cr, pdf::kZebra);
          cairo_rectangle(cr, x, y, w, h);
          cairo_fill(cr);
        }
        if (tint) {
          const Rgb c{(*tint)[0] / 255.0, (*tint)[1] / 255.0, (*tint)[2] / 255.0};
          pdf::SetColour(cr, c, 0.22);
          cairo_rectangle(cr, x, y, widths[0], h);
          cairo_fill(cr);
          pdf::SetColour(cr, c);
          cairo_rectangle(cr, x + kCellPadX, y + h / 2 - 3.5, 7, 7);
          cairo_fill(cr);
        }
        double cx = x;
        for (size_t c = 0; c < n; ++c) {
          const Rgb colour = c == 0 && !link.empty() ? pdf::kLink : pdf::kInk;
          pdf::Show(cr, cells[c].get(), cx + kCellPadX + (c == 0 && tinted ? 10 : 0), y + kCellPadY, colour);
          cx += widths[c];
        }
        pdf::SetColour(cr, pdf::kHairline);
        cairo_rectangle(cr, x, y + h - 0.4, w, 0.4);
        cairo_fill(cr);
        if (!link.empty()) Link(cr, link, x, y, w, h);
      });
      row.repeat_header = repeat;
      // The last row stays with the caption.
      row.keep_with_next = r + 1 == table.rows.size() && !table.caption.empty();
    }
    if (!table.caption.empty()) Caption(table.caption, 4);
  }

  void Caption(const std::string& caption, double space_before) {
    const LayoutPtr layout = text_.Make(caption, kCaption, pdf::kBodyWidth);
    Push(Text::Height(layout.get()), [=](cairo_t* cr, double x, double y) {
      pdf::Show(cr, layout.get(), x, y, pdf::kSoft);
    }, space_before);
  }

  void Add(const FigureGrid& grid) { AddGrid(grid, pdf::kBodyBottom - pdf::kBodyTop - 60, kBlockGap); }

  // A row of figures is one unit (never split); images keep their aspect within the cell
  // width and at most max_image_h tall; a key's bar sits under its image, the caption under
  // both.
  void AddGrid(const FigureGrid& grid, double max_image_h, double space_before) {
    const int columns = std::clamp(grid.columns, 1, 4);
    const double cell_w = (pdf::kBodyWidth - (columns - 1) * kFigureGap) / columns;
    const double key_h = pdf::ColourKeyHeight(text_);
    const size_t count = grid.figures.size();
    for (size_t start = 0; start < count; start += static_cast<size_t>(columns)) {
      const size_t end = std::min(count, start + static_cast<size_t>(columns));
      struct Cell {
        Figure figure;
        double w = 0, h = 0;
        int max_px = 0;
        LayoutPtr caption;
      };
      std::vector<Cell> cells;
      double image_h = 0, caption_h = 0;
      bool any_key = false;
      for (size_t i = start; i < end; ++i) {
        Cell cell;
        cell.figure = grid.figures[i];
        const pdf::PixelSize size = pdf::ProbePng(cell.figure.png);
        const double aspect = static_cast<double>(size.height) / size.width;
        cell.w = std::min(cell_w, max_image_h / aspect);
        cell.h = cell.w * aspect;
        cell.max_px = std::max(1, static_cast<int>(std::ceil(cell.w / 72 * options_.dpi)));
        cell.caption = text_.Make(cell.figure.caption, kCaption, cell_w, PANGO_ALIGN_CENTER);
        image_h = std::max(image_h, cell.h);
        caption_h = std::max(caption_h, cell.figure.caption.empty() ? 0 : Text::Height(cell.caption.get()) + 3);
        any_key = any_key || (cell.figure.key && cell.figure.key->mode != analyze::ViewMode::kColour);
        cells.push_back(std::move(cell));
        ++figures_;
      }
      const double keys = any_key ? key_h + 4 : 0;
      const double h = image_h + keys + caption_h + 4;
      const int quality = options_.jpeg_quality;
      Unit& unit = Push(h, [=, this](cairo_t* cr, double x, double y) {
        for (size_t i = 0; i < cells.size(); ++i) {
          const Cell& cell = cells[i];
          const double cx = x + static_cast<double>(i) * (cell_w + kFigureGap);
          const double ix = cx + (cell_w - cell.w) / 2;
          const pdf::EmbeddedImage image = pdf::LoadForPdf(cell.figure.png, cell.max_px, quality);
          cairo_save(cr);
          cairo_translate(cr, ix, y);
          cairo_scale(cr, cell.w / image.width, cell.h / image.height);
          cairo_set_source_surface(cr, image.surface.get(), 0, 0);
          cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_GOOD);
          cairo_paint(cr);
          cairo_restore(cr);
          cairo_set_line_width(cr, 0.5);
          pdf::SetColour(cr, pdf::kHairline);
          cairo_rectangle(cr, ix, y, cell.w, cell.h);
          cairo_stroke(cr);
          if (cell.figure.key && cell.figure.key->mode != analyze::ViewMode::kColour) {
            pdf::DrawColourKey(cr, text_, *cell.figure.key, ix, y + image_h + 4, cell.w);
          }
          if (!cell.figure.caption.empty()) pdf::Show(cr, cell.caption.get(), cx, y + image_h + keys + 3, pdf::kSoft);
        }
      }, start == 0 ? space_before : 6);
      unit.keep_with_next = end == count && !grid.caption.empty();
    }
    if (!grid.caption.empty()) Caption(grid.caption, 2);
  }

  // ---- Page furniture ----

  void DecoratePage(int page, int count) {
    const double left = pdf::kMarginX, right = pdf::kPageWidth - pdf::kMarginX;
    if (page == 1) {
      // The cover: an accent band across the top, no header or footer.
      pdf::SetColour(cr_, pdf::kAccent);
      cairo_rectangle(cr_, 0, 0, pdf::kPageWidth, 14);
      cairo_fill(cr_);
      return;
    }
    const LayoutPtr title = text_.Make(doc_.cover.title, kPageLine, pdf::kBodyWidth * 0.6);
    const LayoutPtr subtitle = text_.Make(doc_.cover.subtitle, kPageLine);
    pdf::Show(cr_, title.get(), left, 34, pdf::kSoft);
    pdf::Show(cr_, subtitle.get(), right - Text::Width(subtitle.get()), 34, pdf::kSoft);
    cairo_set_line_width(cr_, 0.5);
    pdf::SetColour(cr_, pdf::kHairline);
    cairo_move_to(cr_, left, 48);
    cairo_line_to(cr_, right, 48);
    const double footer_y = pdf::kPageHeight - 44;
    cairo_move_to(cr_, left, footer_y);
    cairo_line_to(cr_, right, footer_y);
    cairo_stroke(cr_);
    const LayoutPtr footer = text_.Make(doc_.footer, kPageLine, pdf::kBodyWidth * 0.7);
    const LayoutPtr number = text_.Make("Page " + std::to_string(page) + " of " + std::to_string(count), kPageLine);
    pdf::Show(cr_, footer.get(), left, footer_y + 6, pdf::kSoft);
    pdf::Show(cr_, number.get(), right - Text::Width(number.get()), footer_y + 6, pdf::kSoft);
  }

  cairo_t* cr_;
  cairo_surface_t* surface_;
  const Document& doc_;
  const PdfOptions& options_;
  Text text_;
  std::vector<Unit> units_;
  std::vector<pdf::Page> pages_;
  std::map<std::string, int> anchor_pages_;
  int figures_ = 0;
};

cairo_status_t AppendToString(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

std::string PdfOptions::Check() const {
  if (!core::InRange(dpi, 72, 600)) return core::OptionFail("dpi", dpi, "in [72, 600]");
  if (jpeg_quality < 50 || jpeg_quality > 100) return core::OptionFail("jpeg_quality", jpeg_quality, "in [50, 100]");
  if (font_family.empty()) return "font_family: must not be empty";
  return "";
}

PdfStats WritePdf(const Document& doc, const std::filesystem::path& path, const PdfOptions& options) {
  assert(options.Check().empty());
  const auto start = std::chrono::steady_clock::now();
  // The PDF is assembled in memory and written atomically at the end: a failure part-way
  // (a bad PNG) leaves nothing on disk. Declared before the surface, which writes into it.
  std::string bytes;
  PdfStats stats;
  {
    std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)> surface(
        cairo_pdf_surface_create_for_stream(AppendToString, &bytes, pdf::kPageWidth, pdf::kPageHeight),
        cairo_surface_destroy);
    std::unique_ptr<cairo_t, decltype(&cairo_destroy)> cr(cairo_create(surface.get()), cairo_destroy);
    const auto set = [&](cairo_pdf_metadata_t field, const std::string& value) {
      if (!value.empty()) cairo_pdf_surface_set_metadata(surface.get(), field, value.c_str());
    };
    set(CAIRO_PDF_METADATA_TITLE, doc.cover.title);
    set(CAIRO_PDF_METADATA_AUTHOR, doc.author);
    set(CAIRO_PDF_METADATA_SUBJECT, doc.subject);
    set(CAIRO_PDF_METADATA_KEYWORDS, doc.keywords);
    set(CAIRO_PDF_METADATA_CREATOR, doc.creator);
    // Cairo would otherwise stamp the clock: identical inputs must give identical bytes.
    set(CAIRO_PDF_METADATA_CREATE_DATE, PdfDate(doc.created_utc));
    set(CAIRO_PDF_METADATA_MOD_DATE, PdfDate(doc.created_utc));

    Builder builder(cr.get(), surface.get(), doc, options);
    builder.Build();
    stats.pages = builder.Draw();
    stats.figures = builder.figures();
    cr.reset();
    cairo_surface_finish(surface.get());
    if (cairo_surface_status(surface.get()) != CAIRO_STATUS_SUCCESS) {
      throw core::OutputError(path, std::string("PDF rendering failed: ") +
                                        cairo_status_to_string(cairo_surface_status(surface.get())));
    }
  }
  core::WriteFileAtomically(path, bytes);
  stats.bytes = static_cast<int64_t>(bytes.size());
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace hw::report
