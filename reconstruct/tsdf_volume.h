#pragma once

// A truncated signed distance field with colour in a sparse voxel-block hash
// (KinectFusion's TSDF, stored as in Nießner et al. 2013 "voxel hashing"): the volume is
// cut into blocks of kBlockSide³ voxels, and only blocks near an observed surface exist,
// so memory grows with the observed surface, never with the bounding box of the scene.

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/transform.h"
#include "reconstruct/camera_maps.h"

namespace hw::reconstruct {

// Options of TSDF fusion.
struct TsdfOptions {
  double voxel_size_m = 0.005;  // side of one voxel, m, in [0.0005, 0.5]
  // Half-width of the band around the surface where distances are stored, m, >= 2 voxels:
  // wider smooths more noise, narrower keeps thin structures apart.
  double truncation_m = 0.02;
  // Each observation adds weight 1; the sum is capped here, so a long-observed surface still
  // follows a changed one (a moving person, a door) after about this many frames. In [1, 65535].
  double max_weight = 64;
  double min_depth_m = 0.3;  // depth pixels nearer than this are not fused, m, >= 0
  double max_depth_m = 4.0;  // ... farther than this, m, > min_depth_m
  // Worker threads for integration and raycasting (0: hardware concurrency). Work is split
  // in a few coarse chunks: fine-grained scheduling collapses on 2 shared cores.
  int num_threads = 0;

  std::string Check() const;  // "" when valid, else names the field, value and constraint
};

// Blocks are kBlockSide voxels along each axis.
inline constexpr int kBlockSide = 8;
inline constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;

// One voxel. sdf is the truncated signed distance divided by truncation_m, in [−1, 1]
// (positive in front of the surface, towards the cameras that saw it); weight 0 means never
// observed (sdf and colour then meaningless).
struct Voxel {
  float sdf = 1.0f;
  float weight = 0.0f;
  Rgb8 colour = Rgb8::Zero();
};

// Integer coordinates of a block: the block holding voxel (i, j, k) is
// (floor(i / kBlockSide), ...). Voxel (i, j, k) has its centre at (i, j, k) · voxel_size_m
// in the world frame.
using BlockKey = Eigen::Vector3i;

struct VoxelBlock {
  BlockKey key;
  // Voxel (x, y, z) inside the block at voxels[x + kBlockSide · (y + kBlockSide · z)].
  std::array<Voxel, kBlockVoxels> voxels;
};

// What one Integrate() call did.
struct IntegrateStats {
  int blocks_allocated = 0;  // new blocks this frame
  int blocks_visible = 0;    // blocks updated this frame
  int64_t voxels_updated = 0;
};

// A colour image to paint the surface with: CV_8UC3 RGB (distortion already removed,
// depth_frame.h), its pinhole camera and world_from_camera at its exposure time.
struct ColourView {
  cv::Mat rgb;
  PinholeCamera camera;
  core::Rigid3d world_from_camera;
};

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
  // projective distance (weight +1, capped at max_weight); voxels more than truncation_m
  // behind the measured surface are left alone. When `colour` is given, voxels within the
  // band take the colour they project to (weighted running mean, same weights).
  IntegrateStats Integrate(const cv::Mat& depth_m, const PinholeCamera& camera,
                           const core::Rigid3d& world_from_camera,
                           const ColourView* colour = nullptr);

  // The block with this key, or nullptr.
  const VoxelBlock* FindBlock(const BlockKey& key) const;
  // The block with this key, created (all voxels unobserved) if missing.
  VoxelBlock& GetOrCreateBlock(const BlockKey& key);
  // The voxel with integer coordinates (i, j, k), or nullptr when its block does not exist.
  const Voxel* FindVoxel(const Eigen::Vector3i& voxel) const;

  // Trilinear interpolation of sdf (in units of truncation_m) at a world point (metres);
  // nullopt unless all 8 surrounding voxels are observed.
  std::optional<float> SdfAt(const Eigen::Vector3f& point_in_world) const;
  // Unit surface normal at a world point: the normalised central-difference gradient of the
  // interpolated sdf; nullopt where a needed voxel is unobserved or the gradient vanishes.
  std::optional<Eigen::Vector3f> NormalAt(const Eigen::Vector3f& point_in_world) const;
  // Trilinear interpolation of colour at a world point; nullopt as SdfAt.
  std::optional<Rgb8> ColourAt(const Eigen::Vector3f& point_in_world) const;

  size_t NumBlocks() const;
  // Bytes held by blocks and the hash table.
  size_t MemoryBytes() const;
  // Calls f on every block (order unspecified but deterministic for a given history).
  void ForEachBlock(const std::function<void(const VoxelBlock&)>& f) const;
  // Axis-aligned bounds of the allocated blocks, world frame (metres); zero when empty.
  void Bounds(Eigen::Vector3f& min_m, Eigen::Vector3f& max_m) const;

 private:
  struct Impl;
  TsdfOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hw::reconstruct
