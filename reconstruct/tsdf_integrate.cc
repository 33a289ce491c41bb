// TsdfVolume::Integrate: allocation of the blocks around the measured surface, then the
// projective TSDF update of every voxel of the blocks seen this frame (KinectFusion,
// Newcombe et al. 2011; block-wise as InfiniTAM, Prisacariu et al. 2017).
//
// The distance stored is the projective one: sdf = depth at the voxel's projection (bilinear
// between the four pixels around it when they lie on one surface, else the nearest pixel's)
// − z of the voxel, along the camera's optical axis. It is exact for a surface facing the camera and
// overestimates the Euclidean distance by 1 / cos(angle between the viewing ray and the
// surface normal) elsewhere; the zero crossing, the only thing raycasting and meshing read,
// stays exactly on the measured surface whatever the angle, and averaging over views with
// different angles only changes the slope of the field away from it. It needs one
// projection per voxel and no search for the nearest surface point, which is what keeps
// fusion at frame rate.

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

#include <Eigen/Geometry>

#include "reconstruct/tsdf_volume.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

using internal::KeyInRange;
using internal::PackKey;

namespace {

// Appends the keys of the blocks a segment (block units, a to b) passes through, in order
// (Amanatides & Woo 1987 grid traversal), skipping those among the last few appended: the
// segments of neighbouring pixels mostly cross the same blocks.
class SegmentBlocks {
 public:
  explicit SegmentBlocks(std::vector<uint64_t>& out) : out_(out) {}

  void Walk(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    int cell[3], step[3];
    float t_max[3], t_delta[3];
    for (int i = 0; i < 3; ++i) {
      const float d = b[i] - a[i];
      cell[i] = FloorToInt(a[i]);
      if (d > 0) {
        step[i] = 1;
        t_delta[i] = 1.0f / d;
        t_max[i] = (static_cast<float>(cell[i]) + 1 - a[i]) / d;
      } else if (d < 0) {
        step[i] = -1;
        t_delta[i] = -1.0f / d;
        t_max[i] = (a[i] - static_cast<float>(cell[i])) / -d;
      } else {
        step[i] = 0;
        t_delta[i] = t_max[i] = std::numeric_limits<float>::infinity();
      }
    }
    // A segment 2·truncation long crosses at most 3 · (2·truncation / block + 1) + 1 blocks;
    // the bound only guards against rounding.
    for (int n = 0; n < 64; ++n) {
      Add(cell[0], cell[1], cell[2]);
      const int axis = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
      if (t_max[axis] > 1) break;
      cell[axis] += step[axis];
      t_max[axis] += t_delta[axis];
    }
  }

 private:
  void Add(int x, int y, int z) {
    if (!KeyInRange(x, y, z)) return;
    const uint64_t key = PackKey(x, y, z);
    for (const uint64_t r : recent_) {
      if (r == key) return;
    }
    recent_[next_] = key;
    next_ = (next_ + 1) % recent_.size();
    out_.push_back(key);
  }

  std::vector<uint64_t>& out_;
  std::array<uint64_t, 16> recent_ = MakeRecent();
  size_t next_ = 0;
  static std::array<uint64_t, 16> MakeRecent() {
    std::array<uint64_t, 16> r;
    r.fill(~uint64_t{0});  // no valid packed key has all 64 bits set
    return r;
  }
};

BlockKey Unpack(uint64_t key) {
  auto field = [](uint64_t v) {
    const int x = static_cast<int>(v & ((uint64_t{1} << 21) - 1));
    return x >= (1 << 20) ? x - (1 << 21) : x;
  };
  return {field(key >> 42), field(key >> 21), field(key)};
}

}  // namespace

IntegrateStats TsdfVolume::Integrate(const cv::Mat& depth_m, const PinholeCamera& camera,
                                     const core::Rigid3d& world_from_camera,
                                     const ColourView* colour) {
  assert(depth_m.type() == CV_32FC1 && depth_m.cols == camera.width && depth_m.rows == camera.height);
  assert(colour == nullptr || colour->rgb.empty() ||
         (colour->rgb.type() == CV_8UC3 && colour->rgb.cols == colour->camera.width &&
          colour->rgb.rows == colour->camera.height));
  IntegrateStats stats;
  Impl& impl = *impl_;
  const int num_threads = internal::ResolveThreads(options_.num_threads);
  const float voxel_m = voxel_size_m();
  const float block_m = voxel_m * kBlockSide;
  const float truncation_m = static_cast<float>(options_.truncation_m);
  const float min_depth_m = static_cast<float>(options_.min_depth_m);
  const float max_depth_m = static_cast<float>(options_.max_depth_m);
  const int width = camera.width, height = camera.height;

  // 1. Allocation. Every valid pixel's viewing ray between depth − truncation and depth +
  // truncation is walked through the block grid. Pixels are sampled every `stride` in x and
  // y, with the stride chosen so that neighbouring samples land less than a quarter block
  // apart at the farthest depth of the frame: a surface patch a quarter block wide is then
  // always hit, and what the sampling misses is a sliver of a block corner whose voxels the
  // next frames (a hand-held camera moves) pick up.
  float far_m = 0;
  for (int y = 0; y < height; ++y) {
    const float* row = depth_m.ptr<float>(y);
    for (int x = 0; x < width; ++x) {
      const float d = row[x];
      if (d >= min_depth_m && d <= max_depth_m && d > far_m) far_m = d;
    }
  }
  if (far_m == 0) return stats;  // nothing to fuse: no block allocated or touched
  const float pixel_m = far_m / std::min(camera.fx, camera.fy);  // footprint of a pixel
  const int stride = std::clamp(static_cast<int>(0.25f * block_m / pixel_m), 1, 8);

  const Eigen::Matrix3f rotation = world_from_camera.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f origin_m = world_from_camera.translation.cast<float>();
  std::vector<std::vector<uint64_t>> keys(num_threads);
  internal::RunChunks(num_threads, [&](int chunk) {
    const int rows = (height + stride - 1) / stride;
    const int row_begin = rows * chunk / num_threads, row_end = rows * (chunk + 1) / num_threads;
    SegmentBlocks walker(keys[chunk]);
    const float inv_block = 1.0f / block_m;
    for (int r = row_begin; r < row_end; ++r) {
      const int y = r * stride;
      const float* row = depth_m.ptr<float>(y);
      for (int x = 0; x < width; x += stride) {
        const float d = row[x];
        if (!(d >= min_depth_m && d <= max_depth_m)) continue;
        const Eigen::Vector3f ray = rotation * camera.Unproject(static_cast<float>(x), static_cast<float>(y), 1.0f);
        const float near_m = std::max(d - truncation_m, 0.0f);
        walker.Walk((origin_m + near_m * ray) * inv_block, (origin_m + (d + truncation_m) * ray) * inv_block);
      }
    }
  });

  // Serial: the hash is never mutated concurrently. The visible list is deduplicated by the
  // stamp of this call.
  const uint32_t stamp = ++impl.integrate_count;
  std::vector<VoxelBlock*> visible;
  const size_t blocks_before = impl.blocks.size();
  for (const auto& chunk_keys : keys) {
    for (const uint64_t key : chunk_keys) {
      const auto it = impl.index.find(key);
      const int32_t index = it != impl.index.end() ? it->second : impl.GetOrCreate(Unpack(key));
      if (impl.visit_stamp[index] == stamp) continue;
      impl.visit_stamp[index] = stamp;
      visible.push_back(impl.blocks[index].get());
    }
  }
  stats.blocks_allocated = static_cast<int>(impl.blocks.size() - blocks_before);
  stats.blocks_visible = static_cast<int>(visible.size());

  // 2. Update of the voxels of the visible blocks, in num_threads contiguous chunks (each
  // block belongs to one chunk: no two threads write one voxel).
  const core::Rigid3d camera_from_world = world_from_camera.Inverse();
  const Eigen::Matrix3f cw_rotation = camera_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f cw_translation = camera_from_world.translation.cast<float>();
  const bool with_colour = colour != nullptr && !colour->rgb.empty();
  Eigen::Matrix3f colour_from_camera_rotation = Eigen::Matrix3f::Identity();
  Eigen::Vector3f colour_from_camera_translation = Eigen::Vector3f::Zero();
  if (with_colour) {
    const core::Rigid3d colour_from_camera = colour->world_from_camera.Inverse() * world_from_camera;
    colour_from_camera_rotation = colour_from_camera.rotation.toRotationMatrix().cast<float>();
    colour_from_camera_translation = colour_from_camera.translation.cast<float>();
  }
  const float colour_fx = with_colour ? colour->camera.fx : 0, colour_fy = with_colour ? colour->camera.fy : 0;
  const float colour_cx = with_colour ? colour->camera.cx : 0, colour_cy = with_colour ? colour->camera.cy : 0;
  const float colour_u_limit = with_colour ? static_cast<float>(colour->camera.width) - 0.5f : 0;
  const float colour_v_limit = with_colour ? static_cast<float>(colour->camera.height) - 0.5f : 0;
  const std::uint8_t* colour_rgb = with_colour ? colour->rgb.ptr<std::uint8_t>(0) : nullptr;
  const size_t colour_step = with_colour ? colour->rgb.step1() : 0;
  const float max_weight = static_cast<float>(options_.max_weight);
  const int max_colour_weight = static_cast<int>(std::min(options_.max_weight, 255.0));
  const float inv_truncation = 1.0f / truncation_m;
  const float u_limit = static_cast<float>(width) - 0.5f, v_limit = static_cast<float>(height) - 0.5f;
  const float u_inner = static_cast<float>(width - 1), v_inner = static_cast<float>(height - 1);
  const float half_truncation_m = 0.5f * truncation_m;
  const float edge_slope_per_m = 4.0f / std::min(camera.fx, camera.fy);  // depth steps, see below
  const float fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy;
  const size_t depth_step = depth_m.step1();
  const float* depth = depth_m.ptr<float>(0);

  // 1 / (w + 1) for every weight a voxel can hold (integers up to max_weight): a
  // multiplication instead of a division per voxel.
  if (impl.inv_count.empty()) {
    impl.inv_count.resize(static_cast<size_t>(max_weight) + 1);
    for (size_t w = 0; w < impl.inv_count.size(); ++w) impl.inv_count[w] = 1.0f / static_cast<float>(w + 1);
  }
  const float* inv_count = impl.inv_count.data();
  std::vector<int64_t> updated(num_threads, 0);
  internal::RunChunks(num_threads, [&](int chunk) {
    const size_t begin = visible.size() * chunk / num_threads;
    const size_t end = visible.size() * (chunk + 1) / num_threads;
    // Voxel steps along the world axes, in the camera frame.
    const Eigen::Vector3f step_x = cw_rotation.col(0) * voxel_m;
    const Eigen::Vector3f step_y = cw_rotation.col(1) * voxel_m;
    const Eigen::Vector3f step_z = cw_rotation.col(2) * voxel_m;
    int64_t count = 0;
    for (size_t b = begin; b < end; ++b) {
      VoxelBlock& block = *visible[b];
      const Eigen::Vector3f corner_in_world = block.key.cast<float>() * block_m;
      const Eigen::Vector3f corner_in_camera = cw_rotation * corner_in_world + cw_translation;
      Voxel* voxel = block.voxels.data();
      for (int z = 0; z < kBlockSide; ++z) {
        for (int y = 0; y < kBlockSide; ++y) {
          Eigen::Vector3f p = corner_in_camera + static_cast<float>(y) * step_y + static_cast<float>(z) * step_z;
          for (int x = 0; x < kBlockSide; ++x, ++voxel, p += step_x) {
            if (!(p.z() > 0)) continue;
            const float inv_z = 1.0f / p.z();
            const float u = fx * p.x() * inv_z + cx, v = fy * p.y() * inv_z + cy;
            if (!(u > -0.5f && u < u_limit && v > -0.5f && v < v_limit)) continue;
            float d = depth[static_cast<size_t>(v + 0.5f) * depth_step + static_cast<size_t>(u + 0.5f)];
            if (!(d >= min_depth_m && d <= max_depth_m)) continue;
            // Bilinear depth can move d by at most the spread it accepts (below): beyond
            // that margin around the band the voxel is free space (tsdf 1) or hidden
            // either way, and most voxels of a block are one or the other.
            const float margin_m = truncation_m + half_truncation_m + d * edge_slope_per_m;
            if (d - p.z() < -margin_m) continue;
            if (d - p.z() < margin_m && u >= 0 && v >= 0 && u < u_inner && v < v_inner) {
              // Bilinear depth where the four pixels around lie on one surface: the nearest
              // pixel's depth alone would be off by up to half a pixel times the depth slope
              // (a quarter voxel on a 45° wall). One surface: a spread below half a
              // truncation plus what a surface at up to 76° (slope 4) to the view spans
              // over a pixel; a larger jump is a depth edge, where interpolating would
              // invent a surface between the two.
              const int x0 = static_cast<int>(u), y0 = static_cast<int>(v);
              const float* d0 = depth + static_cast<size_t>(y0) * depth_step + x0;
              const float* d1 = d0 + depth_step;
              const float lo = std::min(std::min(d0[0], d0[1]), std::min(d1[0], d1[1]));
              const float hi = std::max(std::max(d0[0], d0[1]), std::max(d1[0], d1[1]));
              // (NaN fails every comparison: such a pixel keeps the nearest depth.)
              if (lo >= min_depth_m && hi <= max_depth_m && hi - lo < half_truncation_m + lo * edge_slope_per_m &&
                  d0[0] == d0[0] && d0[1] == d0[1] && d1[0] == d1[0] && d1[1] == d1[1]) {
                const float a = u - static_cast<float>(x0), c = v - static_cast<float>(y0);
                const float top = d0[0] + a * (d0[1] - d0[0]), bottom = d1[0] + a * (d1[1] - d1[0]);
                d = top + c * (bottom - top);
              }
            }
            const float sdf_m = d - p.z();
            if (sdf_m < -truncation_m) continue;  // hidden behind the surface: unknown
            const float tsdf = std::min(1.0f, sdf_m * inv_truncation);
            const float w = voxel->weight;
            const int wi = static_cast<int>(w);  // only a fractional max_weight is not whole
            const float inv = static_cast<float>(wi) == w ? inv_count[wi] : 1.0f / (w + 1);
            voxel->sdf = (voxel->sdf * w + tsdf) * inv;
            voxel->weight = std::min(w + 1, max_weight);
            ++count;
            if (!with_colour || sdf_m >= truncation_m) continue;
            const Eigen::Vector3f q = colour_from_camera_rotation * p + colour_from_camera_translation;
            if (!(q.z() > 0)) continue;
            const float inv_qz = 1.0f / q.z();
            const float cu = colour_fx * q.x() * inv_qz + colour_cx, cv = colour_fy * q.y() * inv_qz + colour_cy;
            if (!(cu > -0.5f && cu < colour_u_limit && cv > -0.5f && cv < colour_v_limit)) continue;
            const auto* rgb = colour_rgb + static_cast<size_t>(cv + 0.5f) * colour_step + 3 * static_cast<size_t>(cu + 0.5f);
            const int cw = voxel->colour_weight;
            const float inv_cw = inv_count[cw];  // cw <= min(max_weight, 255)
            for (int c = 0; c < 3; ++c) {
              const float mean = (static_cast<float>(voxel->colour[c]) * static_cast<float>(cw) + rgb[c]) * inv_cw;
              voxel->colour[c] = static_cast<std::uint8_t>(mean + 0.5f);
            }
            voxel->colour_weight = static_cast<std::uint8_t>(std::min(cw + 1, max_colour_weight));
          }
        }
      }
    }
    updated[chunk] = count;
  });
  for (const int64_t n : updated) stats.voxels_updated += n;
  return stats;
}

}  // namespace hw::reconstruct
