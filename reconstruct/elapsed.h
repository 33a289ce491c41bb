#pragma once

// Internal to reconstruct/: wall time of a stage, for the per-frame timings the pipeline
// records.

#include <chrono>

namespace hw::reconstruct::internal {

// Milliseconds since `start` on the steady clock.
inline double MsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace hw::reconstruct::internal
