#include "reconstruct/thermal_reflections.h"

#include <algorithm>
#include <cassert>
#include <limits>

#include <Eigen/Geometry>

#include "core/option_check.h"
#include "reconstruct/row_bands.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

std::string ThermalReflectionOptions::Check() const {
  using core::InRange;
  using core::OptionFail;
  if (!InRange(min_specular_weight, 0, 1)) return OptionFail("min_specular_weight", min_specular_weight, "in [0, 1]");
  if (!(max_distance_m > 0) || !std::isfinite(max_distance_m)) {
    return OptionFail("max_distance_m", max_distance_m, "finite and > 0 m");
  }
  if (!(operator_apparent_c > -273.15 && operator_apparent_c < 1000)) {
    return OptionFail("operator_apparent_c", operator_apparent_c, "in (-273.15, 1000) °C");
  }
  if (!(operator_distance_m > 0 && operator_distance_m <= 5)) {
    return OptionFail("operator_distance_m", operator_distance_m, "in (0, 5] m");
  }
  if (!InRange(operator_offset_down_m, -2, 2)) {
    return OptionFail("operator_offset_down_m", operator_offset_down_m, "in [-2, 2] m");
  }
  if (!(operator_half_width_m > 0 && operator_half_width_m <= 2)) {
    return OptionFail("operator_half_width_m", operator_half_width_m, "in (0, 2] m");
  }
  if (!(operator_half_height_m > 0 && operator_half_height_m <= 2)) {
    return OptionFail("operator_half_height_m", operator_half_height_m, "in (0, 2] m");
  }
  return "";
}

double DefaultSpecularFraction(core::EmissivityLaw law) {
  return law == core::EmissivityLaw::kMetal ? 0.9 : 0.2;
}

double SpecularFraction(const SurfaceEmissivity& surface) {
  return std::isnan(surface.specular_fraction) ? DefaultSpecularFraction(surface.law) : surface.specular_fraction;
}

std::optional<double> IntersectOperatorBody(const ThermalReflectionOptions& options,
                                            const core::Rigid3d& world_from_camera,
                                            const Eigen::Vector3d& origin_in_world,
                                            const Eigen::Vector3d& direction_in_world) {
  if (!options.operator_body) return std::nullopt;
  const Eigen::Quaterniond camera_from_world = world_from_camera.rotation.conjugate();
  const Eigen::Vector3d o = camera_from_world * (origin_in_world - world_from_camera.translation);
  const Eigen::Vector3d d = camera_from_world * direction_in_world;
  if (d.z() == 0) return std::nullopt;  // parallel to the body's plane
  const double t = (-options.operator_distance_m - o.z()) / d.z();
  if (!(t > 0)) return std::nullopt;
  const Eigen::Vector3d h = o + t * d;
  const double u = h.x() / options.operator_half_width_m;
  const double v = (h.y() - options.operator_offset_down_m) / options.operator_half_height_m;
  if (u * u + v * v > 1) return std::nullopt;
  return t;
}

OccupiedRegions::OccupiedRegions(const TsdfVolume& volume)
    : region_m_(volume.voxel_size_m() * kBlockSide * TsdfVolume::kRegionBlocks) {
  for (const Eigen::Vector3i& key : volume.RegionKeys()) keys_.insert(internal::PackKey(key.x(), key.y(), key.z()));
}

bool OccupiedRegions::Contains(int x, int y, int z) const { return keys_.contains(internal::PackKey(x, y, z)); }

namespace {

// The distance along origin + t·d at which it leaves the axis-aligned cube [corner, corner +
// size) (world frame, m; the cube holds origin + t·d for the current t).
float ExitCube(const Eigen::Vector3f& origin, const Eigen::Vector3f& d, const int corner[3], float size_m) {
  float exit_t = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) continue;
    const float bound_m = static_cast<float>(corner[a] + (d[a] > 0 ? 1 : 0)) * size_m;
    exit_t = std::min(exit_t, (bound_m - origin[a]) / d[a]);
  }
  return exit_t;
}

}  // namespace

float TraceSurface(const TsdfVolume& volume, TsdfSampler& sampler, const Eigen::Vector3f& origin_in_world,
                   const Eigen::Vector3f& direction_in_world, float start_m, float max_m,
                   const OccupiedRegions* regions) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const float voxel_m = volume.voxel_size_m();
  const float truncation_m = static_cast<float>(volume.options().truncation_m);
  const float half_voxel_m = 0.5f * voxel_m;
  const Eigen::Vector3f d = direction_in_world;
  bool left = false;        // the ray has been in free space since it started
  float previous_sdf = kInf, previous_t = 0;  // the last observed sample (inf: none)
  float t = start_m;
  while (t <= max_m) {
    const Eigen::Vector3f p = origin_in_world + t * d;
    const TsdfSampler::Cell cell = sampler.Locate(p);
    float sdf = 0;
    const TsdfSampler::Status status = sampler.Sample(cell, sdf);
    if (status == TsdfSampler::Status::kNoBlock) {
      // Leave the block whole — the cells whose lowest corner lies in it span voxel
      // coordinates [8b, 8b + 8) on each axis — or its region, when that has no block.
      left = true;
      previous_sdf = kInf;
      const int b[3] = {cell.ix >> kBlockShift, cell.iy >> kBlockShift, cell.iz >> kBlockShift};
      const int r[3] = {b[0] >> 3, b[1] >> 3, b[2] >> 3};
      static_assert(TsdfVolume::kRegionBlocks == 8);
      const float exit_t = regions != nullptr && !regions->Contains(r[0], r[1], r[2])
                               ? ExitCube(origin_in_world, d, r, regions->region_m())
                               : ExitCube(origin_in_world, d, b, voxel_m * kBlockSide);
      t = std::max(exit_t + 1e-4f, t + 1e-4f);
      continue;
    }
    if (status == TsdfSampler::Status::kUnobserved) {
      left = true;
      previous_sdf = kInf;
      t += voxel_m;
      continue;
    }
    if (left && previous_sdf > 0 && previous_sdf != kInf && sdf < 0) {
      return previous_t + (t - previous_t) * previous_sdf / (previous_sdf - sdf);
    }
    if (sdf >= 0.5f) left = true;
    previous_sdf = sdf;
    previous_t = t;
    // sdf is in units of the band of the readings fused there, at least truncation_m: the
    // block's narrowest band bounds the distance to the surface (VoxelBlock::min_band_m) when
    // the cell lies inside the block, as the raycast steps (RaycastOptions::band_steps).
    constexpr int m = kBlockSide - 1;
    const bool inside = ((cell.ix & m) < m) & ((cell.iy & m) < m) & ((cell.iz & m) < m);
    const float band_m = inside ? std::max(cell.block->min_band_m, truncation_m) : truncation_m;
    t += std::max(sdf * band_m, half_voxel_m);
  }
  return kInf;
}

std::vector<PixelReflection> ReflectPixels(const TsdfVolume& volume, const PointMap& map,
                                           const Eigen::Vector3f& camera_in_world,
                                           const EmissivityMap& emissivity,
                                           const ThermalReflectionOptions& options, float min_cos_angle,
                                           int num_threads, int* traced) {
  std::vector<PixelReflection> pixels(map.points.size());
  const int height = map.height, width = map.width;
  const int threads = std::max(1, std::min(ResolveThreads(num_threads), height));
  std::vector<int> traced_by(threads, 0);
  const float start_m = 1.5f * volume.voxel_size_m();
  const float max_m = static_cast<float>(options.max_distance_m);
  const OccupiedRegions regions(volume);
  internal::RunChunks(threads, [&](int chunk) {
    TsdfSampler sampler(volume);
    // Rows interleaved: the pixels that need a mirror ray cluster (a metal panel, a grazing
    // floor), and contiguous bands would leave one thread all of them.
    for (int y = chunk; y < height; y += threads) {
      for (int x = 0; x < width; ++x) {
        const size_t i = map.Index(x, y);
        if (!IsValid(map.points[i]) || !IsValid(map.normals[i])) continue;
        PixelReflection& pixel = pixels[i];
        pixel.surface = emissivity.At(map.points[i]);
        const Eigen::Vector3f ray = (map.points[i] - camera_in_world).normalized();
        const float cos_angle = -ray.dot(map.normals[i]);
        pixel.emissivity_at_angle = static_cast<float>(
            core::DirectionalEmissivity(pixel.surface.law, pixel.surface.emissivity, std::clamp(cos_angle, 0.0f, 1.0f)));
        // Rays beyond the largest angle fused get no confidence (c3 = 0): no mirror ray either.
        if (!options.trace || cos_angle < min_cos_angle || cos_angle <= 0) continue;
        const double weight = (1 - static_cast<double>(pixel.emissivity_at_angle)) * SpecularFraction(pixel.surface);
        if (weight < options.min_specular_weight || weight <= 0) continue;
        pixel.mirror_m = TraceSurface(volume, sampler, map.points[i], MirrorDirection(ray, map.normals[i]), start_m, max_m, &regions);
        ++traced_by[chunk];
      }
    }
  });
  if (traced) {
    *traced = 0;
    for (int n : traced_by) *traced += n;
  }
  return pixels;
}

}  // namespace hw::reconstruct
