// Per-frame time of TSDF integration and raycasting on a scan's first frames, fused at the
// ground-truth poses (no tracking), as the reconstruction pipeline runs them: integrate the
// depth frame (with its colour frame), then raycast the model from the same pose at full
// resolution (the ICP reference) and at half resolution.
//
//   bench_tsdf_speed SCAN [--frames N] [--threads T] [--voxel M] [--truncation M] [--no-colour]
//                         [--repeat R] [--dump FILE] [--thermal] [--step S] [--max-depth M] [--fine]
//                         [--fixed-steps]
//
// --step S integrates every S-th depth frame (the pipeline integrates about every third on
// a smooth sweep); --max-depth the range (the TSDF default 4 m; rigs say 5); --fine updates
// every voxel of far blocks too (TsdfOptions::coarse_far off), to compare the two;
// --fixed-steps marches every ray in steps of the truncation (RaycastOptions::band_steps off).
//
// SCAN needs groundtruth.txt (e.g. heatwave synth --scene equipment --size full). Depth is
// fused with the pinhole part of the depth camera (its distortion is ignored: timing only).
// Prints one line per frame and the median and mean of each column. --dump writes the final
// volume (every block sorted by key: 3 int32 key, then its 512 voxels as stored, 8 bytes
// each) so that two builds' volumes can be compared voxel by voxel. --thermal (scans with a
// thermal camera) then raycasts the final volume from every frame's thermal pose (depth pose
// composed with depth_from_thermal), through the lens model (CameraRays) and through its
// pinhole part (PinholeCamera::Of), and prints the cost per ray of each (fastest of R).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "bench/bench_timing.h"
#include "core/scan.h"
#include "reconstruct/raycast.h"
#include "reconstruct/tsdf_volume.h"

namespace {

using hw::bench::Clock;

using hw::bench::CpuMs;
using hw::bench::Ms;
using hw::bench::Summary;

int Run(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: bench_tsdf_speed SCAN [--frames N] [--threads T] [--voxel M] [--truncation M] "
                 "[--no-colour] [--repeat R] [--dump FILE] [--thermal] [--step S] [--max-depth M] [--fine] "
                 "[--fixed-steps]\n");
    return 1;
  }
  const std::string folder = argv[1];
  int frames = 60, threads = 2, repeat = 1, step = 1;
  bool colour = true, thermal = false, fixed_steps = false;
  std::string dump;
  hw::reconstruct::TsdfOptions options;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_tsdf_speed: %s needs a value\n", a.c_str());
        std::exit(1);
      }
      return argv[++i];
    };
    if (a == "--frames") frames = std::atoi(next());
    else if (a == "--threads") threads = std::atoi(next());
    else if (a == "--voxel") options.voxel_size_m = std::atof(next());
    else if (a == "--truncation") options.truncation_m = std::atof(next());
    else if (a == "--no-colour") colour = false;
    else if (a == "--repeat") repeat = std::max(1, std::atoi(next()));
    else if (a == "--dump") dump = next();
    else if (a == "--thermal") thermal = true;
    else if (a == "--step") step = std::max(1, std::atoi(next()));  // every step-th depth frame (the pipeline: ~3)
    else if (a == "--max-depth") options.max_depth_m = std::atof(next());
    else if (a == "--fine") options.coarse_far = false;  // every voxel of far blocks updated
    else if (a == "--fixed-steps") fixed_steps = true;  // RaycastOptions::band_steps off
    else {
      std::fprintf(stderr, "bench_tsdf_speed: unknown option %s\n", a.c_str());
      return 1;
    }
  }
  options.num_threads = threads;
  if (const std::string error = options.Check(); !error.empty()) {
    std::fprintf(stderr, "bench_tsdf_speed: %s\n", error.c_str());
    return 1;
  }
  const hw::core::Scan scan = hw::core::Scan::Open(folder);
  if (!scan.groundtruth()) {
    std::fprintf(stderr, "bench_tsdf_speed: %s has no groundtruth.txt\n", folder.c_str());
    return 1;
  }
  const hw::core::Rig& rig = scan.rig();
  const auto camera = hw::reconstruct::PinholeCamera::Of(rig.depth);
  hw::reconstruct::RaycastOptions raycast;
  raycast.band_steps = !fixed_steps;
  raycast.min_depth_m = options.min_depth_m;
  raycast.max_depth_m = options.max_depth_m;
  raycast.num_threads = threads;
  hw::reconstruct::TsdfVolume volume(options);
  std::printf("%s: %dx%d, voxel %.4g m, truncation %.4g m, %d threads, colour %s\n", folder.c_str(),
              camera.width, camera.height, options.voxel_size_m, options.truncation_m, threads,
              colour && rig.rgb ? "yes" : "no");
  std::printf("wall ms per call, and (cpu) process CPU ms per call summed over its threads\n");
  std::printf("%5s %16s %16s %16s %8s %8s %8s %8s %7s %7s\n", "frame", "integrate (cpu)", "raycast (cpu)",
              "ray 1/2 (cpu)", "blocks", "visible", "coarse", "kvoxels", "valid%", "MiB");
  std::vector<double> integrate_ms, raycast_ms, half_ms, integrate_cpu, raycast_cpu, half_cpu;
  std::vector<hw::core::Rigid3d> poses;
  const int n = std::min(frames * step, scan.NumFrames(hw::core::Stream::kDepth));
  for (int i = 0; i < n; i += step) {
    const double t = scan.DepthClockTime(hw::core::Stream::kDepth, i);
    const auto pose = scan.groundtruth()->At(t);
    if (!pose || !scan.FrameExists(hw::core::Stream::kDepth, i)) continue;
    poses.push_back(*pose);
    const cv::Mat depth = scan.LoadDepth(i);
    hw::reconstruct::ColourView view;
    bool have_colour = false;
    if (colour && rig.rgb) {
      if (const auto j = scan.AssociatedFrame(i, hw::core::Stream::kRgb); j && scan.FrameExists(hw::core::Stream::kRgb, *j)) {
        const auto rgb_pose = scan.groundtruth()->At(scan.DepthClockTime(hw::core::Stream::kRgb, *j));
        if (rgb_pose) {
          view.rgb = scan.LoadRgb(*j);
          view.camera = hw::reconstruct::PinholeCamera::Of(*rig.rgb);
          view.world_from_camera = *rgb_pose * rig.depth_from_rgb;
          have_colour = true;
        }
      }
    }
    const double c0 = CpuMs();
    const auto t0 = Clock::now();
    const auto stats = volume.Integrate(depth, camera, *pose, have_colour ? &view : nullptr);
    const auto t1 = Clock::now();
    const double integrate_end_cpu = CpuMs();
    // With --repeat R, each raycast runs R times and the fastest counts: on a shared
    // machine the others' load only ever adds time.
    double c1 = CpuMs(), c2 = 0, c3 = 0;
    auto t1b = t1, t2 = t1, t2b = t1, t3 = t1;
    hw::reconstruct::PointMap map;
    double best_ray = 1e300, best_half = 1e300;
    for (int r = 0; r < repeat; ++r) {
      const double ca = CpuMs();
      const auto ta = Clock::now();
      map = hw::reconstruct::Raycast(volume, camera, *pose, raycast);
      const auto tb = Clock::now();
      const double cb = CpuMs();
      const auto half = hw::reconstruct::Raycast(volume, camera.Half(), *pose, raycast);
      const auto tc = Clock::now();
      const double cc = CpuMs();
      if (Ms(ta, tb) < best_ray) {
        best_ray = Ms(ta, tb);
        t1b = ta;
        t2 = tb;
        c1 = ca;
        c2 = cb;
      }
      if (Ms(tb, tc) < best_half) {
        best_half = Ms(tb, tc);
        t2b = tb;
        t3 = tc;
        c3 = cc - cb;
      }
    }
    c3 += c2;
    integrate_ms.push_back(Ms(t0, t1));
    raycast_ms.push_back(Ms(t1b, t2));
    half_ms.push_back(Ms(t2b, t3));
    integrate_cpu.push_back(integrate_end_cpu - c0);
    raycast_cpu.push_back(c2 - c1);
    half_cpu.push_back(c3 - c2);
    std::printf("%5d %7.2f (%6.2f) %7.2f (%6.2f) %7.2f (%6.2f) %8zu %8d %8d %8lld %7.1f %7.1f\n", i,
                integrate_ms.back(), integrate_cpu.back(), raycast_ms.back(), raycast_cpu.back(), half_ms.back(),
                half_cpu.back(), volume.NumBlocks(), stats.blocks_visible, stats.blocks_coarse,
                static_cast<long long>(stats.voxels_updated / 1000),
                100.0 * map.NumValid() / static_cast<double>(map.points.size()),
                static_cast<double>(volume.MemoryBytes()) / (1 << 20));
  }
  // The first frames allocate most blocks: the steady state is what the pipeline sees.
  Summary("integrate", integrate_ms);
  Summary("raycast full", raycast_ms);
  Summary("raycast half", half_ms);
  Summary("integrate cpu", integrate_cpu);
  Summary("raycast full cpu", raycast_cpu);
  Summary("raycast half cpu", half_cpu);
  if (thermal && rig.thermal && !poses.empty()) {
    const auto r0 = Clock::now();
    const hw::reconstruct::CameraRays rays(*rig.thermal);
    const double rays_ms = Ms(r0, Clock::now());
    const auto pinhole = hw::reconstruct::PinholeCamera::Of(*rig.thermal);
    double lens_ms = 0, pinhole_ms = 0;
    long long lens_valid = 0, pinhole_valid = 0;
    for (const hw::core::Rigid3d& pose : poses) {
      const hw::core::Rigid3d thermal_pose = pose * rig.depth_from_thermal;
      double best_lens = 1e300, best_pinhole = 1e300;
      for (int r = 0; r < repeat; ++r) {
        const auto ta = Clock::now();
        const auto lens_map = hw::reconstruct::Raycast(volume, rays, thermal_pose, raycast);
        const auto tb = Clock::now();
        const auto pinhole_map = hw::reconstruct::Raycast(volume, pinhole, thermal_pose, raycast);
        const auto tc = Clock::now();
        best_lens = std::min(best_lens, Ms(ta, tb));
        best_pinhole = std::min(best_pinhole, Ms(tb, tc));
        if (r == 0) {
          lens_valid += lens_map.NumValid();
          pinhole_valid += pinhole_map.NumValid();
        }
      }
      lens_ms += best_lens;
      pinhole_ms += best_pinhole;
    }
    const double rays_per_pose = static_cast<double>(pinhole.width) * pinhole.height;
    const double total_rays = rays_per_pose * static_cast<double>(poses.size());
    std::printf("thermal %dx%d, %zu poses, final volume: lens rays %.1f ns/ray (%.1f%% hit), pinhole part "
                "%.1f ns/ray (%.1f%% hit); CameraRays built in %.1f ms\n",
                pinhole.width, pinhole.height, poses.size(), lens_ms * 1e6 / total_rays,
                100.0 * static_cast<double>(lens_valid) / total_rays, pinhole_ms * 1e6 / total_rays,
                100.0 * static_cast<double>(pinhole_valid) / total_rays, rays_ms);
  }
  if (!dump.empty()) {
    std::vector<const hw::reconstruct::VoxelBlock*> blocks;
    volume.ForEachBlock([&](const hw::reconstruct::VoxelBlock& block) { blocks.push_back(&block); });
    std::sort(blocks.begin(), blocks.end(), [](const auto* a, const auto* b) {
      return std::lexicographical_compare(a->key.data(), a->key.data() + 3, b->key.data(), b->key.data() + 3);
    });
    std::ofstream out(dump, std::ios::binary);
    for (const auto* block : blocks) {
      out.write(reinterpret_cast<const char*>(block->key.data()), 3 * sizeof(int));
      out.write(reinterpret_cast<const char*>(block->voxels.data()), sizeof(block->voxels));
    }
    if (!out) {
      std::fprintf(stderr, "bench_tsdf_speed: cannot write %s\n", dump.c_str());
      return 1;
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_tsdf_speed: %s\n", e.what());
    return 1;
  }
}
