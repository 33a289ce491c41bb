#pragma once

// The interactive 3D view of the thermal model in the HTML report: the model decimated and
// quantised, coloured per vertex in the four view modes by the same functions that draw
// the static images, embedded in the page with the bundled three.js viewer
// (report/viewer/viewer.js, built into this library at build time).

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/thermal_mesh.h"
#include "report/document.h"

namespace hw::report {

struct ViewerOptions {
  int max_faces = 150000;  // the model is decimated (meshopt_simplify) to at most this many triangles, [1000, 2000000]
  double max_error_fraction = 0.002;  // meshopt_simplify target error, fraction of the bounding-box diagonal, (0, 0.1]
  int height_px = 560;     // the view's height in the page, [200, 2000]
  // The simplifier sees each vertex displaced along its normal by this fraction of the
  // box diagonal times its temperature's position in the span (0 cold end … 1 hot end),
  // so a spot's temperature contrast is kept like relief even on a flat wall; the
  // embedded positions are never displaced. [0, 0.1]; 0: geometry alone.
  double temperature_relief_fraction = 0.01;
  // The model's up direction, for the initial view; zero: guessed (see ViewerHtml).
  Eigen::Vector3d up_in_world = Eigen::Vector3d::Zero();
  // "" or "field: must be ..., got ...".
  std::string Check() const;
};

struct ViewerStats {
  int faces_in = 0, faces_out = 0, vertices_out = 0;
  int64_t embedded_bytes = 0;  // the whole fragment, bytes (bundle included)
  double seconds = 0;          // decimation, colouring, encoding
};

// The mesh as the viewer receives it, before base64: decimated, positions quantised to
// 16 bits per axis over the bounding box, and 8-bit sRGB colours per vertex for each mode.
struct ViewerMesh {
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero();  // metres, model frame
  Eigen::Vector3d box_max = Eigen::Vector3d::Zero();
  std::vector<std::array<uint16_t, 3>> positions_q;  // x = box_min + q / 65535 · extent
  std::vector<uint32_t> indices;                     // 3 per face, into positions_q
  // Per mode (analyze::ViewMode order: thermal, colour, ih, highlight), 3 bytes a vertex:
  // the unshaded colour, 8-bit sRGB. NaN temperature: the hatch's base grey in the
  // temperature modes (the viewer draws the hatch lines where `unobserved` is set).
  std::array<std::vector<uint8_t>, 4> colours_srgb8;
  std::vector<uint8_t> unobserved;  // per vertex: 255 where the temperature is NaN, else 0
  std::vector<int> source_vertex;   // per vertex: its index in the input mesh
  int faces_in = 0;
};

// Decimates (only when the mesh has more than options.max_faces faces; a smaller mesh is
// kept whole) and colours the mesh. Colours: thermal = PaletteColour(span(T)), colour =
// the visible colour (linear grey 0.5 without colour, as in the images), IH =
// IhColour(span(T), luminance(colour)) (the viewer multiplies by the shading, which for
// the sRGB power law equals shading the intensity as the images do), highlight = palette
// outside [band_low_c, band_high_c] else the visible colour. Without temperature, every
// temperature mode shows the unobserved grey. Asserts options.Check() == "", a mesh with
// faces, view.span.max_c > view.span.min_c.
ViewerMesh EncodeViewerMesh(const analyze::ThermalMesh& mesh, const ModelView& view,
                            const ViewerOptions& options = {});

// The HTML fragment of the 3D view of `mesh` (positions in metres, per-vertex temperature
// and colour; see analyze/thermal_mesh.h) styled by `view` (report/document.h: palette,
// span, highlight band, markers): a <div> with the canvas, the mode switch (Thermal /
// Colour / IH mapping / Highlighting), the inert <script type="application/json"> meta
// data and <script type="application/octet-stream"> mesh (EncodeViewerMesh's arrays, zlib-
// deflated and base64-encoded; the viewer inflates them with DecompressionStream), and
// the bundled viewer <script>. Markers are clickable (→ location.hash = '#' + anchor) and
// show their labels, drawn as canvas text; labels and anchors travel only inside the JSON
// meta data with '<', '>', '&' escaped, so no string can close the script or inject
// markup. The initial mode is thermal (colour without temperature), overridden by a URL
// "#mode=ih" or "?mode=ih" (thermal, colour, ih, highlight).
// Initial view: options.up_in_world when set; else a model whose box lies in front of
// the origin along +z (the box centre's z exceeds its distance from the z axis, and the
// origin is outside the box) is taken to be in its first camera's frame (y down): seen
// from −z (where that camera stood) with −y up; any other model as z-up, seen like the
// analyzer's first overview (azimuth 45°, elevation 35°). The page must carry
// ViewerContentSecurityPolicy(). Asserts what EncodeViewerMesh asserts.
std::string ViewerHtml(const analyze::ThermalMesh& mesh, const ModelView& view,
                       const ViewerOptions& options = {}, ViewerStats* stats = nullptr);

// The Content-Security-Policy the report page must carry for the fragment to run with no
// network access: default-src 'none'; img-src data:; style-src 'unsafe-inline';
// script-src 'unsafe-inline'. (three.js needs no worker, eval or wasm here; canvas
// textures need no img-src.)
std::string ViewerContentSecurityPolicy();

}  // namespace hw::report
