#include "reconstruct/raycast.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Geometry>

#include "reconstruct/option_check.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

std::string RaycastOptions::Check() const {
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return Fail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return Fail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (!(step_fraction > 0 && step_fraction <= 1)) return Fail("step_fraction", step_fraction, "in (0, 1]");
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  return "";
}

namespace {

// Rays are only marched over the depth range where allocated blocks project: every block in
// view is projected into a grid of kTile × kTile pixel tiles, each keeping the nearest and
// farthest depth of the blocks over it (InfiniTAM's "expected depth" ranges). Rays then start
// at the front of the nearest block instead of crossing empty space block by block.
constexpr int kTile = 8;

// Depth range and pixel bounding box of a box's projection: the box is c0 + a·ex + b·ey + c·ez
// for a, b, c in [0, 1] (camera frame, metres). `straddles` when a corner is at or behind the
// camera plane (then u, v bound nothing).
struct Footprint {
  float z_lo, z_hi, u_lo, u_hi, v_lo, v_hi;
  bool straddles;
};
Footprint Project(const PinholeCamera& camera, const Eigen::Vector3f& c0, const Eigen::Vector3f& ex,
                  const Eigen::Vector3f& ey, const Eigen::Vector3f& ez) {
  Footprint f;
  f.z_lo = std::numeric_limits<float>::infinity();
  f.z_hi = -f.z_lo;
  f.u_lo = f.v_lo = f.z_lo;
  f.u_hi = f.v_hi = f.z_hi;
  f.straddles = false;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3f p = c0 + ((c & 1) ? ex : Eigen::Vector3f::Zero()) +
                              ((c & 2) ? ey : Eigen::Vector3f::Zero()) + ((c & 4) ? ez : Eigen::Vector3f::Zero());
    f.z_lo = std::min(f.z_lo, p.z());
    f.z_hi = std::max(f.z_hi, p.z());
    if (p.z() < 1e-3f) {
      f.straddles = true;
      continue;
    }
    const Eigen::Vector2f uv = camera.Project(p);
    f.u_lo = std::min(f.u_lo, uv.x());
    f.u_hi = std::max(f.u_hi, uv.x());
    f.v_lo = std::min(f.v_lo, uv.y());
    f.v_hi = std::max(f.v_hi, uv.y());
  }
  return f;
}

}  // namespace

namespace internal {

DepthRanges ProjectBlocks(const TsdfVolume& volume, const PinholeCamera& camera,
                          const core::Rigid3d& world_from_camera, float min_depth_m, float max_depth_m,
                          bool cull_regions, int num_threads) {
  DepthRanges r;
  r.tile = kTile;
  r.tiles_x = (camera.width + kTile - 1) / kTile;
  r.tiles_y = (camera.height + kTile - 1) / kTile;
  const size_t n_tiles = size_t(r.tiles_x) * r.tiles_y;
  const core::Rigid3d camera_from_world = world_from_camera.Inverse();
  const Eigen::Matrix3f rotation = camera_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f translation = camera_from_world.translation.cast<float>();
  const float voxel_m = volume.voxel_size_m();
  const float block_m = voxel_m * kBlockSide;
  // The blocks to project (those of regions in view with cull_regions), then projected on
  // num_threads threads, each into ranges of its own merged at the end: min and max do not
  // depend on the order, so the ranges are the same bits on any thread count (one thread took
  // 11–13 ms of a 45 ms thermal raycast late in a 4 s sweep, 62 k blocks).
  std::vector<const VoxelBlock*> blocks;
  blocks.reserve(volume.NumBlocks());
  auto collect = [&](const VoxelBlock& block) { blocks.push_back(&block); };
  if (!cull_regions) {
    volume.ForEachBlock(collect);
  } else {
    // A region out of view holds no block in view: its blocks lie in its box, whose
    // projection (all corners in front of the camera: a convex set's image is the hull of its
    // corners' images) and depth range contain theirs. The margins (a pixel, a millimetre)
    // absorb float rounding, so that this only ever keeps more.
    const float region_m = block_m * TsdfVolume::kRegionBlocks;
    const Eigen::Vector3f rx = rotation.col(0) * region_m, ry = rotation.col(1) * region_m,
                          rz = rotation.col(2) * region_m;
    auto keep_region = [&](const Eigen::Vector3f& min_m, const Eigen::Vector3f&) {
      const Footprint f = Project(camera, rotation * min_m + translation, rx, ry, rz);
      if (f.z_hi < min_depth_m - 1e-3f || f.z_lo > max_depth_m + 1e-3f) return false;
      if (f.straddles) return true;
      return !(f.u_hi < -1.5f || f.v_hi < -1.5f || f.u_lo > camera.width + 0.5f || f.v_lo > camera.height + 0.5f);
    };
    volume.ForEachBlockInRegions(keep_region, collect);
  }
  // A sample point reads voxels of its cell's lowest corner's block and the next ones: a
  // block matters for points from its first voxel's centre to one voxel past its last.
  const Eigen::Vector3f ex = rotation.col(0) * block_m, ey = rotation.col(1) * block_m,
                        ez = rotation.col(2) * block_m;
  // At least 2,000 blocks a chunk (~0.2 ms): fewer cost less than handing them to a thread.
  const int n_chunks = std::max(1, std::min(ResolveThreads(num_threads), static_cast<int>(blocks.size() / 2000)));
  std::vector<std::vector<float>> near(n_chunks), far(n_chunks);
  internal::RunChunks(n_chunks, [&](int chunk) {
    std::vector<float>& near_m = near[chunk];
    std::vector<float>& far_m = far[chunk];
    near_m.assign(n_tiles, std::numeric_limits<float>::infinity());
    far_m.assign(n_tiles, -std::numeric_limits<float>::infinity());
    const size_t begin = chunk * blocks.size() / n_chunks, end = (chunk + 1) * blocks.size() / n_chunks;
    for (size_t b = begin; b < end; ++b) {
      const VoxelBlock& block = *blocks[b];
      const Footprint f = Project(camera, rotation * (block.key.cast<float>() * block_m) + translation, ex, ey, ez);
      if (f.z_hi < min_depth_m || f.z_lo > max_depth_m) continue;
      int tx0 = 0, tx1 = r.tiles_x - 1, ty0 = 0, ty1 = r.tiles_y - 1;
      if (!f.straddles) {  // else (at or behind the camera plane) it may cover any pixel
        if (f.u_hi < -0.5f || f.v_hi < -0.5f || f.u_lo > camera.width - 0.5f || f.v_lo > camera.height - 0.5f) {
          continue;
        }
        tx0 = std::max(0, static_cast<int>(std::floor(f.u_lo + 0.5f)) / kTile);
        ty0 = std::max(0, static_cast<int>(std::floor(f.v_lo + 0.5f)) / kTile);
        tx1 = std::min(r.tiles_x - 1, static_cast<int>(std::floor(f.u_hi + 0.5f)) / kTile);
        ty1 = std::min(r.tiles_y - 1, static_cast<int>(std::floor(f.v_hi + 0.5f)) / kTile);
      }
      const float z_lo = std::max(f.z_lo, min_depth_m), z_hi = std::min(f.z_hi, max_depth_m);
      for (int ty = ty0; ty <= ty1; ++ty) {
        for (int tx = tx0; tx <= tx1; ++tx) {
          const size_t i = size_t(ty) * r.tiles_x + tx;
          near_m[i] = std::min(near_m[i], z_lo);
          far_m[i] = std::max(far_m[i], z_hi);
        }
      }
    }
  });
  r.near_m = std::move(near[0]);
  r.far_m = std::move(far[0]);
  for (int c = 1; c < n_chunks; ++c) {
    for (size_t i = 0; i < n_tiles; ++i) {
      r.near_m[i] = std::min(r.near_m[i], near[c][i]);
      r.far_m[i] = std::max(r.far_m[i], far[c][i]);
    }
  }
  return r;
}

}  // namespace internal

namespace {

using internal::DepthRanges;

// One ray of a Raycast: its pixel, its direction (camera frame, z = 1) and the depth window
// it is marched over (m along the optical axis); a hinted ray has a second window (the
// tile's), marched when the first holds no surface met from the front. An empty window
// (begin > end) is skipped.
struct RayTask {
  int x = 0, y = 0;
  Eigen::Vector3f in_camera = Eigen::Vector3f::UnitZ();
  float t_begin = 0, t_end = -1;
  float t_begin_2 = 0, t_end_2 = -1;
};

// What every ray of one Raycast() call shares, and the march.
struct RayMarch {
  Eigen::Matrix3f rotation;  // world_from_camera
  Eigen::Vector3f origin;    // camera centre, world frame (m)
  float truncation_m = 0;
  float inv_truncation_m = 0;
  bool band_steps = true;  // RaycastOptions::band_steps
  float min_step = 0;  // RaycastOptions::step_fraction
  float block_m = 0;
  bool with_colour = false;

  // Rays marched in turn by one thread. A ray's samples depend on each other (each step is
  // the last sample's distance), and a far sweep's raycast spent a quarter of its march
  // waiting for a sample's first voxel row (README, Reconstruction): so kLanes rays are
  // marched together, each prefetching its next sample's rows before the other lanes take
  // their step, and the loads overlap. Each ray takes exactly the samples it would alone
  // (the lanes share nothing but the volume), so the map does not depend on kLanes.
  static constexpr int kLanes = 8;
  struct Lane {
    explicit Lane(const TsdfVolume& volume) : sampler(volume) {}
    TsdfSampler sampler;  // per lane: a ray's blocks stay in its own cache
    RayTask ray;
    // World frame; p = origin + t · direction, the next sample.
    Eigen::Vector3f direction = Eigen::Vector3f::Zero(), inv_direction = Eigen::Vector3f::Zero(),
                    p = Eigen::Vector3f::Zero();
    TsdfSampler::Cell cell{};  // p's, located (and prefetched) when the lane moved there
    float t_per_truncation = 0, t_nudge = 0;
    float t = 0, t_end = 0, t_previous = 0, sdf_previous = 0;
    bool have_previous = false, second_pending = false, active = false;
  };
  enum class Outcome { kGoing, kHit, kMiss };

  // Marches every ray next(RayTask&) hands out (false: none left) and fills their pixels of
  // `map` where they meet a surface from the front.
  template <class Next>
  void MarchAll(const TsdfVolume& volume, Next&& next, PointMap& map) const {
    std::vector<Lane> lanes(kLanes, Lane(volume));
    int active = 0;
    for (Lane& lane : lanes) active += lane.active = Fill(lane, next);
    while (active > 0) {
      for (Lane& lane : lanes) {
        if (!lane.active) continue;
        const Outcome outcome = Step(lane, map);
        if (outcome == Outcome::kGoing) continue;
        if (outcome == Outcome::kMiss && lane.second_pending) {
          lane.second_pending = false;
          if (Begin(lane, lane.ray.t_begin_2, lane.ray.t_end_2)) continue;
        }
        if (!(lane.active = Fill(lane, next))) --active;
      }
    }
  }

  // Starts the next ray with a non-empty window on the lane; false when none is left.
  template <class Next>
  bool Fill(Lane& lane, Next& next) const {
    while (next(lane.ray)) {
      // t is the depth along the optical axis; the world point is origin + t · direction.
      lane.direction = rotation * lane.ray.in_camera;
      lane.inv_direction = lane.direction.cwiseInverse();  // inf where 0: unused
      const float metres_per_t = lane.ray.in_camera.norm();
      lane.t_per_truncation = truncation_m / metres_per_t;
      lane.t_nudge = 1e-3f * block_m / metres_per_t;
      lane.second_pending = true;
      if (Begin(lane, lane.ray.t_begin, lane.ray.t_end)) return true;
      lane.second_pending = false;
      if (Begin(lane, lane.ray.t_begin_2, lane.ray.t_end_2)) return true;
    }
    return false;
  }

  // Places the lane at the start of a window and prefetches its first sample; false when
  // the window is empty.
  bool Begin(Lane& lane, float t_begin, float t_end) const {
    if (!(t_begin <= t_end)) return false;
    lane.t = t_begin;
    lane.t_end = t_end;
    lane.have_previous = false;
    lane.p = origin + lane.t * lane.direction;
    lane.cell = lane.sampler.Locate(lane.p);
    lane.sampler.Prefetch(lane.cell);
    return true;
  }

  // One sample of the lane's ray at lane.p: a surface met from the front fills the pixel
  // (kHit); one met from behind, or the window's end, is a kMiss; else the lane moves on to
  // its next sample and prefetches it.
  Outcome Step(Lane& lane, PointMap& map) const {
    float sdf = 0;
    float& t = lane.t;
    const TsdfSampler::Status status = lane.sampler.Sample(lane.cell, sdf);
    if (status == TsdfSampler::Status::kNoBlock) {
      // Nothing until the ray leaves the block of the cell's lowest corner (points from
      // its first voxel centre to one voxel past its last): jump to that exit.
      float t_exit = std::numeric_limits<float>::infinity();
      for (int a = 0; a < 3; ++a) {
        if (lane.direction[a] == 0) continue;
        const int voxel = a == 0 ? lane.cell.ix : a == 1 ? lane.cell.iy : lane.cell.iz;  // floor(p[a] / voxel)
        const float k = static_cast<float>(voxel >> kBlockShift);
        const float face_m = (lane.direction[a] > 0 ? k + 1 : k) * block_m;
        t_exit = std::min(t_exit, (face_m - origin[a]) * lane.inv_direction[a]);
      }
      t = std::max(t_exit, t) + lane.t_nudge;
      lane.have_previous = false;
    } else if (status == TsdfSampler::Status::kUnobserved) {
      t += min_step * lane.t_per_truncation;
      lane.have_previous = false;
    } else {
      if (lane.have_previous && lane.sdf_previous > 0 && sdf <= 0) {
        Hit(lane.ray.x, lane.ray.y,
            Refine(lane.t_previous, lane.sdf_previous, t, sdf, lane.direction, lane.sampler) * lane.direction + origin,
            lane.sampler, map);
        return Outcome::kHit;
      }
      if (lane.have_previous && lane.sdf_previous < 0 && sdf > 0) return Outcome::kMiss;  // a surface from behind
      lane.t_previous = t;
      lane.sdf_previous = sdf;
      lane.have_previous = true;
      // sdf is in units of each reading's band (truncation_m or wider at range: TsdfOptions::
      // TruncationAt), so sdf · (the narrowest band of the readings the cell's blocks hold,
      // VoxelBlock::min_band_m) never oversteps the distance to the surface, nor does
      // sdf · truncation_m, with more margin (RaycastOptions::band_steps).
      const float band_ratio = band_steps ? std::max(MinBand(lane) * inv_truncation_m, 1.0f) : 1.0f;
      t += std::max(sdf * band_ratio, min_step) * lane.t_per_truncation;
    }
    if (!(t <= lane.t_end)) return Outcome::kMiss;
    lane.p = origin + t * lane.direction;
    lane.cell = lane.sampler.Locate(lane.p);
    lane.sampler.Prefetch(lane.cell);
    return Outcome::kGoing;
  }

  // The narrowest VoxelBlock::min_band_m of the blocks the lane's cell reads (0 if one is
  // unknown, which the caller reads as truncation_m); the cell's blocks exist (its sample
  // was kOk, which needs all eight voxels observed).
  float MinBand(Lane& lane) const {
    constexpr int m = kBlockSide - 1;
    const TsdfSampler::Cell& c = lane.cell;
    float band = c.block->min_band_m;
    const int ex = (c.ix & m) == m, ey = (c.iy & m) == m, ez = (c.iz & m) == m;
    if ((ex | ey | ez) == 0) return band;
    const int kx = c.ix >> kBlockShift, ky = c.iy >> kBlockShift, kz = c.iz >> kBlockShift;
    for (int dz = 0; dz <= ez; ++dz) {
      for (int dy = 0; dy <= ey; ++dy) {
        for (int dx = 0; dx <= ex; ++dx) {
          if ((dx | dy | dz) == 0) continue;
          band = std::min(band, lane.sampler.Block(kx + dx, ky + dy, kz + dz)->min_band_m);
        }
      }
    }
    return band;
  }

  // The zero between ta (sdf sa > 0) and tb (sb <= 0): regula falsi on the trilinear field,
  // since the two samples may be a truncation apart, where the field is not linear
  // (truncated at +1, or across several voxels of a curved surface).
  float Refine(float ta, float sa, float tb, float sb, const Eigen::Vector3f& direction,
               TsdfSampler& sampler) const {
    float t_hit = ta + (tb - ta) * sa / (sa - sb);
    for (int i = 0; i < 3; ++i) {
      float s;
      if (!sampler.Sdf(origin + t_hit * direction, s)) break;
      // Within |s| · truncation (/ |gradient| ≈ 1) of the zero: 0.005 · 2 cm = 0.1 mm at
      // the defaults, a fiftieth of a voxel.
      if (std::abs(s) < 0.005f) break;
      if (s > 0) {
        ta = t_hit;
        sa = s;
      } else {
        tb = t_hit;
        sb = s;
      }
      if (!(sa - sb > 0)) break;
      t_hit = ta + (tb - ta) * sa / (sa - sb);
    }
    return t_hit;
  }

  void Hit(int x, int y, const Eigen::Vector3f& point, TsdfSampler& sampler, PointMap& map) const {
    const size_t i = map.Index(x, y);
    map.points[i] = point;
    Eigen::Vector3f normal;
    if (sampler.Normal(point, normal)) map.normals[i] = normal;
    if (with_colour) {
      Rgb8 rgb;
      if (sampler.Colour(point, rgb)) map.colours[i] = rgb;
    }
  }
};

// One thread's pixels of a width × height image in tile order: the rows of kTile × kTile
// tiles ty = first_tile_row, first_tile_row + tile_row_step, …, each row's tiles left to
// right, each tile's pixels row by row (consecutive rays then read the same few blocks while
// they are in cache). Tiles that keep_tile(tx, ty) refuses are skipped.
class TilePixels {
 public:
  TilePixels(int width, int height, int first_tile_row, int tile_row_step)
      : width_(width), height_(height), tiles_x_((width + kTile - 1) / kTile),
        tiles_y_((height + kTile - 1) / kTile), step_(tile_row_step), ty_(first_tile_row) {}
  // The next pixel (x, y); false when none is left.
  template <class KeepTile>
  bool Next(int& x, int& y, const KeepTile& keep_tile) {
    if (++x_ == x_end_) {
      x_ = tx_ * kTile;
      ++y_;
    }
    while (y_ >= y_end_) {  // the next tile kept
      if (++tx_ == tiles_x_) {
        tx_ = 0;
        ty_ += step_;
      }
      if (ty_ >= tiles_y_) return false;
      if (!keep_tile(tx_, ty_)) continue;
      x_ = tx_ * kTile;
      y_ = ty_ * kTile;
      x_end_ = std::min(width_, (tx_ + 1) * kTile);
      y_end_ = std::min(height_, (ty_ + 1) * kTile);
    }
    x = x_;
    y = y_;
    return true;
  }
  int tile_x() const { return tx_; }
  int tile_y() const { return ty_; }

 private:
  int width_, height_, tiles_x_, tiles_y_, step_;
  int tx_ = -1, ty_, x_ = 0, y_ = 0, x_end_ = 0, y_end_ = 0;
};

// The march shared by both overloads.
RayMarch MakeMarch(const TsdfVolume& volume, const core::Rigid3d& world_from_camera,
                   const RaycastOptions& options) {
  RayMarch march;
  march.rotation = world_from_camera.rotation.toRotationMatrix().cast<float>();
  march.origin = world_from_camera.translation.cast<float>();
  march.truncation_m = static_cast<float>(volume.options().truncation_m);
  march.inv_truncation_m = 1.0f / march.truncation_m;
  march.band_steps = options.band_steps;
  march.min_step = static_cast<float>(options.step_fraction);
  march.block_m = volume.voxel_size_m() * kBlockSide;
  march.with_colour = options.with_colour;
  return march;
}

}  // namespace

PointMap Raycast(const TsdfVolume& volume, const PinholeCamera& camera,
                 const core::Rigid3d& world_from_camera, const RaycastOptions& options) {
  assert(options.Check().empty());
  PointMap map(camera.width, camera.height);
  if (options.with_colour) map.colours.assign(map.points.size(), Rgb8::Zero());
  if (camera.width <= 0 || camera.height <= 0 || volume.NumBlocks() == 0) return map;

  const DepthRanges ranges = internal::ProjectBlocks(volume, camera, world_from_camera,
                                                     static_cast<float>(options.min_depth_m),
                                                     static_cast<float>(options.max_depth_m), true,
                                                     options.num_threads);
  const RayMarch march = MakeMarch(volume, world_from_camera, options);

  // Tile rows dealt to the threads in turn (a scene's empty sky and dense floor would
  // unbalance contiguous bands); pixels in tile order, so that consecutive rays read the
  // same few blocks while they are in cache (a row of a 640-pixel image crosses ~100 blocks,
  // 600 KB: more than a core's share of cache on a loaded machine).
  const int num_threads = std::min(ResolveThreads(options.num_threads), ranges.tiles_y);
  internal::RunChunks(num_threads, [&](int chunk) {
    // The thread's pixels in tile order; tiles no block projects on are skipped.
    TilePixels pixels(camera.width, camera.height, chunk, num_threads);
    auto has_range = [&](int tx, int ty) {
      const size_t tile = size_t(ty) * ranges.tiles_x + tx;
      return ranges.near_m[tile] <= ranges.far_m[tile];
    };
    auto next = [&](RayTask& ray) {
      int x, y;
      if (!pixels.Next(x, y, has_range)) return false;
      const size_t tile = size_t(pixels.tile_y()) * ranges.tiles_x + pixels.tile_x();
      ray.x = x;
      ray.y = y;
      ray.in_camera = Eigen::Vector3f((static_cast<float>(x) - camera.cx) / camera.fx,
                                      (static_cast<float>(y) - camera.cy) / camera.fy, 1.0f);
      ray.t_begin = ranges.near_m[tile];
      ray.t_end = ranges.far_m[tile];
      return true;
    };
    march.MarchAll(volume, next, map);
  });
  return map;
}

namespace {

// Both CameraRays overloads; hints may be null.
PointMap CastRays(const TsdfVolume& volume, const CameraRays& rays, const core::Rigid3d& world_from_camera,
                  const RaycastOptions& options, const RayHints* hints) {
  assert(options.Check().empty());
  const int width = rays.width(), height = rays.height();
  assert(!hints || hints->range_m.size() == size_t(width) * height);
  PointMap map(width, height);
  if (options.with_colour) map.colours.assign(map.points.size(), Rgb8::Zero());
  if (width <= 0 || height <= 0 || volume.NumBlocks() == 0) return map;

  // Depth ranges where the rays are straight lines: in the covering pinhole, whose image
  // holds every ray's undistorted projection (a block a ray crosses projects onto it).
  const PinholeCamera& covering = rays.covering_pinhole();
  const float min_depth_m = static_cast<float>(options.min_depth_m), max_depth_m = static_cast<float>(options.max_depth_m);
  const DepthRanges ranges = internal::ProjectBlocks(volume, covering, world_from_camera, min_depth_m, max_depth_m, true,
                                                     options.num_threads);
  const RayMarch march = MakeMarch(volume, world_from_camera, options);
  const TsdfOptions::NoiseBand band = volume.options().Band();

  // As the pinhole overload, in tiles of the distorted image: neighbouring pixels have
  // neighbouring rays, whatever the lens, so the cache locality holds.
  const int num_threads = std::min(ResolveThreads(options.num_threads), (height + kTile - 1) / kTile);
  internal::RunChunks(num_threads, [&](int chunk) {
    // The thread's pixels with a ray, in tile order as the pinhole overload's.
    TilePixels pixels(width, height, chunk, num_threads);
    auto every_tile = [](int, int) { return true; };
    auto next = [&](RayTask& ray) {
      int x, y;
      do {
        if (!pixels.Next(x, y, every_tile)) return false;
      } while (!rays.valid(x, y));
      ray.x = x;
      ray.y = y;
      const Eigen::Vector2f xy = rays.xy(x, y);
      ray.in_camera = Eigen::Vector3f(xy.x(), xy.y(), 1.0f);
      ray.t_begin = 0;
      ray.t_end = -1;
      if (hints) {
        const float range_m = hints->range_m[size_t(y) * width + x];
        if (range_m > 0 && std::isfinite(range_m)) {
          // Range to depth along the optical axis: / |ray| (z = 1).
          const float metres_per_t = ray.in_camera.norm();
          const float t_hint = range_m / metres_per_t;
          ray.t_begin = std::max(t_hint - band.At(t_hint) / metres_per_t, min_depth_m);
          const float behind_m = std::max(hints->behind_m, hints->behind_fraction * range_m);
          ray.t_end = std::min(t_hint + behind_m / metres_per_t, max_depth_m);
        }
      }
      // Then its covering tile's range, as ProjectBlocks assigns pixels to tiles (nearest
      // pixel); empty where no block projects.
      const Eigen::Vector2f uv = rays.covering_pixel(x, y);
      const int tile_x = FloorToInt(uv.x() + 0.5f) / kTile, tile_y = FloorToInt(uv.y() + 0.5f) / kTile;
      assert(tile_x >= 0 && tile_y >= 0 && tile_x < ranges.tiles_x && tile_y < ranges.tiles_y);
      const size_t tile = size_t(tile_y) * ranges.tiles_x + tile_x;
      ray.t_begin_2 = ranges.near_m[tile];
      ray.t_end_2 = ranges.far_m[tile];
      return true;
    };
    march.MarchAll(volume, next, map);
  });
  return map;
}

}  // namespace

PointMap Raycast(const TsdfVolume& volume, const CameraRays& rays,
                 const core::Rigid3d& world_from_camera, const RaycastOptions& options) {
  return CastRays(volume, rays, world_from_camera, options, nullptr);
}

PointMap Raycast(const TsdfVolume& volume, const CameraRays& rays, const core::Rigid3d& world_from_camera,
                 const RaycastOptions& options, const RayHints& hints) {
  return CastRays(volume, rays, world_from_camera, options, &hints);
}

}  // namespace hw::reconstruct
