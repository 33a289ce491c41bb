#pragma once

// The audit report as a PDF (Cairo + Pango): an A4 cover, a table of contents with links
// and bookmarks, numbered sections, tables that split across pages with their header
// repeated, figure grids with vector colour bars, and images embedded as JPEG at print
// resolution. The layout is computed first (pagination), then drawn, so that the table of
// contents and every footer ("Page n of N") know the final page numbers.

#include <cstdint>
#include <filesystem>
#include <string>

#include "report/document.h"

namespace hw::report {

struct PdfOptions {
  // Images are resampled to at most this resolution at their placed size (never upsampled),
  // pixels per inch, [72, 600].
  double dpi = 300;
  // JPEG quality of the embedded images (DCTDecode), [50, 100].
  int jpeg_quality = 92;
  // Body font, a Pango family name (a comma-separated list falls back in order); not empty.
  std::string font_family = "DejaVu Sans";

  // "" or "field: must be ..., got ...".
  std::string Check() const;
};

struct PdfStats {
  int pages = 0;        // pages of the PDF, cover included
  int figures = 0;      // images placed (the cover's hero included)
  int64_t bytes = 0;    // size of the PDF file
  double seconds = 0;   // wall time of WritePdf (layout, image encoding, drawing, writing)
};

// Writes `doc` as an A4 portrait PDF to `path` atomically (temporary file + rename; a
// failure leaves no file). Identical inputs give byte-identical files: the PDF's dates are
// doc.created_utc (a malformed or empty one is written as 1970-01-01T00:00:00Z), never
// the clock. Throws core::InputError(png path, reason) for a figure PNG that cannot be
// read or decoded, core::OutputError for an unwritable path. Asserts options.Check() == ""
// and the document's invariants (section levels 1 or 2, table row sizes, key spans).
PdfStats WritePdf(const Document& doc, const std::filesystem::path& path, const PdfOptions& options = {});

}  // namespace hw::report
