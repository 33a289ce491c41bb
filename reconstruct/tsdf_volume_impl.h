#pragma once

// Internal to the TSDF sources (tsdf_volume.cc, tsdf_integrate.cc): the block storage and
// the coarse thread split they share.

#include <atomic>
#include <cstdint>
#include <vector>

#include <absl/container/flat_hash_map.h>

#include "reconstruct/row_bands.h"
#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct {

namespace internal {

// A block key packed into 64 bits, 21 bits per axis (±2^20 blocks: ±5 km at 5 mm voxels).
inline uint64_t PackKey(int x, int y, int z) {
  constexpr uint64_t kMask = (uint64_t{1} << 21) - 1;
  return ((static_cast<uint64_t>(x) & kMask) << 42) | ((static_cast<uint64_t>(y) & kMask) << 21) |
         (static_cast<uint64_t>(z) & kMask);
}
inline bool KeyInRange(int x, int y, int z) {
  constexpr int kLimit = 1 << 20;
  return x >= -kLimit && x < kLimit && y >= -kLimit && y < kLimit && z >= -kLimit && z < kLimit;
}

// Whether Integrate may use its SIMD row kernel where the CPU has one (true). A test hook:
// the scalar kernel is the reference the SIMD one must match bit for bit.
inline std::atomic<bool> integrate_simd{true};

// Whether this CPU has AVX2 (checked once at run time: the binary stays portable).
inline bool CpuHasAvx2() {
#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}
// Whether the TSDF update and fill take their AVX2 kernels: the CPU has AVX2 and
// integrate_simd allows them.
inline bool UseAvx2Kernels() { return CpuHasAvx2() && integrate_simd.load(std::memory_order_relaxed); }

// Runs f(0) … f(n − 1), each once, up to n at a time: on the calling thread and the
// workers of ForEachBand's pool (row_bands.h), each taking the next chunk not yet started —
// so a worker the scheduler starts late leaves its chunk to the caller instead of holding
// up the call. Chunks may therefore run one after another on one thread.
template <class F>
void RunChunks(int n, const F& f) {
  if (n <= 1) {
    f(0);
    return;
  }
  RunPieces(n, n, n, [&f](int begin, int end) {
    for (int c = begin; c < end; ++c) f(c);
  });
}

}  // namespace internal

// Storage for voxel blocks in chunks of memory mapped from the system, handed out in order
// and never moved or freed before the arena. A volume gains ~1,300 blocks (6 KB each) per
// integrated frame at 5 mm on a sweep; made one by one (new, value-initialised voxel by
// voxel, then page-faulted on first touch) they cost 3.9 µs each in the serial part of
// Integrate. A chunk (8 MB, 1,362 blocks) is populated when mapped, and Integrate has each new
// block copied from a fresh one by the thread that first updates it. At most one chunk's
// unused tail (8 MB) is resident beyond the blocks. Not thread-safe.
class BlockArena {
 public:
  BlockArena() = default;
  BlockArena(const BlockArena&) = delete;
  BlockArena& operator=(const BlockArena&) = delete;
  ~BlockArena();
  // Memory for one block, not yet a block (construct it with Construct before any use);
  // throws std::bad_alloc when the system has no memory to map.
  void* Allocate();
  // Makes a fresh block (Voxel's defaults) with the key at memory from Allocate.
  static VoxelBlock* Construct(void* at, const BlockKey& key);

 private:
  static constexpr size_t kChunkBytes = size_t{8} << 20;
  static constexpr size_t kStride =
      (sizeof(VoxelBlock) + alignof(VoxelBlock) - 1) / alignof(VoxelBlock) * alignof(VoxelBlock);
  std::vector<void*> chunks_;
  size_t used_in_last_ = kChunkBytes;  // bytes handed out of chunks_.back()
};

struct TsdfVolume::Impl {
  // Packed key → index in `blocks`. An open-addressing table (Abseil's SwissTable): a
  // lookup is one probe of a flat array where std::unordered_map chases a node pointer
  // (measured: bench/tsdf_speed.cc, README).
  // The value holds the block's address beside its index: a lookup (the samplers', millions
  // per raycast) then reads nothing outside the table's slot before the block itself, where
  // blocks[index] was one more dependent load, often a cache miss (FindBlock was a tenth of
  // a far sweep's raycast). A slot takes 24 bytes instead of 16: ~2 MB more for the 110 k
  // blocks of a 10 s sweep, whose voxels take 460 MB.
  struct Entry {
    VoxelBlock* block;
    int32_t index;
  };
  absl::flat_hash_map<uint64_t, Entry> index;
  // Stable addresses: blocks are never moved once created. They live in `arena`.
  std::vector<VoxelBlock*> blocks;
  BlockArena arena;
  // Per block, the last Integrate() call that listed it as visible (dedup of the list).
  std::vector<uint32_t> visit_stamp;
  uint32_t integrate_count = 0;
  // 1 / (w + 1) for w = 0 … max_weight (Integrate).
  std::vector<float> inv_count;
  // Integrate's scratch, kept between calls: the block keys each thread's rays crossed, the
  // visible blocks, the viewing ray's x per image column.
  std::vector<std::vector<uint64_t>> keys;
  std::vector<VoxelBlock*> visible;
  std::vector<uint64_t> visible_fresh;  // per visible block: its packed key if created unconstructed, else ~0
  std::vector<float> ray_x;

  VoxelBlock* Find(uint64_t packed) const {
    const auto it = index.find(packed);
    return it == index.end() ? nullptr : it->second.block;
  }
  // Index of the block, created if missing.
  int32_t GetOrCreate(const BlockKey& key) {
    bool added = false;
    const int32_t i = GetOrAllocate(internal::PackKey(key.x(), key.y(), key.z()), added);
    if (added) BlockArena::Construct(blocks[i], key);
    return i;
  }
  // Index of the block with this packed key; when missing, memory for it is allocated and
  // indexed, `added` set, and the caller must construct it (BlockArena::Construct) before
  // any other use. Throws std::bad_alloc (out of memory) before the key is indexed.
  int32_t GetOrAllocate(uint64_t packed, bool& added) {
    added = false;
    if (const auto it = index.find(packed); it != index.end()) return it->second.index;
    const auto i = static_cast<int32_t>(blocks.size());
    void* at = arena.Allocate();
    blocks.push_back(static_cast<VoxelBlock*>(at));
    visit_stamp.push_back(0);
    index.emplace(packed, Entry{static_cast<VoxelBlock*>(at), i});
    added = true;
    return i;
  }
};

}  // namespace hw::reconstruct
