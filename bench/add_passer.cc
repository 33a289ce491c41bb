// Bench helper: draws a person walking across the view into an already rendered scan, in
// place (fixtures/passer.h), so that a long render can be measured with and without one.
// `heatwave synth --passer F` does the same while rendering.
//
//   build/bench/bench_add_passer SCAN [CROSSING_FRACTION [SEED]]

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "core/output_folder.h"
#include "core/scan.h"
#include "fixtures/passer.h"

int main(int argc, char** argv) {
  if (argc < 2 || argc > 4) {
    std::fprintf(stderr, "usage: %s SCAN [CROSSING_FRACTION [SEED]]\n", argv[0]);
    return 2;
  }
  hw::fixtures::PasserOptions options;
  if (argc > 2) options.crossing_fraction = std::atof(argv[2]);
  if (argc > 3) options.seed = std::strtoull(argv[3], nullptr, 10);
  try {
    const hw::core::Scan scan = hw::core::Scan::Open(argv[1]);
    hw::core::OutputFolder edit(argv[1], "bench_add_passer");  // readers wait for the edit
    const hw::fixtures::PasserSummary s = hw::fixtures::AddPasser(scan, options);
    edit.Commit();
    std::printf("crossing at %.3f s, point (%.3f, %.3f, %.3f) m, walking (%.3f, %.3f, %.3f)\n", s.crossing_time_s,
                s.crossing_point_in_world.x(), s.crossing_point_in_world.y(), s.crossing_point_in_world.z(),
                s.walk_direction_in_world.x(), s.walk_direction_in_world.y(), s.walk_direction_in_world.z());
    std::printf("depth %d frames / %lld px, colour %d / %lld, thermal %d / %lld\n", s.depth_frames,
                static_cast<long long>(s.depth_pixels), s.rgb_frames, static_cast<long long>(s.rgb_pixels),
                s.thermal_frames, static_cast<long long>(s.thermal_pixels));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
