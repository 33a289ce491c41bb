#include "core/rig.h"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/parser.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <cassert>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------
// Numbers as text.

// Shortest text that reads back to the same double, spelled as a YAML float that every
// YAML reader takes for one (PyYAML needs a '.' in "1.0e-05" and "525.0").
std::string FormatDouble(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  std::array<char, 64> buffer{};
  const auto [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  assert(ec == std::errc());
  std::string text(buffer.data(), end);
  const size_t exponent = text.find('e');
  if (text.find('.') == std::string::npos) {
    text.insert(exponent == std::string::npos ? text.size() : exponent, ".0");
  }
  return text;
}

// For messages: short, but still tells 1 from 1.0000001.
std::string FormatForMessage(double value) {
  std::array<char, 32> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.10g", value);
  return buffer.data();
}

std::string FormatList(const double* values, size_t count) {
  std::string text = "[";
  for (size_t i = 0; i < count; ++i) text += (i > 0 ? ", " : "") + FormatDouble(values[i]);
  return text + "]";
}

// ---------------------------------------------------------------------------------------
// Strict YAML reading: every accessor names the key path and the line on failure.

std::string LineSuffix(const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.is_null() || mark.line < 0) return "";
  return " (line " + std::to_string(mark.line + 1) + ")";
}

std::string Join(const std::string& prefix, const std::string& key) {
  return prefix.empty() ? key : prefix + "." + key;
}

// `text` for a one-line message: control characters escaped, long texts cut.
std::string Printable(const std::string& text) {
  constexpr size_t kMaxLength = 40;
  std::string out;
  for (size_t i = 0; i < text.size() && i < kMaxLength; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c == '\n') {
      out += "\\n";
    } else if (c < 0x20 || c == 0x7f) {
      out += '?';
    } else {
      out += static_cast<char>(c);
    }
  }
  return text.size() > kMaxLength ? out + "..." : out;
}

std::string Describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "nothing";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    case YAML::NodeType::Scalar:
      // Plain scalars are YAML's numbers and names; quoted ones are strings.
      if (node.Tag() == "?") return "'" + Printable(node.Scalar()) + "'";
      return "string \"" + Printable(node.Scalar()) + "\"";
    case YAML::NodeType::Undefined:
      break;
  }
  return "nothing";
}

// YAML's spellings of infinity and not-a-number (.inf, -.Inf, .NaN, ...) and C's (inf, nan).
bool IsNonFiniteWord(std::string_view text) {
  if (!text.empty() && (text[0] == '+' || text[0] == '-')) text.remove_prefix(1);
  if (!text.empty() && text[0] == '.') text.remove_prefix(1);
  std::string lower;
  for (const char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == "inf" || lower == "infinity" || lower == "nan";
}

// from_chars takes "-3" but not "+3", which YAML allows.
std::string_view WithoutPlusSign(std::string_view text) {
  if (text.size() >= 2 && text[0] == '+' && text[1] != '-' && text[1] != '+') {
    text.remove_prefix(1);
  }
  return text;
}

// Records where each document starts; ignores everything else.
class DocumentStarts : public YAML::EventHandler {
 public:
  std::vector<YAML::Mark> marks;
  void OnDocumentStart(const YAML::Mark& mark) override { marks.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

class YamlReader {
 public:
  explicit YamlReader(fs::path path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& problem,
                         const YAML::Node& node) const {
    throw InputError(path_, key + ": " + problem + LineSuffix(node));
  }

  // The single YAML document of `text` as a mapping.
  YAML::Node LoadMapping(const std::string& text) const {
    YAML::Node root;
    try {
      // Not YAML::LoadAll: yaml-cpp 0.7 loops forever, allocating until bad_alloc, on a
      // document it cannot get past (one starting with ',': yaml-cpp issue #1040, fixed
      // upstream in 2024 by PR #1319). Walk at most three documents with the event parser
      // instead, catching the parser when it makes no progress, then load the first.
      std::istringstream stream(text);
      YAML::Parser parser(stream);
      DocumentStarts starts;
      for (int i = 0; i < 3 && parser.HandleNextDocument(starts); ++i) {
      }
      const std::vector<YAML::Mark>& marks = starts.marks;
      for (size_t i = 1; i < marks.size(); ++i) {
        if (marks[i].pos != marks[i - 1].pos) continue;
        const size_t pos = static_cast<size_t>(marks[i].pos);
        const unsigned char c = pos < text.size() ? static_cast<unsigned char>(text[pos]) : ' ';
        const std::string what =
            std::isgraph(c) ? std::string("'") + static_cast<char>(c) + "'" : "character";
        throw InputError(path_, "line " + std::to_string(marks[i].line + 1) +
                                    ": YAML syntax error: unexpected " + what);
      }
      if (marks.size() > 1) {
        throw InputError(path_, "more than one YAML document (the second starts on line " +
                                    std::to_string(marks[1].line + 1) + ")");
      }
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      const std::string line =
          e.mark.is_null() ? "" : "line " + std::to_string(e.mark.line + 1) + ": ";
      throw InputError(path_, line + "YAML syntax error: " + e.msg);
    }
    if (root.IsNull()) throw InputError(path_, "empty file");
    if (!root.IsMap()) {
      throw InputError(path_, "expected a mapping of keys at the top level, got " + Describe(root) +
                                  LineSuffix(root));
    }
    return root;
  }

  // The keys of a mapping, each checked against `allowed`, with no duplicates.
  class Fields {
   public:
    Fields(const YamlReader& reader, std::string key, YAML::Node node)
        : reader_(reader), key_(std::move(key)), node_(std::move(node)) {}

    const std::string& key() const { return key_; }
    const YAML::Node& node() const { return node_; }
    bool Has(const std::string& name) const { return values_.count(name) > 0; }
    std::string Path(const std::string& name) const { return Join(key_, name); }

    const YAML::Node& Required(const std::string& name) const {
      const auto it = values_.find(name);
      if (it == values_.end()) reader_.Fail(Path(name), "missing required key", node_);
      return it->second;
    }
    // The node of `name` or, when absent, of the whole mapping: where to point a message.
    const YAML::Node& NodeFor(const std::string& name) const {
      const auto it = values_.find(name);
      return it == values_.end() ? node_ : it->second;
    }

    // Maps "fx: must be > 0, got -3" (a Check() message about field "fx" of this mapping)
    // to "<key>.fx: must be > 0, got -3 (line N)".
    [[noreturn]] void FailCheck(const std::string& message) const {
      const std::string field = message.substr(0, message.find_first_of(":["));
      const size_t colon = message.find(": ");
      const std::string what = message.substr(0, colon);
      const std::string problem = colon == std::string::npos ? "" : message.substr(colon + 2);
      reader_.Fail(Path(what), problem, NodeFor(field));
    }

   private:
    friend class YamlReader;
    const YamlReader& reader_;
    std::string key_;
    YAML::Node node_;
    std::map<std::string, YAML::Node> values_;
  };

  Fields Mapping(const YAML::Node& node, const std::string& key,
                 const std::set<std::string>& allowed) const {
    const std::string where = key.empty() ? "top level" : key;
    if (!node.IsMap()) Fail(where, "must be a mapping of keys, got " + Describe(node), node);
    Fields fields(*this, key, node);
    for (const auto& item : node) {
      if (!item.first.IsScalar()) {
        Fail(where, "keys must be plain names, got " + Describe(item.first), item.first);
      }
      const std::string& name = item.first.Scalar();
      if (allowed.count(name) == 0) {
        Fail(where, "unknown key '" + Printable(name) + "'", item.first);
      }
      if (!fields.values_.emplace(name, item.second).second) {
        Fail(where, "duplicate key '" + Printable(name) + "'", item.first);
      }
    }
    return fields;
  }

  double Number(const YAML::Node& node, const std::string& key) const {
    // Only plain scalars are numbers: "525" in quotes is a string.
    if (!node.IsScalar() || node.Tag() != "?") {
      Fail(key, "must be a number, got " + Describe(node), node);
    }
    const std::string_view text = WithoutPlusSign(node.Scalar());
    double value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec == std::errc::result_out_of_range) {
      Fail(key, "number out of range, got " + Describe(node), node);
    }
    if (IsNonFiniteWord(text) || (ec == std::errc() && !std::isfinite(value))) {
      Fail(key, "must be finite, got " + Describe(node), node);
    }
    if (ec != std::errc() || end != text.data() + text.size() || text.empty()) {
      Fail(key, "must be a number, got " + Describe(node), node);
    }
    return value;
  }

  int Integer(const YAML::Node& node, const std::string& key) const {
    if (!node.IsScalar() || node.Tag() != "?") {
      Fail(key, "must be an integer, got " + Describe(node), node);
    }
    const std::string_view text = WithoutPlusSign(node.Scalar());
    int value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec == std::errc::result_out_of_range) {
      Fail(key, "integer out of range, got " + Describe(node), node);
    }
    if (ec != std::errc() || end != text.data() + text.size() || text.empty()) {
      Fail(key, "must be an integer, got " + Describe(node), node);
    }
    return value;
  }

  std::string String(const YAML::Node& node, const std::string& key) const {
    if (!node.IsScalar()) Fail(key, "must be a name, got " + Describe(node), node);
    return node.Scalar();
  }

  // A list of numbers; of exactly `size` elements unless size is negative.
  std::vector<double> NumberList(const YAML::Node& node, const std::string& key,
                                 int size = -1) const {
    const std::string expected =
        size < 0 ? "a list of numbers" : "a list of " + std::to_string(size) + " numbers";
    if (!node.IsSequence()) Fail(key, "must be " + expected + ", got " + Describe(node), node);
    if (size >= 0 && node.size() != static_cast<size_t>(size)) {
      Fail(key, "must be " + expected + ", got " + std::to_string(node.size()), node);
    }
    std::vector<double> values;
    for (const YAML::Node& element : node) {
      values.push_back(Number(element, key + "[" + std::to_string(values.size()) + "]"));
    }
    return values;
  }

 private:
  fs::path path_;
};

using Fields = YamlReader::Fields;

// ---------------------------------------------------------------------------------------
// rig.yaml pieces.

// A quaternion counts as unit when |q| is within this of 1 (rig.h); smaller errors are
// normalised away.
constexpr double kUnitQuaternionTolerance = 1e-6;

std::string CheckThermalSettings(const ThermalSettings& s) {
  if (!std::isfinite(s.raw_scale) || s.raw_scale == 0) {
    return "raw_scale: must be finite and != 0, got " + FormatForMessage(s.raw_scale);
  }
  if (!std::isfinite(s.raw_offset)) {
    return "raw_offset: must be finite, got " + FormatForMessage(s.raw_offset);
  }
  const auto& band = s.spectral_band_um;
  if (!std::isfinite(band[0]) || !std::isfinite(band[1]) || !(band[0] > 0) ||
      !(band[1] > band[0])) {
    return "spectral_band_um: must be increasing and > 0, got [" + FormatForMessage(band[0]) +
           ", " + FormatForMessage(band[1]) + "]";
  }
  if (!std::isfinite(s.netd_k) || s.netd_k < 0) {
    return "netd_k: must be >= 0, got " + FormatForMessage(s.netd_k);
  }
  if (!std::isfinite(s.emissivity) || !(s.emissivity > 0) || s.emissivity > 1) {
    return "emissivity: must be in (0, 1], got " + FormatForMessage(s.emissivity);
  }
  if (!std::isfinite(s.reflected_c) || !(s.reflected_c > -273.15)) {
    return "reflected_c: must be above absolute zero (-273.15), got " +
           FormatForMessage(s.reflected_c);
  }
  return "";
}

// "" when `depth_from_camera` is a valid transform, else "q_xyzw: ..." or "t_m: ...".
std::string CheckTransform(const Rigid3d& transform) {
  const double norm = transform.rotation.norm();
  if (!transform.rotation.coeffs().allFinite() ||
      !(std::abs(norm - 1) <= kUnitQuaternionTolerance)) {
    return "q_xyzw: not a unit quaternion (norm " + FormatForMessage(norm) + ")";
  }
  if (!transform.translation.allFinite()) return "t_m: must be finite";
  return "";
}

bool IsIdentity(const Rigid3d& transform) {
  return transform.rotation.coeffs() == Eigen::Quaterniond::Identity().coeffs() &&
         transform.translation == Eigen::Vector3d::Zero();
}

const std::set<std::string> kCameraKeys = {"width", "height", "model", "fx",
                                           "fy",    "cx",     "cy",    "distortion"};

CameraModel ParseCamera(const YamlReader& reader, const YAML::Node& node, const std::string& key) {
  const Fields fields = reader.Mapping(node, key, kCameraKeys);
  CameraModel camera;
  camera.width = reader.Integer(fields.Required("width"), fields.Path("width"));
  camera.height = reader.Integer(fields.Required("height"), fields.Path("height"));
  const YAML::Node& model = fields.Required("model");
  const std::string model_name = reader.String(model, fields.Path("model"));
  const std::optional<CameraModelType> type = ParseCameraModelType(model_name);
  if (!type)
    reader.Fail(fields.Path("model"), "must be pinhole or opencv, got " + Describe(model), model);
  camera.type = *type;
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
  if (const std::string problem = CheckThermalSettings(s); !problem.empty()) {
    fields.FailCheck(problem);
  }
  return s;
}

void AppendCamera(std::string& out, const std::string& name, const CameraModel& camera) {
  out += "  " + name + ":\n";
  out += "    width: " + std::to_string(camera.width) + "\n";
  out += "    height: " + std::to_string(camera.height) + "\n";
  out += "    model: " + CameraModelTypeName(camera.type) +
         "   # pinhole | opencv (opencv = OpenCV's k1 k2 p1 p2 [k3 [k4 k5 k6]])\n";
  out += "    fx: " + FormatDouble(camera.fx) + "\n";
  out += "    fy: " + FormatDouble(camera.fy) + "\n";
  out += "    cx: " + FormatDouble(camera.cx) + "\n";
  out += "    cy: " + FormatDouble(camera.cy) + "\n";
  out += "    distortion: " + FormatList(camera.distortion.data(), camera.distortion.size()) +
         "   # OpenCV order; empty for pinhole\n";
}

std::string FormatTransform(const Rigid3d& transform) {
  const Eigen::Quaterniond& q = transform.rotation;
  const std::array<double, 4> q_xyzw = {q.x(), q.y(), q.z(), q.w()};
  return "{ q_xyzw: " + FormatList(q_xyzw.data(), 4) +
         ", t_m: " + FormatList(transform.translation.data(), 3) + " }";
}

// ---------------------------------------------------------------------------------------
// target.yaml pieces.

// AprilTag 3 families (apriltag library's tag*_create).
const std::set<std::string> kAprilTagFamilies = {
    "tag36h11",       "tag25h9",          "tag16h5",          "tagCircle21h7",
    "tagCircle49h12", "tagStandard41h12", "tagStandard52h13", "tagCustom48h12"};

std::optional<TargetType> ParseTargetType(const std::string& name) {
  for (const TargetType type :
       {TargetType::kSquareGrid, TargetType::kChessboard, TargetType::kAprilGrid}) {
    if (TargetTypeName(type) == name) return type;
  }
  return std::nullopt;
}

bool HasPitch(TargetType type) { return type != TargetType::kChessboard; }

}  // namespace

// -----------------------------------------------------------------------------------------
// Rig

std::string Rig::Check() const {
  if (!std::isfinite(depth_scale) || !(depth_scale > 0)) {
    return "depth_scale: must be > 0, got " + FormatForMessage(depth_scale);
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
      if (!std::isfinite(time_offset_s)) {
        return time_offset + ": must be finite, got " + FormatForMessage(time_offset_s);
      }
    } else {
      // rig.yaml has nowhere to keep them: they would be lost on writing.
      if (!IsIdentity(*transform)) {
        return extrinsics + ": must be identity when cameras." + name + " is absent";
      }
      if (time_offset_s != 0) {
        return time_offset + ": must be 0 when cameras." + name + " is absent, got " +
               FormatForMessage(time_offset_s);
      }
    }
  }
  if (thermal.has_value() != thermal_settings.has_value()) {
    return thermal ? "thermal: required when cameras.thermal is present"
                   : "thermal: must be absent when cameras.thermal is absent";
  }
  if (thermal_settings) {
    if (const std::string problem = CheckThermalSettings(*thermal_settings); !problem.empty()) {
      return "thermal." + problem;
    }
  }
  return "";
}

Rig ParseRig(const std::string& yaml_text, const fs::path& path_for_errors) {
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  // The version first: a newer file is reported as such, not by its first unknown key.
  for (const auto& item : root) {
    if (item.first.IsScalar() && item.first.Scalar() == "version") {
      if (const int number = reader.Integer(item.second, "version"); number != 1) {
        reader.Fail(
            "version",
            "unsupported version " + std::to_string(number) + " (this reader knows version 1)",
            item.second);
      }
    }
  }
  const Fields top = reader.Mapping(
      root, "", {"version", "depth_scale", "cameras", "extrinsics", "time_offset_s", "thermal"});
  top.Required("version");

  Rig rig;
  rig.depth_scale = reader.Number(top.Required("depth_scale"), "depth_scale");
  if (!(rig.depth_scale > 0)) {
    reader.Fail("depth_scale", "must be > 0, got " + FormatForMessage(rig.depth_scale),
                top.NodeFor("depth_scale"));
  }

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
                  "must be 0 (depth is the reference clock), got " + FormatForMessage(offset),
                  node);
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

  // Everything above is checked where it was read, with its line; this is a safety net.
  if (const std::string problem = rig.Check(); !problem.empty()) {
    throw InputError(path_for_errors, problem);
  }
  return rig;
}

Rig ReadRig(const fs::path& path) { return ParseRig(ReadFile(path), path); }

std::string FormatRig(const Rig& rig) {
  assert(rig.Check().empty());
  std::string out;
  out += "version: 1\n";
  out += "depth_scale: " + FormatDouble(rig.depth_scale) +
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
    if (rig.rgb) out += "  rgb: " + FormatDouble(rig.rgb_time_offset_s) + "\n";
    if (rig.thermal) out += "  thermal: " + FormatDouble(rig.thermal_time_offset_s) + "\n";
  }
  if (rig.thermal_settings) {
    const ThermalSettings& s = *rig.thermal_settings;
    out += "thermal:\n";
    out += "  raw_scale: " + FormatDouble(s.raw_scale) +
           "   # apparent °C = raw * raw_scale + raw_offset\n";
    out += "  raw_offset: " + FormatDouble(s.raw_offset) + "\n";
    out += "  spectral_band_um: " + FormatList(s.spectral_band_um.data(), 2) + "\n";
    out += "  netd_k: " + FormatDouble(s.netd_k) +
           "   # noise-equivalent temperature difference of one frame\n";
    out += "  emissivity: " + FormatDouble(s.emissivity) +
           "   # default surface emissivity for the whole scene\n";
    out +=
        "  reflected_c: " + FormatDouble(s.reflected_c) + "   # reflected apparent temperature\n";
  }
  return out;
}

void WriteRig(const fs::path& path, const Rig& rig) { WriteFileAtomically(path, FormatRig(rig)); }

// -----------------------------------------------------------------------------------------
// Target

std::string TargetTypeName(TargetType type) {
  switch (type) {
    case TargetType::kSquareGrid:
      return "square_grid";
    case TargetType::kChessboard:
      return "chessboard";
    case TargetType::kAprilGrid:
      return "aprilgrid";
  }
  assert(false && "unknown TargetType");
  return "unknown";
}

std::string Target::Check() const {
  // A chessboard's corners are interior: it needs 2 x 2 of them to be a grid at all.
  const int min_size = type == TargetType::kChessboard ? 2 : 1;
  const std::string for_type = " for " + TargetTypeName(type);
  if (rows < min_size) {
    return "rows: must be >= " + std::to_string(min_size) + for_type + ", got " +
           std::to_string(rows);
  }
  if (cols < min_size) {
    return "cols: must be >= " + std::to_string(min_size) + for_type + ", got " +
           std::to_string(cols);
  }
  if (!std::isfinite(square_m) || !(square_m > 0)) {
    return "square_m: must be > 0, got " + FormatForMessage(square_m);
  }
  if (HasPitch(type)) {
    if (!std::isfinite(pitch_m) || !(pitch_m > square_m)) {
      return "pitch_m: must be > square_m (" + FormatForMessage(square_m) + ")" + for_type +
             ", got " + FormatForMessage(pitch_m);
    }
  } else if (pitch_m != 0) {
    return "pitch_m: not used" + for_type + ", must be absent (0), got " +
           FormatForMessage(pitch_m);
  }
  if (type == TargetType::kAprilGrid) {
    if (kAprilTagFamilies.count(family) == 0) {
      std::string known;
      for (const std::string& name : kAprilTagFamilies) known += (known.empty() ? "" : ", ") + name;
      return "family: unknown AprilTag family '" + family + "' (known: " + known + ")";
    }
  } else if (!family.empty()) {
    return "family: only for aprilgrid, got '" + family + "'" + for_type;
  }
  return "";
}

Target ParseTarget(const std::string& yaml_text, const fs::path& path_for_errors) {
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  const Fields fields =
      reader.Mapping(root, "", {"type", "rows", "cols", "square_m", "pitch_m", "family"});
  Target target;
  const YAML::Node& type_node = fields.Required("type");
  const std::optional<TargetType> type = ParseTargetType(reader.String(type_node, "type"));
  if (!type) {
    reader.Fail("type", "must be square_grid, chessboard or aprilgrid, got " + Describe(type_node),
                type_node);
  }
  target.type = *type;
  target.rows = reader.Integer(fields.Required("rows"), "rows");
  target.cols = reader.Integer(fields.Required("cols"), "cols");
  target.square_m = reader.Number(fields.Required("square_m"), "square_m");
  if (HasPitch(target.type)) {
    target.pitch_m = reader.Number(fields.Required("pitch_m"), "pitch_m");
  } else if (fields.Has("pitch_m")) {
    reader.Fail("pitch_m", "not used for " + TargetTypeName(target.type) + ", remove it",
                fields.NodeFor("pitch_m"));
  }
  if (target.type == TargetType::kAprilGrid) {
    target.family = reader.String(fields.Required("family"), "family");
  } else if (fields.Has("family")) {
    reader.Fail("family", "only for aprilgrid, not " + TargetTypeName(target.type),
                fields.NodeFor("family"));
  }
  if (const std::string problem = target.Check(); !problem.empty()) fields.FailCheck(problem);
  return target;
}

Target ReadTarget(const fs::path& path) { return ParseTarget(ReadFile(path), path); }

void WriteTarget(const fs::path& path, const Target& target) {
  assert(target.Check().empty());
  std::string out;
  out += "type: " + TargetTypeName(target.type) + "   # square_grid | chessboard | aprilgrid\n";
  const bool chessboard = target.type == TargetType::kChessboard;
  out += "rows: " + std::to_string(target.rows) +
         (chessboard ? "   # inner corners per column\n" : "   # squares per column\n");
  out += "cols: " + std::to_string(target.cols) +
         (chessboard ? "   # inner corners per row\n" : "   # squares per row\n");
  out += "square_m: " + FormatDouble(target.square_m) + "   # side of one square, metres\n";
  if (HasPitch(target.type)) {
    out += "pitch_m: " + FormatDouble(target.pitch_m) + "   # centre-to-centre distance, metres\n";
  }
  if (target.type == TargetType::kAprilGrid) out += "family: " + target.family + "\n";
  WriteFileAtomically(path, out);
}

}  // namespace hw::core
