// Per-frame time of depth preparation and ICP tracking on a scan's first frames, as the
// reconstruction pipeline runs them (its default options: model raycast at level 1, ICP on
// levels 1 and 2 with the photometric term), with the model fused at the ground-truth poses
// so that every frame sees the same model whatever the code under test estimates.
//
//   bench_track_speed SCAN [--frames N] [--threads T] [--repeat R]
//
// Per frame: "prepare" = undistort depth and colour, build the depth pyramid, register the
// colour to its finest ICP level; "track" = AlignToModel of that pyramid against the raycast of the frames
// before it, from the previous frame's true pose. Each runs R times, the fastest counts (a
// shared machine's load only adds time); the summary also splits "prepare" into its four
// parts (fastest of R each). Also prints ICP's iterations and the estimate's
// error against the truth (mm, deg): a speed change must not change them beyond noise.
// SCAN needs groundtruth.txt and an rgb stream (e.g. heatwave synth --scene equipment).
//
// Also the basin of each frame's minimum: ICP is run a second time from the frame's true pose,
// and "apart mm" is how far that result ends from the one started at the previous frame's
// pose (the two starts are a frame's motion apart). Near 0 where the depth (and colour) fix
// the pose; about the starts' distance where the minimum is flat along a wall (README,
// Tracking without colour). --rig FILE reads another rig.yaml (e.g. the sensor's true depth
// field), --photometric-weight W sets ICP's colour term (0: depth alone).

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <exception>
#include <string>
#include <vector>

#include "bench/bench_timing.h"
#include "core/scan.h"
#include "reconstruct/depth_frame.h"
#include "reconstruct/icp.h"
#include "reconstruct/raycast.h"
#include "reconstruct/reconstruction.h"
#include "reconstruct/tsdf_volume.h"

namespace {

using hw::bench::Clock;
namespace rc = hw::reconstruct;

using hw::bench::CpuMs;
using hw::bench::Ms;
using hw::bench::Summary;

int Run(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_track_speed SCAN [--frames N] [--threads T] [--repeat R] [--rig FILE] "
                         "[--photometric-weight W]\n");
    return 1;
  }
  const std::string folder = argv[1];
  int frames = 20, threads = 2, repeat = 3;
  hw::core::ScanOptions scan_options;
  double photometric_weight = -1;  // < 0: the pipeline's default
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "bench_track_speed: %s needs a value\n", a.c_str());
      return 1;
    }
    if (a == "--frames") frames = std::atoi(argv[++i]);
    else if (a == "--threads") threads = std::atoi(argv[++i]);
    else if (a == "--repeat") repeat = std::max(1, std::atoi(argv[++i]));
    else if (a == "--rig") scan_options.rig_path = argv[++i];
    else if (a == "--photometric-weight") photometric_weight = std::atof(argv[++i]);
    else {
      std::fprintf(stderr, "bench_track_speed: unknown option %s\n", a.c_str());
      return 1;
    }
  }
  const hw::core::Scan scan = hw::core::Scan::Open(folder, scan_options);
  const hw::core::Rig& rig = scan.rig();
  if (!scan.groundtruth() || !rig.rgb) {
    std::fprintf(stderr, "bench_track_speed: %s needs groundtruth.txt and an rgb stream\n",
                 folder.c_str());
    return 1;
  }
  // The pipeline's defaults (reconstruction.cc's Effective()): one depth range, model raycast
  // at level 1, so no maps and no ICP at level 0.
  rc::ReconstructionOptions o;
  o.tsdf.min_depth_m = o.depth.min_depth_m = o.raycast.min_depth_m = o.min_depth_m;
  o.tsdf.max_depth_m = o.depth.max_depth_m = o.raycast.max_depth_m = o.max_depth_m;
  o.tsdf.num_threads = o.depth.num_threads = o.icp.num_threads = o.raycast.num_threads = threads;
  for (int l = 0; l < o.raycast_level; ++l) o.icp.iterations[l] = 0;
  o.depth.first_map_level = o.raycast_level;
  o.raycast.with_colour = true;
  if (photometric_weight >= 0) o.icp.photometric_weight = photometric_weight;

  const rc::Undistorter depth_undistorter(rig.depth);
  const rc::Undistorter rgb_undistorter(*rig.rgb);
  rc::TsdfVolume volume(o.tsdf);
  std::optional<rc::ModelPyramid> model;
  hw::core::Rigid3d previous_pose;
  std::printf("%s: %d threads, best of %d\n", folder.c_str(), threads, repeat);
  std::printf("wall ms and (cpu) process CPU ms summed over its threads\n");
  std::printf("%5s %10s %10s %10s %10s %6s %9s %9s %9s\n", "frame", "prepare", "(cpu)", "track", "(cpu)",
              "iters", "err mm", "err deg", "apart mm");
  std::vector<double> prepare_ms, track_ms, prepare_cpu, track_cpu, err_mm, apart_mm;
  std::vector<double> prepare_part_ms[4];  // undistort depth, undistort colour, pyramid, register colour
  const int n = std::min(frames, scan.NumFrames(hw::core::Stream::kDepth));
  for (int i = 0; i < n; ++i) {
    const double t = scan.DepthClockTime(hw::core::Stream::kDepth, i);
    const auto pose = scan.groundtruth()->At(t);
    const auto j = scan.AssociatedFrame(i, hw::core::Stream::kRgb);
    if (!pose || !j || !scan.FrameExists(hw::core::Stream::kDepth, i) ||
        !scan.FrameExists(hw::core::Stream::kRgb, *j)) {
      continue;
    }
    const auto rgb_pose = scan.groundtruth()->At(scan.DepthClockTime(hw::core::Stream::kRgb, *j));
    if (!rgb_pose) continue;
    const cv::Mat depth = scan.LoadDepth(i);
    const cv::Mat rgb = scan.LoadRgb(*j);
    const hw::core::Rigid3d depth_from_rgb_now = pose->Inverse() * *rgb_pose * rig.depth_from_rgb;

    double best_prepare = 1e300, best_prepare_cpu = 1e300;
    double best_part[4] = {1e300, 1e300, 1e300, 1e300};
    rc::DepthPyramid pyramid;
    cv::Mat rgb_pinhole;
    for (int r = 0; r < repeat; ++r) {
      const auto t0 = Clock::now();
      const double c0 = CpuMs();
      const cv::Mat undistorted = depth_undistorter.UndistortDepth(depth);
      const auto t1 = Clock::now();
      rgb_pinhole = rgb_undistorter.UndistortColour(rgb);
      const auto t2 = Clock::now();
      pyramid = rc::BuildDepthPyramid(undistorted, depth_undistorter.pinhole(), o.depth);
      const auto t3 = Clock::now();
      // As the pipeline: the colour registered to the finest level ICP iterates on.
      const int level = std::min(o.depth.first_map_level, static_cast<int>(pyramid.levels.size()) - 1);
      rc::SetIntensity(pyramid,
                       rc::RegisterGrey(pyramid.levels[level].depth_m, pyramid.levels[level].camera, rgb_pinhole,
                                        rgb_undistorter.pinhole(), 1 << level, depth_from_rgb_now.Inverse(), threads),
                       level, threads);
      const auto t4 = Clock::now();
      best_prepare_cpu = std::min(best_prepare_cpu, CpuMs() - c0);
      best_prepare = std::min(best_prepare, Ms(t0, t4));
      const double part[4] = {Ms(t0, t1), Ms(t1, t2), Ms(t2, t3), Ms(t3, t4)};
      for (int k = 0; k < 4; ++k) best_part[k] = std::min(best_part[k], part[k]);
    }
    prepare_ms.push_back(best_prepare);
    prepare_cpu.push_back(best_prepare_cpu);
    for (int k = 0; k < 4; ++k) prepare_part_ms[k].push_back(best_part[k]);

    if (model) {
      double best_track = 1e300, best_track_cpu = 1e300;
      rc::IcpResult result;
      for (int r = 0; r < repeat; ++r) {
        const auto t0 = Clock::now();
        const double c0 = CpuMs();
        result = rc::AlignToModel(pyramid, *model, previous_pose, o.icp);
        best_track_cpu = std::min(best_track_cpu, CpuMs() - c0);
        best_track = std::min(best_track, Ms(t0, Clock::now()));
      }
      track_ms.push_back(best_track);
      track_cpu.push_back(best_track_cpu);
      const hw::core::PoseError e = hw::core::ComparePoses(*pose, result.world_from_camera);
      err_mm.push_back(e.translation_m * 1e3);
      const rc::IcpResult from_truth = rc::AlignToModel(pyramid, *model, *pose, o.icp);
      const hw::core::PoseError apart = hw::core::ComparePoses(from_truth.world_from_camera, result.world_from_camera);
      apart_mm.push_back(apart.translation_m * 1e3);
      std::printf("%5d %10.3f %10.3f %10.3f %10.3f %6d %9.3f %9.4f %9.3f %s\n", i, best_prepare,
                  best_prepare_cpu, best_track, best_track_cpu,
                  result.iterations, e.translation_m * 1e3, e.rotation_rad * 180 / 3.14159265358979,
                  apart.translation_m * 1e3, rc::IcpStatusName(result.status).c_str());
    } else {
      std::printf("%5d %10.3f %10.3f\n", i, best_prepare, best_prepare_cpu);
    }

    // The model for the next frame: this frame fused at its true pose, raycast from there.
    rc::ColourView view;
    view.rgb = rgb_pinhole;
    view.camera = rgb_undistorter.pinhole();
    view.world_from_camera = *rgb_pose * rig.depth_from_rgb;
    volume.Integrate(pyramid.raw_depth_m, depth_undistorter.pinhole(), *pose, &view);
    rc::PinholeCamera camera = depth_undistorter.pinhole();
    for (int l = 0; l < o.raycast_level; ++l) camera = camera.Half();
    rc::PointMap level = rc::Raycast(volume, camera, *pose, o.raycast);
    rc::ModelPyramid built = rc::BuildModelPyramid(
        std::move(level), camera, *pose,
        static_cast<int>(o.icp.iterations.size()) - o.raycast_level, threads);
    rc::ModelPyramid padded;  // empty finer levels, as the pipeline's
    padded.world_from_camera = built.world_from_camera;
    rc::PinholeCamera finer = depth_undistorter.pinhole();
    for (int l = 0; l < o.raycast_level; ++l) {
      padded.cameras.push_back(finer);
      padded.maps.emplace_back();
      finer = finer.Half();
    }
    for (size_t l = 0; l < built.maps.size(); ++l) {
      padded.cameras.push_back(built.cameras[l]);
      padded.maps.push_back(std::move(built.maps[l]));
    }
    model = std::move(padded);
    previous_pose = *pose;
  }
  Summary("prepare ms", prepare_ms);
  Summary(" undistort depth", prepare_part_ms[0]);
  Summary(" undistort colour", prepare_part_ms[1]);
  Summary(" depth pyramid", prepare_part_ms[2]);
  Summary(" register colour", prepare_part_ms[3]);
  Summary("track ms", track_ms);
  Summary("prep cpu", prepare_cpu);
  Summary("track cpu", track_cpu);
  Summary("err", err_mm, " mm");
  Summary("apart", apart_mm, " mm");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_track_speed: %s\n", e.what());
    return 1;
  }
}
