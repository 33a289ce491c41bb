#pragma once

// Coarse threading for the per-pixel stages of reconstruct/: an image's rows (or any range
// of work items) split into a few contiguous pieces per thread, run by a small pool of
// persistent worker threads and the calling thread. Coarse on purpose: the target machine
// has 2 shared cores, where spinning waits and fine-grained tasks cost more than they save.
// Pieces rather than one band per thread, and a pool rather than threads started per call,
// because the cores are shared: a thread started for a 1 ms stage while another process
// holds the other core waits its turn, and the call waited for it (measured before the
// pool: depth preparation and tracking 3-4× slower with 2 threads than with 1 beside a
// rendering process, README "Reconstruction", Speed). Now whoever runs takes the next
// piece, and the caller waits only for pieces a worker has started.

#include <algorithm>
#include <functional>
#include <thread>

namespace hw::reconstruct {

// Threads to use for `requested` (0: hardware concurrency, at least 1).
inline int ResolveThreads(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

namespace internal {
// ForEachBand's engine: calls band(begin, end) on `num_pieces` contiguous pieces covering
// [0, num_items) in order of their start, on the calling thread and on up to
// `num_threads` − 1 pool workers. Runs everything on the calling thread when the pool is
// already serving another call (nested or concurrent calls; then as one range) or cannot
// start its workers.
void RunPieces(int num_items, int num_pieces, int num_threads, const std::function<void(int, int)>& band);
}  // namespace internal

// Calls band(begin, end) on disjoint contiguous ranges covering [0, num_items), each once,
// at most `num_threads` (0: hardware concurrency) at once; how many ranges there are is not
// specified (a few per thread), so a caller must not keep one result per call or per
// thread indexed by call order — index results by item. Returns when all have finished.
// `band` must not throw.
template <typename Band>
void ForEachBand(int num_items, int num_threads, const Band& band) {
  const int threads = std::min(ResolveThreads(num_threads), num_items);
  if (threads <= 1) {
    if (num_items > 0) band(0, num_items);
    return;
  }
  // Four pieces per thread: a thread that starts late (the core was busy) leaves at most a
  // quarter of its share to wait for.
  internal::RunPieces(num_items, std::min(num_items, 4 * threads), threads, band);
}

}  // namespace hw::reconstruct
