#pragma once

// Internal to thermal_fusion.cc and thermal_fusion_regions.cc: the per-region state, the
// per-frame scratch and ThermalFusion::Impl.

#include <array>
#include <cstdint>
#include <future>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <absl/container/flat_hash_map.h>
#include <opencv2/core/mat.hpp>

#include "core/radiometry.h"
#include "reconstruct/thermal_fusion.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

namespace thermal_internal {

inline constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// One region (voxel): every method's state side by side (thermal_fusion.h). 'Surface' is the
// emissivity-corrected temperature, 'apparent' the camera's reading.
struct Region {
  // Latest observation.
  float latest_surface_c = kNaN, latest_apparent_c = kNaN, latest_confidence = 0;
  // ... which fused frame (Impl::fused_frames) and pixel (y · width + x, the splat of most
  // weight) it came from: the scene correction pairs it with the next frame's rays.
  int32_t latest_frame = -1, latest_pixel = -1;
  // Plain mean (Welford, so that the spread of tens of views at ~300 K stays exact in float).
  uint16_t views = 0;
  float mean_surface_c = 0, mean_apparent_c = 0, mean_confidence = 0, m2_surface = 0;
  // Confidence-weighted mean size of a thermal pixel on the surface over the views, m
  // (√(across · along) of the footprint): the thermal image's resolution there, which
  // analyze/ turns into the blur's bound on a spot's width.
  float footprint_m = 0;
  // Confidence-weighted mean of the vector from the region to the thermal camera's centre
  // over the views, world frame, m: where the surface was seen from, which analyze/ mirrors
  // about the normal to find what a shiny surface reflected into the camera.
  float view_x = 0, view_y = 0, view_z = 0;
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

// std::allocator, except that an element made without a value is left uninitialised: an
// array of records about to be overwritten is not zeroed first (Compact's grouped copy of
// ~10 M records on a 4 s full-size scan: 164 MB whose pages one thread would fault in
// before the copy, instead of the threads writing them).
template <class T>
struct UninitialisedAllocator : std::allocator<T> {
  using value_type = T;
  UninitialisedAllocator() noexcept = default;
  template <class U>
  UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}  // NOLINT: rebinding
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
using RecordChunk = std::vector<Record, UninitialisedAllocator<Record>>;

// Accumulates a frame's rays per region before the update rules run once per region and
// frame: several rays of one frame are one view, not several.
struct FrameSum {
  float weight = 0, weight_confidence = 0, surface = 0, apparent = 0, footprint = 0;
  float view_x = 0, view_y = 0, view_z = 0;  // Σ weight·confidence·(camera − hit), m
  float best = 0;       // largest splat weight (share · confidence) so far
  int32_t pixel = -1;   // its ray's pixel
};

// A fused ray, ready to splat: its hit and the axes of its pixel's footprint on the surface
// (world frame, m): across the ray, distance / f; along the surface's slope, that divided by
// cos θ; footprint_m = √(across · along), the pixel's size there.
struct Ray {
  Eigen::Vector3f point_in_world;
  Eigen::Vector3f footprint_u, footprint_v;
  float footprint_m;
  float confidence, surface_c, apparent_c;
  float emissivity;  // at the viewing angle
  int32_t pixel;     // y · width + x
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
  int hits = 0, low_confidence = 0, no_normal = 0, depth_edge = 0, occluded = 0, no_surface = 0;
  int mirror_operator = 0, mirror_surface = 0;
  double confidence_sum = 0;
  void Clear() {
    rays.clear();
    hits = low_confidence = no_normal = depth_edge = occluded = no_surface = 0;
    mirror_operator = mirror_surface = 0;
    confidence_sum = 0;
  }
};

// What a traced mirror ray met (Impl::ReflectedC).
enum class MirrorSource { kRoom, kOperator, kSurface };

// One splat of a ray (Impl::Splat).
struct SplatRef {
  int32_t i, j, k;  // voxel
  int32_t ray;      // index in the frame's fused rays
  int32_t region;   // < 0: to be created (-1) or outside the key range (-2)
  float share;      // the ray's footprint points in this voxel / all its points
};

// Compact() runs when it would drop at least half of the kept observations and at least
// this many (1 M, 16 MB): its cost (two passes over them on each thread, 15–50 ns per
// observation on the 2-core machine, much of it faulting the new copy's pages in) is then
// paid by the observations it frees.
inline constexpr size_t kMinCompactDrop = size_t{1} << 20;

// Splats per footprint axis at most: a ray whose footprint spans more voxels (a grazing view
// from afar) covers its centre 8 voxels wide and leaves the rest to its neighbours' rays.
inline constexpr int kMaxFootprintSplats = 8;

}  // namespace thermal_internal

using namespace thermal_internal;  // NOLINT: internal header, two sources

struct ThermalFusion::Impl {
  core::Rig rig;
  ThermalFusionOptions options;
  EmissivityMap emissivity;
  std::vector<double> ffc_timestamps_s;
  // The camera's band, tabulated: three conversions per ray through the series took 9–10 ms
  // of a 320×240 frame's ~23 ms of shading (2 s full-size scan, 2 threads); the table's
  // error is below 1e-6 K in thermal bands (core/radiometry.h).
  core::BandRadianceTable band;
  CameraRays rays;
  std::vector<float> distortion_confidence;  // c2 per pixel (fixed for the camera)
  std::vector<float> pixel_angle_rad;        // each pixel's angular size (depth-edge test)
  int num_rays = 0;                          // pixels with a ray through the lens model
  std::vector<float> vignetting_gain;        // 1 − v·r² per pixel; empty without vignetting
  SceneCorrection scene_correction;
  std::vector<SceneResidual> residual_scratch, temporal_scratch;
  int32_t fused_frames = 0;  // frames splatted so far
  Eigen::Vector3f camera_in_world = Eigen::Vector3f::Zero();  // the frame being splatted's centre
  double last_frozen_s = -std::numeric_limits<double>::infinity();  // thermal clock
  // The latest shutter event seen by CorrectFrame (thermal clock), the first fused frame after
  // it, and whether its offset has been measured.
  double event_time_s = -std::numeric_limits<double>::infinity();
  int32_t event_frame = 0;
  bool event_measured = false;
  float voxel_m = 0;

  // Regions: blocks of kBlockVoxels slots (region index or -1), keyed like the TSDF's.
  absl::flat_hash_map<uint64_t, int32_t> block_index;  // SwissTable, as the TSDF's index
  ChunkedVector<BlockRegions, 8> blocks;  // 512 KB chunks
  ChunkedVector<Region, 16> regions;       // 4.7 MB chunks
  ChunkedVector<FrameSum, 16> frame_sums;  // per region, zero between frames
  // Per fused frame (and thread of Splat), its region observations: chunks, so that keeping
  // them never copies what is already kept (one vector would move gigabytes each time it grows).
  std::vector<RecordChunk> records;
  size_t num_records = 0;
  size_t records_dropped = 0;  // by max_views_per_region
  // Kept observations Compact() would drop now: one per view of a region beyond
  // max_views_per_region since the last compaction (exact: a region keeps min(views, cap)).
  size_t records_droppable = 0;
  std::vector<ThermalFrameRecord> frames;
  // Scratch of ShadeRays and Splat, kept between frames: fresh buffers each frame cost more
  // in page faults than the work they hold (measured: half of Splat's time).
  std::vector<ShadePart> shade_scratch;
  std::vector<Ray> fused_scratch;
  std::vector<float> range_scratch;  // ShadeRays: each pixel's hit distance, NaN without one
  std::vector<uint8_t> occluded_scratch;  // ShadeRays: hits the live depth saw occluded
  std::vector<std::vector<float>> live_range_scratch;  // WarpLiveDepth: its per-thread buffers
  // WarpLiveDepth: the live depth's nearest range per thermal pixel, m (+inf: none); empty
  // without live depth or without the occlusion test. The raycast's hints and that test.
  std::vector<float> live_range;
  std::vector<Eigen::Vector3f> depth_rays;  // each depth pixel's ray (z = 1), built on first use
  std::vector<std::vector<SplatRef>> splat_scratch;
  cv::Mat previous_image;
  // frame_interval_s: the most confident frame of the current window so far, with what its
  // fusion needs, and the window's start (its first frame's thermal-clock time).
  struct HeldFrame {
    size_t record = 0;  // its index in `frames`
    cv::Mat image;      // apparent °C (its own copy)
    core::Rigid3d world_from_thermal;
    Eigen::Vector3d linear_velocity_mps = Eigen::Vector3d::Zero(), angular_velocity_radps = Eigen::Vector3d::Zero();
    double operating = 1;  // c5
    std::vector<LiveDepth> live;
  };
  std::optional<HeldFrame> held;
  // The background stage (options.background): the frame it fuses and its record, stored in
  // frames[background_index] by Wait (AddFrame may grow `frames` meanwhile).
  std::future<void> background;
  size_t background_index = 0;
  ThermalFrameRecord background_record;
  double window_start_s = 0;
  // Median range (m) of the last fused frame's hits: where the frame confidence evaluates
  // the motion blur before the frame's own rays are cast. 1.5 m before any.
  double reference_range_m = 1.5;
  bool finished = false;
  int64_t offline_rejected = 0;

  Impl(const core::Rig& r, const ThermalFusionOptions& o, EmissivityMap e, std::vector<double> ffc)
      : rig(r), options(o), emissivity(std::move(e)), ffc_timestamps_s(std::move(ffc)),
        band(core::BandRadiance(r.thermal_settings->spectral_band_um[0], r.thermal_settings->spectral_band_um[1])),
        rays(*r.thermal), scene_correction(o.scene_correction, r.thermal->width, r.thermal->height) {}
  // The background stage uses this object: it must end first (its error has nowhere to go).
  ~Impl() {
    if (background.valid()) background.wait();
  }

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

  // c1^p1 · c5^p5 (ThermalFusionOptions::frame_interval_s): the mean over a 3×3 grid of the
  // thermal image's pixels of the motion term at reference_range_m, times the operating term.
  double FrameConfidence(const Eigen::Vector3d& linear_velocity_mps,
                         const Eigen::Vector3d& angular_velocity_radps, double operating) const;
  // Raycasts, shades, corrects and splats one frame; fills frames[frame.record]. With
  // options.background (and frame_interval_s > 0) everything after the raycast runs on a
  // thread of its own until Wait(); the next Fuse waits for it first.
  void Fuse(const TsdfVolume& volume, const HeldFrame& frame);
  // Fuses the held frame, if any (its stage may run on in the background), and ends the window.
  void CloseWindow(const TsdfVolume& volume);
  // Waits for the background stage, if one runs, and stores its record; rethrows what it
  // threw. Every public call that reads or changes the regions or the records calls it.
  void Wait();
  // Fills live_range from the live depth frames seen from world_from_thermal (cleared when
  // `live` is empty or the occlusion test is off: both its margins 0).
  void WarpLiveDepth(const core::Rigid3d& world_from_thermal, std::span<const LiveDepth> live);
  // Computes the rays of one frame (parallel), with the occlusion test against live_range
  // when it is filled; returns the fused ones (valid until the next call).
  // reflections: ReflectPixels of the map (the emissivity at each hit and its mirror ray), or
  // empty without tracing (each fused ray then looks its emissivity up itself).
  std::vector<Ray>& ShadeRays(const PointMap& map, const std::vector<PixelReflection>& reflections,
                              const cv::Mat& apparent_c, const core::Rigid3d& world_from_thermal,
                              const Eigen::Vector3d& linear_velocity_mps,
                              const Eigen::Vector3d& angular_velocity_radps, double operating,
                              ThermalFrameRecord& record);
  // The reflected apparent temperature (°C) of pixel i, whose mirror ray was traced
  // (reflection.mirror_m not NaN): (1 − s)·L(room) + s·L(mirror source), the source the
  // operator's body when the ray meets it before the model's surface, else that surface's
  // reading in this frame (apparent_c, vignetting undone) where the frame sees it within
  // max(3 voxels, 1 % of its range) of the mirror hit, else its regions' mean apparent
  // temperature (trilinear over the observed ones), else the room; *source says which.
  // Reads the regions: call before this frame's Splat, not beside one.
  double ReflectedC(const PointMap& map, const cv::Mat& apparent_c, const core::Rigid3d& world_from_thermal,
                    size_t i, const PixelReflection& reflection, MirrorSource* source) const;
  // Scene-based correction of one frame's rays (ThermalFusionOptions::scene_correction):
  // their residuals against the reference regions update the estimates, and the frame's
  // offset is taken off every ray (its surface temperature linearised: δ/ε).
  // frozen_s: last_frozen_s as it was when the frame's fusion began (the caller may add
  // frames meanwhile).
  void CorrectFrame(std::vector<Ray>& fused, double frozen_s, ThermalFrameRecord& record);
  void Splat(const std::vector<Ray>& fused, ThermalFrameRecord& record);
  // Applies every update rule to region r from its frame sum (then zeroed); appends its
  // observation to frame_records when observations are kept. True when the region now has
  // more views than max_views_per_region (> 0).
  bool UpdateRegion(int32_t r, float max_weight, RecordChunk& frame_records);
  // Groups the kept observations by region into one chunk (stable: each region's stay in
  // arrival order), keeping each region's max_views_per_region most confident (ties: the
  // earlier); `begin` (optional) receives each region's offset into that chunk (n + 1).
  // Which views survive does not depend on when it runs: the best k of a union are the best
  // k of (the best k of the first part) and the rest.
  void Compact(std::vector<uint32_t>* begin);
};

}  // namespace hw::reconstruct
