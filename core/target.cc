// target.yaml (declared in rig.h with rig.yaml: both are scan-format.md's configuration files).
#include "core/rig.h"

#include <yaml-cpp/yaml.h>

#include <array>
#include <cassert>
#include <cmath>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include "core/atomic_file.h"
#include "core/yaml_reader.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;

using Fields = YamlReader::Fields;

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
  const std::array<std::pair<const char*, int>, 2> counts = {{{"rows", rows}, {"cols", cols}}};
  for (const auto& [name, count] : counts) {
    if (count < min_size || count > kMaxRowsCols) {
      return std::string(name) + ": must be in [" + std::to_string(min_size) + ", " +
             std::to_string(kMaxRowsCols) + "]" + for_type + ", got " + std::to_string(count);
    }
  }
  if (std::string problem = RangeProblem("square_m", square_m, kMinSizeM, kMaxSizeM, "m");
      !problem.empty()) {
    return problem;
  }
  if (HasPitch(type)) {
    if (!std::isfinite(pitch_m) || !(pitch_m > square_m) || !(pitch_m <= kMaxSizeM)) {
      return "pitch_m: must be > square_m (" + MessageNumber(square_m) +
             ") and <= " + MessageNumber(kMaxSizeM) + " m" + for_type + ", got " +
             MessageNumber(pitch_m);
    }
  } else if (pitch_m != 0) {
    return "pitch_m: not used" + for_type + ", must be absent (0), got " + MessageNumber(pitch_m);
  }
  if (type == TargetType::kSquareGrid) {
    if (!(thickness_m >= 0 && thickness_m <= kMaxThicknessM)) {
      return "thickness_m: must be in [0, " + MessageNumber(kMaxThicknessM) + "] m, got " + MessageNumber(thickness_m);
    }
  } else if (thickness_m != 0) {
    return "thickness_m: only for square_grid (a plate with holes), must be absent (0)" + for_type + ", got " +
           MessageNumber(thickness_m);
  }
  if (type == TargetType::kAprilGrid) {
    if (kAprilTagFamilies.count(family) == 0) {
      std::string known;
      for (const std::string& name : kAprilTagFamilies) known += (known.empty() ? "" : ", ") + name;
      return "family: unknown AprilTag family '" + Printable(family) + "' (known: " + known + ")";
    }
  } else if (!family.empty()) {
    return "family: only for aprilgrid, got '" + Printable(family) + "'" + for_type;
  }
  return "";
}

Target ParseTarget(const std::string& yaml_text, const fs::path& path_for_errors) {
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  const Fields fields =
      reader.Mapping(root, "", {"type", "rows", "cols", "square_m", "pitch_m", "family", "thickness_m"});
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
  if (fields.Has("thickness_m")) {
    if (target.type != TargetType::kSquareGrid) {
      reader.Fail("thickness_m", "only for square_grid, not " + TargetTypeName(target.type),
                  fields.NodeFor("thickness_m"));
    }
    target.thickness_m = reader.Number(fields.NodeFor("thickness_m"), "thickness_m");
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

Target ReadTarget(const fs::path& path) {
  return ParseTarget(ReadFile(path, kMaxConfigFileBytes), path);
}

void WriteTarget(const fs::path& path, const Target& target) {
  assert(target.Check().empty());
  std::string out;
  out += "type: " + TargetTypeName(target.type) + "   # square_grid | chessboard | aprilgrid\n";
  const bool chessboard = target.type == TargetType::kChessboard;
  out += "rows: " + std::to_string(target.rows) +
         (chessboard ? "   # inner corners per column\n" : "   # squares per column\n");
  out += "cols: " + std::to_string(target.cols) +
         (chessboard ? "   # inner corners per row\n" : "   # squares per row\n");
  out += "square_m: " + FormatYamlDouble(target.square_m) + "   # side of one square, metres\n";
  if (HasPitch(target.type)) {
    out +=
        "pitch_m: " + FormatYamlDouble(target.pitch_m) + "   # centre-to-centre distance, metres\n";
  }
  if (target.type == TargetType::kAprilGrid) out += "family: " + target.family + "\n";
  if (target.thickness_m > 0) {
    out += "thickness_m: " + FormatYamlDouble(target.thickness_m) + "   # plate thickness, metres (heatwave)\n";
  }
  WriteFileAtomically(path, out);
}

std::vector<Eigen::Vector3d> TargetCorners(const Target& target) {
  assert(target.Check().empty());
  std::vector<Eigen::Vector3d> corners;
  const double s = target.square_m;
  if (target.type == TargetType::kChessboard) {
    corners.reserve(static_cast<size_t>(target.rows) * target.cols);
    for (int r = 0; r < target.rows; ++r) {
      for (int c = 0; c < target.cols; ++c) corners.emplace_back(c * s, r * s, 0.0);
    }
    return corners;
  }
  const double p = target.pitch_m;
  corners.reserve(4 * static_cast<size_t>(target.rows) * target.cols);
  for (int r = 0; r < target.rows; ++r) {
    for (int c = 0; c < target.cols; ++c) {
      const double x0 = c * p, y0 = r * p;
      if (target.type == TargetType::kSquareGrid) {
        // Clockwise seen from the front: TL, TR, BR, BL.
        corners.emplace_back(x0, y0, 0.0);
        corners.emplace_back(x0 + s, y0, 0.0);
        corners.emplace_back(x0 + s, y0 + s, 0.0);
        corners.emplace_back(x0, y0 + s, 0.0);
      } else {
        // libapriltag's order for an upright tag: BL, BR, TR, TL.
        corners.emplace_back(x0, y0 + s, 0.0);
        corners.emplace_back(x0 + s, y0 + s, 0.0);
        corners.emplace_back(x0 + s, y0, 0.0);
        corners.emplace_back(x0, y0, 0.0);
      }
    }
  }
  return corners;
}

}  // namespace hw::core
