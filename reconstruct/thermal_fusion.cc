#include "reconstruct/thermal_fusion.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

#include <Eigen/Geometry>
#include <absl/container/flat_hash_map.h>

#include "core/option_check.h"
#include "core/strings.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

double Ms(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// One region (voxel): every method's state side by side (thermal_fusion.h). 'Surface' is the
// emissivity-corrected temperature, 'apparent' the camera's reading.
struct Region {
  // Latest observation.
  float latest_surface_c = kNaN, latest_apparent_c = kNaN, latest_confidence = 0;
  // Plain mean (Welford, so that the spread of tens of views at ~300 K stays exact in float).
  uint16_t views = 0;
  float mean_surface_c = 0, mean_apparent_c = 0, mean_confidence = 0, m2_surface = 0;
  // voxblox's capped running mean.
  float capped_surface_c = 0, capped_apparent_c = 0, capped_weight = 0;
  // The paper's online rule (confidence < 0: not yet observed).
  float online_surface_c = kNaN, online_apparent_c = kNaN, online_confidence = -1;
  // Offline robust estimate (Finish).
  uint16_t offline_views = 0;
  float offline_surface_c = kNaN, offline_apparent_c = kNaN, offline_confidence = 0,
        offline_std_c = kNaN;
};

// One region's merged observation in one frame, kept for the offline estimate.
struct Record {
  int32_t region;
  float surface_c, apparent_c, confidence;
};

// Accumulates a frame's rays per region before the update rules run once per region and
// frame: several rays of one frame are one view, not several.
struct FrameSum {
  float weight = 0, weight_confidence = 0, surface = 0, apparent = 0;
};

// A fused ray, ready to splat: its hit and the half-axes of its pixel's footprint on the
// surface (world frame, m): across the ray, distance / f; along the surface's slope, that
// divided by cos θ.
struct Ray {
  Eigen::Vector3f point_in_world;
  Eigen::Vector3f footprint_u, footprint_v;
  float confidence, surface_c, apparent_c;
};

// A growable array whose elements never move: chunks of 2^kShift value-initialised
// elements. A std::vector of regions (~700k, 50 MB on a 2 s scan) copied itself on every
// doubling, faulting the new copy's pages in: a quarter of the fusion's time on that scan.
template <class T, int kShift>
class ChunkedVector {
 public:
  T& operator[](size_t i) { return chunks_[i >> kShift][i & kMask]; }
  const T& operator[](size_t i) const { return chunks_[i >> kShift][i & kMask]; }
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  // Appends a value-initialised element; returns its index.
  size_t Grow() {
    if ((size_ >> kShift) == chunks_.size()) chunks_.push_back(std::make_unique<T[]>(kChunk));
    return size_++;
  }
  size_t CapacityBytes() const { return chunks_.size() * kChunk * sizeof(T); }

 private:
  static constexpr size_t kChunk = size_t{1} << kShift, kMask = kChunk - 1;
  std::vector<std::unique_ptr<T[]>> chunks_;
  size_t size_ = 0;
};

// The region slots of one block's voxels (region index, -1: none yet).
struct BlockRegions {
  std::array<int32_t, kBlockVoxels> slot;
  BlockRegions() { slot.fill(-1); }
};

// One thread's share of Impl::ShadeRays.
struct ShadePart {
  std::vector<Ray> rays;
  int hits = 0, low_confidence = 0, no_normal = 0, no_surface = 0;
  double confidence_sum = 0;
  void Clear() {
    rays.clear();
    hits = low_confidence = no_normal = no_surface = 0;
    confidence_sum = 0;
  }
};

// One splat of a ray (Impl::Splat).
struct SplatRef {
  int32_t i, j, k;  // voxel
  int32_t ray;      // index in the frame's fused rays
  int32_t region;   // < 0: to be created (-1) or outside the key range (-2)
  float share;      // 1 / splats of the ray
};

// Splats per footprint axis at most: a ray whose footprint spans more voxels (a grazing view
// from afar) covers its centre 8 voxels wide and leaves the rest to its neighbours' rays.
constexpr int kMaxFootprintSplats = 8;

}  // namespace

std::string ThermalFusionOptions::Check() const {
  using core::OptionFail;
  using core::InRange;
  if (std::string e = confidence.Check(); !e.empty()) return "confidence." + e;
  if (std::string e = offline.Check(); !e.empty()) return "offline." + e;
  if (!InRange(recency_bias, 0, 1)) return OptionFail("recency_bias", recency_bias, "in [0, 1]");
  if (!(capped_mean_max_weight >= 1) || !std::isfinite(capped_mean_max_weight)) {
    return OptionFail("capped_mean_max_weight", capped_mean_max_weight, "finite and >= 1");
  }
  if (!(min_ray_confidence >= 0 && min_ray_confidence < 1)) {
    return OptionFail("min_ray_confidence", min_ray_confidence, "in [0, 1)");
  }
  if (!(max_pose_gap_s > 0) || !std::isfinite(max_pose_gap_s)) {
    return OptionFail("max_pose_gap_s", max_pose_gap_s, "finite and > 0 s");
  }
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return OptionFail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return OptionFail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (!(vignetting >= 0 && vignetting < 1)) return OptionFail("vignetting", vignetting, "in [0, 1)");
  if (num_threads < 0) return OptionFail("num_threads", num_threads, ">= 0");
  return "";
}

std::string ThermalFrameStatusName(ThermalFrameStatus status) {
  switch (status) {
    case ThermalFrameStatus::kFused: return "fused";
    case ThermalFrameStatus::kNoPose: return "no-pose";
    case ThermalFrameStatus::kFrozen: return "frozen";
    case ThermalFrameStatus::kNoSurface: return "no-surface";
  }
  return "?";
}

struct ThermalFusion::Impl {
  core::Rig rig;
  ThermalFusionOptions options;
  EmissivityMap emissivity;
  std::vector<double> ffc_timestamps_s;
  core::BandRadiance band;
  CameraRays rays;
  std::vector<float> distortion_confidence;  // c2 per pixel (fixed for the camera)
  int num_rays = 0;                          // pixels with a ray through the lens model
  std::vector<float> vignetting_gain;        // 1 − v·r² per pixel; empty without vignetting
  float voxel_m = 0;

  // Regions: blocks of kBlockVoxels slots (region index or -1), keyed like the TSDF's.
  absl::flat_hash_map<uint64_t, int32_t> block_index;  // SwissTable, as the TSDF's index
  ChunkedVector<BlockRegions, 8> blocks;  // 512 KB chunks
  ChunkedVector<Region, 16> regions;       // 4.7 MB chunks
  ChunkedVector<FrameSum, 16> frame_sums;  // per region, zero between frames
  // Per fused frame (and thread of Splat), its region observations: chunks, so that keeping
  // them never copies what is already kept (one vector would move gigabytes each time it grows).
  std::vector<std::vector<Record>> records;
  size_t num_records = 0;
  std::vector<ThermalFrameRecord> frames;
  // Scratch of ShadeRays and Splat, kept between frames: fresh buffers each frame cost more
  // in page faults than the work they hold (measured: half of Splat's time).
  std::vector<ShadePart> shade_scratch;
  std::vector<Ray> fused_scratch;
  std::vector<std::vector<SplatRef>> splat_scratch;
  cv::Mat previous_image;
  bool finished = false;
  int64_t offline_rejected = 0;

  Impl(const core::Rig& r, const ThermalFusionOptions& o, EmissivityMap e, std::vector<double> ffc)
      : rig(r), options(o), emissivity(std::move(e)), ffc_timestamps_s(std::move(ffc)),
        band(r.thermal_settings->spectral_band_um[0], r.thermal_settings->spectral_band_um[1]),
        rays(*r.thermal) {}

  // Region of voxel (i, j, k); creates it when `create`. -1 when absent (or out of range).
  int32_t RegionOf(int i, int j, int k, bool create, uint64_t& cached_key, int32_t& cached_block) {
    if (!internal::KeyInRange(i >> kBlockShift, j >> kBlockShift, k >> kBlockShift)) return -1;
    const uint64_t key = internal::PackKey(i >> kBlockShift, j >> kBlockShift, k >> kBlockShift);
    if (key != cached_key || cached_block < 0) {
      auto it = block_index.find(key);
      if (it == block_index.end()) {
        if (!create) return -1;
        it = block_index.emplace(key, static_cast<int32_t>(blocks.Grow())).first;
      }
      cached_key = key;
      cached_block = it->second;
    }
    const int slot = (i & (kBlockSide - 1)) + kBlockSide * ((j & (kBlockSide - 1)) + kBlockSide * (k & (kBlockSide - 1)));
    int32_t& region = blocks[cached_block].slot[slot];
    if (region < 0 && create) {
      region = static_cast<int32_t>(regions.Grow());
      frame_sums.Grow();
    }
    return region;
  }

  // The region of voxel (i, j, k), or -1 (RegionOf without creating, for readers).
  int32_t FindRegion(int i, int j, int k, uint64_t& cached_key, int32_t& cached_block) const {
    if (!internal::KeyInRange(i >> kBlockShift, j >> kBlockShift, k >> kBlockShift)) return -1;
    const uint64_t key = internal::PackKey(i >> kBlockShift, j >> kBlockShift, k >> kBlockShift);
    if (key != cached_key || cached_block < 0) {
      const auto it = block_index.find(key);
      if (it == block_index.end()) return -1;
      cached_key = key;
      cached_block = it->second;
    }
    return blocks[cached_block].slot[(i & (kBlockSide - 1)) +
                                kBlockSide * ((j & (kBlockSide - 1)) + kBlockSide * (k & (kBlockSide - 1)))];
  }

  // The 8 voxels around a point (voxel centres at integer multiples of voxel_m) and their
  // trilinear weights.
  void Corners(const Eigen::Vector3f& p, std::array<Eigen::Vector3i, 8>& voxel,
               std::array<float, 8>& weight) const {
    const Eigen::Vector3f g = p / voxel_m;
    const Eigen::Vector3i base(FloorToInt(g.x()), FloorToInt(g.y()), FloorToInt(g.z()));
    const Eigen::Vector3f f = g - base.cast<float>();
    for (int c = 0; c < 8; ++c) {
      const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
      voxel[c] = base + Eigen::Vector3i(dx, dy, dz);
      weight[c] = (dx ? f.x() : 1 - f.x()) * (dy ? f.y() : 1 - f.y()) * (dz ? f.z() : 1 - f.z());
    }
  }

  double TimeSinceFfc(double thermal_timestamp_s) const {
    auto it = std::upper_bound(ffc_timestamps_s.begin(), ffc_timestamps_s.end(), thermal_timestamp_s);
    if (it == ffc_timestamps_s.begin()) return std::numeric_limits<double>::quiet_NaN();
    return thermal_timestamp_s - *(it - 1);
  }

  // Computes the rays of one frame (parallel); returns the fused ones (valid until the
  // next call).
  const std::vector<Ray>& ShadeRays(const PointMap& map, const cv::Mat& apparent_c,
                                    const core::Rigid3d& world_from_thermal,
                                    const Eigen::Vector3d& linear_velocity_mps,
                                    const Eigen::Vector3d& angular_velocity_radps, double operating,
                                    ThermalFrameRecord& record);
  void Splat(const std::vector<Ray>& fused, ThermalFrameRecord& record);
  // Applies every update rule to region r from its frame sum (then zeroed); appends its
  // observation to frame_records when observations are kept.
  void UpdateRegion(int32_t r, float max_weight, std::vector<Record>& frame_records);
};

const std::vector<Ray>& ThermalFusion::Impl::ShadeRays(const PointMap& map, const cv::Mat& apparent_c,
                                                       const core::Rigid3d& world_from_thermal,
                                                       const Eigen::Vector3d& linear_velocity_mps,
                                                       const Eigen::Vector3d& angular_velocity_radps, double operating,
                                                       ThermalFrameRecord& record) {
  const int width = map.width, height = map.height;
  const int num_threads = std::min(internal::ResolveThreads(options.num_threads), height);
  std::vector<ShadePart>& parts = shade_scratch;
  parts.resize(num_threads);
  for (ShadePart& part : parts) part.Clear();
  const Eigen::Matrix3d thermal_from_world = world_from_thermal.rotation.conjugate().toRotationMatrix();
  const Eigen::Vector3d origin = world_from_thermal.translation;
  const double fx = rig.thermal->fx, fy = rig.thermal->fy;
  const ThermalConfidenceOptions& co = options.confidence;
  internal::RunChunks(num_threads, [&](int chunk) {
    ShadePart& part = parts[chunk];
    for (int y = chunk * height / num_threads; y < (chunk + 1) * height / num_threads; ++y) {
      const float* row = apparent_c.ptr<float>(y);
      for (int x = 0; x < width; ++x) {
        const size_t i = map.Index(x, y);
        if (!IsValid(map.points[i])) continue;
        ++part.hits;
        if (!IsValid(map.normals[i])) {
          ++part.no_normal;
          continue;
        }
        const Eigen::Vector3d point = map.points[i].cast<double>();
        const Eigen::Vector3d ray = point - origin;
        const double distance_m = ray.norm();
        const double cos_angle = -ray.dot(map.normals[i].cast<double>()) / distance_m;
        ConfidenceTerms terms;
        const Eigen::Vector3d point_in_camera = thermal_from_world * ray;
        terms.motion = MotionConfidence(
            ImageSpeedPxPerS(point_in_camera, linear_velocity_mps, angular_velocity_radps, fx, fy) *
                co.integration_time_s,
            co);
        terms.distortion = distortion_confidence[i];
        terms.angle = AngleConfidence(cos_angle, co);
        terms.distance = DistanceConfidence(distance_m, co);
        terms.operating = operating;
        const double confidence = RayConfidence(terms, co);
        if (!(confidence >= options.min_ray_confidence) || confidence <= 0) {
          ++part.low_confidence;
          continue;
        }
        const SurfaceEmissivity e = emissivity.At(map.points[i]);
        const double emissivity_at_angle =
            core::DirectionalEmissivity(e.law, e.emissivity, std::clamp(cos_angle, 0.0, 1.0));
        double apparent = row[x];
        if (!vignetting_gain.empty()) {
          // Undo the radiance the optics lost at this pixel.
          apparent = core::KelvinToCelsius(
              band.Temperature(band.Radiance(core::CelsiusToKelvin(apparent)) / static_cast<double>(vignetting_gain[i])));
        }
        const double surface = emissivity_at_angle > 0
                                   ? core::SurfaceFromApparent(band, apparent, emissivity_at_angle, e.reflected_c)
                                   : std::numeric_limits<double>::quiet_NaN();
        if (!std::isfinite(surface)) {
          ++part.no_surface;
          continue;
        }
        // The footprint: one pixel (1/f rad) across, stretched by 1/cos θ along the slope
        // (cos θ floored at the largest angle fused, so the axis stays finite).
        const Eigen::Vector3d normal = map.normals[i].cast<double>();
        const double across_m = distance_m / fx;
        Eigen::Vector3d along = ray - ray.dot(normal) * normal;
        if (along.norm() < 1e-9 * distance_m) along = normal.unitOrthogonal();
        along.normalize();
        const Eigen::Vector3d side = normal.cross(along);
        const double along_m = across_m / std::max(cos_angle, 0.1);
        part.rays.push_back(Ray{map.points[i], (along * along_m).cast<float>(), (side * across_m).cast<float>(),
                                static_cast<float>(confidence), static_cast<float>(surface),
                                static_cast<float>(apparent)});
        part.confidence_sum += confidence;
      }
    }
  });
  std::vector<Ray>& fused = fused_scratch;
  fused.clear();
  double confidence_sum = 0;
  for (ShadePart& part : parts) {
    record.hits += part.hits;
    record.low_confidence += part.low_confidence;
    record.no_normal += part.no_normal;
    record.no_surface_temperature += part.no_surface;
    confidence_sum += part.confidence_sum;
    fused.insert(fused.end(), part.rays.begin(), part.rays.end());
  }
  record.fused = static_cast<int>(fused.size());
  record.mean_confidence = fused.empty() ? 0 : confidence_sum / fused.size();
  return fused;
}

void ThermalFusion::Impl::Splat(const std::vector<Ray>& fused, ThermalFrameRecord& record) {
  // Four passes, so that the hash lookups, the accumulation and the update rules run on
  // every thread while the result stays exactly that of one thread taking the splats in ray
  // order: (1) per ray chunk, each splat's voxel and its region if it exists (read-only
  // lookups); (2) one thread creates the missing regions in splat order (so region indices
  // do not depend on the thread count); (3) each thread sums, in splat order, the splats of
  // the regions it owns (runs of 64 region indices dealt round-robin, so that
  // two threads never write the same cache line); (4) each thread runs the update rules
  // on its own regions.
  const int num_threads = std::max(1, std::min(internal::ResolveThreads(options.num_threads),
                                               static_cast<int>(fused.size() / 1024) + 1));
  constexpr int32_t kMissing = -1, kOutOfRange = -2;
  std::vector<std::vector<SplatRef>>& parts = splat_scratch;
  parts.resize(num_threads);
  const size_t n_rays = fused.size();
  internal::RunChunks(num_threads, [&](int chunk) {
    std::vector<SplatRef>& part = parts[chunk];
    part.clear();
    uint64_t cached_key = ~uint64_t{0};
    int32_t cached_block = -1;
    for (size_t r = chunk * n_rays / num_threads; r < (chunk + 1) * n_rays / num_threads; ++r) {
      const Ray& ray = fused[r];
      // A footprint wider than a voxel is covered by a grid of splats at most a voxel apart,
      // so that a far or grazing view leaves no voxel between its rays unobserved.
      const int nu = std::clamp(static_cast<int>(std::ceil(ray.footprint_u.norm() / voxel_m)), 1, kMaxFootprintSplats);
      const int nv = std::clamp(static_cast<int>(std::ceil(ray.footprint_v.norm() / voxel_m)), 1, kMaxFootprintSplats);
      const float share = 1.0f / static_cast<float>(nu * nv);
      for (int a = 0; a < nu; ++a) {
        for (int b = 0; b < nv; ++b) {
          const Eigen::Vector3f point = ray.point_in_world +
                                        ((a + 0.5f) / static_cast<float>(nu) - 0.5f) * ray.footprint_u +
                                        ((b + 0.5f) / static_cast<float>(nv) - 0.5f) * ray.footprint_v;
          // The nearest voxel takes it (a trilinear splat would touch 8, twice the surface's
          // two layers of voxels, for no gain: Sample() interpolates between observed voxels).
          const Eigen::Vector3f g = point / voxel_m;
          const int i = FloorToInt(g.x() + 0.5f), j = FloorToInt(g.y() + 0.5f), k = FloorToInt(g.z() + 0.5f);
          int32_t region = kOutOfRange;
          if (internal::KeyInRange(i >> kBlockShift, j >> kBlockShift, k >> kBlockShift)) {
            region = FindRegion(i, j, k, cached_key, cached_block);
            if (region < 0) region = kMissing;
          }
          part.push_back(SplatRef{i, j, k, static_cast<int32_t>(r), region, share});
        }
      }
    }
  });
  {
    uint64_t cached_key = ~uint64_t{0};
    int32_t cached_block = -1;
    for (std::vector<SplatRef>& part : parts) {
      for (SplatRef& s : part) {
        // A region created by an earlier splat of this frame is found here, not re-created.
        if (s.region == kMissing) s.region = RegionOf(s.i, s.j, s.k, true, cached_key, cached_block);
      }
    }
  }
  const float max_weight = static_cast<float>(options.capped_mean_max_weight);
  std::vector<std::vector<Record>> chunk_records(num_threads);
  std::vector<int> chunk_touched(num_threads, 0);
  internal::RunChunks(num_threads, [&](int chunk) {
    std::vector<int32_t> touched;
    for (const std::vector<SplatRef>& part : parts) {
      for (const SplatRef& splat : part) {
        if (splat.region < 0 || (splat.region >> 6) % num_threads != chunk) continue;
        const Ray& ray = fused[splat.ray];
        FrameSum& s = frame_sums[splat.region];
        if (s.weight == 0) touched.push_back(splat.region);
        const float wc = splat.share * ray.confidence;
        s.weight += splat.share;
        s.weight_confidence += wc;
        s.surface += wc * ray.surface_c;
        s.apparent += wc * ray.apparent_c;
      }
    }
    std::vector<Record>& frame_records = chunk_records[chunk];
    if (options.keep_observations) frame_records.reserve(touched.size());
    for (int32_t r : touched) UpdateRegion(r, max_weight, frame_records);
    chunk_touched[chunk] = static_cast<int>(touched.size());
  });
  for (int chunk = 0; chunk < num_threads; ++chunk) {
    record.regions_updated += chunk_touched[chunk];
    num_records += chunk_records[chunk].size();
    if (!chunk_records[chunk].empty()) records.push_back(std::move(chunk_records[chunk]));
  }
}

void ThermalFusion::Impl::UpdateRegion(int32_t r, float max_weight, std::vector<Record>& frame_records) {
  FrameSum& s = frame_sums[r];
  const float confidence = s.weight_confidence / s.weight;
  const float surface = s.surface / s.weight_confidence;
  const float apparent = s.apparent / s.weight_confidence;
  s = FrameSum();
  Region& region = regions[r];
  region.latest_surface_c = surface;
  region.latest_apparent_c = apparent;
  region.latest_confidence = confidence;
  if (region.views < std::numeric_limits<uint16_t>::max()) ++region.views;
  const float n = region.views;
  const float delta = surface - region.mean_surface_c;
  region.mean_surface_c += delta / n;
  region.m2_surface += delta * (surface - region.mean_surface_c);
  region.mean_apparent_c += (apparent - region.mean_apparent_c) / n;
  region.mean_confidence += (confidence - region.mean_confidence) / n;
  double capped_value = region.capped_surface_c, capped_weight = region.capped_weight;
  CappedMeanUpdate(max_weight, surface, capped_value, capped_weight);
  double capped_apparent = region.capped_apparent_c, apparent_weight = region.capped_weight;
  CappedMeanUpdate(max_weight, apparent, capped_apparent, apparent_weight);
  region.capped_surface_c = static_cast<float>(capped_value);
  region.capped_apparent_c = static_cast<float>(capped_apparent);
  region.capped_weight = static_cast<float>(capped_weight);
  double value_a = region.online_surface_c, confidence_a = region.online_confidence;
  const double q = OnlineUpdate(options.recency_bias, surface, confidence, value_a, confidence_a);
  region.online_surface_c = static_cast<float>(value_a);
  region.online_confidence = static_cast<float>(confidence_a);
  region.online_apparent_c = static_cast<float>(
      q >= 1 ? static_cast<double>(apparent)
             : q * static_cast<double>(apparent) + (1 - q) * static_cast<double>(region.online_apparent_c));
  if (options.keep_observations) frame_records.push_back(Record{r, surface, apparent, confidence});
}

namespace {

// 1 − v·r² per pixel (ThermalFusionOptions::vignetting).
std::vector<float> VignettingGain(const core::CameraModel& camera, double vignetting) {
  std::vector<float> gain;
  if (vignetting == 0) return gain;
  double r_max2 = 0;
  for (double x : {-0.5, camera.width - 0.5}) {
    for (double y : {-0.5, camera.height - 0.5}) {
      r_max2 = std::max(r_max2, (x - camera.cx) * (x - camera.cx) + (y - camera.cy) * (y - camera.cy));
    }
  }
  gain.resize(size_t(camera.width) * camera.height);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double r2 = ((x - camera.cx) * (x - camera.cx) + (y - camera.cy) * (y - camera.cy)) / r_max2;
      gain[size_t(y) * camera.width + x] = static_cast<float>(1 - vignetting * r2);
    }
  }
  return gain;
}

}  // namespace

ThermalFusion::ThermalFusion(const core::Rig& rig, const ThermalFusionOptions& options, EmissivityMap emissivity,
                             std::vector<double> ffc_timestamps_s) {
  assert(options.Check().empty());
  assert(rig.thermal && rig.thermal_settings);
  impl_ = std::make_unique<Impl>(rig, options, std::move(emissivity), std::move(ffc_timestamps_s));
  Impl& m = *impl_;
  m.voxel_m = 0;  // set from the volume on the first frame
  m.vignetting_gain = VignettingGain(*rig.thermal, options.vignetting);
  const int width = m.rays.width(), height = m.rays.height();
  m.distortion_confidence.resize(size_t(width) * height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      m.num_rays += m.rays.valid(x, y);
      m.distortion_confidence[size_t(y) * width + x] =
          m.rays.valid(x, y) ? static_cast<float>(DistortionConfidence(m.rays.distortion_px(x, y), options.confidence))
                             : 0.0f;
    }
  }
}

ThermalFusion::~ThermalFusion() = default;

ThermalFusion::ThermalFusion(ThermalFusion&&) noexcept = default;
ThermalFusion& ThermalFusion::operator=(ThermalFusion&&) noexcept = default;

double ThermalFusion::DepthClockTime(double thermal_timestamp_s) const {
  return thermal_timestamp_s + impl_->rig.thermal_time_offset_s;
}

bool ThermalFusion::PoseAvailable(double thermal_timestamp_s, const core::Trajectory& world_from_depth) const {
  return !world_from_depth.empty() && world_from_depth.EndTime() >= DepthClockTime(thermal_timestamp_s);
}

const ThermalFrameRecord& ThermalFusion::AddFrame(const TsdfVolume& volume, const ThermalFrameInput& frame,
                                                  const core::Trajectory& world_from_depth) {
  Impl& m = *impl_;
  const core::CameraModel& camera = *m.rig.thermal;
  if (frame.apparent_c.type() != CV_32FC1 || frame.apparent_c.cols != camera.width ||
      frame.apparent_c.rows != camera.height) {
    throw std::invalid_argument(core::StringPrintf(
        "thermal frame %d: expected a %dx%d CV_32FC1 image of apparent temperature, got %dx%d type %d",
        frame.index, camera.width, camera.height, frame.apparent_c.cols, frame.apparent_c.rows,
        frame.apparent_c.type()));
  }
  if (m.voxel_m == 0) m.voxel_m = volume.voxel_size_m();
  assert(m.voxel_m == volume.voxel_size_m());
  m.finished = false;
  ThermalFrameRecord& record = m.frames.emplace_back();
  record.index = frame.index;
  record.timestamp_s = frame.timestamp_s;
  record.depth_clock_s = DepthClockTime(frame.timestamp_s);
  record.time_since_ffc_s = m.TimeSinceFfc(frame.timestamp_s);

  // A repeated image: the camera froze it during a shutter closure, and its pose now is
  // not the pose it was taken at.
  const cv::Mat image = frame.apparent_c.isContinuous() ? frame.apparent_c : frame.apparent_c.clone();
  const bool frozen = !m.previous_image.empty() &&
                      std::memcmp(image.data, m.previous_image.data, image.total() * sizeof(float)) == 0;
  m.previous_image = image.clone();
  if (frozen) {
    record.status = ThermalFrameStatus::kFrozen;
    return record;
  }

  // The two fused depth poses around the frame's time, within max_pose_gap_s.
  const auto& poses = world_from_depth.poses();
  const double t = record.depth_clock_s;
  auto after = std::lower_bound(poses.begin(), poses.end(), t,
                                [](const core::TimedPose& p, double time) { return p.timestamp_s < time; });
  if (after == poses.end() || poses.size() < 2) {
    record.status = ThermalFrameStatus::kNoPose;
    return record;
  }
  if (after == poses.begin()) {
    if (after->timestamp_s > t) {
      record.status = ThermalFrameStatus::kNoPose;
      return record;
    }
    ++after;  // t is exactly the first pose's time
  }
  const core::TimedPose& p0 = *(after - 1);
  const core::TimedPose& p1 = *after;
  const double dt = p1.timestamp_s - p0.timestamp_s;
  if (!(dt > 0) || dt > m.options.max_pose_gap_s) {
    record.status = ThermalFrameStatus::kNoPose;
    return record;
  }
  const std::optional<core::Rigid3d> world_from_depth_at_t = world_from_depth.At(t, m.options.max_pose_gap_s);
  if (!world_from_depth_at_t) {
    record.status = ThermalFrameStatus::kNoPose;
    return record;
  }
  const core::Rigid3d world_from_thermal = *world_from_depth_at_t * m.rig.depth_from_thermal;
  const core::Rigid3d world_from_thermal0 = p0.world_from_sensor * m.rig.depth_from_thermal;
  const core::Rigid3d world_from_thermal1 = p1.world_from_sensor * m.rig.depth_from_thermal;
  // Velocity of the thermal camera in its own frame: the body-frame twist between the two poses.
  const Eigen::Quaterniond thermal_from_world = world_from_thermal.rotation.conjugate();
  const Eigen::Vector3d linear_velocity_mps =
      thermal_from_world * (world_from_thermal1.translation - world_from_thermal0.translation) / dt;
  const Eigen::AngleAxisd rotation(world_from_thermal0.rotation.conjugate() * world_from_thermal1.rotation);
  const Eigen::Vector3d angular_velocity_radps = rotation.axis() * rotation.angle() / dt;
  record.linear_speed_mps = linear_velocity_mps.norm();
  record.angular_speed_dps = angular_velocity_radps.norm() * 180 / M_PI;

  auto start = std::chrono::steady_clock::now();
  RaycastOptions raycast;
  raycast.min_depth_m = m.options.min_depth_m;
  raycast.max_depth_m = m.options.max_depth_m;
  raycast.num_threads = m.options.num_threads;
  const PointMap map = Raycast(volume, m.rays, world_from_thermal, raycast);
  record.raycast_ms = Ms(start);
  record.rays = m.num_rays;

  start = std::chrono::steady_clock::now();
  const double operating = OperatingConfidence(record.time_since_ffc_s, false, m.options.confidence);
  const std::vector<Ray>& fused = m.ShadeRays(map, image, world_from_thermal, linear_velocity_mps,
                                             angular_velocity_radps, operating, record);
  m.Splat(fused, record);
  record.fuse_ms = Ms(start);
  record.status = record.hits == 0 ? ThermalFrameStatus::kNoSurface : ThermalFrameStatus::kFused;
  return record;
}

void ThermalFusion::Finish() {
  Impl& m = *impl_;
  m.finished = true;
  m.offline_rejected = 0;
  if (!m.options.keep_observations || m.num_records == 0) return;
  // Group the observations by region (counting sort), then estimate each region alone.
  const size_t n_regions = m.regions.size();
  std::vector<uint32_t> begin(n_regions + 1, 0);
  for (const std::vector<Record>& frame : m.records) {
    for (const Record& r : frame) ++begin[r.region + 1];
  }
  for (size_t i = 0; i < n_regions; ++i) begin[i + 1] += begin[i];
  std::vector<Observation> surface(m.num_records), apparent(m.num_records);
  {
    std::vector<uint32_t> next(begin.begin(), begin.end() - 1);
    for (const std::vector<Record>& frame : m.records) {
      for (const Record& r : frame) {
        const uint32_t k = next[r.region]++;
        surface[k] = Observation{r.surface_c, r.confidence};
        apparent[k] = Observation{r.apparent_c, r.confidence};
      }
    }
  }
  const int num_threads = internal::ResolveThreads(m.options.num_threads);
  std::vector<int64_t> rejected(num_threads, 0);
  internal::RunChunks(num_threads, [&](int chunk) {
    for (size_t i = chunk; i < n_regions; i += num_threads) {
      Region& region = m.regions[i];
      const size_t b = begin[i], e = begin[i + 1];
      if (b == e) continue;
      const OfflineEstimate s = RobustEstimate(std::span<Observation>(surface.data() + b, e - b), m.options.offline);
      const OfflineEstimate a = RobustEstimate(std::span<Observation>(apparent.data() + b, e - b), m.options.offline);
      region.offline_views = static_cast<uint16_t>(std::min<int>(s.views, std::numeric_limits<uint16_t>::max()));
      region.offline_surface_c = static_cast<float>(s.value_c);
      region.offline_apparent_c = static_cast<float>(a.value_c);
      region.offline_confidence = static_cast<float>(s.confidence);
      region.offline_std_c = static_cast<float>(s.std_c);
      rejected[chunk] += s.rejected;
    }
  });
  for (int64_t r : rejected) m.offline_rejected += r;
}

PointTemperatures ThermalFusion::Sample(const std::vector<Eigen::Vector3f>& points_in_world,
                                        ThermalMethod method) const {
  const Impl& m = *impl_;
  PointTemperatures out;
  const size_t n = points_in_world.size();
  out.surface_c.assign(n, kNaN);
  out.apparent_c.assign(n, kNaN);
  out.confidence.assign(n, 0.0f);
  out.std_c.assign(n, kNaN);
  out.views.assign(n, 0);
  if (m.regions.empty() || m.voxel_m == 0) return out;
  const int num_threads = std::max(1, std::min<int>(internal::ResolveThreads(m.options.num_threads),
                                                    static_cast<int>(n / 4096) + 1));
  internal::RunChunks(num_threads, [&](int chunk) {
    uint64_t cached_key = ~uint64_t{0};
    int32_t cached_block = -1;
    std::array<Eigen::Vector3i, 8> voxel;
    std::array<float, 8> weight;
    for (size_t i = chunk * n / num_threads; i < (chunk + 1) * n / num_threads; ++i) {
      m.Corners(points_in_world[i], voxel, weight);
      double w_sum = 0, surface = 0, apparent = 0, confidence = 0, spread = 0, views = 0, w_spread = 0;
      for (int c = 0; c < 8; ++c) {
        if (weight[c] <= 0) continue;
        const int32_t r = m.FindRegion(voxel[c].x(), voxel[c].y(), voxel[c].z(), cached_key, cached_block);
        if (r < 0) continue;
        const Region& g = m.regions[r];
        float s = kNaN, a = kNaN, conf = 0, sd = kNaN, v = 0;
        switch (method) {
          case ThermalMethod::kLatest:
            s = g.latest_surface_c, a = g.latest_apparent_c, conf = g.latest_confidence;
            break;
          case ThermalMethod::kMean:
            if (g.views > 0) s = g.mean_surface_c, a = g.mean_apparent_c, conf = g.mean_confidence;
            break;
          case ThermalMethod::kCappedMean:
            if (g.views > 0) s = g.capped_surface_c, a = g.capped_apparent_c, conf = g.mean_confidence;
            break;
          case ThermalMethod::kOnline:
            if (g.online_confidence >= 0) s = g.online_surface_c, a = g.online_apparent_c, conf = g.online_confidence;
            break;
          case ThermalMethod::kOffline:
            if (g.offline_views > 0) {
              s = g.offline_surface_c, a = g.offline_apparent_c, conf = g.offline_confidence, sd = g.offline_std_c;
              v = g.offline_views;
            }
            break;
        }
        if (!std::isfinite(s) || !std::isfinite(a)) continue;
        if (method != ThermalMethod::kOffline) {
          v = g.views;
          sd = g.views > 1 ? std::sqrt(g.m2_surface / (g.views - 1)) : 0.0f;
        }
        const double w = weight[c];
        w_sum += w;
        surface += w * static_cast<double>(s);
        apparent += w * static_cast<double>(a);
        confidence += w * static_cast<double>(conf);
        views += w * static_cast<double>(v);
        if (std::isfinite(sd)) {
          spread += w * static_cast<double>(sd);
          w_spread += w;
        }
      }
      if (w_sum <= 0) continue;
      out.surface_c[i] = static_cast<float>(surface / w_sum);
      out.apparent_c[i] = static_cast<float>(apparent / w_sum);
      out.confidence[i] = static_cast<float>(confidence / w_sum);
      out.views[i] = static_cast<uint16_t>(std::max(1.0, std::round(views / w_sum)));
      if (w_spread > 0) out.std_c[i] = static_cast<float>(spread / w_spread);
    }
  });
  return out;
}

const std::vector<ThermalFrameRecord>& ThermalFusion::frames() const { return impl_->frames; }
const ThermalFusionOptions& ThermalFusion::options() const { return impl_->options; }
size_t ThermalFusion::NumRegions() const { return impl_->regions.size(); }
size_t ThermalFusion::NumObservations() const { return impl_->num_records; }
int64_t ThermalFusion::OfflineRejected() const { return impl_->offline_rejected; }

size_t ThermalFusion::MemoryBytes() const {
  const Impl& m = *impl_;
  return m.regions.CapacityBytes() + m.frame_sums.CapacityBytes() + m.blocks.CapacityBytes() +
         m.block_index.size() * 32 +
         m.num_records * sizeof(Record);
}

}  // namespace hw::reconstruct
