#include "report/report_inputs.h"

#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"

namespace hw::report {
namespace {

using Json = nlohmann::json;
namespace fs = std::filesystem;

constexpr uint64_t kMaxJsonBytes = uint64_t{256} << 20;

// Strict field access on one JSON file: every failure names the file and the field path.
class JsonReader {
 public:
  explicit JsonReader(fs::path path) : path_(std::move(path)) {}

  Json Load() const {
    const std::string text = core::ReadFile(path_, kMaxJsonBytes);
    try {
      Json root = Json::parse(text);
      if (!root.is_object()) throw core::InputError(path_, "expected a JSON object at the top level");
      return root;
    } catch (const Json::parse_error& e) {
      // e.what() is "[json.exception.parse_error.101] parse error at line 3, column 5: ...".
      std::string what = e.what();
      const size_t at = what.find("] ");
      throw core::InputError(path_, "not valid JSON: " + (at == std::string::npos ? what : what.substr(at + 2)));
    }
  }

  [[noreturn]] void Fail(const std::string& where, const std::string& problem) const {
    throw core::InputError(path_, where + ": " + problem);
  }

  const Json& At(const Json& object, const std::string& key, const std::string& where) const {
    if (!object.is_object()) Fail(where, "must be an object");
    const auto it = object.find(key);
    if (it == object.end()) Fail(Join(where, key), "missing");
    return *it;
  }
  bool Has(const Json& object, const std::string& key) const { return object.is_object() && object.contains(key); }

  // A number; null (how heatwave writes NaN) reads as NaN.
  double Number(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = At(object, key, where);
    if (v.is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!v.is_number()) Fail(Join(where, key), "must be a number, got " + std::string(v.type_name()));
    return v.get<double>();
  }
  double FiniteNumber(const Json& object, const std::string& key, const std::string& where) const {
    const double v = Number(object, key, where);
    if (!std::isfinite(v)) Fail(Join(where, key), "must be a finite number, got null");
    return v;
  }
  int Integer(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = At(object, key, where);
    if (!v.is_number_integer()) Fail(Join(where, key), "must be an integer, got " + std::string(v.type_name()));
    const int64_t i = v.get<int64_t>();
    if (i < std::numeric_limits<int>::min() || i > std::numeric_limits<int>::max()) {
      Fail(Join(where, key), "integer out of range");
    }
    return static_cast<int>(i);
  }
  std::string String(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = At(object, key, where);
    if (!v.is_string()) Fail(Join(where, key), "must be a string, got " + std::string(v.type_name()));
    return v.get<std::string>();
  }
  bool Bool(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = At(object, key, where);
    if (!v.is_boolean()) Fail(Join(where, key), "must be true or false, got " + std::string(v.type_name()));
    return v.get<bool>();
  }
  const Json& Array(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = At(object, key, where);
    if (!v.is_array()) Fail(Join(where, key), "must be a list, got " + std::string(v.type_name()));
    return v;
  }
  Eigen::Vector3d Vector3(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = Array(object, key, where);
    if (v.size() != 3) Fail(Join(where, key), "must be a list of 3 numbers");
    Eigen::Vector3d out;
    for (int i = 0; i < 3; ++i) {
      if (!v[static_cast<size_t>(i)].is_number()) Fail(Join(where, key), "must be a list of 3 numbers");
      out[i] = v[static_cast<size_t>(i)].get<double>();
    }
    return out;
  }
  analyze::Span Span(const Json& object, const std::string& key, const std::string& where) const {
    const Json& v = Array(object, key, where);
    if (v.size() != 2 || !v[0].is_number() || !v[1].is_number() || !(v[0].get<double>() < v[1].get<double>())) {
      Fail(Join(where, key), "must be a list of 2 increasing numbers");
    }
    return {v[0].get<double>(), v[1].get<double>()};
  }
  std::vector<std::string> Strings(const Json& object, const std::string& key, const std::string& where) const {
    std::vector<std::string> out;
    for (const Json& s : Array(object, key, where)) {
      if (!s.is_string()) Fail(Join(where, key), "must be a list of strings");
      out.push_back(s.get<std::string>());
    }
    return out;
  }

  static std::string Join(const std::string& where, const std::string& key) {
    return where.empty() ? key : where + "." + key;
  }

 private:
  fs::path path_;
};

std::string Index(const std::string& key, size_t i) { return key + "[" + std::to_string(i) + "]"; }

ReportSpot ReadSpot(const JsonReader& r, const Json& s, const std::string& w) {
  ReportSpot o;
  o.id = r.String(s, "id", w);
  o.kind = r.String(s, "kind", w);
  if (o.kind != "hot" && o.kind != "cold") r.Fail(w + ".kind", "must be hot or cold, got '" + o.kind + "'");
  o.severity = r.String(s, "severity", w);
  o.action = r.String(s, "action", w);
  o.reference = r.String(s, "reference", w);
  o.unrolling = r.String(s, "unrolling", w);
  o.peak_c = r.FiniteNumber(s, "peak_c", w);
  o.mean_c = r.FiniteNumber(s, "mean_c", w);
  o.reference_c = r.FiniteNumber(s, "reference_c", w);
  o.delta_k = r.FiniteNumber(s, "delta_k", w);
  o.level_c = r.FiniteNumber(s, "level_c", w);
  o.area_m2 = r.FiniteNumber(s, "area_m2", w);
  o.area_sigma_m2 = r.Number(s, "area_sigma_m2", w);
  o.length_m = r.FiniteNumber(s, "length_m", w);
  o.length_sigma_m = r.Number(s, "length_sigma_m", w);
  o.width_m = r.FiniteNumber(s, "width_m", w);
  o.width_sigma_m = r.Number(s, "width_sigma_m", w);
  o.mean_confidence = r.Number(s, "mean_confidence", w);
  o.mean_views = r.Number(s, "mean_views", w);
  o.spread_c = r.Has(s, "mean_view_spread_c") ? r.Number(s, "mean_view_spread_c", w)
                                              : std::numeric_limits<double>::quiet_NaN();
  o.footprint_m = r.Has(s, "footprint_m") ? r.Number(s, "footprint_m", w) : std::numeric_limits<double>::quiet_NaN();
  o.width_px = r.Has(s, "width_px") ? r.Number(s, "width_px", w) : std::numeric_limits<double>::quiet_NaN();
  o.resolved = r.Has(s, "resolved") ? r.Bool(s, "resolved", w) : true;
  const auto optional_number = [&](const char* key) {
    return r.Has(s, key) ? r.Number(s, key, w) : std::numeric_limits<double>::quiet_NaN();
  };
  o.delta_sigma_k = optional_number("delta_sigma_k");
  o.delta_blur_bound_k = optional_number("delta_blur_bound_k");
  o.incidence_deg = optional_number("incidence_deg");
  o.reflection_fraction = optional_number("reflection_fraction");
  o.reflection_source_c = optional_number("reflection_source_c");
  o.reflection_source = r.Has(s, "reflection_source") ? r.String(s, "reflection_source", w) : "";
  o.possible_reflection = r.Has(s, "possible_reflection") ? r.Bool(s, "possible_reflection", w) : false;
  o.centroid_m = r.Vector3(s, "centroid_m", w);
  o.peak_m = r.Vector3(s, "peak_m", w);
  o.normal = r.Vector3(s, "normal", w);
  o.images = r.Strings(s, "images", w);
  return o;
}

}  // namespace

AnalysisRecord ReadAnalysisRecord(const fs::path& path) {
  const JsonReader r(path);
  const Json root = r.Load();
  AnalysisRecord a;
  a.folder = path.parent_path();
  if (r.Integer(root, "version", "") != 1) r.Fail("version", "this heatwave reads version 1");
  a.model = r.String(root, "model", "");
  a.field = r.String(root, "field", "");
  a.palette = r.String(root, "palette", "");
  // Absent in files of analyzers that always drew legends.
  a.legends = r.Has(root, "legends") ? r.Bool(root, "legends", "") : true;
  const Json& mesh = r.At(root, "mesh", "");
  a.vertices = r.Integer(mesh, "vertices", "mesh");
  a.faces = r.Integer(mesh, "faces", "mesh");
  a.area_m2 = r.FiniteNumber(mesh, "area_m2", "mesh");
  a.observed_area_m2 = r.FiniteNumber(mesh, "observed_area_m2", "mesh");
  if (!r.Bool(mesh, "has_temperature", "mesh")) {
    r.Fail("mesh.has_temperature", "false: the model has no temperature, there is nothing to report");
  }
  a.has_colour = r.Bool(mesh, "has_colour", "mesh");
  a.unobserved = r.Integer(mesh, "temperatures_unobserved", "mesh");
  a.min_c = r.Number(mesh, "temperature_min_c", "mesh");
  a.median_c = r.Number(mesh, "temperature_median_c", "mesh");
  a.max_c = r.Number(mesh, "temperature_max_c", "mesh");
  const Json& d = r.At(root, "detection", "");
  a.detect = r.String(d, "detect", "detection");
  a.reference = r.String(d, "reference", "detection");
  a.ambient_c = r.Number(d, "ambient_c", "detection");
  a.min_delta_k = r.Number(d, "min_delta_k", "detection");
  a.hot_above_c = r.Number(d, "hot_above_c", "detection");
  a.cold_below_c = r.Number(d, "cold_below_c", "detection");
  a.find_hot = r.Bool(d, "hot", "detection");
  a.find_cold = r.Bool(d, "cold", "detection");
  a.boundary_fraction = r.Number(d, "boundary_fraction", "detection");
  a.min_area_m2 = r.Number(d, "min_area_m2", "detection");
  a.max_area_m2 = r.Number(d, "max_area_m2", "detection");
  a.background_radius_m = r.Number(d, "background_radius_m", "detection");
  const Json& table = r.Array(root, "severity_table", "");
  for (size_t i = 0; i < table.size(); ++i) {
    const std::string w = Index("severity_table", i);
    a.severity.push_back({r.String(table[i], "name", w), r.String(table[i], "action", w),
                          r.FiniteNumber(table[i], "min_delta_k", w)});
  }
  a.candidates = r.Integer(root, "candidates", "");
  const Json& spots = r.Array(root, "spots", "");
  for (size_t i = 0; i < spots.size(); ++i) a.spots.push_back(ReadSpot(r, spots[i], Index("spots", i)));
  const Json& rejected = r.Array(root, "rejected", "");
  for (size_t i = 0; i < rejected.size(); ++i) {
    const std::string w = Index("rejected", i);
    char peak[64];
    std::snprintf(peak, sizeof peak, "%s, %.1f °C", r.String(rejected[i], "kind", w).c_str(),
                  r.Number(rejected[i], "peak_c", w));
    a.rejected.emplace_back(peak, r.String(rejected[i], "reason", w));
  }
  a.span = r.Span(root, "span_c", "");
  a.band = r.Span(root, "highlight_band_c", "");
  const Json& images = r.Array(root, "images", "");
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string w = Index("images", i);
    ReportImageRecord im;
    im.file = r.String(images[i], "file", w);
    im.view = r.String(images[i], "view", w);
    im.mode = r.String(images[i], "mode", w);
    im.spot = r.String(images[i], "spot", w);
    im.span = r.Span(images[i], "span_c", w);
    if (im.file.empty() || im.file.find("..") != std::string::npos || fs::path(im.file).is_absolute()) {
      r.Fail(w + ".file", "must be a path inside the analysis folder, got '" + im.file + "'");
    }
    a.images.push_back(im);
  }
  a.warnings = r.Strings(root, "warnings", "");
  return a;
}

ReconstructionRecord ReadReconstructionRecord(const fs::path& path) {
  const JsonReader r(path);
  const Json root = r.Load();
  ReconstructionRecord o;
  const Json& input = r.At(root, "input", "");
  o.scan = r.String(input, "scan", "input");
  o.rig = r.String(input, "rig", "input");
  o.depth_frames = r.Integer(input, "depth_frames", "input");
  const Json& s = r.At(root, "summary", "");
  o.fused = r.Integer(s, "fused", "summary");
  o.tracked = r.Integer(s, "tracked", "summary");
  o.recovered = r.Integer(s, "recovered", "summary");
  o.lost = r.Integer(s, "lost", "summary");
  o.no_depth = r.Integer(s, "no_depth", "summary");
  o.missing = r.Integer(s, "missing", "summary");
  const Json& mesh = r.At(root, "mesh", "");
  o.vertices = r.Integer(mesh, "vertices", "mesh");
  o.faces = r.Integer(mesh, "faces", "mesh");
  o.area_m2 = r.Number(mesh, "area_m2", "mesh");
  const Json& t = r.At(root, "timings", "");
  o.total_s = r.Number(t, "total_s", "timings");
  o.frames_per_s = r.Number(t, "frames_per_s", "timings");
  o.voxel_size_m = r.Number(r.At(r.At(root, "settings", ""), "tsdf", "settings"), "voxel_size_m", "settings.tsdf");
  if (r.Has(root, "groundtruth_evaluation")) {
    const Json& g = r.At(root, "groundtruth_evaluation", "");
    if (r.Has(g, "ate_m")) o.ate_rmse_m = r.Number(r.At(g, "ate_m", "groundtruth_evaluation"), "rmse", "groundtruth_evaluation.ate_m");
  }
  if (r.Has(root, "thermal")) {
    const Json& th = r.At(root, "thermal", "");
    o.has_thermal = true;
    const Json& ts = r.At(th, "settings", "thermal");
    o.thermal_method = r.String(ts, "method", "thermal.settings");
    o.emissivity = r.String(ts, "emissivity", "thermal.settings");
    const Json& sum = r.At(th, "summary", "thermal");
    o.thermal_frames = r.Integer(sum, "frames", "thermal.summary");
    o.thermal_fused = r.Integer(sum, "fused", "thermal.summary");
    if (r.Has(sum, "skipped")) o.thermal_skipped = r.Integer(sum, "skipped", "thermal.summary");
    if (r.Has(ts, "frame_interval_s")) o.thermal_frame_interval_s = r.Number(ts, "frame_interval_s", "thermal.settings");
    o.vertices_with_temperature = r.Integer(sum, "vertices_with_temperature", "thermal.summary");
  }
  o.warnings = r.Strings(root, "warnings", "");
  return o;
}

}  // namespace hw::report
