#include "reconstruct/emissivity_map.h"

#include <yaml-cpp/yaml.h>

#include <array>
#include <cassert>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/yaml_reader.h"

namespace hw::reconstruct {
namespace {

namespace fs = std::filesystem;

using core::YamlReader;
using Fields = YamlReader::Fields;

// |q| may differ from 1 by this much (as in rig.yaml); smaller errors are normalised away.
constexpr double kUnitQuaternionTolerance = 1e-6;
// Largest centre coordinate and size/radius, metres. No scanned model spans 1000 km, and
// at 1e6 m doubles still resolve 2e-10 m, far below kRegionOverlapToleranceM; the bound
// also keeps squared distances finite.
constexpr double kMaxCoordinateM = 1e6;
// Separating-axis candidates from nearly parallel edges (|e_a × e_b| below this) are
// skipped: the face axes already decide those pairs, and normalising a tiny cross product
// would amplify its rounding.
constexpr double kParallelCrossNorm = 1e-9;

std::string Indexed(const std::string& key, size_t i) {
  return key + "[" + std::to_string(i) + "]";
}

// emissivity and reflected_c through ThermalSettings::Check, so that the emissivity file
// refuses exactly what rig.yaml's thermal block refuses, with the same messages.
void CheckRanges(const Fields& fields, const core::ThermalSettings& rig_thermal,
                 const SurfaceEmissivity& surface) {
  core::ThermalSettings settings = rig_thermal;
  settings.emissivity = surface.emissivity;
  settings.reflected_c = surface.reflected_c;
  if (const std::string problem = settings.Check(); !problem.empty()) fields.FailCheck(problem);
}

// The `specular` key: the mirror share of the reflectance, [0, 1].
double ParseSpecular(const YamlReader& reader, const Fields& fields) {
  const YAML::Node& node = fields.Required("specular");
  const double value = reader.Number(node, fields.Path("specular"));
  if (!(value >= 0 && value <= 1)) {
    reader.Fail(fields.Path("specular"), "must be in [0, 1], got " + core::MessageNumber(value), node);
  }
  return value;
}

// Law metal needs an ε_n that a metal's optical constants can give (core/radiometry.h).
void CheckMetal(const YamlReader& reader, const Fields& fields, const SurfaceEmissivity& surface) {
  if (surface.law != core::EmissivityLaw::kMetal ||
      surface.emissivity <= core::MaxMetalNormalEmissivity()) {
    return;
  }
  const std::string limit = core::RoundedNumber(core::MaxMetalNormalEmissivity());
  const std::string why = " for law metal (a metal above it is oxidised or coated and emits "
                          "like a dielectric: use law dielectric)";
  if (fields.Has("emissivity")) {
    reader.Fail(fields.Path("emissivity"),
                "must be <= " + limit + why + ", got " + core::MessageNumber(surface.emissivity),
                fields.NodeFor("emissivity"));
  }
  reader.Fail(fields.Path("law"),
              "metal needs emissivity <= " + limit + ", got " +
                  core::MessageNumber(surface.emissivity) +
                  " from rig.yaml's thermal block (give emissivity here)",
              fields.NodeFor("law"));
}

core::EmissivityLaw ParseLaw(const YamlReader& reader, const YAML::Node& node,
                             const std::string& key) {
  const std::string name = reader.String(node, key);
  const std::optional<core::EmissivityLaw> law = core::ParseEmissivityLaw(name);
  if (!law) reader.Fail(key, "must be dielectric or metal, got " + core::Describe(node), node);
  return *law;
}

Eigen::Vector3d ParseCentre(const YamlReader& reader, const Fields& fields) {
  const YAML::Node& node = fields.Required("centre_m");
  const std::vector<double> c = reader.NumberList(node, fields.Path("centre_m"), 3);
  for (size_t i = 0; i < 3; ++i) {
    if (!(std::abs(c[i]) <= kMaxCoordinateM)) {
      reader.Fail(Indexed(fields.Path("centre_m"), i),
                  "must be in [-1e6, 1e6] m, got " + core::MessageNumber(c[i]), node[i]);
    }
  }
  return {c[0], c[1], c[2]};
}

double ParseLength(const YamlReader& reader, const YAML::Node& node, const std::string& key) {
  const double value = reader.Number(node, key);
  if (!(value > 0 && value <= kMaxCoordinateM)) {
    reader.Fail(key, "must be in (0, 1e6] m, got " + core::MessageNumber(value), node);
  }
  return value;
}

void ParseBox(const YamlReader& reader, const YAML::Node& node, const std::string& key,
              EmissivityRegion* region) {
  const Fields fields = reader.Mapping(node, key, {"centre_m", "size_m", "q_xyzw"});
  region->shape = EmissivityRegion::Shape::kBox;
  region->centre_in_world = ParseCentre(reader, fields);
  const YAML::Node& size = fields.Required("size_m");
  reader.NumberList(size, fields.Path("size_m"), 3);  // shape and numbers, then each value
  for (size_t i = 0; i < 3; ++i) {
    region->half_size_m[static_cast<Eigen::Index>(i)] =
        0.5 * ParseLength(reader, size[i], Indexed(fields.Path("size_m"), i));
  }
  if (fields.Has("q_xyzw")) {
    const YAML::Node& q_node = fields.Required("q_xyzw");
    const std::vector<double> q = reader.NumberList(q_node, fields.Path("q_xyzw"), 4);
    Eigen::Quaterniond rotation(q[3], q[0], q[1], q[2]);
    const double norm = rotation.norm();
    if (!(std::abs(norm - 1) <= kUnitQuaternionTolerance)) {
      reader.Fail(fields.Path("q_xyzw"),
                  "not a unit quaternion (norm " + core::RoundedNumber(norm) + ")", q_node);
    }
    rotation.normalize();
    region->world_from_box = rotation;
  }
}

void ParseSphere(const YamlReader& reader, const YAML::Node& node, const std::string& key,
                 EmissivityRegion* region) {
  const Fields fields = reader.Mapping(node, key, {"centre_m", "radius_m"});
  region->shape = EmissivityRegion::Shape::kSphere;
  region->centre_in_world = ParseCentre(reader, fields);
  region->radius_m =
      ParseLength(reader, fields.Required("radius_m"), fields.Path("radius_m"));
}

bool BoxesOverlap(const EmissivityRegion& a, const EmissivityRegion& b) {
  const Eigen::Matrix3d axes_a = a.world_from_box.toRotationMatrix();
  const Eigen::Matrix3d axes_b = b.world_from_box.toRotationMatrix();
  const Eigen::Vector3d t = b.centre_in_world - a.centre_in_world;
  // Two convex polyhedra are disjoint iff some face normal of either, or the cross product
  // of an edge of each, separates them (Gottschalk, Lin & Manocha, "OBBTree", 1996).
  std::array<Eigen::Vector3d, 15> candidates;
  for (int i = 0; i < 3; ++i) {
    candidates[static_cast<size_t>(i)] = axes_a.col(i);
    candidates[static_cast<size_t>(3 + i)] = axes_b.col(i);
    for (int j = 0; j < 3; ++j) {
      candidates[static_cast<size_t>(6 + 3 * i + j)] = axes_a.col(i).cross(axes_b.col(j));
    }
  }
  for (const Eigen::Vector3d& candidate : candidates) {
    const double norm = candidate.norm();
    if (norm < kParallelCrossNorm) continue;
    const Eigen::Vector3d axis = candidate / norm;
    const double reach_a = (axes_a.transpose() * axis).cwiseAbs().dot(a.half_size_m);
    const double reach_b = (axes_b.transpose() * axis).cwiseAbs().dot(b.half_size_m);
    if (std::abs(t.dot(axis)) - reach_a - reach_b >= -kRegionOverlapToleranceM) return false;
  }
  return true;
}

bool BoxSphereOverlap(const EmissivityRegion& box, const EmissivityRegion& sphere) {
  const Eigen::Vector3d centre_in_box =
      box.world_from_box.conjugate() * (sphere.centre_in_world - box.centre_in_world);
  const Eigen::Vector3d closest =
      centre_in_box.cwiseMax(-box.half_size_m).cwiseMin(box.half_size_m);
  return (centre_in_box - closest).norm() < sphere.radius_m - kRegionOverlapToleranceM;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Regions

double EmissivityRegion::BoundingRadiusM() const {
  return shape == Shape::kBox ? half_size_m.norm() : radius_m;
}

bool EmissivityRegion::Contains(const Eigen::Vector3d& point_in_world) const {
  const Eigen::Vector3d d = point_in_world - centre_in_world;
  if (shape == Shape::kSphere) return d.squaredNorm() <= radius_m * radius_m;
  const Eigen::Vector3d in_box = world_from_box.conjugate() * d;
  return (in_box.cwiseAbs().array() <= half_size_m.array()).all();
}

bool RegionsOverlap(const EmissivityRegion& a, const EmissivityRegion& b) {
  using Shape = EmissivityRegion::Shape;
  if (a.shape == Shape::kBox && b.shape == Shape::kBox) return BoxesOverlap(a, b);
  if (a.shape == Shape::kBox) return BoxSphereOverlap(a, b);
  if (b.shape == Shape::kBox) return BoxSphereOverlap(b, a);
  return (a.centre_in_world - b.centre_in_world).norm() <
         a.radius_m + b.radius_m - kRegionOverlapToleranceM;
}

// ---------------------------------------------------------------------------------------
// EmissivityMap

EmissivityMap::EmissivityMap(const core::ThermalSettings& rig_thermal) {
  assert(rig_thermal.Check().empty() && "rig thermal block");
  default_.emissivity = rig_thermal.emissivity;
  default_.reflected_c = rig_thermal.reflected_c;
  default_.law = core::EmissivityLaw::kDielectric;
  default_.region = -1;
}

const EmissivityRegion& EmissivityMap::region(int i) const {
  assert(i >= 0 && i < num_regions());
  return regions_[static_cast<size_t>(i)];
}

void EmissivityMap::AddRegion(EmissivityRegion region) {
  region.surface.region = num_regions();
  const Eigen::Vector3d& c = region.centre_in_world;
  // Float rounding moves the centre and a query point by <= 2^-24 of their coordinates
  // each (|point| <= |c| + radius for any point that matters); pad by 4x that and 1 µm.
  const double radius = region.BoundingRadiusM();
  const double pad = 2.4e-7 * (2 * c.cwiseAbs().maxCoeff() + radius) * std::sqrt(3.0) + 1e-6;
  bounds_.push_back({static_cast<float>(c.x()), static_cast<float>(c.y()),
                     static_cast<float>(c.z()),
                     static_cast<float>((radius + pad) * (radius + pad))});
  Exact exact;
  exact.box_from_world = region.world_from_box.conjugate().toRotationMatrix();
  exact.centre_in_world = c;
  exact.half_size_m = region.half_size_m;
  exact.radius2_m2 = region.radius_m * region.radius_m;
  exact.is_box = region.shape == EmissivityRegion::Shape::kBox;
  exact_.push_back(exact);
  regions_.push_back(std::move(region));
}

EmissivityMap EmissivityMap::FromLookup(const core::ThermalSettings& rig_thermal, Lookup lookup) {
  EmissivityMap map(rig_thermal);
  map.lookup_ = std::move(lookup);
  return map;
}

SurfaceEmissivity EmissivityMap::At(const Eigen::Vector3f& point_in_world) const {
  if (lookup_) {
    SurfaceEmissivity s = default_;
    return lookup_(point_in_world, s) ? s : default_;
  }
  const float px = point_in_world.x(), py = point_in_world.y(), pz = point_in_world.z();
  for (size_t i = 0; i < bounds_.size(); ++i) {
    const Bound& b = bounds_[i];
    const float dx = px - b.x, dy = py - b.y, dz = pz - b.z;
    if (!(dx * dx + dy * dy + dz * dz <= b.radius2_m2)) continue;  // also skips NaN points
    const Exact& e = exact_[i];
    const Eigen::Vector3d d = point_in_world.cast<double>() - e.centre_in_world;
    const bool inside =
        e.is_box ? ((e.box_from_world * d).cwiseAbs().array() <= e.half_size_m.array()).all()
                 : d.squaredNorm() <= e.radius2_m2;
    if (inside) return regions_[i].surface;
  }
  return default_;
}

EmissivityMap EmissivityMap::Parse(const std::string& yaml_text, const fs::path& path_for_errors,
                                   const core::ThermalSettings& rig_thermal) {
  EmissivityMap map(rig_thermal);
  const YamlReader reader(path_for_errors);
  const YAML::Node root = reader.LoadMapping(yaml_text);
  reader.CheckVersion(root, 1);
  const Fields top = reader.Mapping(root, "", {"version", "default", "regions"});
  top.Required("version");

  if (top.Has("default")) {
    const Fields fields =
        reader.Mapping(top.Required("default"), "default", {"emissivity", "law", "reflected_c", "specular"});
    SurfaceEmissivity& d = map.default_;
    if (fields.Has("emissivity")) {
      d.emissivity = reader.Number(fields.Required("emissivity"), fields.Path("emissivity"));
    }
    if (fields.Has("law")) d.law = ParseLaw(reader, fields.Required("law"), fields.Path("law"));
    if (fields.Has("reflected_c")) {
      d.reflected_c = reader.Number(fields.Required("reflected_c"), fields.Path("reflected_c"));
    }
    if (fields.Has("specular")) d.specular_fraction = ParseSpecular(reader, fields);
    CheckRanges(fields, rig_thermal, d);
    CheckMetal(reader, fields, d);
  }

  if (!top.Has("regions")) return map;
  const YAML::Node& list = top.Required("regions");
  if (!list.IsSequence()) {
    reader.Fail("regions", "must be a list of regions, got " + core::Describe(list), list);
  }
  if (list.size() > static_cast<size_t>(kMaxEmissivityRegions)) {
    reader.Fail("regions",
                "at most " + std::to_string(kMaxEmissivityRegions) + " regions, got " +
                    std::to_string(list.size()),
                list);
  }
  std::map<std::string, int> index_of_name;
  size_t i = 0;
  for (const YAML::Node& node : list) {
    const std::string key = Indexed("regions", i++);
    const Fields fields = reader.Mapping(
        node, key, {"name", "emissivity", "law", "reflected_c", "specular", "box", "sphere"});
    EmissivityRegion region;
    region.line = node.Mark().line + 1;
    const YAML::Node& name = fields.Required("name");
    region.name = reader.String(name, fields.Path("name"));
    if (region.name.empty()) reader.Fail(fields.Path("name"), "must not be empty", name);
    if (const auto it = index_of_name.find(region.name); it != index_of_name.end()) {
      const EmissivityRegion& other = map.regions_[static_cast<size_t>(it->second)];
      reader.Fail(fields.Path("name"),
                  "duplicate region name '" + core::Printable(region.name) + "' (also " +
                      Indexed("regions", static_cast<size_t>(it->second)) + ", line " +
                      std::to_string(other.line) + ")",
                  name);
    }
    SurfaceEmissivity& s = region.surface;
    s.emissivity = reader.Number(fields.Required("emissivity"), fields.Path("emissivity"));
    s.law = fields.Has("law") ? ParseLaw(reader, fields.Required("law"), fields.Path("law"))
                              : core::EmissivityLaw::kDielectric;
    s.reflected_c = fields.Has("reflected_c") ? reader.Number(fields.Required("reflected_c"),
                                                              fields.Path("reflected_c"))
                                              : map.default_.reflected_c;
    if (fields.Has("specular")) s.specular_fraction = ParseSpecular(reader, fields);
    CheckRanges(fields, rig_thermal, s);
    CheckMetal(reader, fields, s);
    if (fields.Has("box") == fields.Has("sphere")) {
      reader.Fail(key,
                  fields.Has("box") ? "has both box and sphere (one shape per region)"
                                    : "needs a shape: box or sphere",
                  node);
    }
    if (fields.Has("box")) {
      ParseBox(reader, fields.Required("box"), fields.Path("box"), &region);
    } else {
      ParseSphere(reader, fields.Required("sphere"), fields.Path("sphere"), &region);
    }
    for (int j = 0; j < map.num_regions(); ++j) {
      const EmissivityRegion& other = map.region(j);
      const double reach = region.BoundingRadiusM() + other.BoundingRadiusM();
      if ((region.centre_in_world - other.centre_in_world).norm() >= reach) continue;
      if (RegionsOverlap(region, other)) {
        reader.Fail(key,
                    "region '" + core::Printable(region.name) + "' overlaps region '" +
                        core::Printable(other.name) + "' (" +
                        Indexed("regions", static_cast<size_t>(j)) + ", line " +
                        std::to_string(other.line) + "); regions must not overlap",
                    node);
      }
    }
    index_of_name.emplace(region.name, map.num_regions());
    map.AddRegion(std::move(region));
  }
  return map;
}

EmissivityMap EmissivityMap::Read(const fs::path& path, const core::ThermalSettings& rig_thermal) {
  return Parse(core::ReadFile(path, core::kMaxConfigFileBytes), path, rig_thermal);
}

}  // namespace hw::reconstruct
