#include "analyze/analyze_config.h"

#include <cmath>

#include <Eigen/Geometry>

#include "analyze/palette.h"
#include "core/atomic_file.h"
#include "core/option_check.h"
#include "core/yaml_reader.h"

namespace hw::analyze {
namespace {

using core::YamlReader;
using Fields = YamlReader::Fields;

bool ReadBool(const YamlReader& reader, const YAML::Node& node, const std::string& key) {
  const std::string s = reader.String(node, key);
  if (s == "true") return true;
  if (s == "false") return false;
  reader.Fail(key, "must be true or false, got '" + core::Printable(s) + "'", node);
}

void ParseSpots(const YamlReader& reader, const YAML::Node& node, SpotOptions* o) {
  const Fields f = reader.Mapping(node, "spots",
                                  {"detect", "reference", "ambient_c", "min_delta_k", "hot_above_c",
                                   "cold_below_c", "kinds", "boundary_fraction", "min_area_m2",
                                   "max_area_m2", "background_radius_m", "min_ring_coverage", "min_ring_area_ratio",
                                   "min_contrast_sigmas", "min_views", "min_views_ratio", "max_view_spread_ratio",
                                   "min_emissivity", "optics_psf_px", "min_resolved_px", "max_candidates"});
  if (f.Has("detect")) {
    const std::string s = reader.String(f.Required("detect"), f.Path("detect"));
    if (s == "delta") {
      o->detect = SpotOptions::Detect::kDelta;
    } else if (s == "absolute") {
      o->detect = SpotOptions::Detect::kAbsolute;
    } else {
      reader.Fail(f.Path("detect"), "must be delta or absolute, got '" + core::Printable(s) + "'",
                  f.Required("detect"));
    }
  }
  if (f.Has("reference")) {
    const std::string s = reader.String(f.Required("reference"), f.Path("reference"));
    if (s == "surrounding") {
      o->reference = SpotOptions::Reference::kSurrounding;
    } else if (s == "ambient") {
      o->reference = SpotOptions::Reference::kAmbient;
    } else {
      reader.Fail(f.Path("reference"), "must be surrounding or ambient, got '" + core::Printable(s) + "'",
                  f.Required("reference"));
    }
  }
  auto number = [&](const char* name, double* out) {
    if (f.Has(name)) *out = reader.Number(f.Required(name), f.Path(name));
  };
  number("ambient_c", &o->ambient_c);
  number("min_delta_k", &o->min_delta_k);
  number("hot_above_c", &o->hot_above_c);
  number("cold_below_c", &o->cold_below_c);
  number("boundary_fraction", &o->boundary_fraction);
  number("min_area_m2", &o->min_area_m2);
  number("max_area_m2", &o->max_area_m2);
  number("background_radius_m", &o->background_radius_m);
  number("min_ring_coverage", &o->min_ring_coverage);
  number("min_ring_area_ratio", &o->min_ring_area_ratio);
  number("min_contrast_sigmas", &o->min_contrast_sigmas);
  number("min_views", &o->min_views);
  number("min_views_ratio", &o->min_views_ratio);
  number("max_view_spread_ratio", &o->max_view_spread_ratio);
  number("min_emissivity", &o->min_emissivity);
  number("optics_psf_px", &o->optics_psf_px);
  number("min_resolved_px", &o->min_resolved_px);
  if (f.Has("max_candidates")) o->max_candidates = reader.Integer(f.Required("max_candidates"), f.Path("max_candidates"));
  if (f.Has("kinds")) {
    const YAML::Node& kinds = f.Required("kinds");
    if (!kinds.IsSequence() || kinds.size() == 0) {
      reader.Fail(f.Path("kinds"), "must be a non-empty list of hot and cold, got " + core::Describe(kinds), kinds);
    }
    o->find_hot = o->find_cold = false;
    for (const YAML::Node& k : kinds) {
      const std::string s = reader.String(k, f.Path("kinds"));
      if (s == "hot") {
        o->find_hot = true;
      } else if (s == "cold") {
        o->find_cold = true;
      } else {
        reader.Fail(f.Path("kinds"), "must hold hot or cold, got '" + core::Printable(s) + "'", k);
      }
    }
  }
}

void ParseSeverity(const YamlReader& reader, const YAML::Node& list, std::vector<SeverityBand>* table) {
  if (!list.IsSequence() || list.size() == 0) {
    reader.Fail("severity", "must be a non-empty list of bands, got " + core::Describe(list), list);
  }
  size_t i = 0;
  for (const YAML::Node& node : list) {
    const std::string key = "severity[" + std::to_string(i++) + "]";
    const Fields f = reader.Mapping(node, key, {"name", "min_delta_k", "action"});
    SeverityBand band;
    band.name = reader.String(f.Required("name"), f.Path("name"));
    band.min_delta_k = reader.Number(f.Required("min_delta_k"), f.Path("min_delta_k"));
    if (f.Has("action")) band.action = reader.String(f.Required("action"), f.Path("action"));
    table->push_back(band);
  }
}

void ParseReflections(const YamlReader& reader, const YAML::Node& node, ReflectionOptions* o) {
  const Fields f = reader.Mapping(node, "reflections",
                                  {"check", "operator_radius_m", "operator_max_c", "min_fraction", "max_faces"});
  if (f.Has("check")) o->check = ReadBool(reader, f.Required("check"), f.Path("check"));
  if (f.Has("operator_radius_m")) o->operator_radius_m = reader.Number(f.Required("operator_radius_m"), f.Path("operator_radius_m"));
  if (f.Has("operator_max_c")) o->operator_max_c = reader.Number(f.Required("operator_max_c"), f.Path("operator_max_c"));
  if (f.Has("min_fraction")) o->min_fraction = reader.Number(f.Required("min_fraction"), f.Path("min_fraction"));
  if (f.Has("max_faces")) o->max_faces = reader.Integer(f.Required("max_faces"), f.Path("max_faces"));
}

Eigen::Vector3d Vector(const YamlReader& reader, const Fields& f, const char* name) {
  const std::vector<double> v = reader.NumberList(f.Required(name), f.Path(name), 3);
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

void ParseImages(const YamlReader& reader, const YAML::Node& node, AnalyzeConfig* c) {
  const Fields f = reader.Mapping(node, "images",
                                  {"width", "height", "samples_per_pixel", "palette", "span_c",
                                   "highlight_band_c", "overviews", "closeups", "max_closeups", "float_format", "legends", "up",
                                   "views"});
  if (f.Has("width")) c->width = reader.Integer(f.Required("width"), f.Path("width"));
  if (f.Has("height")) c->height = reader.Integer(f.Required("height"), f.Path("height"));
  if (f.Has("samples_per_pixel")) {
    c->samples_per_pixel = reader.Integer(f.Required("samples_per_pixel"), f.Path("samples_per_pixel"));
  }
  if (f.Has("palette")) c->palette = reader.String(f.Required("palette"), f.Path("palette"));
  if (f.Has("span_c")) {
    const std::vector<double> s = reader.NumberList(f.Required("span_c"), f.Path("span_c"), 2);
    c->span_min_c = s[0];
    c->span_max_c = s[1];
  }
  if (f.Has("highlight_band_c")) {
    const std::vector<double> s = reader.NumberList(f.Required("highlight_band_c"), f.Path("highlight_band_c"), 2);
    c->highlight_low_c = s[0];
    c->highlight_high_c = s[1];
  }
  if (f.Has("overviews")) c->overviews = reader.Integer(f.Required("overviews"), f.Path("overviews"));
  if (f.Has("closeups")) c->closeups = ReadBool(reader, f.Required("closeups"), f.Path("closeups"));
  if (f.Has("max_closeups")) c->max_closeups = reader.Integer(f.Required("max_closeups"), f.Path("max_closeups"));
  if (f.Has("up")) c->up_in_world = Vector(reader, f, "up");
  if (f.Has("legends")) c->legends = ReadBool(reader, f.Required("legends"), f.Path("legends"));
  if (f.Has("float_format")) c->float_format = reader.String(f.Required("float_format"), f.Path("float_format"));
  if (f.Has("views")) {
    const YAML::Node& list = f.Required("views");
    if (!list.IsSequence()) reader.Fail(f.Path("views"), "must be a list of views, got " + core::Describe(list), list);
    size_t i = 0;
    for (const YAML::Node& v : list) {
      const std::string key = "images.views[" + std::to_string(i++) + "]";
      const Fields vf = reader.Mapping(v, key, {"name", "eye", "target", "up", "fov_y_deg", "ortho_height_m"});
      UserView view;
      view.name = reader.String(vf.Required("name"), vf.Path("name"));
      view.eye_in_world = Vector(reader, vf, "eye");
      view.target_in_world = Vector(reader, vf, "target");
      if (vf.Has("up")) view.up_in_world = Vector(reader, vf, "up");
      if (vf.Has("fov_y_deg")) view.fov_y_deg = reader.Number(vf.Required("fov_y_deg"), vf.Path("fov_y_deg"));
      if (vf.Has("ortho_height_m")) {
        view.ortho_height_m = reader.Number(vf.Required("ortho_height_m"), vf.Path("ortho_height_m"));
      }
      c->views.push_back(view);
    }
  }
}

}  // namespace

std::string AnalyzeConfig::Check() const {
  if (field.empty()) return "field: must not be empty";
  if (const std::string p = spots.Check(); !p.empty()) return "spots." + p;
  if (const std::string p = reflections.Check(); !p.empty()) return p;
  if (width < 16 || width > 8192) return core::OptionFail("images.width", width, "in [16, 8192]");
  if (height < 16 || height > 8192) return core::OptionFail("images.height", height, "in [16, 8192]");
  if (samples_per_pixel != 1 && samples_per_pixel != 4 && samples_per_pixel != 9 && samples_per_pixel != 16) {
    return core::OptionFail("images.samples_per_pixel", samples_per_pixel, "1, 4, 9 or 16");
  }
  if (!ParsePalette(palette)) {
    return "images.palette: must be iron, rainbow or grey (optionally -inverted), got '" + palette + "'";
  }
  if (std::isnan(span_min_c) != std::isnan(span_max_c) ||
      (!std::isnan(span_min_c) && !(std::isfinite(span_min_c) && std::isfinite(span_max_c) && span_min_c < span_max_c))) {
    return core::OptionFail("images.span_c[1]", span_max_c, "finite and > span_c[0] (an inverted span)");
  }
  if (std::isnan(highlight_low_c) != std::isnan(highlight_high_c) ||
      (!std::isnan(highlight_low_c) &&
       !(std::isfinite(highlight_low_c) && std::isfinite(highlight_high_c) && highlight_low_c < highlight_high_c))) {
    return core::OptionFail("images.highlight_band_c[1]", highlight_high_c,
                            "finite and > highlight_band_c[0] (an inverted band)");
  }
  if (overviews < 0 || overviews > 12) return core::OptionFail("images.overviews", overviews, "in [0, 12]");
  if (max_closeups < 0 || max_closeups > 200) return core::OptionFail("images.max_closeups", max_closeups, "in [0, 200]");
  if (!up_in_world.allFinite() || up_in_world.norm() < 1e-9) return "images.up: must be a finite non-zero vector";
  if (float_format != "exr" && float_format != "tiff") {
    return "images.float_format: must be exr or tiff, got '" + float_format + "'";
  }
  for (size_t i = 0; i < views.size(); ++i) {
    const UserView& v = views[i];
    const std::string key = "images.views[" + std::to_string(i) + "]";
    if (v.name.empty() || v.name.find_first_of("/\\ \t\n") != std::string::npos) {
      return key + ".name: must be a non-empty file-name part without spaces or slashes, got '" + v.name + "'";
    }
    if (!v.eye_in_world.allFinite() || !v.target_in_world.allFinite() || !v.up_in_world.allFinite()) {
      return key + ": eye, target and up must be finite";
    }
    const Eigen::Vector3d forward = v.target_in_world - v.eye_in_world;
    if (forward.norm() < 1e-9) return key + ".target: must differ from eye";
    if (forward.normalized().cross(v.up_in_world).norm() < 1e-6) return key + ".up: must not be parallel to the view direction";
    if (!(v.fov_y_deg > 0 && v.fov_y_deg < 170)) return core::OptionFail(key + ".fov_y_deg", v.fov_y_deg, "in (0, 170)");
    if (!(v.ortho_height_m >= 0) || !std::isfinite(v.ortho_height_m)) {
      return core::OptionFail(key + ".ortho_height_m", v.ortho_height_m, ">= 0");
    }
  }
  return "";
}

AnalyzeConfig ParseAnalyzeConfig(const std::string& yaml_text, const std::filesystem::path& path_for_errors) {
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  reader.CheckVersion(root, 1);
  const Fields top = reader.Mapping(root, "", {"version", "field", "spots", "severity", "reflections", "images"});
  AnalyzeConfig c;
  if (top.Has("field")) c.field = reader.String(top.Required("field"), "field");
  if (top.Has("spots")) ParseSpots(reader, top.Required("spots"), &c.spots);
  if (top.Has("severity")) ParseSeverity(reader, top.Required("severity"), &c.spots.severity);
  if (top.Has("reflections")) ParseReflections(reader, top.Required("reflections"), &c.reflections);
  if (top.Has("images")) ParseImages(reader, top.Required("images"), &c);
  if (const std::string problem = c.Check(); !problem.empty()) {
    // spots.severity[i] is the file's severity[i].
    std::string p = problem;
    if (p.rfind("spots.severity", 0) == 0) p = p.substr(6);
    reader.FailCheck(root, "", p);
  }
  return c;
}

AnalyzeConfig ReadAnalyzeConfig(const std::filesystem::path& path) {
  return ParseAnalyzeConfig(core::ReadFile(path, core::kMaxConfigFileBytes), path);
}

}  // namespace hw::analyze
