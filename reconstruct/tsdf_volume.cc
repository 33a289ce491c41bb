#include "reconstruct/tsdf_volume.h"

#include <cassert>
#include <cmath>

#include "reconstruct/option_check.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

std::string TsdfOptions::Check() const {
  if (!InRange(voxel_size_m, 0.0005, 0.5)) return Fail("voxel_size_m", voxel_size_m, "in [0.0005, 0.5] m");
  if (!(truncation_m >= 2 * voxel_size_m) || !std::isfinite(truncation_m)) {
    return Fail("truncation_m", truncation_m, "finite and >= 2 voxels (2 * voxel_size_m)");
  }
  if (!InRange(max_weight, 1, 65535)) return Fail("max_weight", max_weight, "in [1, 65535]");
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return Fail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return Fail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  return "";
}

using internal::KeyInRange;
using internal::PackKey;

TsdfVolume::TsdfVolume(const TsdfOptions& options) : options_(options), impl_(std::make_unique<Impl>()) {
  assert(options.Check().empty());
}
TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

float TsdfVolume::voxel_size_m() const { return static_cast<float>(options_.voxel_size_m); }

const VoxelBlock* TsdfVolume::FindBlock(const BlockKey& key) const {
  if (!KeyInRange(key.x(), key.y(), key.z())) return nullptr;
  return impl_->Find(PackKey(key.x(), key.y(), key.z()));
}

VoxelBlock& TsdfVolume::GetOrCreateBlock(const BlockKey& key) {
  assert(KeyInRange(key.x(), key.y(), key.z()));
  return *impl_->blocks[impl_->GetOrCreate(key)];
}

const Voxel* TsdfVolume::FindVoxel(const Eigen::Vector3i& voxel) const {
  return TsdfSampler(*this).FindVoxel(voxel);
}

std::optional<float> TsdfVolume::SdfAt(const Eigen::Vector3f& point_in_world) const {
  float sdf;
  if (!TsdfSampler(*this).Sdf(point_in_world, sdf)) return std::nullopt;
  return sdf;
}

std::optional<Eigen::Vector3f> TsdfVolume::NormalAt(const Eigen::Vector3f& point_in_world) const {
  Eigen::Vector3f normal;
  if (!TsdfSampler(*this).Normal(point_in_world, normal)) return std::nullopt;
  return normal;
}

std::optional<Rgb8> TsdfVolume::ColourAt(const Eigen::Vector3f& point_in_world) const {
  Rgb8 colour;
  if (!TsdfSampler(*this).Colour(point_in_world, colour)) return std::nullopt;
  return colour;
}

bool TsdfSampler::Normal(const Eigen::Vector3f& point_in_world, Eigen::Vector3f& normal) {
  const Eigen::Vector3f g = point_in_world * inv_voxel_m_;
  const Eigen::Vector3f base = g.array().floor();
  const Eigen::Vector3f f = g - base;
  // The 4×4×4 voxels from base − 1 to base + 2 hold every corner of the six samples
  // p ± one voxel along each axis; only the 32 of the three axis-aligned 4×2×2 bars are used.
  const Eigen::Vector3i lo = base.cast<int>().array() - 1;
  const int m = kBlockSide - 1;
  const Eigen::Vector3i k0(lo.x() >> kBlockShift, lo.y() >> kBlockShift, lo.z() >> kBlockShift);
  const Eigen::Vector3i l0(lo.x() & m, lo.y() & m, lo.z() & m);
  const int sx = l0.x() + 3 > m, sy = l0.y() + 3 > m, sz = l0.z() + 3 > m;
  const VoxelBlock* near[2][2][2] = {};
  for (int dz = 0; dz <= sz; ++dz) {
    for (int dy = 0; dy <= sy; ++dy) {
      for (int dx = 0; dx <= sx; ++dx) near[dz][dy][dx] = volume_->FindBlock(k0 + Eigen::Vector3i(dx, dy, dz));
    }
  }
  float s[4][4][4];  // [z][y][x], offsets −1 … 2 from base
  auto fetch = [&](int x, int y, int z) {
    const int ax = l0.x() + x, ay = l0.y() + y, az = l0.z() + z;
    const VoxelBlock* b = near[az >> kBlockShift][ay >> kBlockShift][ax >> kBlockShift];
    if (b == nullptr) return false;
    const Voxel& v = b->voxels[(ax & m) + kBlockSide * ((ay & m) + kBlockSide * (az & m))];
    s[z][y][x] = v.sdf;
    return v.weight > 0;
  };
  for (int a = 0; a < 4; ++a) {
    for (int b = 1; b <= 2; ++b) {
      for (int c = 1; c <= 2; ++c) {
        if (!fetch(a, b, c) || !fetch(b, a, c) || !fetch(b, c, a)) return false;
      }
    }
  }
  // Trilinear value at base + (ox, oy, oz) + f from the cell whose lowest corner is there.
  auto trilinear = [&](int ox, int oy, int oz) {
    const int x = ox + 1, y = oy + 1, z = oz + 1;
    const float x00 = s[z][y][x] + f.x() * (s[z][y][x + 1] - s[z][y][x]);
    const float x10 = s[z][y + 1][x] + f.x() * (s[z][y + 1][x + 1] - s[z][y + 1][x]);
    const float x01 = s[z + 1][y][x] + f.x() * (s[z + 1][y][x + 1] - s[z + 1][y][x]);
    const float x11 = s[z + 1][y + 1][x] + f.x() * (s[z + 1][y + 1][x + 1] - s[z + 1][y + 1][x]);
    const float y0 = x00 + f.y() * (x10 - x00);
    const float y1 = x01 + f.y() * (x11 - x01);
    return y0 + f.z() * (y1 - y0);
  };
  const Eigen::Vector3f gradient(trilinear(1, 0, 0) - trilinear(-1, 0, 0),
                                 trilinear(0, 1, 0) - trilinear(0, -1, 0),
                                 trilinear(0, 0, 1) - trilinear(0, 0, -1));
  const float norm = gradient.norm();
  if (!(norm > 1e-12f)) return false;
  normal = gradient / norm;
  return true;
}

bool TsdfSampler::Colour(const Eigen::Vector3f& point_in_world, Rgb8& colour) {
  std::array<const Voxel*, 8> c;
  Eigen::Vector3f f;
  if (Corners(point_in_world, c, f) != Status::kOk) return false;
  Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
  float total = 0;
  for (int i = 0; i < 8; ++i) {
    if (c[i]->colour_weight == 0) continue;
    const float w = ((i & 1) ? f.x() : 1 - f.x()) * ((i & 2) ? f.y() : 1 - f.y()) * ((i & 4) ? f.z() : 1 - f.z());
    rgb += w * c[i]->colour.cast<float>();
    total += w;
  }
  if (total > 1e-6f) rgb /= total;
  else rgb.setZero();
  colour = (rgb.array() + 0.5f).min(255.0f).max(0.0f).matrix().cast<std::uint8_t>();
  return true;
}

size_t TsdfVolume::NumBlocks() const { return impl_->blocks.size(); }

size_t TsdfVolume::MemoryBytes() const {
  // Blocks, the block pointer and stamp arrays and the hash map's nodes and buckets
  // (libstdc++: a node holds the pair and a next pointer).
  const size_t node = sizeof(std::pair<const uint64_t, int32_t>) + sizeof(void*);
  return impl_->blocks.size() * (sizeof(VoxelBlock) + sizeof(void*) + sizeof(uint32_t)) +
         impl_->index.size() * node + impl_->index.bucket_count() * sizeof(void*);
}

void TsdfVolume::ForEachBlock(const std::function<void(const VoxelBlock&)>& f) const {
  for (const auto& block : impl_->blocks) f(*block);
}

void TsdfVolume::Bounds(Eigen::Vector3f& min_m, Eigen::Vector3f& max_m) const {
  if (impl_->blocks.empty()) {
    min_m.setZero();
    max_m.setZero();
    return;
  }
  Eigen::Vector3i lo = impl_->blocks.front()->key, hi = lo;
  for (const auto& block : impl_->blocks) {
    lo = lo.cwiseMin(block->key);
    hi = hi.cwiseMax(block->key);
  }
  const float block_m = voxel_size_m() * kBlockSide;
  // Voxel centres of block k span [k·8, k·8 + 7] voxels.
  min_m = lo.cast<float>() * block_m;
  max_m = (hi.cast<float>() * block_m).array() + (kBlockSide - 1) * voxel_size_m();
}

}  // namespace hw::reconstruct
