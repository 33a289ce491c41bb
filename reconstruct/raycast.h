#pragma once

// Raycasting the TSDF: the model surface as a camera at a given pose would see it, for
// frame-to-model tracking (ICP against the fused model rather than the last noisy frame) and
// for laying temperature onto the model.

#include <span>
#include <string>
#include <vector>

#include "core/transform.h"
#include "reconstruct/camera_maps.h"
#include "reconstruct/camera_rays.h"
#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct {

struct RaycastOptions {
  double min_depth_m = 0.3;  // rays start here (along the optical axis), m, >= 0
  double max_depth_m = 4.0;  // ... and end here, m, > min_depth_m
  // March step inside the truncation band, as a fraction of truncation_m, in (0, 1]. Rays
  // skip absent blocks whole; inside allocated ones they step by max(sdf, this) · truncation.
  double step_fraction = 0.5;
  // Step by each block's narrowest band instead of truncation_m: a far reading's sdf is in
  // units of its wider band (TsdfOptions::TruncationAt: 7.8 cm at 4 m at the defaults), so a
  // ray approaching a surface fused only from far covers the distance in a step or two
  // rather than closing it a quarter band at a time. VoxelBlock::min_band_m bounds the
  // distance (as truncation_m does, with less margin); a cell across blocks takes the
  // narrowest of theirs. The map is the same surfaces, refined to the same tolerance (the
  // bracketing samples differ); false: every step in units of truncation_m (for comparison).
  bool band_steps = true;
  bool with_colour = false;  // also fill PointMap::colours (black where none)
  int num_threads = 0;       // 0: hardware concurrency; coarse chunks as TsdfOptions

  std::string Check() const;
};

// Casts one ray per pixel of `camera` placed at world_from_camera and returns, per pixel,
// the first zero crossing from + to − of the trilinearly interpolated sdf (refined by linear
// interpolation between the two samples around it) as a world point, the surface normal
// there (TsdfVolume::NormalAt) and, with with_colour, its colour. Pixels whose ray meets no
// surface, or meets one from behind (− to +), are invalid. A nearest-voxel raycast would bias
// depth by up to half a voxel and make frame-to-model tracking drift: interpolation is required.
// Details (raycast.cc): rays only span the depths where allocated blocks project (per 8×8
// pixel tile); the crossing is refined by regula falsi on the trilinear field (to 0.005 of
// truncation_m); rows of tiles are dealt to num_threads threads, each marching eight rays
// in turn with their next samples prefetched (the map does not depend on either). A point
// may have an invalid normal where the 32 voxels of NormalAt are not all observed (rim of
// the observed surface).
PointMap Raycast(const TsdfVolume& volume, const PinholeCamera& camera,
                 const core::Rigid3d& world_from_camera, const RaycastOptions& options);

// Raycast (same contract as the pinhole overload) with one ray per pixel of rays.camera(): the
// map has that camera's size, pixel (x, y) holds the first surface along rays.xy(x, y) (the
// exact ray of its centre through the lens model, not an undistorted resampling); pixels
// without a ray (!rays.valid) are invalid. A pixel's depth range is that of the tile of
// rays.covering_pinhole() its undistorted projection falls in; pixels are marched in 8×8
// tiles of the distorted image. For a model without distortion the map equals the pinhole
// overload's on PinholeCamera::Of(rays.camera()) bit for bit. A default CameraRays gives an
// empty (0 × 0) map.
PointMap Raycast(const TsdfVolume& volume, const CameraRays& rays,
                 const core::Rigid3d& world_from_camera, const RaycastOptions& options);

// Where each pixel's surface is expected (the thermal fusion's live depth warped into its
// view), so that its ray need not march the space in front of it.
struct RayHints {
  // Per pixel of the map (row-major): the expected range, m from the camera centre along the
  // pixel's ray; not finite or <= 0 where there is none.
  std::span<const float> range_m;
  // The window searched first runs from the volume's band in front of the hint (the
  // half-width a reading there is fused over, TsdfOptions::TruncationAt: where its noise puts
  // the surface) to max(behind_m, behind_fraction · range) behind it, m.
  float behind_m = 0.1f;
  float behind_fraction = 0.05f;
};

// The CameraRays Raycast that first marches each hinted pixel's ray over its window (within
// [min_depth_m, max_depth_m]) and keeps the first surface met there from the front; pixels
// without a hint, or whose window holds none, are cast as by the overload above. Beyond the
// refinement's tolerance (the two marches bracket a crossing with different samples: < 1 mm
// within 60° of the normal, tested) the map therefore differs from that overload's only
// where the model has a surface in front of the window as well as one inside it: what the
// live view no longer shows (moved away, or a model artefact), which this keeps out.
// Marching from the window instead of the nearest block over an 8×8 tile took a hinted
// thermal ray from 22 samples to ~4 late in a 4 s sweep (all rays: ~11), the raycast from
// 55 to 42 ms (README, *Temperature on the model*). hints.range_m must hold rays.width() ·
// rays.height() values (asserted).
PointMap Raycast(const TsdfVolume& volume, const CameraRays& rays, const core::Rigid3d& world_from_camera,
                 const RaycastOptions& options, const RayHints& hints);

namespace internal {

// The depth ranges rays are marched over (raycast.cc), exposed for tests: per tile of
// tile × tile pixels (row-major, tiles_x × tiles_y), the nearest and farthest depth (m, along
// the optical axis, clamped to [min_depth_m, max_depth_m]) of the allocated blocks whose
// projection covers it; near > far where none does. With cull_regions, only the blocks of
// regions in view are projected (TsdfVolume::ForEachBlockInRegions): the same ranges at a
// cost independent of the map's size outside the view. The blocks are projected on up to
// num_threads threads (0: hardware concurrency); the ranges do not depend on it.
struct DepthRanges {
  int tile = 0, tiles_x = 0, tiles_y = 0;
  std::vector<float> near_m, far_m;
};
DepthRanges ProjectBlocks(const TsdfVolume& volume, const PinholeCamera& camera,
                          const core::Rigid3d& world_from_camera, float min_depth_m, float max_depth_m,
                          bool cull_regions, int num_threads = 1);

}  // namespace internal

}  // namespace hw::reconstruct
