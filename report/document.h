#pragma once

// The audit report as a document, independent of its form: a cover, then numbered sections
// of paragraphs, label/value lists, tables and figure grids. report_model.h fills it from
// job.yaml, analyze.json, reconstruct.json and the rig; html_report.h and pdf_report.h lay
// it out and compute nothing, so both forms say exactly the same thing.
//
// Every string is plain UTF-8 text, never markup: the writers escape it (HTML) or hand it
// to Pango as text (PDF), so nothing from a job file can inject markup or script. Numbers
// arrive already formatted, with their units.

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "analyze/palette.h"
#include "analyze/views.h"

namespace hw::report {

// A paragraph of running text. '\n' in text is a line break within the paragraph.
struct Paragraph {
  std::string text;
  enum class Style { kBody, kNote, kWarning } style = Style::kBody;  // note: smaller grey;
                                                                      // warning: boxed
};

// Label/value rows in two columns ("Client" | "ACME Ltd"); a value may hold '\n'.
struct KeyValues {
  std::vector<std::pair<std::string, std::string>> rows;
};

// A table with a header row. Cells are text; `numeric[c]` right-aligns column c (same
// size as header). `tint_srgb8[r]`, when set, shades row r's first cell (severity colour).
struct Table {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;  // each of header.size() cells
  std::vector<bool> numeric;                   // header.size()
  std::vector<std::optional<std::array<std::uint8_t, 3>>> tint_srgb8;  // rows.size() or empty
  std::string caption;                         // under the table; may be empty
  // Anchor of each row's target section (e.g. "spot-H1"), or "" for none: the HTML makes
  // the row's first cell a link, the PDF a link annotation. rows.size() or empty.
  std::vector<std::string> row_links;
};

// What a figure's colour bar maps: drawn as a vector bar with ticks beside the image (PDF)
// or as a CSS gradient (HTML), from the same palette functions as the images.
struct ColourKey {
  analyze::ViewMode mode = analyze::ViewMode::kThermal;  // kColour has no key
  analyze::Palette palette = analyze::Palette::kIron;
  bool inverted = false;
  analyze::Span span;               // °C at the bar's ends
  double band_low_c = 0;            // kHighlight: the normal band (drawn as a neutral gap)
  double band_high_c = 0;
  std::string unit = "°C";
};

// One image: an 8-bit sRGB PNG on disk (absolute or relative to the process's working
// directory), shown at the grid cell's width with its aspect ratio.
struct Figure {
  std::filesystem::path png;
  int width_px = 0, height_px = 0;  // of the PNG
  std::string caption;              // e.g. "Thermal (iron), 17.0–39.1 °C"
  std::optional<ColourKey> key;     // none for the colour view
};

// Figures side by side, `columns` per row (1..4), with an optional caption for the grid.
struct FigureGrid {
  std::vector<Figure> figures;
  int columns = 2;
  std::string caption;
};

using Block = std::variant<Paragraph, KeyValues, Table, FigureGrid>;

// A heading with its content. level 1 = numbered section ("3 Hot and cold spots"), level 2
// = subsection ("3.1 H1 — hot spot, probable"). `anchor` is unique in the document,
// [a-z0-9-] only: the HTML id, the PDF link/bookmark destination.
struct Section {
  int level = 1;
  std::string anchor;
  std::string title;
  std::vector<Block> blocks;
  // PDF: start this section on a new page.
  bool new_page = false;
};

// The cover page: title, the facts an auditor reads first, a hero image and the summary.
struct Cover {
  std::string title;     // "Infrared thermography inspection report"
  std::string subtitle;  // "Plant room 2, ACME Ltd"
  KeyValues facts;       // client, site, date, reference, inspector, standard
  std::optional<Figure> hero;
  Table summary;         // spots by severity
};

// A marker on the HTML report's 3D view: a spot, placed at its peak, linking to its section.
struct Marker {
  std::string label;   // "H1"
  std::string anchor;  // "spot-h1"
  bool hot = true;
  Eigen::Vector3d position_in_world = Eigen::Vector3d::Zero();  // metres, model frame
  Eigen::Vector3d normal_in_world = Eigen::Vector3d::UnitZ();   // unit; offsets the marker
};

// What the HTML report's 3D view shows: the model, coloured per vertex in the four modes
// with the same styles as the static images.
struct ModelView {
  std::filesystem::path model_ply;  // the thermal model (reconstruct's model.ply)
  std::vector<Marker> markers;
  analyze::Palette palette = analyze::Palette::kIron;
  bool inverted = false;
  analyze::Span span;               // thermal / IH span, °C
  double band_low_c = 0;            // highlighting's normal band, °C
  double band_high_c = 0;
};

struct Document {
  Cover cover;
  std::vector<Section> sections;
  // PDF metadata (and HTML <meta>): title = cover.title.
  std::string author;         // the inspector
  std::string subject;        // "Client — site"
  std::string keywords;       // "thermography, ASTM E1934, ..."
  std::string creator;        // "heatwave 0.x"
  // ISO 8601 UTC, "2026-12-02T10:00:00Z": the PDF's creation and modification date (never
  // the clock, so identical inputs give identical bytes) and the HTML's printed date.
  std::string created_utc;
  std::string footer;         // left of every PDF page's footer: "Report HW-0142 · ACME Ltd"
  std::optional<ModelView> model_view;  // HTML only; none: no 3D view
};

}  // namespace hw::report
