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

float TraceSurface(const TsdfVolume& volume, TsdfSampler& sampler, const Eigen::Vector3f& origin_in_world,
                   const Eigen::Vector3f& direction_in_world, float start_m, float max_m) {
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
      // Leave the block whole: the cells whose lowest corner lies in it span voxel
      // coordinates [8b, 8b + 8) on each axis.
      left = true;
      previous_sdf = kInf;
      float exit_t = kInf;
      const int b[3] = {cell.ix >> kBlockShift, cell.iy >> kBlockShift, cell.iz >> kBlockShift};
      for (int a = 0; a < 3; ++a) {
        if (d[a] == 0) continue;
        const float bound_m = static_cast<float>((b[a] + (d[a] > 0 ? 1 : 0)) * kBlockSide) * voxel_m;
        exit_t = std::min(exit_t, (bound_m - origin_in_world[a]) / d[a]);
      }
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
    t += std::max(sdf * truncation_m, half_voxel_m);
  }
  return kInf;
}

std::vector<PixelReflection> ReflectPixels(const TsdfVolume& volume, const PointMap& map,
                                           const Eigen::Vector3f& camera_in_world,
                                           const EmissivityMap& emissivity,
                                           const ThermalReflectionOptions& options, int num_threads,
                                           int* traced) {
  std::vector<PixelReflection> pixels(map.points.size());
  const int height = map.height, width = map.width;
  const int threads = std::max(1, std::min(ResolveThreads(num_threads), height));
  std::vector<int> traced_by(threads, 0);
  const float start_m = 1.5f * volume.voxel_size_m();
  const float max_m = static_cast<float>(options.max_distance_m);
  internal::RunChunks(threads, [&](int chunk) {
    TsdfSampler sampler(volume);
    for (int y = chunk * height / threads; y < (chunk + 1) * height / threads; ++y) {
      for (int x = 0; x < width; ++x) {
        const size_t i = map.Index(x, y);
        if (!IsValid(map.points[i]) || !IsValid(map.normals[i])) continue;
        PixelReflection& pixel = pixels[i];
        pixel.surface = emissivity.At(map.points[i]);
        const Eigen::Vector3f ray = (map.points[i] - camera_in_world).normalized();
        const float cos_angle = -ray.dot(map.normals[i]);
        pixel.emissivity_at_angle = static_cast<float>(
            core::DirectionalEmissivity(pixel.surface.law, pixel.surface.emissivity, std::clamp(cos_angle, 0.0f, 1.0f)));
        if (!options.trace || cos_angle <= 0) continue;
        const double weight = (1 - static_cast<double>(pixel.emissivity_at_angle)) * SpecularFraction(pixel.surface);
        if (weight < options.min_specular_weight || weight <= 0) continue;
        pixel.mirror_m = TraceSurface(volume, sampler, map.points[i], MirrorDirection(ray, map.normals[i]), start_m, max_m);
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
