#include "report/html_report.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "analyze/srgb.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/strings.h"

namespace hw::report {
namespace {

using core::StringPrintf;

// Stops per colour bar: enough that a CSS gradient between them is indistinguishable from
// the palette (the palettes' own control points are ≥ 1/8 apart).
constexpr int kGradientStops = 33;

constexpr uint64_t kMaxFigureBytes = uint64_t{64} << 20;

const char* kStyle = R"CSS(
:root { --ink: #1d2329; --muted: #5f6b76; --rule: #c9d1d9; --accent: #b3261e; --bg-alt: #f4f6f8; }
* { box-sizing: border-box; }
body { font-family: "DejaVu Sans", "Helvetica Neue", Arial, sans-serif; color: var(--ink); margin: 0;
       line-height: 1.45; font-size: 15px; background: #fff; }
main { max-width: 1040px; margin: 0 auto; padding: 24px 32px 64px; }
header.cover { border-bottom: 3px solid var(--accent); padding-bottom: 16px; margin-bottom: 24px; }
header.cover h1 { font-size: 30px; margin: 8px 0 4px; }
header.cover p.subtitle { font-size: 19px; color: var(--muted); margin: 0 0 16px; }
.cover-grid { display: grid; grid-template-columns: 1fr 1fr; gap: 24px; align-items: start; }
h2 { font-size: 22px; border-bottom: 1px solid var(--rule); padding-bottom: 4px; margin-top: 40px; }
h3 { font-size: 18px; margin-top: 28px; }
h2 .num, h3 .num { color: var(--muted); margin-right: 0.5em; }
dl.kv { display: grid; grid-template-columns: minmax(160px, 30%) 1fr; gap: 4px 16px; margin: 12px 0; }
dl.kv dt { color: var(--muted); }
dl.kv dd { margin: 0; white-space: pre-line; }
table { border-collapse: collapse; width: 100%; margin: 12px 0 4px; font-size: 14px; }
th { text-align: left; border-bottom: 2px solid var(--ink); padding: 4px 8px; }
td { border-bottom: 1px solid var(--rule); padding: 4px 8px; vertical-align: top; white-space: pre-line; }
td:first-child { white-space: nowrap; }
.bar-spacer { height: 38px; }  /* a .bar with its border and margins */
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tbody tr:nth-child(even) { background: var(--bg-alt); }
.swatch { display: inline-block; width: 0.8em; height: 0.8em; border-radius: 2px; margin-right: 0.4em;
          vertical-align: -0.05em; }
p.caption, figcaption { color: var(--muted); font-size: 13px; margin: 2px 0 12px; }
p.note { color: var(--muted); font-size: 13px; }
p.warning { border-left: 4px solid #d98a00; background: #fff6e0; padding: 6px 10px; }
p { white-space: pre-line; }
.grid { display: grid; gap: 12px; margin: 12px 0; }
figure { margin: 0; }
figure img { width: 100%; height: auto; display: block; border: 1px solid var(--rule); }
.bar { position: relative; height: 12px; margin: 6px 0 18px; border: 1px solid var(--rule); }
.bar span { position: absolute; top: 13px; font-size: 11px; color: var(--muted); transform: translateX(-50%);
            white-space: nowrap; }
nav.toc ol { list-style: none; padding-left: 0; }
nav.toc ol ol { padding-left: 1.6em; }
nav.toc a { color: var(--ink); text-decoration: none; }
nav.toc a:hover { text-decoration: underline; }
nav.toc .num { color: var(--muted); display: inline-block; min-width: 2.4em; }
a { color: #0b5cad; }
footer { margin-top: 48px; color: var(--muted); font-size: 12px; border-top: 1px solid var(--rule); padding-top: 8px; }
@media (max-width: 760px) { .cover-grid { grid-template-columns: 1fr; } .grid { grid-template-columns: 1fr !important; } }
@media print {
  @page { size: A4; margin: 15mm; }
  main { max-width: none; padding: 0; }
  .hw-viewer, .no-print { display: none !important; }
  section.new-page { break-before: page; }
  figure, tr, .bar { break-inside: avoid; }
  h2, h3 { break-after: avoid; }
}
)CSS";

std::string Css(const std::array<std::uint8_t, 3>& c) { return StringPrintf("rgb(%d,%d,%d)", c[0], c[1], c[2]); }

std::string Srgb(const Eigen::Vector3f& linear) {
  return Css({analyze::LinearToSrgb8(linear.x()), analyze::LinearToSrgb8(linear.y()), analyze::LinearToSrgb8(linear.z())});
}

// The colour bar of a figure: the palette (IH: hue at full intensity) over the span, for
// highlighting a neutral grey inside the normal band; ticks from analyze::NiceTicks.
std::string ColourBar(const ColourKey& key) {
  const double width = key.span.max_c - key.span.min_c;
  std::string stops;
  for (int i = 0; i < kGradientStops; ++i) {
    const double t = static_cast<double>(i) / (kGradientStops - 1);
    const double value = key.span.min_c + t * width;
    std::string colour;
    if (key.mode == analyze::ViewMode::kIhMapping) {
      colour = Srgb(analyze::IhColour(t, 1.0f));
    } else if (key.mode == analyze::ViewMode::kHighlight && value >= key.band_low_c && value <= key.band_high_c) {
      colour = "rgb(190,190,190)";
    } else {
      colour = Srgb(analyze::PaletteColour(key.palette, key.inverted, t));
    }
    stops += StringPrintf(",%s %.2f%%", colour.c_str(), 100 * t);
  }
  std::string html = "<div class=\"bar\" style=\"background:linear-gradient(to right" + stops + ")\">";
  const std::vector<double> ticks = analyze::NiceTicks(key.span, 6);
  const double step = ticks.size() > 1 ? ticks[1] - ticks[0] : width;
  for (size_t i = 0; i < ticks.size(); ++i) {
    std::string label = analyze::FormatTick(ticks[i], step);
    if (i + 1 == ticks.size()) label += " " + key.unit;
    html += StringPrintf("<span style=\"left:%.2f%%\">", 100 * key.span.Normalize(ticks[i])) + HtmlEscape(label) + "</span>";
  }
  return html + "</div>";
}

struct Renderer {
  const Document& doc;
  const HtmlOptions& options;
  std::string out;
  int images = 0;

  // spacer: a figure without a colour bar in a grid with bars keeps its caption level.
  void Figure(const report::Figure& f, bool spacer = false) {
    const std::string png = core::ReadFile(f.png, kMaxFigureBytes);
    if (png.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0) throw core::InputError(f.png, "not a PNG file");
    ++images;
    out += "<figure><img alt=\"" + HtmlEscape(f.caption) + "\" width=\"" + std::to_string(f.width_px) +
           "\" height=\"" + std::to_string(f.height_px) + "\" src=\"data:image/png;base64," + core::Base64(png) + "\">";
    if (f.key) {
      out += ColourBar(*f.key);
    } else if (spacer) {
      out += "<div class=\"bar-spacer\"></div>";
    }
    out += "<figcaption>" + HtmlEscape(f.caption) + "</figcaption></figure>\n";
  }

  void Block(const Paragraph& p) {
    const char* cls = p.style == Paragraph::Style::kNote ? "note" : p.style == Paragraph::Style::kWarning ? "warning" : "body";
    out += std::string("<p class=\"") + cls + "\">" + HtmlEscape(p.text) + "</p>\n";
  }

  void Block(const KeyValues& kv) {
    out += "<dl class=\"kv\">";
    for (const auto& [label, value] : kv.rows) out += "<dt>" + HtmlEscape(label) + "</dt><dd>" + HtmlEscape(value) + "</dd>";
    out += "</dl>\n";
  }

  void Block(const Table& t) {
    auto cls = [&](size_t c) { return c < t.numeric.size() && t.numeric[c] ? " class=\"num\"" : ""; };
    out += "<table><thead><tr>";
    for (size_t c = 0; c < t.header.size(); ++c) out += std::string("<th") + cls(c) + ">" + HtmlEscape(t.header[c]) + "</th>";
    out += "</tr></thead><tbody>\n";
    for (size_t r = 0; r < t.rows.size(); ++r) {
      out += "<tr>";
      for (size_t c = 0; c < t.rows[r].size(); ++c) {
        std::string cell = HtmlEscape(t.rows[r][c]);
        if (c == 0 && r < t.row_links.size() && !t.row_links[r].empty()) {
          cell = "<a href=\"#" + HtmlEscape(t.row_links[r]) + "\">" + cell + "</a>";
        }
        if (c == 0 && r < t.tint_srgb8.size() && t.tint_srgb8[r]) {
          cell = "<span class=\"swatch\" style=\"background:" + Css(*t.tint_srgb8[r]) + "\"></span>" + cell;
        }
        out += std::string("<td") + cls(c) + ">" + cell + "</td>";
      }
      out += "</tr>\n";
    }
    out += "</tbody></table>\n";
    if (!t.caption.empty()) out += "<p class=\"caption\">" + HtmlEscape(t.caption) + "</p>\n";
  }

  void Block(const FigureGrid& g) {
    out += StringPrintf("<div class=\"grid\" style=\"grid-template-columns:repeat(%d,1fr)\">\n", std::max(1, g.columns));
    const bool any_key = std::any_of(g.figures.begin(), g.figures.end(), [](const report::Figure& f) { return f.key.has_value(); });
    for (const report::Figure& f : g.figures) Figure(f, any_key);
    out += "</div>\n";
    if (!g.caption.empty()) out += "<p class=\"caption\">" + HtmlEscape(g.caption) + "</p>\n";
  }

  void Render() {
    out += "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n";
    out += "<meta http-equiv=\"Content-Security-Policy\" content=\"" + HtmlEscape(options.content_security_policy) + "\">\n";
    out += "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n";
    out += "<title>" + HtmlEscape(doc.cover.title + " — " + doc.cover.subtitle) + "</title>\n";
    out += "<meta name=\"author\" content=\"" + HtmlEscape(doc.author) + "\">\n";
    out += "<meta name=\"keywords\" content=\"" + HtmlEscape(doc.keywords) + "\">\n";
    out += "<meta name=\"generator\" content=\"" + HtmlEscape(doc.creator) + "\">\n";
    out += "<style>" + std::string(kStyle) + "</style>\n</head>\n<body>\n<main>\n";

    out += "<header class=\"cover\"><h1>" + HtmlEscape(doc.cover.title) + "</h1><p class=\"subtitle\">" +
           HtmlEscape(doc.cover.subtitle) + "</p>\n<div class=\"cover-grid\"><div>";
    Block(doc.cover.facts);
    Block(doc.cover.summary);
    out += "</div><div>";
    if (doc.cover.hero) Figure(*doc.cover.hero);
    out += "</div></div></header>\n";

    // Numbering and the table of contents.
    std::vector<std::string> numbers;
    int major = 0, minor = 0;
    for (const Section& s : doc.sections) {
      if (s.level == 1) {
        ++major;
        minor = 0;
        numbers.push_back(std::to_string(major));
      } else {
        numbers.push_back(std::to_string(major) + "." + std::to_string(++minor));
      }
    }
    out += "<nav class=\"toc\"><h2>Contents</h2><ol>";
    for (size_t i = 0; i < doc.sections.size(); ++i) {
      const Section& s = doc.sections[i];
      const bool opens_sub = s.level == 1 && i + 1 < doc.sections.size() && doc.sections[i + 1].level == 2;
      out += "<li><a href=\"#" + HtmlEscape(s.anchor) + "\"><span class=\"num\">" + numbers[i] + "</span>" +
             HtmlEscape(s.title) + "</a>";
      if (opens_sub) {
        out += "<ol>";
      } else {
        out += "</li>";
        const bool closes_sub = s.level == 2 && (i + 1 == doc.sections.size() || doc.sections[i + 1].level == 1);
        if (closes_sub) out += "</ol></li>";
      }
    }
    out += "</ol></nav>\n";

    for (size_t i = 0; i < doc.sections.size(); ++i) {
      const Section& s = doc.sections[i];
      out += "<section id=\"" + HtmlEscape(s.anchor) + "\"" + (s.new_page ? " class=\"new-page\"" : "") + ">\n";
      const char* h = s.level == 1 ? "h2" : "h3";
      out += std::string("<") + h + "><span class=\"num\">" + numbers[i] + "</span>" + HtmlEscape(s.title) + "</" + h + ">\n";
      if (s.anchor == "overview" && !options.model_view_html.empty()) {
        out += "<div class=\"no-print\" id=\"model-3d\">" + options.model_view_html + "</div>\n";
      }
      for (const report::Block& b : s.blocks) std::visit([&](const auto& x) { Block(x); }, b);
      out += "</section>\n";
    }
    out += "<footer>" + HtmlEscape(doc.footer) + " · " + HtmlEscape(doc.creator) + " · " + HtmlEscape(doc.created_utc) +
           "</footer>\n</main>\n</body>\n</html>\n";
  }
};

}  // namespace

std::string HtmlEscape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      switch (c) {
        case '&': out += "&amp;"; break;
        case '<': out += "&lt;"; break;
        case '>': out += "&gt;"; break;
        case '"': out += "&quot;"; break;
        case '\'': out += "&#39;"; break;
        default:
          if (c >= 0x20 && c != 0x7f) {
            out += static_cast<char>(c);
          } else if (c == '\n' || c == '\t') {
            out += static_cast<char>(c);
          }
      }
      ++i;
      continue;
    }
    // A UTF-8 sequence passes whole when valid (no overlong form, no surrogate, ≤ U+10FFFF).
    int length = c >= 0xf0 && c <= 0xf4 ? 4 : c >= 0xe0 ? 3 : c >= 0xc2 && c <= 0xdf ? 2 : 0;
    if (c >= 0xf5) length = 0;
    bool valid = length > 0 && i + static_cast<size_t>(length) <= text.size();
    for (int k = 1; valid && k < length; ++k) valid = (static_cast<unsigned char>(text[i + static_cast<size_t>(k)]) & 0xc0) == 0x80;
    if (valid && length >= 3) {
      const auto c1 = static_cast<unsigned char>(text[i + 1]);
      if (c == 0xe0 && c1 < 0xa0) valid = false;  // overlong
      if (c == 0xed && c1 >= 0xa0) valid = false;  // surrogate
      if (c == 0xf0 && c1 < 0x90) valid = false;  // overlong
      if (c == 0xf4 && c1 >= 0x90) valid = false;  // past U+10FFFF
    }
    if (valid) {
      out.append(text.substr(i, static_cast<size_t>(length)));
      i += static_cast<size_t>(length);
    } else {
      out += "\xEF\xBF\xBD";
      ++i;
    }
  }
  return out;
}

std::string RenderHtml(const Document& doc, const HtmlOptions& options, int* images) {
  Renderer r{doc, options, {}, 0};
  r.Render();
  if (images) *images = r.images;
  return std::move(r.out);
}

HtmlStats WriteHtml(const Document& doc, const std::filesystem::path& path, const HtmlOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  Renderer r{doc, options, {}, 0};
  r.Render();
  core::WriteFileAtomically(path, r.out);
  HtmlStats stats;
  stats.bytes = static_cast<int64_t>(r.out.size());
  stats.images = r.images;
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace hw::report
