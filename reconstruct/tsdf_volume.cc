#include "reconstruct/tsdf_volume.h"

#include <cassert>
#include <cmath>
#include <unordered_map>

#include "reconstruct/option_check.h"

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

namespace {

struct BlockKeyHash {
  size_t operator()(const BlockKey& k) const {
    // The spatial hash of Teschner et al. (2003), as voxel hashing uses.
    return static_cast<size_t>((static_cast<uint64_t>(k.x()) * 73856093u) ^
                               (static_cast<uint64_t>(k.y()) * 19349669u) ^
                               (static_cast<uint64_t>(k.z()) * 83492791u));
  }
};
struct BlockKeyEqual {
  bool operator()(const BlockKey& a, const BlockKey& b) const { return a == b; }
};

int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

}  // namespace

struct TsdfVolume::Impl {
  std::unordered_map<BlockKey, int, BlockKeyHash, BlockKeyEqual> index;
  // Stable addresses: blocks are never moved once created.
  std::vector<std::unique_ptr<VoxelBlock>> blocks;
};

TsdfVolume::TsdfVolume(const TsdfOptions& options) : options_(options), impl_(std::make_unique<Impl>()) {
  assert(options.Check().empty());
}
TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

float TsdfVolume::voxel_size_m() const { return static_cast<float>(options_.voxel_size_m); }

const VoxelBlock* TsdfVolume::FindBlock(const BlockKey& key) const {
  const auto it = impl_->index.find(key);
  return it == impl_->index.end() ? nullptr : impl_->blocks[it->second].get();
}

VoxelBlock& TsdfVolume::GetOrCreateBlock(const BlockKey& key) {
  const auto [it, inserted] = impl_->index.try_emplace(key, static_cast<int>(impl_->blocks.size()));
  if (inserted) {
    auto block = std::make_unique<VoxelBlock>();
    block->key = key;
    impl_->blocks.push_back(std::move(block));
  }
  return *impl_->blocks[it->second];
}

const Voxel* TsdfVolume::FindVoxel(const Eigen::Vector3i& voxel) const {
  const BlockKey key(FloorDiv(voxel.x(), kBlockSide), FloorDiv(voxel.y(), kBlockSide),
                     FloorDiv(voxel.z(), kBlockSide));
  const VoxelBlock* block = FindBlock(key);
  if (block == nullptr) return nullptr;
  const Eigen::Vector3i local = voxel - key * kBlockSide;
  return &block->voxels[local.x() + kBlockSide * (local.y() + kBlockSide * local.z())];
}

namespace {

// The 8 voxels around a world point and the trilinear weights; false when one is unobserved.
bool Corners(const TsdfVolume& volume, const Eigen::Vector3f& point_in_world,
             std::array<const Voxel*, 8>& voxels, std::array<float, 8>& weights) {
  const Eigen::Vector3f g = point_in_world / volume.voxel_size_m();
  const Eigen::Vector3f base = g.array().floor();
  const Eigen::Vector3f f = g - base;
  const Eigen::Vector3i b = base.cast<int>();
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const Voxel* v = volume.FindVoxel(b + Eigen::Vector3i(dx, dy, dz));
    if (v == nullptr || v->weight <= 0) return false;
    voxels[c] = v;
    weights[c] = (dx ? f.x() : 1 - f.x()) * (dy ? f.y() : 1 - f.y()) * (dz ? f.z() : 1 - f.z());
  }
  return true;
}

}  // namespace

std::optional<float> TsdfVolume::SdfAt(const Eigen::Vector3f& point_in_world) const {
  std::array<const Voxel*, 8> voxels;
  std::array<float, 8> weights;
  if (!Corners(*this, point_in_world, voxels, weights)) return std::nullopt;
  float sdf = 0;
  for (int c = 0; c < 8; ++c) sdf += weights[c] * voxels[c]->sdf;
  return sdf;
}

std::optional<Eigen::Vector3f> TsdfVolume::NormalAt(const Eigen::Vector3f& point_in_world) const {
  const float h = voxel_size_m();
  Eigen::Vector3f gradient;
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Vector3f step = Eigen::Vector3f::Zero();
    step[axis] = h;
    const auto plus = SdfAt(point_in_world + step);
    const auto minus = SdfAt(point_in_world - step);
    if (!plus || !minus) return std::nullopt;
    gradient[axis] = *plus - *minus;
  }
  const float norm = gradient.norm();
  if (!(norm > 1e-12f)) return std::nullopt;
  return gradient / norm;
}

std::optional<Rgb8> TsdfVolume::ColourAt(const Eigen::Vector3f& point_in_world) const {
  std::array<const Voxel*, 8> voxels;
  std::array<float, 8> weights;
  if (!Corners(*this, point_in_world, voxels, weights)) return std::nullopt;
  Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
  for (int c = 0; c < 8; ++c) rgb += weights[c] * voxels[c]->colour.cast<float>();
  return (rgb.array() + 0.5f).min(255.0f).max(0.0f).matrix().cast<std::uint8_t>();
}

size_t TsdfVolume::NumBlocks() const { return impl_->blocks.size(); }

size_t TsdfVolume::MemoryBytes() const {
  // Blocks, the block pointer array and the hash map's nodes and buckets (libstdc++: a node
  // holds the pair and a next pointer; the cached hash is stored too).
  const size_t node = sizeof(std::pair<const BlockKey, int>) + 2 * sizeof(void*);
  return impl_->blocks.size() * (sizeof(VoxelBlock) + sizeof(void*)) +
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
