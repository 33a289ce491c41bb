#pragma once

// What analyze and compare share: one spelling of a vector, a span, a camera and a spot in
// JSON, the colour-bar span rounding, and the views a config asks for.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/palette.h"
#include "analyze/render.h"
#include "analyze/analyze_config.h"
#include "analyze/spot.h"
#include "analyze/thermal_mesh.h"
#include "analyze/view_select.h"

namespace hw::analyze {

// `value` with `digits` decimals ("%.*f").
std::string FixedText(double value, int digits);
// [x, y, z] / [min, max] / ["a", "b"] as JSON.
std::string Vector3Json(const Eigen::Vector3d& v);
std::string SpanJson(const Span& span);
std::string StringsJson(const std::vector<std::string>& values);
// Projection, size, field of view or height, position and orientation (q_xyzw).
std::string CameraJson(const Camera& camera);
// The reflection check's options (check, operator_radius_m, operator_max_c, min_fraction,
// max_faces).
std::string ReflectionOptionsJson(const ReflectionOptions& options);
// Every figure of a spot; `image_files` its close-ups (may be empty).
std::string SpotJson(const Spot& spot, const std::vector<std::string>& image_files);
// A colour-bar span rounded outwards to its ticks' step (widened to 0.1 when narrower), so
// the bar's ends are round numbers.
Span RoundOut(double lo_c, double hi_c);

// View selection as the config asks: image size, world up.
ViewSelectOptions SelectOptions(const AnalyzeConfig& config);
// Rendering for the images: the config's samples per pixel, back faces culled (overviews of
// a scanned room look in through the backs of its walls).
RenderOptions ImageRenderOptions(const AnalyzeConfig& config, int num_threads);
// The config's `overviews` automatic overviews of `mesh` (and "top"), then its own views.
std::vector<NamedView> ConfiguredViews(const ThermalMesh& mesh, const AnalyzeConfig& config);

}  // namespace hw::analyze
