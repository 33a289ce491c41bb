#pragma once

// Reflections traced on the model. A surface of directional emissivity ε(θ) sends the camera
// ε(θ)·L(T_s) plus 1 − ε(θ) of what it reflects. The correction used to take that reflection
// as one uniform surrounding (rig.yaml's or the emissivity file's reflected_c) — right for the
// diffuse part of the reflectance, wrong for its mirror part, which shows one direction: the
// operator's body behind the camera (the thermographer's classic false warm spot on polished
// metal seen head-on) or a hot pipe mirrored in cladding. The model knows the surface's normal
// and the camera's pose, so the mirror ray can be followed:
//   L_reflected = (1 − s)·L(T_room) + s·L_mirror,
// s the specular fraction of the reflectance (SurfaceEmissivity::specular_fraction, by law by
// default), L_mirror what the mirror ray meets first: the operator's body (an upright
// ellipse fixed behind the camera, radiating L(operator_apparent_c)), a model surface (its
// reading in this frame where the frame sees it, else its fused apparent temperature so far),
// or, where it meets nothing with a temperature, the room. Only the fusion's inline part may
// read the volume (ThermalFusionOptions::background), so TraceMirrorRays marches the mirror
// rays there and the background stage looks their sources up.

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <absl/container/flat_hash_set.h>

#include "core/radiometry.h"
#include "core/transform.h"
#include "reconstruct/camera_maps.h"
#include "reconstruct/emissivity_map.h"
#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct {

struct ThermalReflectionOptions {
  // false: the uniform surrounding everywhere (the correction before reflections were traced).
  bool trace = true;
  // A mirror ray is followed only where the specular weight (1 − ε(θ))·s reaches this; below
  // it the uniform surrounding stands in, at an error of at most the weight times the
  // reflected scene's contrast over ε. 0.05: every bare metal (s = 0.9, 1 − ε >= 0.5) and
  // gloss, and paint (s = 0.2) only beyond ~78°, where ε(θ) has fallen to 0.75; paint seen
  // at 60–78° then errs by up to 0.05 × contrast / ε — 0.6 K for a person 12 K over the
  // room, 2 K where it mirrors a 40 K hotter motor — on rays the angle term already weighs
  // at cos θ <= 0.5. Measured (README, Reflections traced on the model): on a 4 s
  // full-size sweep 0.02 traced 440 k mirror rays and 0.05 35 k, for 0.337 vs 0.338 K;
  // with the rig's one emissivity 0.02 cost 12 % of the whole pipeline's rate for no change
  // in the error. [0, 1].
  double min_specular_weight = 0.05;
  // Mirror rays end this far from the surface, m, > 0 (beyond it: the room).
  double max_distance_m = 5.0;
  // The operator's body: an upright ellipse (head and torso as one shape) facing the camera,
  // fixed in the camera frame (x right, y down, z forward) at z = −operator_distance_m,
  // centred operator_offset_down_m below the optical axis, semi-axes operator_half_width_m
  // (x) and operator_half_height_m (y). Defaults: an adult holding the rig at the chest —
  // shoulders 0.4 m wide, head to hips 0.7 m, the lens 0.4 m in front of the body, its axis
  // near the sternum. Clothing and skin read 28–34 °C to a thermal camera; 32 °C.
  bool operator_body = true;
  double operator_apparent_c = 32;       // °C, (−273.15, 1000)
  double operator_distance_m = 0.4;      // m, (0, 5]
  double operator_offset_down_m = 0.15;  // m, |·| <= 2
  double operator_half_width_m = 0.2;    // m, (0, 2]
  double operator_half_height_m = 0.35;  // m, (0, 2]

  std::string Check() const;  // "" or the field, its value and the constraint
};

// The specular fraction s of a law's reflectance when the emissivity file gives none: bare
// metals are near-mirrors in the long-wave infrared, their roughness far below the 8–14 µm
// wavelength (0.9); paints, plaster, masonry and plastics scatter most of their small
// reflectance diffusely (0.2: between matt and semi-gloss paint).
double DefaultSpecularFraction(core::EmissivityLaw law);
// surface.specular_fraction, or the law's default where it is NaN.
double SpecularFraction(const SurfaceEmissivity& surface);

// The mirror image of the unit direction d about the unit normal n: d − 2 (d·n) n.
inline Eigen::Vector3f MirrorDirection(const Eigen::Vector3f& d, const Eigen::Vector3f& n) {
  return d - 2.0f * d.dot(n) * n;
}

// Distance (m) along the unit ray origin + t·direction (world frame), t > 0, to the
// operator's ellipse for a camera at world_from_camera; nullopt when the ray misses it or
// options.operator_body is false.
std::optional<double> IntersectOperatorBody(const ThermalReflectionOptions& options,
                                            const core::Rigid3d& world_from_camera,
                                            const Eigen::Vector3d& origin_in_world,
                                            const Eigen::Vector3d& direction_in_world);

// The regions of a volume that hold blocks (TsdfVolume::RegionKeys), for leaving empty space
// 32 cm at a time. A snapshot: rebuild it after the volume gains blocks.
class OccupiedRegions {
 public:
  explicit OccupiedRegions(const TsdfVolume& volume);
  bool Contains(int x, int y, int z) const;  // region key (block key >> 3)
  float region_m() const { return region_m_; }

 private:
  absl::flat_hash_set<uint64_t> keys_;
  float region_m_;
};

// Distance (m) along the unit ray origin + t·direction (world frame) to the first surface the
// volume has in front of it — a zero crossing of the trilinear sdf from + to −, refined
// linearly — for t in [start_m, max_m]; +inf when none. A crossing counts only after the ray
// has been in free space (sdf >= 0.5, or outside the observed voxels), so that a ray leaving
// a surface at a grazing angle does not find that surface again in its own noise. Steps:
// absent blocks are left whole (and regions without blocks, given `regions`: a 5 m ray then
// looks up ~16 regions rather than ~125 blocks), observed cells by max(sdf · band_m, half a
// voxel), band_m the block's narrowest band (VoxelBlock::min_band_m, at least truncation_m)
// where the cell lies inside one block, else truncation_m.
float TraceSurface(const TsdfVolume& volume, TsdfSampler& sampler, const Eigen::Vector3f& origin_in_world,
                   const Eigen::Vector3f& direction_in_world, float start_m, float max_m,
                   const OccupiedRegions* regions = nullptr);

// What the correction needs of each pixel of a thermal raycast: the emissivity at its hit,
// the directional emissivity there, and how far its mirror ray went.
struct PixelReflection {
  SurfaceEmissivity surface;
  float emissivity_at_angle = 0;  // ε(θ) of the hit; 0 where the pixel has no hit or normal
  // Distance from the hit along the mirror ray to the first model surface, m: NaN where the
  // ray was not traced (no hit or normal, weight below min_specular_weight, trace off), +inf
  // where it met none within max_distance_m.
  float mirror_m = std::numeric_limits<float>::quiet_NaN();
};

// For every pixel of `map` (a raycast from a camera centred at camera_in_world) with a hit
// and a normal: its emissivity (emissivity.At), ε(θ) at the angle between its ray and normal,
// and — where options.trace, cos θ >= min_cos_angle (the fusion's largest angle: rays beyond
// it are not fused) and (1 − ε(θ))·s >= min_specular_weight — the distance along its mirror
// ray to the model (TraceSurface from 1.5 voxels off the hit). Reads the volume: call
// where it may be read (not beside an integration). Rows dealt to num_threads threads in turn.
// *traced receives the number of mirror rays marched.
std::vector<PixelReflection> ReflectPixels(const TsdfVolume& volume, const PointMap& map,
                                           const Eigen::Vector3f& camera_in_world,
                                           const EmissivityMap& emissivity,
                                           const ThermalReflectionOptions& options, float min_cos_angle,
                                           int num_threads, int* traced);

}  // namespace hw::reconstruct
