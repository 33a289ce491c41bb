#include "report/viewer_embed.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <string_view>

#include <nlohmann/json.hpp>
#include <zlib.h>

#include "analyze/srgb.h"
#include "analyze/views.h"
#include "core/option_check.h"
#include "core/strings.h"

// The viewer bundle (esbuild output of report/viewer/viewer.js), linked in by
// viewer_bundle.cc.
extern "C" const char hw_report_viewer_bundle[];
extern "C" const char hw_report_viewer_bundle_end[];

namespace hw::report {
namespace {

using core::InRange;
using core::OptionFail;

// Linear grey for the visible colour of a mesh without colour (analyze/views.cc: sRGB 188).
constexpr float kNoColourGreyLinear = 0.5f;
// The hatch's base grey (analyze::UnobservedHatchGrey away from its lines), sRGB.
constexpr float kHatchBaseSrgb = 0.62f;

float Luminance(const Eigen::Vector3f& linear) {
  return 0.2126f * linear[0] + 0.7152f * linear[1] + 0.0722f * linear[2];
}

void PutSrgb8(std::vector<uint8_t>& out, size_t v, const Eigen::Vector3f& linear) {
  for (int c = 0; c < 3; ++c) out[v * 3 + static_cast<size_t>(c)] = analyze::LinearToSrgb8(linear[c]);
}

// zlib stream (RFC 1950) of `bytes`, which the viewer inflates with the browser's
// DecompressionStream("deflate"): the mesh data shrinks to ~40 %.
std::vector<uint8_t> Deflate(const std::vector<uint8_t>& bytes) {
  uLongf size = compressBound(static_cast<uLong>(bytes.size()));
  std::vector<uint8_t> out(size);
  const int status = compress2(out.data(), &size, bytes.data(), static_cast<uLong>(bytes.size()), 6);
  assert(status == Z_OK);  // only memory or a too small buffer fail, and compressBound sizes it
  (void)status;
  out.resize(size);
  return out;
}

// JSON for a <script type="application/json">: '<', '>' and '&' as \u escapes, so that no
// string in it can end the element ("</script") or open a comment ("<!--").
std::string ScriptSafeJson(const nlohmann::json& value) {
  const std::string text = value.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    if (c == '<') {
      out += "\\u003c";
    } else if (c == '>') {
      out += "\\u003e";
    } else if (c == '&') {
      out += "\\u0026";
    } else {
      out += c;
    }
  }
  return out;
}

// The bundle inside a <script>: "</script" (any case) could only occur in a JS string,
// regex or comment, where "<\/" means the same.
std::string ScriptSafeBundle() {
  std::string js(hw_report_viewer_bundle,
                 static_cast<size_t>(hw_report_viewer_bundle_end - hw_report_viewer_bundle));
  // "<!--" in a script would change how the HTML parser ends it; esbuild never writes one.
  assert(js.find("<!--") == std::string::npos);
  std::string out;
  out.reserve(js.size());
  for (size_t i = 0; i < js.size(); ++i) {
    if (js[i] == '<' && i + 1 < js.size() && js[i + 1] == '/' && i + 8 <= js.size()) {
      std::string word = js.substr(i + 2, 6);
      std::transform(word.begin(), word.end(), word.begin(), [](char ch) { return static_cast<char>(std::tolower(static_cast<unsigned char>(ch))); });
      if (word == "script") {
        out += "<\\/";
        ++i;
        continue;
      }
    }
    out += js[i];
  }
  return out;
}

// Face indices of the mesh to embed: all of them when within max_faces, else simplified.
std::vector<uint32_t> DecimatedIndices(const analyze::ThermalMesh& mesh, const ModelView& view,
                                       const ViewerOptions& options, double diagonal) {
  std::vector<uint32_t> indices;
  indices.reserve(static_cast<size_t>(mesh.NumFaces()) * 3);
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) indices.push_back(static_cast<uint32_t>(f[k]));
  }
  if (mesh.NumFaces() <= options.max_faces) return indices;

  // The simplifier's positions: displaced along the normal by the temperature (see
  // ViewerOptions::temperature_relief_fraction), so temperature contrast counts as error.
  const size_t n = static_cast<size_t>(mesh.NumVertices());
  std::vector<float> positions(n * 3);
  const double relief_m = options.temperature_relief_fraction * diagonal;
  for (size_t v = 0; v < n; ++v) {
    Eigen::Vector3d p = mesh.points_in_world[v];
    if (mesh.HasTemperature() && std::isfinite(mesh.temperature_c[v]) && v < mesh.normals.size()) {
      p += mesh.normals[v] * (relief_m * view.span.Normalize(mesh.temperature_c[v]));
    }
    for (int c = 0; c < 3; ++c) positions[v * 3 + static_cast<size_t>(c)] = static_cast<float>(p[c]);
  }
  const size_t target = static_cast<size_t>(options.max_faces) * 3;
  const float scale = meshopt_simplifyScale(positions.data(), n, sizeof(float) * 3);
  const auto relative_error =
      static_cast<float>(scale > 0 ? options.max_error_fraction * diagonal / static_cast<double>(scale) : 0.0);
  std::vector<uint32_t> out(indices.size());
  size_t count = meshopt_simplify(out.data(), indices.data(), indices.size(), positions.data(), n,
                                  sizeof(float) * 3, target, relative_error, 0, nullptr);
  if (count > target) {
    // The error bound stopped it above the face budget: the budget wins.
    count = meshopt_simplify(out.data(), indices.data(), indices.size(), positions.data(), n,
                             sizeof(float) * 3, target, std::numeric_limits<float>::max(), 0, nullptr);
  }
  if (count > target) {
    // Borders and seams the simplifier must keep: the sloppy simplifier has no such limit.
    count = meshopt_simplifySloppy(out.data(), indices.data(), indices.size(), positions.data(), n,
                                   sizeof(float) * 3, target, std::numeric_limits<float>::max(), nullptr);
  }
  out.resize(std::min(count, target) / 3 * 3);
  return out;
}

}  // namespace

std::string ViewerOptions::Check() const {
  if (!InRange(max_faces, 1000, 2000000)) return OptionFail("max_faces", max_faces, "in [1000, 2000000]");
  if (!(max_error_fraction > 0) || !(max_error_fraction <= 0.1)) {
    return OptionFail("max_error_fraction", max_error_fraction, "in (0, 0.1]");
  }
  if (!InRange(height_px, 200, 2000)) return OptionFail("height_px", height_px, "in [200, 2000]");
  if (!InRange(temperature_relief_fraction, 0, 0.1)) {
    return OptionFail("temperature_relief_fraction", temperature_relief_fraction, "in [0, 0.1]");
  }
  for (int c = 0; c < 3; ++c) {
    if (!std::isfinite(up_in_world[c])) {
      return OptionFail("up_in_world", up_in_world[c], "finite (zero: guessed)");
    }
  }
  return "";
}

ViewerMesh EncodeViewerMesh(const analyze::ThermalMesh& mesh, const ModelView& view,
                            const ViewerOptions& options) {
  assert(options.Check().empty());
  assert(mesh.NumFaces() > 0);
  assert(view.span.max_c > view.span.min_c);
  ViewerMesh out;
  out.faces_in = mesh.NumFaces();

  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      lo = lo.cwiseMin(mesh.points_in_world[static_cast<size_t>(f[k])]);
      hi = hi.cwiseMax(mesh.points_in_world[static_cast<size_t>(f[k])]);
    }
  }
  const std::vector<uint32_t> indices = DecimatedIndices(mesh, view, options, (hi - lo).norm());

  // Compact: only the vertices the kept faces use, in first-use order (cache friendly).
  std::vector<int> remap(static_cast<size_t>(mesh.NumVertices()), -1);
  out.indices.reserve(indices.size());
  for (const uint32_t i : indices) {
    if (remap[i] < 0) {
      remap[i] = static_cast<int>(out.source_vertex.size());
      out.source_vertex.push_back(static_cast<int>(i));
    }
    out.indices.push_back(static_cast<uint32_t>(remap[i]));
  }
  // The box of what is embedded (after decimation: vertices only move inwards, if at all).
  lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  hi = -lo;
  for (const int v : out.source_vertex) {
    lo = lo.cwiseMin(mesh.points_in_world[static_cast<size_t>(v)]);
    hi = hi.cwiseMax(mesh.points_in_world[static_cast<size_t>(v)]);
  }
  out.box_min = lo;
  out.box_max = hi;

  const size_t n = out.source_vertex.size();
  out.positions_q.resize(n);
  for (auto& c : out.colours_srgb8) c.assign(n * 3, 0);
  out.unobserved.assign(n, 0);
  const Eigen::Vector3d extent = hi - lo;
  const Eigen::Vector3f hatch_grey = Eigen::Vector3f::Constant(analyze::SrgbToLinear(kHatchBaseSrgb));
  for (size_t v = 0; v < n; ++v) {
    const auto source = static_cast<size_t>(out.source_vertex[v]);
    const Eigen::Vector3d& p = mesh.points_in_world[source];
    for (int c = 0; c < 3; ++c) {
      const double q = extent[c] > 0 ? (p[c] - lo[c]) / extent[c] * 65535.0 : 0.0;
      out.positions_q[v][static_cast<size_t>(c)] = static_cast<uint16_t>(std::lround(std::clamp(q, 0.0, 65535.0)));
    }
    const Eigen::Vector3f colour = mesh.HasColour() ? mesh.colour_linear[source]
                                                    : Eigen::Vector3f::Constant(kNoColourGreyLinear);
    PutSrgb8(out.colours_srgb8[1], v, colour);
    const double t_c = mesh.HasTemperature() ? mesh.temperature_c[source] : std::numeric_limits<double>::quiet_NaN();
    if (std::isnan(t_c)) {
      out.unobserved[v] = 255;
      PutSrgb8(out.colours_srgb8[0], v, hatch_grey);
      PutSrgb8(out.colours_srgb8[2], v, hatch_grey);
      PutSrgb8(out.colours_srgb8[3], v, hatch_grey);
      continue;
    }
    const double t01 = view.span.Normalize(t_c);
    const Eigen::Vector3f thermal = analyze::PaletteColour(view.palette, view.inverted, t01);
    PutSrgb8(out.colours_srgb8[0], v, thermal);
    PutSrgb8(out.colours_srgb8[2], v, analyze::IhColour(t01, Luminance(colour)));
    const bool outside = t_c < view.band_low_c || t_c > view.band_high_c;
    PutSrgb8(out.colours_srgb8[3], v, outside ? thermal : colour);
  }
  return out;
}

std::string ViewerHtml(const analyze::ThermalMesh& mesh, const ModelView& view,
                       const ViewerOptions& options, ViewerStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  const ViewerMesh encoded = EncodeViewerMesh(mesh, view, options);
  const size_t n = encoded.positions_q.size();
  const size_t faces = encoded.indices.size() / 3;
  const bool index32 = n > 65535;

  // Binary layout; each block starts on a 4-byte boundary so the viewer's typed arrays
  // could view it in place.
  std::vector<uint8_t> bytes;
  const auto align4 = [&bytes] { bytes.resize((bytes.size() + 3) / 4 * 4, 0); };
  const auto put = [&bytes](const void* data, size_t size) {
    const auto* p = static_cast<const uint8_t*>(data);
    bytes.insert(bytes.end(), p, p + size);
  };
  const size_t positions_offset = 0;
  for (const auto& q : encoded.positions_q) {
    for (const uint16_t c : q) put(&c, 2);  // little endian on every platform we build for
  }
  align4();
  const size_t indices_offset = bytes.size();
  for (const uint32_t i : encoded.indices) {
    if (index32) {
      put(&i, 4);
    } else {
      const auto i16 = static_cast<uint16_t>(i);
      put(&i16, 2);
    }
  }
  align4();
  const size_t colours_offset = bytes.size();
  for (const auto& c : encoded.colours_srgb8) put(c.data(), c.size());
  const size_t unobserved_offset = bytes.size();
  put(encoded.unobserved.data(), encoded.unobserved.size());

  const std::vector<uint8_t> compressed = Deflate(bytes);

  // Initial view (see the header).
  const Eigen::Vector3d centre = (encoded.box_min + encoded.box_max) / 2;
  Eigen::Vector3d up = options.up_in_world;
  Eigen::Vector3d eye_direction;
  if (up.norm() == 0) {
    const bool origin_inside = (encoded.box_min.array() <= 0).all() && (encoded.box_max.array() >= 0).all();
    const bool camera_frame = !origin_inside && centre.z() > centre.head<2>().norm();
    up = camera_frame ? Eigen::Vector3d(0, -1, 0) : Eigen::Vector3d::UnitZ();
  }
  up.normalize();
  if (std::abs(up.dot(Eigen::Vector3d::UnitY())) > 0.9 && up.y() < 0) {
    eye_direction = -Eigen::Vector3d::UnitZ();  // camera frame: from where the first camera stood
  } else {
    // Like the analyzer's first overview: azimuth 45° from the first horizontal axis,
    // elevation 35°, around `up`.
    Eigen::Vector3d x_axis = Eigen::Vector3d::UnitX() - up * up.x();
    if (x_axis.norm() < 1e-6) x_axis = Eigen::Vector3d::UnitY() - up * up.y();
    x_axis.normalize();
    const Eigen::Vector3d y_axis = up.cross(x_axis);
    const double azimuth = 45 * std::numbers::pi / 180, elevation = 35 * std::numbers::pi / 180;
    eye_direction = std::cos(elevation) * (std::cos(azimuth) * x_axis + std::sin(azimuth) * y_axis) +
                    std::sin(elevation) * up;
  }

  nlohmann::json meta;
  meta["vertices"] = n;
  meta["faces"] = faces;
  meta["index32"] = index32;
  meta["compression"] = "deflate";
  meta["bytes"] = bytes.size();
  meta["offsets"] = {{"positions", positions_offset},
                     {"indices", indices_offset},
                     {"colours", colours_offset},
                     {"unobserved", unobserved_offset}};
  meta["box_min"] = {encoded.box_min.x(), encoded.box_min.y(), encoded.box_min.z()};
  meta["box_max"] = {encoded.box_max.x(), encoded.box_max.y(), encoded.box_max.z()};
  meta["up"] = {up.x(), up.y(), up.z()};
  meta["eye_direction"] = {eye_direction.x(), eye_direction.y(), eye_direction.z()};
  const analyze::ViewStyle style;  // the images' shading and hatch
  meta["ambient"] = style.ambient;
  meta["diffuse"] = style.diffuse;
  meta["hatch_period_px"] = style.hatch_period_px;
  meta["modes"] = mesh.HasTemperature() ? nlohmann::json{"thermal", "colour", "ih", "highlight"}
                                        : nlohmann::json{"colour"};
  meta["initial_mode"] = mesh.HasTemperature() ? "thermal" : "colour";
  nlohmann::json markers = nlohmann::json::array();
  for (const Marker& m : view.markers) {
    markers.push_back({{"label", m.label},
                       {"anchor", m.anchor},
                       {"hot", m.hot},
                       {"position", {m.position_in_world.x(), m.position_in_world.y(), m.position_in_world.z()}},
                       {"normal", {m.normal_in_world.x(), m.normal_in_world.y(), m.normal_in_world.z()}}});
  }
  meta["markers"] = markers;

  std::string html;
  html += "<style>\n"
          ".hw-viewer{position:relative;margin:1em 0;border:1px solid #bbb;background:#303030}\n"
          ".hw-viewer canvas{display:block;width:100%;height:" + std::to_string(options.height_px) + "px;touch-action:none}\n"
          ".hw-viewer-modes{position:absolute;top:8px;left:8px;display:flex;gap:4px}\n"
          ".hw-viewer-modes button{font:13px sans-serif;padding:4px 10px;border:1px solid #888;"
          "border-radius:3px;background:rgba(255,255,255,.85);color:#222;cursor:pointer}\n"
          ".hw-viewer-modes button.hw-active{background:#1f4e8c;color:#fff;border-color:#1f4e8c}\n"
          ".hw-viewer-modes button:disabled{opacity:.4;cursor:default}\n"
          ".hw-viewer-hint{position:absolute;bottom:6px;right:8px;font:12px sans-serif;color:#ddd}\n"
          ".hw-viewer-message{padding:1em;font:14px sans-serif;color:#eee}\n"
          ".hw-viewer.hw-full{position:fixed;inset:0;z-index:1000;margin:0;border:0}\n"
          ".hw-viewer.hw-full canvas{height:100vh}\n"
          "@media print{.hw-viewer{display:none}}\n"
          "</style>\n";
  html += "<div class=\"hw-viewer\">\n<canvas aria-label=\"3D view of the thermal model\"></canvas>\n";
  html += "<div class=\"hw-viewer-modes\" role=\"group\" aria-label=\"View mode\">";
  const std::array<std::pair<const char*, const char*>, 4> modes = {
      {{"thermal", "Thermal"}, {"colour", "Colour"}, {"ih", "IH mapping"}, {"highlight", "Highlighting"}}};
  for (const auto& [name, title] : modes) {
    const bool enabled = mesh.HasTemperature() || std::string_view(name) == "colour";
    html += std::string("<button type=\"button\" data-mode=\"") + name + "\" aria-pressed=\"false\"" +
            (enabled ? "" : " disabled") + ">" + title + "</button>";
  }
  html += "<button type=\"button\" data-action=\"full\" aria-pressed=\"false\" title=\"Fill the window (Esc to leave)\">Full window</button>";
  html += "</div>\n<div class=\"hw-viewer-hint\">Drag to rotate, right-drag to pan, wheel to zoom; click a marker to go to its spot</div>\n";
  html += "<div class=\"hw-viewer-message\" hidden></div>\n";
  html += "<script type=\"application/json\" class=\"hw-viewer-meta\">" + ScriptSafeJson(meta) + "</script>\n";
  html += "<script type=\"application/octet-stream\" class=\"hw-viewer-data\">" + core::Base64(std::string_view(reinterpret_cast<const char*>(compressed.data()), compressed.size())) +
          "</script>\n";
  html += "<script>" + ScriptSafeBundle() + "</script>\n</div>\n";

  if (stats != nullptr) {
    stats->faces_in = encoded.faces_in;
    stats->faces_out = static_cast<int>(faces);
    stats->vertices_out = static_cast<int>(n);
    stats->embedded_bytes = static_cast<int64_t>(html.size());
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return html;
}

std::string ViewerContentSecurityPolicy() {
  return "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'";
}

}  // namespace hw::report
