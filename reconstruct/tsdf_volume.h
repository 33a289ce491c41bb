#pragma once

// A truncated signed distance field with colour in a sparse voxel-block hash
// (KinectFusion's TSDF, stored as in Nießner et al. 2013 "voxel hashing"): the volume is
// cut into blocks of kBlockSide³ voxels, and only blocks near an observed surface exist,
// so memory grows with the observed surface, never with the bounding box of the scene.

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/transform.h"
#include "reconstruct/camera_maps.h"
#include "reconstruct/depth_noise.h"

namespace hw::reconstruct {

// Options of TSDF fusion.
struct TsdfOptions {
  double voxel_size_m = 0.005;  // side of one voxel, m, in [0.0005, 0.5]
  // Half-width of the band around the surface where distances are stored, m, >= 2 voxels:
  // wider smooths more noise, narrower keeps thin structures apart.
  double truncation_m = 0.02;
  // The band widens where the depth sensor's noise outgrows it: a measurement at depth z is
  // fused over ±max(truncation_m, truncation_noise_sigmas · σ_z(z)) (TruncationAt), with
  // the axial noise σ_z(z) = noise.base_m + noise.quadratic_per_m · (z − noise.reference_m)²
  // of a structured-light sensor (Nguyen, Izadi & Lovell 2012, fitted on a Kinect; the
  // defaults are theirs: 6 mm at 2 m, 14 mm at 3 m, 26 mm at 4 m). A band narrower than the
  // noise clips it unevenly — a voxel on the surface keeps every reading in front (clipped
  // to +1) but drops those more than a band behind — so a far surface's zero crossing lies
  // behind the true one by a part of σ that depends on the view, and tracking against it
  // drifts. At 3 σ the band is the fixed one up to 2.1 m (the defaults): near surfaces and
  // thin objects are fused as before. Measured (README, Reconstruction): the 10 s full-size
  // `equipment` sweep with the true depth field, ATE 13.4 → 5.0 mm, surface error (median)
  // 23 → 5 mm; the `building` 4 s sweep (walls at 3–4 m) 17.2 → 10.4 mm. 0: the fixed band.
  double truncation_noise_sigmas = 3;    // >= 0
  DepthNoiseModel noise;  // σ_z(z), m (depth_noise.h); ICP's gate uses the same model
  // Each observation adds weight 1; the sum is capped here, so a long-observed surface still
  // follows a changed one (a moving person, a door) after about this many frames. A whole
  // number in [1, 65535] (a voxel stores its weight as a 16-bit count).
  double max_weight = 64;
  // Far blocks on a coarser lattice: a block no camera has seen from nearer than
  // CoarseBeyondM() is updated on its even voxels only (twice the voxel size; the others
  // filled from them, tsdf_fill.h) — an eighth of the projections and depth reads where one
  // reading's noise and a depth pixel are both wider than a voxel, which is where a sweep's
  // integration spends most of its time (a depth pixel at 4 m costs ~60 times one at 1 m:
  // its band is 4 times wider and it covers 16 times as many voxels). The first view from
  // nearer makes the block fine for good, starting from the interpolated values. Measured
  // (README, Reconstruction).
  bool coarse_far = true;
  double min_depth_m = 0.3;  // depth pixels nearer than this are not fused, m, >= 0
  double max_depth_m = 4.0;  // ... farther than this, m, > min_depth_m
  // Worker threads for integration and raycasting (0: hardware concurrency). Work is split
  // in a few coarse chunks: fine-grained scheduling collapses on 2 shared cores.
  int num_threads = 0;

  std::string Check() const;  // "" when valid, else names the field, value and constraint

  // The band model in float, as the integration kernels evaluate it (they must give the
  // same bits): Band().At(depth_m) is the half-width of the band (m) of a measurement at
  // depth_m (m), max(truncation_m, truncation_noise_sigmas · σ_z(depth_m)).
  struct NoiseBand {
    float truncation_m, sigmas, base_m, quadratic_per_m, reference_m;
    float At(float depth_m) const {
      const float dz = depth_m - reference_m;
      return std::max(truncation_m, sigmas * (base_m + quadratic_per_m * (dz * dz)));
    }
  };
  NoiseBand Band() const {
    return {static_cast<float>(truncation_m), static_cast<float>(truncation_noise_sigmas),
            static_cast<float>(noise.base_m), static_cast<float>(noise.quadratic_per_m),
            static_cast<float>(noise.reference_m)};
  }
  float TruncationAt(float depth_m) const { return Band().At(depth_m); }
  // The depth (m, along the optical axis) beyond which a block not yet seen nearer is
  // updated coarsely (coarse_far): where both one reading's noise σ_z exceeds the coarse
  // lattice (2 voxels) and a depth pixel (focal_px, pixels) is wider than a voxel — 2.63 m
  // at 5 mm voxels and 525 px (the noise's bound 2.55 m); beyond any depth when coarse_far is
  // off or the noise model never gets there.
  double CoarseBeyondM(double focal_px) const;
};

// floor(x) as an int for |x| < 2^31, without the libm call std::floor becomes on plain
// x86-64 (no SSE4.1 rounding instruction): samplers call it millions of times per frame.
inline int FloorToInt(float x) {
  const int i = static_cast<int>(x);
  return i - (static_cast<float>(i) > x);
}

// Blocks are kBlockSide voxels along each axis (8: the samplers divide by shifting).
inline constexpr int kBlockSide = 8;
inline constexpr int kBlockShift = 3;
static_assert(kBlockSide == 1 << kBlockShift);
inline constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;

// One voxel, 8 bytes. sdf() is the mean of the readings' truncated signed distances, each
// divided by its band (truncation_m, wider for far readings: TsdfOptions::TruncationAt), in
// [−1, 1] (positive in front of the surface, towards the cameras that saw it); weight() counts
// the readings fused (capped at max_weight); 0 means never observed (sdf and colour then
// meaningless). colour_weight counts the observations that painted the voxel (capped at
// min(max_weight, 255)): a voxel first seen far in front of the surface (weight > 0, no colour
// yet) must not average its unset black into the first real colour.
//
// Stored compactly (stop 51; 12 bytes before, float distance and weight): the distance as a
// 16-bit fixed-point number with kSdfUnit steps per band — 2⁻¹⁴ of the band, 1.2 µm at the
// default 2 cm, 4.7 µm at 4 m's 7.7 cm: far below the sensor's noise and the voxel — and the
// weight as a 16-bit count (every reading adds 1, so max_weight is whole). Integration
// touches a third less memory per voxel and the volume holds a third less (README, Scale).
// Rounding is to nearest (even), as the SIMD kernel's conversion rounds: both write the same
// bits.
struct Voxel {
  static constexpr float kSdfUnit = 16384.0f;  // stored steps per band: 2^14, exact scaling
  std::int16_t sdf_steps = 16384;              // sdf · kSdfUnit, in [−kSdfUnit, kSdfUnit]
  std::uint16_t weight_count = 0;
  Rgb8 colour = Rgb8::Zero();
  std::uint8_t colour_weight = 0;

  float sdf() const { return static_cast<float>(sdf_steps) * (1.0f / kSdfUnit); }
  float weight() const { return static_cast<float>(weight_count); }
  bool observed() const { return weight_count != 0; }
  // Stores s (clamped to [−1, 1]; NaN is a bug: asserts) rounded to the nearest step.
  void set_sdf(float s) {
    assert(s == s);
    const float scaled = std::clamp(s * kSdfUnit, -kSdfUnit, kSdfUnit);
    // Round to nearest even by adding and removing 1.5 · 2^23 (exact below 2^22; std::lrint
    // is a library call here).
    constexpr float kRound = 12582912.0f;
    sdf_steps = static_cast<std::int16_t>((scaled + kRound) - kRound);
  }
  // w must be whole, in [0, 65535].
  void set_weight(float w) { weight_count = static_cast<std::uint16_t>(w); }
};
static_assert(sizeof(Voxel) == 8);

// Integer coordinates of a block: the block holding voxel (i, j, k) is
// (floor(i / kBlockSide), ...). Voxel (i, j, k) has its centre at (i, j, k) · voxel_size_m
// in the world frame.
using BlockKey = Eigen::Vector3i;

// Cache-line aligned, the voxels first: each row of 8 voxels (64 bytes) is one cache line.
struct alignas(64) VoxelBlock {
  // Voxel (x, y, z) inside the block at voxels[x + kBlockSide · (y + kBlockSide · z)].
  std::array<Voxel, kBlockVoxels> voxels;
  BlockKey key;
  // Updated at least once from nearer than TsdfOptions::CoarseBeyondM: every voxel takes its
  // own reading from then on (false: only the even ones, the others interpolated).
  bool seen_near = false;
  // The narrowest band (m) of any reading fused into the block — a lower bound, from the
  // nearest depth a reading that updated it can have — or 0 when unknown (a block written
  // other than by Integrate and CarveFreeSpace): a voxel's sdf · min_band_m never exceeds
  // the distance the readings put between it and their surface, so the ray march steps by
  // it (truncation_m when 0).
  float min_band_m = 0;
  // Records that a reading of band band_m (m, > 0) was fused into the block.
  void LowerBand(float band_m) { min_band_m = min_band_m > 0 ? std::min(min_band_m, band_m) : band_m; }
};

// What one Integrate() call did.
struct IntegrateStats {
  int blocks_allocated = 0;  // new blocks this frame
  int blocks_visible = 0;    // blocks updated this frame
  int blocks_coarse = 0;     // of those, updated on their even voxels (TsdfOptions::coarse_far)
  int64_t voxels_updated = 0;
};

// A colour image to paint the surface with: CV_8UC3 RGB (distortion already removed,
// depth_frame.h), its pinhole camera and world_from_camera at its exposure time.
struct ColourView {
  cv::Mat rgb;
  PinholeCamera camera;
  core::Rigid3d world_from_camera;
  // A rolling shutter (empty: global): the camera's pose for each of N equal bands of rows,
  // top band first, N in [2, kMaxColourBands]; world_from_camera is then the pose of the
  // middle row, with which a voxel is projected first, to find the band whose pose projects
  // it for good.
  std::vector<core::Rigid3d> world_from_camera_bands;
};
inline constexpr int kMaxColourBands = 64;

// The volume. Not thread-safe for concurrent calls; each call may use num_threads threads.
class TsdfVolume {
 public:
  explicit TsdfVolume(const TsdfOptions& options);  // asserts options.Check() is empty
  ~TsdfVolume();
  TsdfVolume(TsdfVolume&&) noexcept;
  TsdfVolume& operator=(TsdfVolume&&) noexcept;
  const TsdfOptions& options() const { return options_; }
  float voxel_size_m() const;

  // Fuses one depth frame: depth_m is CV_32FC1 metres along the optical axis of `camera`
  // (undistorted, depth_frame.h), 0 = no measurement, seen from world_from_camera. Allocates
  // the blocks within truncation_m of every valid pixel's surface point (between
  // min_depth_m and max_depth_m) and updates every voxel of the blocks in view with the
  // projective distance (weight +1, capped at max_weight) — of a block beyond
  // CoarseBeyondM never seen nearer, its even voxels, the others filled from them
  // (coarse_far) —; voxels more than their band behind the measured surface are left alone.
  // When `colour` is given, voxels within the band take the colour they project to
  // (weighted running mean, same weights).
  // Details (tsdf_integrate.cc): rays are walked for pixels sampled a quarter block apart
  // at the frame's farthest depth (every pixel up to 8 apart); the blocks updated are the
  // ones those rays touched this frame; depth is read bilinearly where the four pixels
  // around a voxel's projection lie on one surface, else from the nearest pixel; colour
  // from the nearest colour pixel; an AVX2 kernel where the CPU has one (same bits as the
  // scalar one). Asserts depth_m's type and size and rgb's (CV_8UC3, camera size). NaN depth
  // counts as no measurement.
  IntegrateStats Integrate(const cv::Mat& depth_m, const PinholeCamera& camera,
                           const core::Rigid3d& world_from_camera,
                           const ColourView* colour = nullptr);

  // Free space seen where the model had a surface (dynamic_mask.h: ModelSeenThrough): for
  // each point, the observed voxels of existing blocks within truncation_m of it along the
  // ray from camera_in_world take one observation of empty space (sdf +1, weight +1, capped
  // at max_weight), so that a surface fused from something that has since left (a person
  // walking by) fades after as many views through it as it had (each voxel once per call).
  // Unobserved voxels and missing blocks are left alone. World frame, metres. Returns the
  // voxels updated.
  int64_t CarveFreeSpace(const std::vector<Eigen::Vector3f>& points_in_world, const Eigen::Vector3f& camera_in_world);

  // The block with this key, or nullptr.
  const VoxelBlock* FindBlock(const BlockKey& key) const;
  // The block with this key, created (all voxels unobserved) if missing.
  VoxelBlock& GetOrCreateBlock(const BlockKey& key);
  // The voxel with integer coordinates (i, j, k), or nullptr when its block does not exist.
  const Voxel* FindVoxel(const Eigen::Vector3i& voxel) const;

  // Trilinear interpolation of sdf (in units of truncation_m) at a world point (metres);
  // nullopt unless all 8 surrounding voxels are observed. One call costs a hash lookup or
  // more: for many nearby queries use TsdfSampler, which gives the same values.
  std::optional<float> SdfAt(const Eigen::Vector3f& point_in_world) const;
  // Unit surface normal at a world point: the normalised central-difference gradient of the
  // interpolated sdf; nullopt where a needed voxel is unobserved or the gradient vanishes.
  std::optional<Eigen::Vector3f> NormalAt(const Eigen::Vector3f& point_in_world) const;
  // Trilinear interpolation of colour at a world point over the corners that were painted
  // (weights renormalised; black when none was); nullopt as SdfAt.
  std::optional<Rgb8> ColourAt(const Eigen::Vector3f& point_in_world) const;

  size_t NumBlocks() const;
  // Bytes held by blocks and the hash table.
  size_t MemoryBytes() const;
  // Calls f on every block (order unspecified but deterministic for a given history).
  void ForEachBlock(const std::function<void(const VoxelBlock&)>& f) const;
  // Axis-aligned bounds of the allocated blocks, world frame (metres); zero when empty.
  void Bounds(Eigen::Vector3f& min_m, Eigen::Vector3f& max_m) const;

  // Blocks are grouped in regions: world-aligned cubes of kRegionBlocks³ blocks (32 cm at
  // 5 mm voxels). Calls f on every block of each region whose box (min_m, max_m: world
  // frame, metres; it holds every point of the region's blocks) passes keep_region, so that
  // a view (raycasting) costs the regions of the map plus the blocks it keeps, not every
  // block: the map grows ~kRegionBlocks² times faster than its region count. Order
  // deterministic for a given history. The region index is brought up to date on the call
  // (blocks created since the last call are added): not thread-safe with Integrate, as
  // every call here.
  static constexpr int kRegionBlocks = 8;
  void ForEachBlockInRegions(
      const std::function<bool(const Eigen::Vector3f& min_m, const Eigen::Vector3f& max_m)>& keep_region,
      const std::function<void(const VoxelBlock&)>& f) const;
  // The keys of the regions holding at least one block (region (x, y, z) spans world
  // [x, x + 1) · kRegionBlocks · kBlockSide voxels on x, likewise y and z), in first-block
  // order; brings the region index up to date as ForEachBlockInRegions does (so that a ray
  // can leave empty 32 cm regions whole instead of block by block).
  std::vector<Eigen::Vector3i> RegionKeys() const;

 private:
  void UpdateRegionIndex() const;  // with regions_->mutex held
  struct Impl;
  struct RegionIndex;
  TsdfOptions options_;
  std::unique_ptr<Impl> impl_;
  mutable std::unique_ptr<RegionIndex> regions_;  // built lazily by ForEachBlockInRegions
};

// Fast sampling of a volume for many nearby queries (a ray, a mesh, a thermal image): it
// keeps the last blocks it looked up (one per parity class of the key: any 2×2×2 group of
// neighbours fits), so that nearby queries cost no hash lookup, and reads the 8 voxels of a
// cell inside one block (7 cells of 8 per axis) by plain indexing. Results equal
// TsdfVolume::SdfAt / NormalAt / ColourAt. Cheap to make (one per thread and task); not
// thread-safe; invalid once the volume gains blocks.
class TsdfSampler {
 public:
  explicit TsdfSampler(const TsdfVolume& volume)
      : volume_(&volume), inv_voxel_m_(1.0f / volume.voxel_size_m()) {}

  // What Sample() found at a point.
  enum class Status {
    kOk,          // sdf holds the trilinear value
    kUnobserved,  // the cell's blocks exist but one of its 8 voxels has weight 0 (or a
                  // block other than the lowest corner's is missing)
    kNoBlock,     // the block holding the cell's lowest corner voxel does not exist:
                  // nothing to find before leaving that block (raycasting skips it whole)
  };
  // The cell of the trilinear interpolation at a point: its lowest corner voxel, the
  // point's fractional position in it, and the block holding that corner (nullptr: none).
  struct Cell {
    int ix, iy, iz;
    float fx, fy, fz;
    const VoxelBlock* block;
  };
  // The cell at a world point (metres), its block looked up through the cache.
  [[gnu::always_inline]] Cell Locate(const Eigen::Vector3f& point_in_world) {
    const float gx = point_in_world.x() * inv_voxel_m_, gy = point_in_world.y() * inv_voxel_m_,
                gz = point_in_world.z() * inv_voxel_m_;
    Cell c;
    c.ix = FloorToInt(gx);
    c.iy = FloorToInt(gy);
    c.iz = FloorToInt(gz);
    c.fx = gx - static_cast<float>(c.ix);
    c.fy = gy - static_cast<float>(c.iy);
    c.fz = gz - static_cast<float>(c.iz);
    c.block = Block(c.ix >> kBlockShift, c.iy >> kBlockShift, c.iz >> kBlockShift);
    return c;
  }
  // Trilinear sdf (units of truncation_m) at a world point (metres). Always inlined: GCC
  // kept it a call in the ray march, and inlining it makes raycasting 3-6 % faster with the
  // same bits (README, Measured).
  [[gnu::always_inline]] Status Sample(const Eigen::Vector3f& point_in_world, float& sdf) {
    return Sample(Locate(point_in_world), sdf);
  }
  // Sample() of a located cell.
  [[gnu::always_inline]] Status Sample(const Cell& c, float& sdf) {
    constexpr int m = kBlockSide - 1;
    const int lx = c.ix & m, ly = c.iy & m, lz = c.iz & m;
    if (c.block == nullptr) return Status::kNoBlock;
    if ((lx < m) & (ly < m) & (lz < m)) {  // all 8 in this block: plain indexing
      constexpr int kY = kBlockSide, kZ = kBlockSide * kBlockSide;
      const Voxel* v = &c.block->voxels[lx + kY * ly + kZ * lz];
      const Voxel &v000 = v[0], &v100 = v[1], &v010 = v[kY], &v110 = v[kY + 1], &v001 = v[kZ],
                  &v101 = v[kZ + 1], &v011 = v[kZ + kY], &v111 = v[kZ + kY + 1];
      if (!(v000.observed() & v100.observed() & v010.observed() & v110.observed() & v001.observed() &
            v101.observed() & v011.observed() & v111.observed())) {
        return Status::kUnobserved;
      }
      sdf = Trilinear(v000.sdf(), v100.sdf(), v010.sdf(), v110.sdf(), v001.sdf(), v101.sdf(), v011.sdf(),
                      v111.sdf(), c.fx, c.fy, c.fz);
      return Status::kOk;
    }
    return SampleAcrossBlocks(c.ix, c.iy, c.iz, c.fx, c.fy, c.fz, sdf);
  }
  bool Sdf(const Eigen::Vector3f& point_in_world, float& sdf) {
    return Sample(point_in_world, sdf) == Status::kOk;
  }
  // Starts loading the cache lines Sample(cell) will read (the rows of its 8 voxels, in up
  // to 8 blocks looked up through the cache) and returns at once: a caller that marches
  // several rays in turn overlaps their memory latency, which is what a far sweep's raycast
  // waited on (a sample's first voxel load took a quarter of the march: README,
  // Reconstruction). Changes no result.
  [[gnu::always_inline]] void Prefetch(const Cell& c) {
    if (c.block == nullptr) return;  // Sample reads nothing (kNoBlock)
    constexpr int m = kBlockSide - 1;
    const int kx = c.ix >> kBlockShift, ky = c.iy >> kBlockShift, kz = c.iz >> kBlockShift;
    const int ly = c.iy & m, lz = c.iz & m;
    const bool next_x = (c.ix & m) == m;
    for (int dz = 0; dz <= 1; ++dz) {
      for (int dy = 0; dy <= 1; ++dy) {
        const int y = ly + dy, z = lz + dz;
        const int row = kBlockSide * ((y & m) + kBlockSide * (z & m));
        const VoxelBlock* block =
            (dy | dz) == 0 ? c.block : Block(kx, ky + (y >> kBlockShift), kz + (z >> kBlockShift));
        if (block != nullptr) __builtin_prefetch(&block->voxels[row]);
        if (next_x) {
          if (const VoxelBlock* next = Block(kx + 1, ky + (y >> kBlockShift), kz + (z >> kBlockShift))) {
            __builtin_prefetch(&next->voxels[row]);
          }
        }
      }
    }
  }
  // TsdfVolume::NormalAt: the normalised central difference (step one voxel) of the
  // trilinear sdf, from the 32 voxels those six samples need. False where one is unobserved
  // or the gradient vanishes.
  bool Normal(const Eigen::Vector3f& point_in_world, Eigen::Vector3f& normal);
  // TsdfVolume::ColourAt.
  bool Colour(const Eigen::Vector3f& point_in_world, Rgb8& colour);
  // FindBlock through the cache.
  const VoxelBlock* Block(int kx, int ky, int kz) {
    Slot& slot = slots_[(kx & 1) | ((ky & 1) << 1) | ((kz & 1) << 2)];
    if ((kx != slot.x) | (ky != slot.y) | (kz != slot.z)) {
      slot.x = kx;
      slot.y = ky;
      slot.z = kz;
      slot.block = volume_->FindBlock(BlockKey(kx, ky, kz));
    }
    return slot.block;
  }
  const VoxelBlock* Block(const BlockKey& key) { return Block(key.x(), key.y(), key.z()); }
  // The voxel with integer coordinates, or nullptr when its block is absent.
  const Voxel* FindVoxel(const Eigen::Vector3i& voxel) {
    const VoxelBlock* block = Block(voxel.x() >> kBlockShift, voxel.y() >> kBlockShift, voxel.z() >> kBlockShift);
    if (block == nullptr) return nullptr;
    const int m = kBlockSide - 1;
    return &block->voxels[(voxel.x() & m) + kBlockSide * ((voxel.y() & m) + kBlockSide * (voxel.z() & m))];
  }

  static float Trilinear(float s000, float s100, float s010, float s110, float s001, float s101,
                         float s011, float s111, float fx, float fy, float fz) {
    const float x00 = s000 + fx * (s100 - s000), x10 = s010 + fx * (s110 - s010);
    const float x01 = s001 + fx * (s101 - s001), x11 = s011 + fx * (s111 - s011);
    const float y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);
    return y0 + fz * (y1 - y0);
  }

 private:
  // Sample() for a cell whose voxels lie in several blocks.
  Status SampleAcrossBlocks(int ix, int iy, int iz, float fx, float fy, float fz, float& sdf);
  // The 8 voxels around a point (x fastest) and the fractional position; as Sample.
  Status Corners(const Eigen::Vector3f& point_in_world, std::array<const Voxel*, 8>& corners,
                 Eigen::Vector3f& fraction);

  struct Slot {
    // Starts at a key no block can have (FindBlock returns nullptr for it: consistent).
    int x = std::numeric_limits<int>::min(), y = std::numeric_limits<int>::min(),
        z = std::numeric_limits<int>::min();
    const VoxelBlock* block = nullptr;
  };
  const TsdfVolume* volume_;
  float inv_voxel_m_;
  std::array<Slot, 8> slots_;
};

}  // namespace hw::reconstruct
