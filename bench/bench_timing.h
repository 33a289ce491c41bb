#pragma once

// Timing helpers shared by the speed benchmarks (bench_tsdf_speed, bench_track_speed).

#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

namespace hw::bench {

using Clock = std::chrono::steady_clock;

// Wall time from a to b, ms.
inline double Ms(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// CPU time of the whole process (all threads), ms: on a shared machine the wall time of a
// call grows with the other jobs' load; CPU time / threads is what it costs on idle cores.
inline double CpuMs() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

// Prints "name  median …  mean …  max …" of the values (nothing when empty), each followed
// by `unit`.
inline void Summary(const char* name, std::vector<double> v, const char* unit = " ms") {
  if (v.empty()) return;
  double sum = 0;
  for (const double x : v) sum += x;
  std::sort(v.begin(), v.end());
  std::printf("%-22s median %8.3f%s  mean %8.3f%s  max %8.3f%s\n", name, v[v.size() / 2], unit,
              sum / static_cast<double>(v.size()), unit, v.back(), unit);
}

}  // namespace hw::bench
