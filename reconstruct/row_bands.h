#pragma once

// Coarse threading for the per-pixel stages of reconstruct/: an image's rows (or any range
// of work items) split into one contiguous band per thread, run with std::thread, the
// calling thread taking the last band. Coarse on purpose: the target machine has 2 shared
// cores, where spinning waits and fine-grained tasks cost more than they save.

#include <algorithm>
#include <system_error>
#include <thread>
#include <vector>

namespace hw::reconstruct {

// Threads to use for `requested` (0: hardware concurrency, at least 1).
inline int ResolveThreads(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

// Calls band(begin, end) on disjoint ranges covering [0, num_items), at most `num_threads`
// of them at once (0: hardware concurrency). Returns when all have finished; a band whose
// thread cannot be started runs on the calling thread. `band` must not throw.
template <typename Band>
void ForEachBand(int num_items, int num_threads, const Band& band) {
  const int bands = std::min(ResolveThreads(num_threads), num_items);
  if (bands <= 1) {
    if (num_items > 0) band(0, num_items);
    return;
  }
  std::vector<std::thread> workers;
  workers.reserve(bands - 1);
  auto begin_of = [&](int i) { return static_cast<int>(static_cast<long>(num_items) * i / bands); };
  for (int i = 0; i + 1 < bands; ++i) {
    try {
      workers.emplace_back([&band, b = begin_of(i), e = begin_of(i + 1)] { band(b, e); });
    } catch (const std::system_error&) {
      band(begin_of(i), begin_of(i + 1));  // no thread to be had: do it here
    }
  }
  band(begin_of(bands - 1), num_items);
  for (auto& worker : workers) worker.join();
}

}  // namespace hw::reconstruct
