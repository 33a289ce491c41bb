#pragma once

// The audit report as one self-contained HTML file: every image inline (data: URIs), the
// styles inline, no external URL, and a Content-Security-Policy that forbids the page any
// network request, so it opens offline, from an e-mail attachment, years later. Colour bars
// are CSS gradients sampled from the same palettes as the images. The interactive 3D view
// (report/viewer_embed.h) is passed in as a ready fragment; the static images stay the
// fallback and are what prints.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "report/document.h"

namespace hw::report {

struct HtmlOptions {
  // The 3D view's HTML fragment (ViewerHtml), placed at the top of the "overview" section;
  // "" for none.
  std::string model_view_html;
  // The page's Content-Security-Policy (ViewerContentSecurityPolicy() when there is a 3D
  // view). Without scripts: default-src 'none'; img-src data:; style-src 'unsafe-inline'.
  std::string content_security_policy = "default-src 'none'; img-src data:; style-src 'unsafe-inline'";
};

struct HtmlStats {
  int64_t bytes = 0;
  int images = 0;
  double seconds = 0;
};

// `text` escaped for HTML element content and attribute values (& < > " ' as entities);
// invalid UTF-8 bytes become U+FFFD, control characters other than \n and \t are dropped.
std::string HtmlEscape(std::string_view text);

// The page as a string; *images (if given) the count of images inlined. Throws
// core::InputError(png, reason) for a figure whose PNG cannot be read.
std::string RenderHtml(const Document& doc, const HtmlOptions& options = {}, int* images = nullptr);

// RenderHtml written to `path` atomically (a failure leaves no file). Throws
// core::InputError as RenderHtml, core::OutputError when `path` cannot be written.
HtmlStats WriteHtml(const Document& doc, const std::filesystem::path& path, const HtmlOptions& options = {});

}  // namespace hw::report
