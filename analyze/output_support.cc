#include "analyze/output_support.h"

#include <cmath>
#include <cstdio>

#include <Eigen/Geometry>

#include "core/json.h"

namespace hw::analyze {

std::string FixedText(double value, int digits) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", digits, value);
  return buffer;
}

std::string Vector3Json(const Eigen::Vector3d& v) {
  return "[" + core::JsonNumber(v.x()) + ", " + core::JsonNumber(v.y()) + ", " + core::JsonNumber(v.z()) + "]";
}

std::string SpanJson(const Span& span) {
  return "[" + core::JsonNumber(span.min_c) + ", " + core::JsonNumber(span.max_c) + "]";
}

std::string ReflectionOptionsJson(const ReflectionOptions& options) {
  return core::JsonObject()
      .Bool("check", options.check)
      .Number("operator_radius_m", options.operator_radius_m)
      .Number("operator_max_c", options.operator_max_c)
      .Number("min_fraction", options.min_fraction)
      .Int("max_faces", options.max_faces)
      .str();
}

std::string StringsJson(const std::vector<std::string>& values) {
  std::string s;
  for (size_t k = 0; k < values.size(); ++k) s += (k ? ", " : "") + core::JsonString(values[k]);
  return "[" + s + "]";
}

std::string CameraJson(const Camera& c) {
  const Eigen::Quaterniond q(c.world_from_camera.linear());
  core::JsonObject o;
  o.String("projection", c.orthographic ? "orthographic" : "perspective").Int("width", c.width).Int("height", c.height);
  if (c.orthographic) {
    o.Number("ortho_height_m", c.ortho_height_m);
  } else {
    o.Number("fov_y_deg", c.fov_y_deg);
  }
  o.Add("position_m", Vector3Json(c.world_from_camera.translation()))
      .Add("q_xyzw", "[" + core::JsonNumber(q.x()) + ", " + core::JsonNumber(q.y()) + ", " + core::JsonNumber(q.z()) +
                         ", " + core::JsonNumber(q.w()) + "]");
  return o.str();
}

std::string SpotJson(const Spot& s, const std::vector<std::string>& image_files) {
  return core::JsonObject()
      .String("id", s.id)
      .String("kind", s.hot ? "hot" : "cold")
      .Number("peak_c", s.peak_c)
      .Number("mean_c", s.mean_c)
      .String("reference", s.reference)
      .Number("reference_c", s.reference_c)
      .Number("delta_k", s.delta_k)
      .Number("delta_sigma_k", s.delta_sigma_k)
      .Number("delta_blur_bound_k", s.delta_blur_bound_k)
      .Number("level_c", s.level_c)
      .Number("area_m2", s.area_m2)
      .Number("area_sigma_m2", s.area_sigma_m2)
      .Number("length_m", s.length_m)
      .Number("length_sigma_m", s.length_sigma_m)
      .Number("width_m", s.width_m)
      .Number("width_sigma_m", s.width_sigma_m)
      .String("unrolling", s.unrolling)
      .Add("centroid_m", Vector3Json(s.centroid_in_world))
      .Add("peak_m", Vector3Json(s.peak_in_world))
      .Add("normal", Vector3Json(s.normal_in_world))
      .Number("radius_m", s.radius_m)
      .Number("mean_confidence", s.mean_confidence)
      .Number("mean_views", s.mean_views)
      .Number("mean_view_spread_c", s.mean_view_spread_c)
      .Number("boundary_sigma_c", s.boundary_std_c)
      .Number("footprint_m", s.footprint_m)
      .Number("blur_sigma_m", s.blur_sigma_m)
      .Number("width_px", s.width_px)
      .Bool("resolved", s.resolved)
      .Number("incidence_deg", s.incidence_deg)
      .Number("reflection_fraction", s.reflection_fraction)
      .Number("reflection_unseen_fraction", s.reflection_unseen_fraction)
      .String("reflection_source", s.reflection_source)
      .Add("reflection_source_m", Vector3Json(s.reflection_source_in_world))
      .Number("reflection_source_c", s.reflection_source_c)
      .Bool("possible_reflection", s.possible_reflection)
      .String("severity", s.severity)
      .String("action", s.action)
      .Int("faces", static_cast<int64_t>(s.faces.size()))
      .Add("images", StringsJson(image_files))
      .str();
}

Span RoundOut(double lo, double hi) {
  if (!(hi - lo >= 0.1)) {
    const double mid = 0.5 * (lo + hi);
    lo = mid - 0.05;
    hi = mid + 0.05;
  }
  const double step = NiceStep(hi - lo, 6);
  return Span{std::floor(lo / step) * step, std::ceil(hi / step) * step};
}

ViewSelectOptions SelectOptions(const AnalyzeConfig& config) {
  ViewSelectOptions select;
  select.width = config.width;
  select.height = config.height;
  select.up_in_world = config.up_in_world.normalized();
  if (config.overviews > 0) select.overview_count = config.overviews;
  return select;
}

RenderOptions ImageRenderOptions(const AnalyzeConfig& config, int num_threads) {
  RenderOptions options;
  options.samples_per_pixel = config.samples_per_pixel;
  options.num_threads = num_threads;
  options.cull_back_faces = true;
  return options;
}

std::vector<NamedView> ConfiguredViews(const ThermalMesh& mesh, const AnalyzeConfig& config) {
  std::vector<NamedView> views;
  if (config.overviews > 0) views = OverviewViews(mesh, SelectOptions(config));
  for (const UserView& u : config.views) {
    Camera camera;
    camera.width = config.width;
    camera.height = config.height;
    camera.fov_y_deg = u.fov_y_deg;
    if (u.ortho_height_m > 0) {
      camera.orthographic = true;
      camera.ortho_height_m = u.ortho_height_m;
    }
    views.push_back({u.name, LookAt(u.eye_in_world, u.target_in_world, u.up_in_world, camera)});
  }
  return views;
}

}  // namespace hw::analyze
