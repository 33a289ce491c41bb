// Why the TSDF's block index is absl::flat_hash_map and not std::unordered_map: the time of
// one find() of a packed block key (reconstruct/tsdf_volume_impl.h) in each, for tables of
// blocks on a wavy surface (as a scan allocates them) over a 2000 × 2000 block area,
// queried at random keys in the surface's layers over that area: mostly absent keys in the
// smaller tables, as when a ray looks for the blocks ahead of it. Best of 5 passes over
// 1 Mi queries.
//
//   bench_block_hash_speed

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <unordered_map>
#include <vector>

#include <absl/container/flat_hash_map.h>

namespace {

uint64_t Pack(int x, int y, int z) {
  constexpr uint64_t kMask = (uint64_t{1} << 21) - 1;
  return ((static_cast<uint64_t>(x) & kMask) << 42) | ((static_cast<uint64_t>(y) & kMask) << 21) |
         (static_cast<uint64_t>(z) & kMask);
}

// The surface: z = 10 sin(0.05 x) + 5 cos(0.07 y) blocks, two blocks thick.
int SurfaceZ(int x, int y) {
  return static_cast<int>(10 * std::sin(x * 0.05) + 5 * std::cos(y * 0.07));
}

// std::unordered_map with a Fibonacci hash (std::hash<uint64_t> is the identity).
struct FibonacciHash {
  size_t operator()(uint64_t key) const {
    const uint64_t h = key * 0x9E3779B97F4A7C15ull;
    return static_cast<size_t>(h ^ (h >> 29));
  }
};

long found_total = 0;

template <class Map>
double NsPerFind(size_t blocks, const std::vector<uint64_t>& queries) {
  Map map;
  std::mt19937 rng(3);
  while (map.size() < blocks) {
    const int x = static_cast<int>(rng() % 2000) - 1000, y = static_cast<int>(rng() % 2000) - 1000;
    for (int d = 0; d < 2; ++d) map.emplace(Pack(x, y, SurfaceZ(x, y) + d), static_cast<int32_t>(map.size()));
  }
  double best = 1e300;
  long found = 0;
  for (int pass = 0; pass < 5; ++pass) {
    const auto t0 = std::chrono::steady_clock::now();
    for (const uint64_t q : queries) found += map.find(q) != map.end();
    const auto t1 = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::nano>(t1 - t0).count() / static_cast<double>(queries.size()));
  }
  found_total += found;  // printed: the finds cannot be optimised away
  return best;
}

}  // namespace

int main() {
  std::mt19937 rng(7);
  std::vector<uint64_t> queries(1 << 20);
  for (auto& q : queries) {
    const int x = static_cast<int>(rng() % 2000) - 1000, y = static_cast<int>(rng() % 2000) - 1000;
    q = Pack(x, y, SurfaceZ(x, y) + static_cast<int>(rng() % 4) - 1);
  }
  std::printf("%10s %22s %22s\n", "blocks", "unordered_map ns/find", "flat_hash_map ns/find");
  for (const size_t blocks : {8000, 200000, 2000000}) {
    std::printf("%10zu %22.1f %22.1f\n", blocks,
                NsPerFind<std::unordered_map<uint64_t, int32_t, FibonacciHash>>(blocks, queries),
                NsPerFind<absl::flat_hash_map<uint64_t, int32_t>>(blocks, queries));
  }
  std::printf("(%ld keys found in all)\n", found_total);
  return 0;
}
