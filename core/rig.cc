#include "core/rig.h"

#include <yaml-cpp/yaml.h>

#include <array>
#include <cassert>
#include <cmath>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/yaml_reader.h"

// rig.yaml. The strict YAML reader and the message helpers are core/yaml_reader.h; the
// target.yaml reader is core/target.cc.

namespace hw::core {
namespace {

namespace fs = std::filesystem;

using Fields = YamlReader::Fields;

// A quaternion counts as unit when |q| is within this of 1 (rig.h); smaller errors are
// normalised away.
constexpr double kUnitQuaternionTolerance = 1e-6;

// "" when `depth_from_camera` is a valid transform, else "q_xyzw: ..." or "t_m: ...".
std::string CheckTransform(const Rigid3d& transform) {
  const double norm = transform.rotation.norm();
  if (!transform.rotation.coeffs().allFinite() ||
      !(std::abs(norm - 1) <= kUnitQuaternionTolerance)) {
    return "q_xyzw: not a unit quaternion (norm " + RoundedNumber(norm) + ")";
  }
  if (const std::string problem = CheckExtrinsicTranslation(transform.translation);
      !problem.empty()) {
    return "t_m: " + problem;
  }
  return "";
}

bool IsIdentity(const Rigid3d& transform) {
  return transform.rotation.coeffs() == Eigen::Quaterniond::Identity().coeffs() &&
         transform.translation == Eigen::Vector3d::Zero();
}

const std::set<std::string> kCameraKeys = {"width", "height", "model",      "fx",     "fy",
                                           "cx",    "cy",     "distortion", "splined"};

// The `splined: {order, nx, ny, fov_x_deg}` block of a splined camera (an extension of
// scan-format.md, camera.h SplinedConfig); ranges checked with the camera.
SplinedConfig ParseSplinedConfig(const YamlReader& reader, const YAML::Node& node,
                                 const std::string& key) {
  const Fields fields = reader.Mapping(node, key, {"order", "nx", "ny", "fov_x_deg"});
  SplinedConfig config;
  config.order = reader.Integer(fields.Required("order"), fields.Path("order"));
  config.nx = reader.Integer(fields.Required("nx"), fields.Path("nx"));
  config.ny = reader.Integer(fields.Required("ny"), fields.Path("ny"));
  config.fov_x_deg = reader.Integer(fields.Required("fov_x_deg"), fields.Path("fov_x_deg"));
  return config;
}

CameraModel ParseCamera(const YamlReader& reader, const YAML::Node& node, const std::string& key) {
  const Fields fields = reader.Mapping(node, key, kCameraKeys);
  CameraModel camera;
  camera.width = reader.Integer(fields.Required("width"), fields.Path("width"));
  camera.height = reader.Integer(fields.Required("height"), fields.Path("height"));
  const YAML::Node& model = fields.Required("model");
  const std::string model_name = reader.String(model, fields.Path("model"));
  const std::optional<CameraModelType> type = ParseCameraModelType(model_name);
  if (!type)
    reader.Fail(fields.Path("model"), "must be pinhole, opencv or splined, got " + Describe(model),
                model);
  camera.type = *type;
  if (camera.type == CameraModelType::kSplined) {
    camera.splined = ParseSplinedConfig(reader, fields.Required("splined"), fields.Path("splined"));
  } else if (fields.Has("splined")) {
    reader.Fail(fields.Path("splined"), "only a splined camera has this block, model is " +
                                            model_name, fields.NodeFor("splined"));
  }
  camera.fx = reader.Number(fields.Required("fx"), fields.Path("fx"));
  camera.fy = reader.Number(fields.Required("fy"), fields.Path("fy"));
  camera.cx = reader.Number(fields.Required("cx"), fields.Path("cx"));
  camera.cy = reader.Number(fields.Required("cy"), fields.Path("cy"));
  camera.distortion = reader.NumberList(fields.Required("distortion"), fields.Path("distortion"));
  if (const std::string problem = camera.Check(); !problem.empty()) fields.FailCheck(problem);
  return camera;
}

Rigid3d ParseTransform(const YamlReader& reader, const YAML::Node& node, const std::string& key) {
  const Fields fields = reader.Mapping(node, key, {"q_xyzw", "t_m"});
  const std::vector<double> q =
      reader.NumberList(fields.Required("q_xyzw"), fields.Path("q_xyzw"), 4);
  const std::vector<double> t = reader.NumberList(fields.Required("t_m"), fields.Path("t_m"), 3);
  Rigid3d transform;
  transform.rotation = Eigen::Quaterniond(q[3], q[0], q[1], q[2]);
  transform.translation = Eigen::Vector3d(t[0], t[1], t[2]);
  if (const std::string problem = CheckTransform(transform); !problem.empty()) {
    fields.FailCheck(problem);
  }
  // Normalise, except a quaternion already unit to rounding: a written rig reads back
  // bit for bit (normalising twice need not give the same last bit).
  if (std::abs(transform.rotation.squaredNorm() - 1) > 4 * 2.220446049250313e-16) {
    transform.rotation.normalize();
  }
  return transform;
}

// The `depth_correction` block (an extension of scan-format.md, depth_correction.h).
DepthCorrection ParseDepthCorrection(const YamlReader& reader, const YAML::Node& node,
                                     const std::string& key) {
  const Fields fields =
      reader.Mapping(node, key, {"nx", "ny", "x_range", "y_range", "offset_per_m", "plate_affine_per_m"});
  DepthCorrection correction;
  correction.nx = reader.Integer(fields.Required("nx"), fields.Path("nx"));
  correction.ny = reader.Integer(fields.Required("ny"), fields.Path("ny"));
  const std::vector<double> x_range =
      reader.NumberList(fields.Required("x_range"), fields.Path("x_range"), 2);
  const std::vector<double> y_range =
      reader.NumberList(fields.Required("y_range"), fields.Path("y_range"), 2);
  correction.x_range = {x_range[0], x_range[1]};
  correction.y_range = {y_range[0], y_range[1]};
  correction.offset_per_m =
      reader.NumberList(fields.Required("offset_per_m"), fields.Path("offset_per_m"));
  if (fields.Has("plate_affine_per_m")) {
    const std::vector<double> a =
        reader.NumberList(fields.Required("plate_affine_per_m"), fields.Path("plate_affine_per_m"), 3);
    correction.plate_affine_per_m = std::array<double, 3>{a[0], a[1], a[2]};
  }
  if (const std::string problem = correction.Check(); !problem.empty()) fields.FailCheck(problem);
  return correction;
}

ThermalSettings ParseThermal(const YamlReader& reader, const YAML::Node& node,
                             const std::string& key) {
  const Fields fields = reader.Mapping(
      node, key,
      {"raw_scale", "raw_offset", "spectral_band_um", "netd_k", "emissivity", "reflected_c"});
  ThermalSettings s;
  s.raw_scale = reader.Number(fields.Required("raw_scale"), fields.Path("raw_scale"));
  s.raw_offset = reader.Number(fields.Required("raw_offset"), fields.Path("raw_offset"));
  const std::vector<double> band =
      reader.NumberList(fields.Required("spectral_band_um"), fields.Path("spectral_band_um"), 2);
  s.spectral_band_um = {band[0], band[1]};
  s.netd_k = reader.Number(fields.Required("netd_k"), fields.Path("netd_k"));
  s.emissivity = reader.Number(fields.Required("emissivity"), fields.Path("emissivity"));
  s.reflected_c = reader.Number(fields.Required("reflected_c"), fields.Path("reflected_c"));
  if (const std::string problem = s.Check(); !problem.empty()) fields.FailCheck(problem);
  return s;
}

void AppendCamera(std::string& out, const std::string& name, const CameraModel& camera) {
  out += "  " + name + ":\n";
  out += "    width: " + std::to_string(camera.width) + "\n";
  out += "    height: " + std::to_string(camera.height) + "\n";
  out += "    model: " + CameraModelTypeName(camera.type) +
         "   # pinhole | opencv (OpenCV's k1 k2 p1 p2 [k3 [k4 k5 k6]]) | splined (mrcal's)\n";
  if (camera.type == CameraModelType::kSplined) {
    const SplinedConfig& c = camera.splined;
    out += "    splined: { order: " + std::to_string(c.order) + ", nx: " + std::to_string(c.nx) +
           ", ny: " + std::to_string(c.ny) + ", fov_x_deg: " + std::to_string(c.fov_x_deg) +
           " }   # mrcal LENSMODEL_SPLINED_STEREOGRAPHIC\n";
  }
  out += "    fx: " + FormatYamlDouble(camera.fx) + "\n";
  out += "    fy: " + FormatYamlDouble(camera.fy) + "\n";
  out += "    cx: " + FormatYamlDouble(camera.cx) + "\n";
  out += "    cy: " + FormatYamlDouble(camera.cy) + "\n";
  out += "    distortion: " + FormatYamlList(camera.distortion.data(), camera.distortion.size()) +
         (camera.type == CameraModelType::kSplined
              ? "   # spline control values, mrcal's order (2 nx ny)\n"
              : "   # OpenCV order; empty for pinhole\n");
}

std::string FormatTransform(const Rigid3d& transform) {
  const Eigen::Quaterniond& q = transform.rotation;
  const std::array<double, 4> q_xyzw = {q.x(), q.y(), q.z(), q.w()};
  return "{ q_xyzw: " + FormatYamlList(q_xyzw.data(), 4) +
         ", t_m: " + FormatYamlList(transform.translation.data(), 3) + " }";
}

}  // namespace

// -----------------------------------------------------------------------------------------
// Rig

std::string ThermalSettings::Check() const {
  if (!std::isfinite(raw_scale) || !(std::abs(raw_scale) >= kMinAbsRawScale) ||
      !(std::abs(raw_scale) <= kMaxAbsRawScale)) {
    return "raw_scale: |raw_scale| must be in [" + MessageNumber(kMinAbsRawScale) + ", " +
           MessageNumber(kMaxAbsRawScale) + "] °C per count (either sign), got " +
           MessageNumber(raw_scale);
  }
  if (std::string problem =
          RangeProblem("raw_offset", raw_offset, -kMaxAbsRawOffsetC, kMaxAbsRawOffsetC, "°C");
      !problem.empty()) {
    return problem;
  }
  const auto& band = spectral_band_um;
  const auto in_range = [](double um) { return um >= kMinBandUm && um <= kMaxBandUm; };
  if (!in_range(band[0]) || !in_range(band[1]) || !(band[1] > band[0])) {
    return "spectral_band_um: must be [lo, hi] with " + MessageNumber(kMinBandUm) +
           " <= lo < hi <= " + MessageNumber(kMaxBandUm) + " µm, got [" + MessageNumber(band[0]) +
           ", " + MessageNumber(band[1]) + "]";
  }
  if (std::string problem = RangeProblem("netd_k", netd_k, 0, kMaxNetdK, "K"); !problem.empty()) {
    return problem;
  }
  if (std::string problem = RangeProblem("emissivity", emissivity, kMinEmissivity, 1, "");
      !problem.empty()) {
    return problem;
  }
  // Strictly above absolute zero: the band radiance model needs a temperature.
  if (!std::isfinite(reflected_c)) {
    return "reflected_c: must be finite, got " + MessageNumber(reflected_c);
  }
  if (!(reflected_c > -273.15 && reflected_c <= kMaxReflectedC)) {
    return "reflected_c: must be in (-273.15, " + MessageNumber(kMaxReflectedC) +
           "] °C (above absolute zero), got " + MessageNumber(reflected_c);
  }
  return "";
}

std::string CheckExtrinsicTranslation(const Eigen::Vector3d& t_m) {
  // !(x <= max) also refuses NaN.
  if (!(t_m.norm() <= kMaxExtrinsicTranslationM)) {
    return "must be at most " + MessageNumber(kMaxExtrinsicTranslationM) + " m long, got [" +
           MessageNumber(t_m.x()) + ", " + MessageNumber(t_m.y()) + ", " + MessageNumber(t_m.z()) +
           "]";
  }
  return "";
}

std::string Rig::Check() const {
  if (std::string problem = RangeProblem("depth_scale", depth_scale, kMinDepthScale, kMaxDepthScale,
                                         "raw units per metre");
      !problem.empty()) {
    return problem;
  }
  const std::array<std::pair<const char*, const CameraModel*>, 3> cameras = {
      {{"depth", &depth},
       {"rgb", rgb ? &*rgb : nullptr},
       {"thermal", thermal ? &*thermal : nullptr}}};
  for (const auto& [name, camera] : cameras) {
    if (camera == nullptr) continue;
    if (const std::string problem = camera->Check(); !problem.empty()) {
      return "cameras." + std::string(name) + "." + problem;
    }
  }
  const std::array<std::tuple<const char*, bool, const Rigid3d*, double>, 2> others = {
      {{"rgb", rgb.has_value(), &depth_from_rgb, rgb_time_offset_s},
       {"thermal", thermal.has_value(), &depth_from_thermal, thermal_time_offset_s}}};
  for (const auto& [name, present, transform, time_offset_s] : others) {
    const std::string extrinsics = "extrinsics.depth_from_" + std::string(name);
    const std::string time_offset = "time_offset_s." + std::string(name);
    if (present) {
      if (const std::string problem = CheckTransform(*transform); !problem.empty()) {
        return extrinsics + "." + problem;
      }
      if (std::string problem =
              RangeProblem(time_offset, time_offset_s, -kMaxTimeOffsetS, kMaxTimeOffsetS, "s");
          !problem.empty()) {
        return problem;
      }
    } else {
      // rig.yaml has nowhere to keep them: they would be lost on writing.
      if (!IsIdentity(*transform)) {
        return extrinsics + ": must be identity when cameras." + name + " is absent";
      }
      if (time_offset_s != 0) {
        return time_offset + ": must be 0 when cameras." + name + " is absent, got " +
               MessageNumber(time_offset_s);
      }
    }
  }
  if (!(rgb_readout_s >= 0 && rgb_readout_s <= kMaxReadoutS)) {
    return "rolling_shutter_s.rgb: must be in [0, 0.1] s, got " + MessageNumber(rgb_readout_s);
  }
  if (!rgb && rgb_readout_s != 0) {
    return "rolling_shutter_s.rgb: must be 0 when cameras.rgb is absent, got " + MessageNumber(rgb_readout_s);
  }
  if (thermal.has_value() != thermal_settings.has_value()) {
    return thermal ? "thermal: required when cameras.thermal is present"
                   : "thermal: must be absent when cameras.thermal is absent";
  }
  if (thermal_settings) {
    if (const std::string problem = thermal_settings->Check(); !problem.empty()) {
      return "thermal." + problem;
    }
  }
  if (depth_correction) {
    if (const std::string problem = depth_correction->Check(); !problem.empty()) {
      return "depth_correction." + problem;
    }
  }
  return "";
}

Rig ParseRig(const std::string& yaml_text, const fs::path& path_for_errors) {
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  reader.CheckVersion(root, 1);
  const Fields top = reader.Mapping(
      root, "", {"version", "depth_scale", "cameras", "extrinsics", "time_offset_s", "thermal",
                  "depth_correction", "rolling_shutter_s"});
  top.Required("version");

  Rig rig;
  rig.depth_scale = reader.Number(top.Required("depth_scale"), "depth_scale");

  const Fields cameras =
      reader.Mapping(top.Required("cameras"), "cameras", {"depth", "rgb", "thermal"});
  rig.depth = ParseCamera(reader, cameras.Required("depth"), "cameras.depth");
  if (cameras.Has("rgb")) {
    rig.rgb = ParseCamera(reader, cameras.Required("rgb"), "cameras.rgb");
  }
  if (cameras.Has("thermal")) {
    rig.thermal = ParseCamera(reader, cameras.Required("thermal"), "cameras.thermal");
  }

  // extrinsics and time_offset_s may be left out when there is only the depth camera; an
  // absent block reads as an empty one so that a missing entry is named precisely.
  const Fields extrinsics = top.Has("extrinsics")
                                ? reader.Mapping(top.Required("extrinsics"), "extrinsics",
                                                 {"depth_from_rgb", "depth_from_thermal"})
                                : Fields(reader, "extrinsics", YAML::Node());
  const Fields time_offsets = top.Has("time_offset_s")
                                  ? reader.Mapping(top.Required("time_offset_s"), "time_offset_s",
                                                   {"depth", "rgb", "thermal"})
                                  : Fields(reader, "time_offset_s", YAML::Node());

  if (time_offsets.Has("depth")) {
    const YAML::Node& node = time_offsets.Required("depth");
    if (const double offset = reader.Number(node, "time_offset_s.depth"); offset != 0) {
      reader.Fail("time_offset_s.depth",
                  "must be 0 (depth is the reference clock), got " + MessageNumber(offset), node);
    }
  }
  const std::array<std::tuple<std::string, bool, Rigid3d*, double*>, 2> others = {
      {{"rgb", rig.rgb.has_value(), &rig.depth_from_rgb, &rig.rgb_time_offset_s},
       {"thermal", rig.thermal.has_value(), &rig.depth_from_thermal, &rig.thermal_time_offset_s}}};
  for (const auto& [name, present, transform, time_offset_s] : others) {
    const std::string extrinsics_key = "depth_from_" + name;
    if (present) {
      *transform = ParseTransform(reader, extrinsics.Required(extrinsics_key),
                                  extrinsics.Path(extrinsics_key));
      *time_offset_s = reader.Number(time_offsets.Required(name), time_offsets.Path(name));
    } else {
      if (extrinsics.Has(extrinsics_key)) {
        reader.Fail(extrinsics.Path(extrinsics_key), "given but cameras." + name + " is absent",
                    extrinsics.NodeFor(extrinsics_key));
      }
      if (time_offsets.Has(name)) {
        reader.Fail(time_offsets.Path(name), "given but cameras." + name + " is absent",
                    time_offsets.NodeFor(name));
      }
    }
  }

  if (rig.thermal) {
    rig.thermal_settings = ParseThermal(reader, top.Required("thermal"), "thermal");
  } else if (top.Has("thermal")) {
    reader.Fail("thermal", "given but cameras.thermal is absent", top.NodeFor("thermal"));
  }

  if (top.Has("rolling_shutter_s")) {
    const Fields readout = reader.Mapping(top.Required("rolling_shutter_s"), "rolling_shutter_s", {"rgb"});
    if (readout.Has("rgb")) {
      if (!rig.rgb) {
        reader.Fail(readout.Path("rgb"), "given but cameras.rgb is absent", readout.NodeFor("rgb"));
      }
      rig.rgb_readout_s = reader.Number(readout.Required("rgb"), readout.Path("rgb"));
    }
  }

  if (top.Has("depth_correction")) {
    rig.depth_correction = ParseDepthCorrection(reader, top.Required("depth_correction"),
                                                "depth_correction");
  }

  // Cameras, extrinsics and the thermal block were checked where they were read (a
  // quaternion must be checked before it is normalised); the rest of the ranges, and any
  // future field, here, with the line of the key the message names.
  if (const std::string problem = rig.Check(); !problem.empty()) {
    reader.FailCheck(root, "", problem);
  }
  return rig;
}

// The size cap and the refusal of FIFOs and devices are ReadFile's.
Rig ReadRig(const fs::path& path) { return ParseRig(ReadFile(path, kMaxConfigFileBytes), path); }

std::string FormatRig(const Rig& rig) {
  assert(rig.Check().empty());
  std::string out;
  out += "version: 1\n";
  out += "depth_scale: " + FormatYamlDouble(rig.depth_scale) +
         "   # raw depth units per metre (TUM uses 5000)\n";
  out += "cameras:\n";
  AppendCamera(out, "depth", rig.depth);
  if (rig.rgb) AppendCamera(out, "rgb", *rig.rgb);
  if (rig.thermal) AppendCamera(out, "thermal", *rig.thermal);
  if (rig.rgb || rig.thermal) {
    out += "extrinsics:   # each maps points from the named camera into the depth camera\n";
    if (rig.rgb) out += "  depth_from_rgb: " + FormatTransform(rig.depth_from_rgb) + "\n";
    if (rig.thermal) {
      out += "  depth_from_thermal: " + FormatTransform(rig.depth_from_thermal) + "\n";
    }
    out += "time_offset_s:   # per stream: t_depth_clock = t_stream + time_offset_s\n";
    if (rig.rgb) out += "  rgb: " + FormatYamlDouble(rig.rgb_time_offset_s) + "\n";
    if (rig.thermal) out += "  thermal: " + FormatYamlDouble(rig.thermal_time_offset_s) + "\n";
  }
  if (rig.rgb && rig.rgb_readout_s > 0) {
    out += "rolling_shutter_s:   # heatwave: colour readout, first row to last (frame time: middle row)\n";
    out += "  rgb: " + FormatYamlDouble(rig.rgb_readout_s) + "\n";
  }
  if (rig.thermal_settings) {
    const ThermalSettings& s = *rig.thermal_settings;
    out += "thermal:\n";
    out += "  raw_scale: " + FormatYamlDouble(s.raw_scale) +
           "   # apparent °C = raw * raw_scale + raw_offset\n";
    out += "  raw_offset: " + FormatYamlDouble(s.raw_offset) + "\n";
    out += "  spectral_band_um: " + FormatYamlList(s.spectral_band_um.data(), 2) + "\n";
    out += "  netd_k: " + FormatYamlDouble(s.netd_k) +
           "   # noise-equivalent temperature difference of one frame\n";
    out += "  emissivity: " + FormatYamlDouble(s.emissivity) +
           "   # default surface emissivity for the whole scene\n";
    out += "  reflected_c: " + FormatYamlDouble(s.reflected_c) +
           "   # reflected apparent temperature\n";
  }
  if (rig.depth_correction) {
    const DepthCorrection& c = *rig.depth_correction;
    out += "depth_correction:   # heatwave: 1/z_true = 1/z_measured - offset(x/z, y/z), bilinear\n";
    out += "  nx: " + std::to_string(c.nx) + "\n";
    out += "  ny: " + std::to_string(c.ny) + "\n";
    out += "  x_range: " + FormatYamlList(c.x_range.data(), 2) + "\n";
    out += "  y_range: " + FormatYamlList(c.y_range.data(), 2) + "\n";
    if (c.plate_affine_per_m) {
      out += "  plate_affine_per_m: " + FormatYamlList(c.plate_affine_per_m->data(), 3) +
             "   # a, c_x, c_y (1/m) measured on the extrinsics plate, included below\n";
    }
    out += "  offset_per_m:   # 1/m, row-major (ny rows of nx)\n";
    out += "    [";
    for (int iy = 0; iy < c.ny; ++iy) {
      if (iy > 0) out += ",\n     ";
      for (int ix = 0; ix < c.nx; ++ix) {
        if (ix > 0) out += ", ";
        out += FormatYamlDouble(c.offset_per_m[static_cast<size_t>(iy) * c.nx + ix]);
      }
    }
    out += "]\n";
  }
  return out;
}

void WriteRig(const fs::path& path, const Rig& rig) { WriteFileAtomically(path, FormatRig(rig)); }

}  // namespace hw::core
