#include "reconstruct/tsdf_volume.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <mutex>
#include <new>

#include <sys/mman.h>

#include <absl/container/flat_hash_set.h>

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
  if (!(truncation_noise_sigmas >= 0) || !std::isfinite(truncation_noise_sigmas)) {
    return Fail("truncation_noise_sigmas", truncation_noise_sigmas, "finite and >= 0");
  }
  if (std::string m = noise.Check(); !m.empty()) return "noise." + m;
  if (!InRange(max_weight, 1, 65535) || max_weight != std::floor(max_weight)) {
    return Fail("max_weight", max_weight, "a whole number in [1, 65535]");
  }
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return Fail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return Fail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  return "";
}

double TsdfOptions::CoarseBeyondM(double focal_px) const {
  constexpr double kNever = std::numeric_limits<double>::infinity();
  if (!coarse_far) return kNever;
  // σ_z(z) >= 2 voxels: z >= reference + sqrt((2 v − base) / quadratic), and at once from the
  // reference when the noise starts there.
  const double excess_m = 2 * voxel_size_m - noise.base_m;
  double noisy_m = noise.reference_m;
  if (excess_m > 0) noisy_m = noise.quadratic_per_m > 0 ? noise.reference_m + std::sqrt(excess_m / noise.quadratic_per_m) : kNever;
  return std::max(noisy_m, focal_px * voxel_size_m);  // a pixel z / f wider than a voxel
}

using internal::KeyInRange;
using internal::PackKey;

// Region key → the blocks in it, in creation order; extended by ForEachBlockInRegions with
// the blocks created since its last call (blocks are only ever appended to Impl::blocks).
struct TsdfVolume::RegionIndex {
  std::mutex mutex;      // const callers on several threads share the lazy update
  size_t num_indexed = 0;  // Impl::blocks[0, num_indexed) are in `blocks`
  absl::flat_hash_map<uint64_t, int32_t> slot;  // packed region key → index in keys/blocks
  std::vector<Eigen::Vector3i> keys;
  std::vector<std::vector<const VoxelBlock*>> blocks;
};

BlockArena::~BlockArena() {
  for (void* chunk : chunks_) munmap(chunk, kChunkBytes);
}

void* BlockArena::Allocate() {
  if (used_in_last_ + kStride > kChunkBytes) {
    // Populated at once: one call instead of a page fault per 4 KB on first touch.
    void* chunk = mmap(nullptr, kChunkBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE, -1, 0);
    if (chunk == MAP_FAILED) throw std::bad_alloc();
    chunks_.push_back(chunk);
    used_in_last_ = 0;
  }
  void* at = static_cast<char*>(chunks_.back()) + used_in_last_;
  used_in_last_ += kStride;
  return at;
}

VoxelBlock* BlockArena::Construct(void* at, const BlockKey& key) {
  static_assert(std::is_trivially_destructible_v<VoxelBlock>);  // never destroyed one by one
  // Copied from a fresh block: value-initialising 512 voxels one by one took 4 µs a block.
  static const VoxelBlock kFresh{};
  VoxelBlock* block = new (at) VoxelBlock(kFresh);
  block->key = key;
  return block;
}

TsdfVolume::TsdfVolume(const TsdfOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()), regions_(std::make_unique<RegionIndex>()) {
  assert(options.Check().empty());
}
TsdfVolume::~TsdfVolume() = default;
TsdfVolume::TsdfVolume(TsdfVolume&&) noexcept = default;
TsdfVolume& TsdfVolume::operator=(TsdfVolume&&) noexcept = default;

float TsdfVolume::voxel_size_m() const { return static_cast<float>(options_.voxel_size_m); }

int64_t TsdfVolume::CarveFreeSpace(const std::vector<Eigen::Vector3f>& points_in_world,
                                   const Eigen::Vector3f& camera_in_world) {
  const float voxel_m = voxel_size_m(), inv_voxel_m = 1.0f / voxel_m;
  const float max_weight = static_cast<float>(options_.max_weight);
  const TsdfOptions::NoiseBand band = options_.Band();
  // Each voxel once per call: rays of neighbouring points cross the same voxels.
  absl::flat_hash_set<uint64_t> done;
  int64_t updated = 0;
  for (const Eigen::Vector3f& point : points_in_world) {
    const Eigen::Vector3f ray = point - camera_in_world;
    const float length = ray.norm();
    if (!(length > 0)) continue;
    const Eigen::Vector3f direction = ray / length;
    // Half-voxel steps over the band around the point (its width at the point's range: what
    // a frame that saw it from here fused), nearest voxel.
    const int steps = static_cast<int>(std::ceil(band.At(length) / (0.5f * voxel_m)));
    for (int k = -steps; k <= steps; ++k) {
      const Eigen::Vector3f p = point + (static_cast<float>(k) * 0.5f * voxel_m) * direction;
      const int ix = FloorToInt(p.x() * inv_voxel_m + 0.5f), iy = FloorToInt(p.y() * inv_voxel_m + 0.5f),
                iz = FloorToInt(p.z() * inv_voxel_m + 0.5f);
      if (!internal::KeyInRange(ix >> kBlockShift, iy >> kBlockShift, iz >> kBlockShift)) continue;
      if (!done.insert(internal::PackKey(ix, iy, iz)).second) continue;
      VoxelBlock* block = impl_->Find(internal::PackKey(ix >> kBlockShift, iy >> kBlockShift, iz >> kBlockShift));
      if (block == nullptr) continue;
      constexpr int m = kBlockSide - 1;
      Voxel& v = block->voxels[(ix & m) + kBlockSide * ((iy & m) + kBlockSide * (iz & m))];
      if (!v.observed()) continue;
      block->LowerBand(band.At(length));  // carving fuses a "free space" reading of this range's band
      const float w = v.weight();
      v.set_sdf((v.sdf() * w + 1.0f) / (w + 1.0f));
      v.set_weight(std::min(w + 1.0f, max_weight));
      ++updated;
    }
  }
  return updated;
}

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

TsdfSampler::Status TsdfSampler::Corners(const Eigen::Vector3f& point_in_world,
                                         std::array<const Voxel*, 8>& corners, Eigen::Vector3f& fraction) {
  const Cell cell = Locate(point_in_world);
  fraction = Eigen::Vector3f(cell.fx, cell.fy, cell.fz);
  if (cell.block == nullptr) return Status::kNoBlock;
  const int m = kBlockSide - 1;
  for (int c = 0; c < 8; ++c) {
    const int x = cell.ix + (c & 1), y = cell.iy + ((c >> 1) & 1), z = cell.iz + (c >> 2);
    const VoxelBlock* b = Block(x >> kBlockShift, y >> kBlockShift, z >> kBlockShift);
    if (b == nullptr) return Status::kUnobserved;
    corners[c] = &b->voxels[(x & m) + kBlockSide * ((y & m) + kBlockSide * (z & m))];
    if (!corners[c]->observed()) return Status::kUnobserved;
  }
  return Status::kOk;
}

TsdfSampler::Status TsdfSampler::SampleAcrossBlocks(int ix, int iy, int iz, float fx, float fy, float fz,
                                                    float& sdf) {
  // The cell's lowest corner is in block k and at voxel l of it; per axis the upper corner
  // is in the next block only when l is the block's last voxel. Each distinct block is
  // looked up once (two, four or eight of them), not once per corner.
  const int m = kBlockSide - 1;
  const int kx = ix >> kBlockShift, ky = iy >> kBlockShift, kz = iz >> kBlockShift;
  const int lx = ix & m, ly = iy & m, lz = iz & m;
  const int nx = lx == m, ny = ly == m, nz = lz == m;
  const VoxelBlock* b[2][2][2];  // [z][y][x]: 0 the lowest corner's block, 1 the next one
  for (int z = 0; z <= 1; ++z) {
    for (int y = 0; y <= 1; ++y) {
      for (int x = 0; x <= 1; ++x) {
        const int dx = x & nx, dy = y & ny, dz = z & nz;
        if ((dx != x) | (dy != y) | (dz != z)) {
          b[z][y][x] = b[dz][dy][dx];  // the block of a corner already looked up
        } else {
          b[z][y][x] = Block(kx + dx, ky + dy, kz + dz);
        }
      }
    }
  }
  const int ox[2] = {lx, (lx + 1) & m};
  const int oy[2] = {kBlockSide * ly, kBlockSide * ((ly + 1) & m)};
  const int oz[2] = {kBlockSide * kBlockSide * lz, kBlockSide * kBlockSide * ((lz + 1) & m)};
  float s[8];
  for (int c = 0; c < 8; ++c) {
    const int x = c & 1, y = (c >> 1) & 1, z = c >> 2;
    const VoxelBlock* block = b[z][y][x];
    if (block == nullptr) return Status::kUnobserved;
    const Voxel& v = block->voxels[ox[x] + oy[y] + oz[z]];
    if (!v.observed()) return Status::kUnobserved;
    s[c] = v.sdf();
  }
  sdf = Trilinear(s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7], fx, fy, fz);
  return Status::kOk;
}

bool TsdfSampler::Normal(const Eigen::Vector3f& point_in_world, Eigen::Vector3f& normal) {
  const Eigen::Vector3f g = point_in_world * inv_voxel_m_;
  const Eigen::Vector3i base(FloorToInt(g.x()), FloorToInt(g.y()), FloorToInt(g.z()));
  const Eigen::Vector3f f = g - base.cast<float>();
  // The 4×4×4 voxels from base − 1 to base + 2 hold every corner of the six samples
  // p ± one voxel along each axis; only the 32 of the three axis-aligned 4×2×2 bars are used.
  const Eigen::Vector3i lo = base.array() - 1;
  const int m = kBlockSide - 1;
  const Eigen::Vector3i k0(lo.x() >> kBlockShift, lo.y() >> kBlockShift, lo.z() >> kBlockShift);
  const Eigen::Vector3i l0(lo.x() & m, lo.y() & m, lo.z() & m);
  const int sx = l0.x() + 3 > m, sy = l0.y() + 3 > m, sz = l0.z() + 3 > m;
  const VoxelBlock* near[2][2][2] = {};
  for (int dz = 0; dz <= sz; ++dz) {
    for (int dy = 0; dy <= sy; ++dy) {
      for (int dx = 0; dx <= sx; ++dx) near[dz][dy][dx] = Block(k0 + Eigen::Vector3i(dx, dy, dz));
    }
  }
  float s[4][4][4];  // [z][y][x], offsets −1 … 2 from base
  bool observed = true;
  if ((sx | sy | sz) == 0) {  // all in one block: plain indexing
    if (near[0][0][0] == nullptr) return false;
    const Voxel* v0 = &near[0][0][0]->voxels[l0.x() + kBlockSide * (l0.y() + kBlockSide * l0.z())];
    auto fetch = [&](int x, int y, int z) {
      const Voxel& v = v0[x + kBlockSide * (y + kBlockSide * z)];
      s[z][y][x] = v.sdf();
      observed &= v.observed();
    };
    for (int a = 0; a < 4; ++a) {
      for (int b = 1; b <= 2; ++b) {
        for (int c = 1; c <= 2; ++c) {
          fetch(a, b, c);
          fetch(b, a, c);
          fetch(b, c, a);
        }
      }
    }
  } else {
    // Per axis, which of the two blocks and which voxel in it each offset −1 … 2 falls in.
    int bx[4], by[4], bz[4], ix[4], iy[4], iz[4];
    for (int a = 0; a < 4; ++a) {
      bx[a] = (l0.x() + a) >> kBlockShift;
      by[a] = (l0.y() + a) >> kBlockShift;
      bz[a] = (l0.z() + a) >> kBlockShift;
      ix[a] = (l0.x() + a) & m;
      iy[a] = kBlockSide * ((l0.y() + a) & m);
      iz[a] = kBlockSide * kBlockSide * ((l0.z() + a) & m);
    }
    auto fetch = [&](int x, int y, int z) {
      const VoxelBlock* b = near[bz[z]][by[y]][bx[x]];
      if (b == nullptr) return false;
      const Voxel& v = b->voxels[ix[x] + iy[y] + iz[z]];
      s[z][y][x] = v.sdf();
      return v.observed();
    };
    for (int a = 0; a < 4; ++a) {
      for (int b = 1; b <= 2; ++b) {
        for (int c = 1; c <= 2; ++c) {
          if (!fetch(a, b, c) || !fetch(b, a, c) || !fetch(b, c, a)) return false;
        }
      }
    }
  }
  if (!observed) return false;
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
  // Blocks, the block pointer and stamp arrays, and the hash table's slots (key, block
  // address and index) and control bytes (one per slot).
  return impl_->blocks.size() * (sizeof(VoxelBlock) + sizeof(void*) + sizeof(uint32_t)) +
         impl_->index.capacity() * (sizeof(std::pair<uint64_t, Impl::Entry>) + 1);
}

void TsdfVolume::ForEachBlock(const std::function<void(const VoxelBlock&)>& f) const {
  for (const auto& block : impl_->blocks) f(*block);
}

void TsdfVolume::UpdateRegionIndex() const {
  static_assert(kRegionBlocks == 8);  // region key = block key >> 3
  RegionIndex& r = *regions_;
  for (; r.num_indexed < impl_->blocks.size(); ++r.num_indexed) {
    const VoxelBlock* block = impl_->blocks[r.num_indexed];
    const Eigen::Vector3i key(block->key.x() >> 3, block->key.y() >> 3, block->key.z() >> 3);
    const auto [it, inserted] = r.slot.try_emplace(PackKey(key.x(), key.y(), key.z()),
                                                   static_cast<int32_t>(r.keys.size()));
    if (inserted) {
      r.keys.push_back(key);
      r.blocks.emplace_back();
    }
    r.blocks[it->second].push_back(block);
  }
}

std::vector<Eigen::Vector3i> TsdfVolume::RegionKeys() const {
  RegionIndex& r = *regions_;
  const std::lock_guard<std::mutex> lock(r.mutex);
  UpdateRegionIndex();
  return r.keys;
}

void TsdfVolume::ForEachBlockInRegions(
    const std::function<bool(const Eigen::Vector3f& min_m, const Eigen::Vector3f& max_m)>& keep_region,
    const std::function<void(const VoxelBlock&)>& f) const {
  RegionIndex& r = *regions_;
  const std::lock_guard<std::mutex> lock(r.mutex);
  UpdateRegionIndex();
  const float region_m = voxel_size_m() * kBlockSide * kRegionBlocks;
  for (size_t i = 0; i < r.keys.size(); ++i) {
    const Eigen::Vector3f min_m = r.keys[i].cast<float>() * region_m;
    if (!keep_region(min_m, min_m.array() + region_m)) continue;
    for (const VoxelBlock* block : r.blocks[i]) f(*block);
  }
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
