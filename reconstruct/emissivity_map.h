#pragma once

#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/radiometry.h"
#include "core/rig.h"

// The user's emissivity file: which normal emissivity, directional law and reflected
// apparent temperature hold where in the model's world frame, for correcting thermal
// observations (apparent -> surface temperature). Format (README, "Emissivity file"):
//
//   version: 1
//   default: { emissivity: 0.95, law: dielectric, reflected_c: 21.0 }   # optional
//   regions:                                                              # optional
//     - name: motor-boss
//       emissivity: 0.30
//       law: metal                  # optional, dielectric | metal, default dielectric
//       specular: 0.9               # optional, mirror share of the reflectance, [0, 1]
//       reflected_c: 25.0           # optional, default: the default block's
//       box: { centre_m: [0.41, -0.12, 1.85], size_m: [0.2, 0.1, 0.1], q_xyzw: [0, 0, 0, 1] }
//     - name: pipe-tape
//       emissivity: 0.97
//       sphere: { centre_m: [0.1, 0.2, 1.5], radius_m: 0.05 }
//
// Keys of `default` left out come from rig.yaml's thermal block (its law: dielectric); a
// block without `specular` (default or region) takes its own law's.
// Regions must not overlap, so that no point's emissivity depends on the order of the list.

namespace hw::reconstruct {

// What the correction assumes at one surface point.
struct SurfaceEmissivity {
  double emissivity = 0.95;  // normal emissivity, [ThermalSettings::kMinEmissivity, 1]
  core::EmissivityLaw law = core::EmissivityLaw::kDielectric;
  double reflected_c = 20;   // reflected apparent temperature, °C
  // The share of the reflectance (1 − ε) that is mirror-like, [0, 1]; the rest is diffuse,
  // the uniform surrounding at reflected_c (thermal_reflections.h). NaN: the law's default
  // (DefaultSpecularFraction: metal 0.9, dielectric 0.2).
  double specular_fraction = std::numeric_limits<double>::quiet_NaN();
  int region = -1;           // index of the region, -1 = the default
};

// Regions whose interiors overlap by less than this (metres) count as touching. The file's
// numbers are rounded decimals: a quaternion written to 7 digits moves the corner of a 1 m
// box by ~1e-7 m, so boxes meant to share a face may "overlap" by that. 1 µm is far below
// any model's voxel (mm), so no lookup can notice it.
inline constexpr double kRegionOverlapToleranceM = 1e-6;
// At most this many regions: At() tests them in a flat list (~1–2 ns each), so 1000
// regions would cost ~1 µs per thermal ray (0.1 s per 1e5-ray frame).
inline constexpr int kMaxEmissivityRegions = 1000;

// One region of the file, a closed box or ball in the world frame (metres).
struct EmissivityRegion {
  enum class Shape { kBox, kSphere };

  std::string name;
  int line = 0;                 // 1-based line of the region in its file (for messages)
  SurfaceEmissivity surface;    // surface.region = this region's index
  Shape shape = Shape::kSphere;
  Eigen::Vector3d centre_in_world = Eigen::Vector3d::Zero();                // m
  Eigen::Quaterniond world_from_box = Eigen::Quaterniond::Identity();      // box, unit
  Eigen::Vector3d half_size_m = Eigen::Vector3d::Zero();  // box: half edge lengths, > 0
  double radius_m = 0;                                    // sphere, > 0

  // Radius of the smallest ball about centre_in_world that holds the region, m.
  double BoundingRadiusM() const;
  // True for points inside or on the boundary.
  bool Contains(const Eigen::Vector3d& point_in_world) const;
};

// True when the interiors of a and b intersect deeper than kRegionOverlapToleranceM (exact
// tests: separating axes for two boxes, the box's closest point to the centre for a box and
// a sphere, the centre distance for two spheres). Touching regions do not overlap.
bool RegionsOverlap(const EmissivityRegion& a, const EmissivityRegion& b);

class EmissivityMap {
 public:
  // The whole scene at the rig's thermal block values (emissivity, reflected_c),
  // dielectric. Asserts rig_thermal.Check() is empty (rig.yaml readers check it).
  explicit EmissivityMap(const core::ThermalSettings& rig_thermal);

  // Reads the file; defaults missing from it come from rig_thermal. Throws
  // core::InputError naming the file, the key (e.g. "regions[2].emissivity") and the line:
  // unknown or missing keys, a version other than 1, emissivity or reflected_c outside
  // ThermalSettings' ranges, specular outside [0, 1], size_m/radius_m <= 0, a quaternion whose norm is off 1 by more
  // than 1e-6 (smaller errors are normalised), an unknown law, law metal with emissivity
  // above core::MaxMetalNormalEmissivity() (no metal has optical constants for it: an
  // oxidised or painted metal emits like a dielectric), a region with neither or both of
  // box and sphere, an empty or duplicate name, more than kMaxEmissivityRegions regions,
  // overlapping regions (naming both and their lines). Plus ReadFile's and
  // YamlReader::LoadMapping's errors (unreadable, over 1 MiB, YAML syntax).
  static EmissivityMap Read(const std::filesystem::path& path,
                            const core::ThermalSettings& rig_thermal);
  // Read() on the file's text; path_for_errors only names it in messages.
  static EmissivityMap Parse(const std::string& yaml_text,
                             const std::filesystem::path& path_for_errors,
                             const core::ThermalSettings& rig_thermal);

  // Emissivity from a lookup the caller provides (a material map, a synthetic scan's truth
  // mesh): At() returns what lookup fills (its reflected_c and region as given) when it
  // returns true, else the rig's default. lookup is called from several threads at once.
  using Lookup = std::function<bool(const Eigen::Vector3f& point_in_world, SurfaceEmissivity& out)>;
  static EmissivityMap FromLookup(const core::ThermalSettings& rig_thermal, Lookup lookup);

  // The emissivity at a world point (metres): the region containing it (closed; a point on
  // the boundary two touching regions share gets the one listed first), else the default.
  // Flat list with bounding-sphere rejection; see emissivity_map_test.cc's timing output.
  SurfaceEmissivity At(const Eigen::Vector3f& point_in_world) const;

  const SurfaceEmissivity& default_surface() const { return default_; }
  int num_regions() const { return static_cast<int>(regions_.size()); }
  const std::string& region_name(int i) const { return region(i).name; }
  const EmissivityRegion& region(int i) const;

 private:
  // At()'s rejection test, 16 bytes per region so that the scan over all regions stays in
  // cache: the bounding ball in float, its radius padded to cover the float rounding of
  // the centre and of the query point.
  struct Bound {
    float x, y, z;     // centre, m
    float radius2_m2;  // squared padded bounding radius
  };
  // The exact test of a region that passed the bound, in double.
  struct Exact {
    Eigen::Matrix3d box_from_world;
    Eigen::Vector3d centre_in_world;
    Eigen::Vector3d half_size_m;  // box
    double radius2_m2;            // sphere: squared radius
    bool is_box;
  };
  void AddRegion(EmissivityRegion region);

  SurfaceEmissivity default_;
  std::vector<EmissivityRegion> regions_;
  Lookup lookup_;  // FromLookup
  std::vector<Bound> bounds_;
  std::vector<Exact> exact_;
};

}  // namespace hw::reconstruct
