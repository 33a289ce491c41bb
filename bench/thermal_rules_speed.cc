// Cost of the thermal rules (reconstruct/thermal_confidence.h, thermal_update.h) as the
// fusion calls them: the offline estimate per region (1e6 regions × 30 views: the model of
// a room at 5 mm voxels seen ~30 times), and the per-ray confidence (all five metrics and
// their product, 1e7 rays) with the default powers (1) and with powers that need pow.
//
//   bench_thermal_rules_speed [--regions N] [--views V]
//
// Regions are copied from a pool of 4096 (the estimate sorts its span in place) so that
// memory stays small; the copy is part of the time, as the fusion copies a voxel's views
// out of its store too.

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <vector>

#include "bench/bench_timing.h"
#include "reconstruct/thermal_confidence.h"
#include "reconstruct/thermal_update.h"

namespace {

using hw::bench::Clock;
using hw::bench::Ms;
namespace rc = hw::reconstruct;

double sink = 0;  // printed: keeps the work from being optimised away

void TimeRobustEstimate(long regions, int views) {
  constexpr int kPool = 4096;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0, 0.3);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<rc::Observation> pool(static_cast<size_t>(kPool) * views);
  for (rc::Observation& o : pool) {
    const bool reflection = unit(rng) < 0.1;
    o.value_c = static_cast<float>(25 + noise(rng) + (reflection ? 5 : 0));
    o.confidence = static_cast<float>(0.2 + 0.8 * unit(rng));
  }
  std::vector<rc::Observation> scratch(static_cast<size_t>(views));
  const rc::OfflineOptions options;
  long rejected = 0;
  const auto t0 = Clock::now();
  const double cpu0 = hw::bench::CpuMs();
  for (long r = 0; r < regions; ++r) {
    const rc::Observation* src = pool.data() + static_cast<size_t>(r % kPool) * views;
    std::memcpy(scratch.data(), src, sizeof(rc::Observation) * static_cast<size_t>(views));
    const rc::OfflineEstimate e = rc::RobustEstimate(scratch, options);
    sink += e.value_c;
    rejected += e.rejected;
  }
  const double cpu_ms = hw::bench::CpuMs() - cpu0;
  const double wall_ms = Ms(t0, Clock::now());
  std::printf("RobustEstimate  %ld regions × %d views: %.0f ms wall, %.0f ms CPU, "
              "%.2f M regions/s, %.0f ns/region (%.1f %% rejected)\n",
              regions, views, wall_ms, cpu_ms, static_cast<double>(regions) / cpu_ms * 1e-3,
              cpu_ms * 1e6 / static_cast<double>(regions),
              100.0 * static_cast<double>(rejected) / static_cast<double>(regions * views));
}

void TimeRayConfidence(long rays, const rc::ThermalConfidenceOptions& o, const char* label) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> unit(-1, 1);
  // Inputs vary per ray (from a small table, so that generating them costs nothing).
  constexpr int kTable = 1024;
  struct Input {
    Eigen::Vector3d point, v, w;
    double distortion_px, cos_angle, time_since_ffc_s;
  };
  std::vector<Input> table(kTable);
  for (Input& in : table) {
    in.point = {unit(rng), unit(rng), 1.5 + unit(rng)};
    in.v = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 0.5;
    in.w = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    in.distortion_px = 10 * (1 + unit(rng));
    in.cos_angle = 0.5 * (1 + unit(rng));
    in.time_since_ffc_s = 100 * (1 + unit(rng));
  }
  double cpu0 = 0;
  for (long r = -rays / 10; r < rays; ++r) {  // the first tenth warms up, untimed
    if (r == 0) cpu0 = hw::bench::CpuMs();
    const Input& in = table[static_cast<size_t>((r + rays) % kTable)];
    rc::ConfidenceTerms c;
    c.motion = rc::MotionConfidence(
        rc::ImageSpeedPxPerS(in.point, in.v, in.w, 300, 300) * o.integration_time_s, o);
    c.distortion = rc::DistortionConfidence(in.distortion_px, o);
    c.angle = rc::AngleConfidence(in.cos_angle, o);
    c.distance = rc::DistanceConfidence(in.point.norm(), o);
    c.operating = rc::OperatingConfidence(in.time_since_ffc_s, false, o);
    sink += rc::RayConfidence(c, o);
  }
  const double cpu_ms = hw::bench::CpuMs() - cpu0;
  std::printf("RayConfidence   %ld rays, %s: %.0f ms CPU, %.1f ns/ray\n", rays, label, cpu_ms,
              cpu_ms * 1e6 / static_cast<double>(rays));
}

}  // namespace

int main(int argc, char** argv) {
  long regions = 1000000;
  int views = 30;
  const auto usage = [&] {
    std::fprintf(stderr, "usage: %s [--regions N] [--views V]\n", argv[0]);
  };
  if ((argc - 1) % 2 != 0) {
    usage();
    return 2;
  }
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--regions") == 0) {
      regions = std::atol(argv[i + 1]);
    } else if (std::strcmp(argv[i], "--views") == 0) {
      views = std::atoi(argv[i + 1]);
    } else {
      usage();
      return 2;
    }
  }
  if (regions < 1 || views < 1) {
    std::fprintf(stderr, "--regions and --views must be >= 1\n");
    return 2;
  }
  TimeRobustEstimate(regions, views);
  rc::ThermalConfidenceOptions powers;
  TimeRayConfidence(10000000, powers, "powers 1");
  powers.motion_power = 0.5;
  powers.distortion_power = 1.5;
  powers.angle_power = 3;
  powers.distance_power = 0.7;
  powers.operating_power = 2.5;
  TimeRayConfidence(10000000, powers, "powers ≠ 0, 1, 2");
  std::printf("(checksum %g)\n", sink);
  return 0;
}
