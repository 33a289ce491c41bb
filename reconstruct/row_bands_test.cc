#include "reconstruct/row_bands.h"

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace hw::reconstruct {
namespace {

// Every item exactly once, in contiguous ranges, for sizes around the piece count.
TEST(ForEachBand, CoversEveryItemOnceInDisjointRanges) {
  for (int threads : {1, 2, 3, 8}) {
    for (int n : {0, 1, 2, 7, 8, 9, 100, 4801}) {
      std::vector<std::atomic<int>> seen(n);
      std::mutex mutex;
      std::vector<std::pair<int, int>> ranges;
      ForEachBand(n, threads, [&](int begin, int end) {
        EXPECT_LT(begin, end);
        for (int i = begin; i < end; ++i) ++seen[i];
        const std::lock_guard<std::mutex> lock(mutex);
        ranges.emplace_back(begin, end);
      });
      for (int i = 0; i < n; ++i) ASSERT_EQ(seen[i].load(), 1) << "item " << i << " n " << n << " threads " << threads;
      EXPECT_LE(static_cast<int>(ranges.size()), std::max(1, 4 * threads)) << n;
    }
  }
}

// At most num_threads ranges run at once, and with 2 threads two do run at once (the
// pool's worker takes part), unless the machine never schedules it: then the caller runs
// them all and the call still returns.
TEST(ForEachBand, RunsAtMostNumThreadsAtOnce) {
  for (int threads : {2, 3}) {
    std::atomic<int> running{0}, most{0};
    ForEachBand(64, threads, [&](int, int) {
      const int now = ++running;
      int seen = most.load();
      while (now > seen && !most.compare_exchange_weak(seen, now)) {
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      --running;
    });
    EXPECT_LE(most.load(), threads);
    EXPECT_GE(most.load(), 1);
  }
}

// A call from inside a range (nested) or from another thread while the pool is serving a
// call runs on its own thread, completely, instead of waiting for the pool.
TEST(ForEachBand, NestedAndConcurrentCallsComplete) {
  std::atomic<long> total{0};
  ForEachBand(8, 2, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      ForEachBand(100, 2, [&](int b, int e) { total += e - b; });
    }
  });
  EXPECT_EQ(total.load(), 800);

  std::atomic<long> a{0}, b{0};
  std::thread other([&] {
    for (int r = 0; r < 200; ++r) ForEachBand(1000, 2, [&](int begin, int end) { a += end - begin; });
  });
  for (int r = 0; r < 200; ++r) ForEachBand(1000, 2, [&](int begin, int end) { b += end - begin; });
  other.join();
  EXPECT_EQ(a.load(), 200 * 1000);
  EXPECT_EQ(b.load(), 200 * 1000);
}

// Many short calls in a row (the per-frame pattern): results complete and visible to the
// caller at return each time — a worker that wakes late for one call must not run a range
// of the next one twice or lose one.
TEST(ForEachBand, ManyShortCallsEachComplete) {
  std::vector<int> out(97);
  for (int r = 1; r <= 2000; ++r) {
    ForEachBand(static_cast<int>(out.size()), 2, [&](int begin, int end) {
      for (int i = begin; i < end; ++i) out[i] = r;
    });
    for (size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], r) << "call " << r << " item " << i;
  }
}

}  // namespace
}  // namespace hw::reconstruct
