// Targetless thermal↔depth extrinsics (calibrate/extrinsics_targetless.h) on a rendered
// `extrinsics-targetless` session: time, error against truth/rig.yaml, error in sigmas.
//
//   heatwave synth --session extrinsics-targetless --size full --seed 1 --out S
//   bench_targetless_speed S [--no-trajectory] [--frames N] [--diagnostic out.png]
//
// As on the bench: the TRUE rig's intrinsics and clock offsets (calibrated before), the
// NOMINAL rig's depth_from_thermal as the start; the trajectory is groundtruth.txt (world_from_depth).

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "bench/bench_timing.h"
#include "calibrate/extrinsics_targetless.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/rig.h"
#include "core/scan.h"

namespace fs = std::filesystem;
using namespace hw;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SESSION [--no-trajectory] [--frames N] [--diagnostic out.png]\n", argv[0]);
    return 2;
  }
  const fs::path session = argv[1];
  bool use_trajectory = true;
  bool start_truth = false;  // start from the true extrinsics (to see the solver's bias)
  std::string diagnostic;
  calibrate::TargetlessOptions options;
  for (int i = 2; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--no-trajectory") {
      use_trajectory = false;
    } else if (flag == "--no-folds") {
      options.use_fold_lines = false;
    } else if (flag == "--no-occlusions") {
      options.use_occlusion_lines = false;
    } else if (flag == "--start-truth") {
      start_truth = true;
    } else if (flag == "--cluster-frames" && i + 1 < argc) {
      options.alignment.cluster_frames = std::atoi(argv[++i]);
    } else if (flag == "--frames" && i + 1 < argc) {
      options.max_frames = std::atoi(argv[++i]);
    } else if (flag == "--diagnostic" && i + 1 < argc) {
      diagnostic = argv[++i];
    } else {
      std::fprintf(stderr, "unknown argument %s\n", flag.c_str());
      return 2;
    }
  }
  if (const std::string e = options.Check(); !e.empty()) {
    std::fprintf(stderr, "%s\n", e.c_str());
    return 2;
  }
  try {
    const core::Rig truth = core::ReadRig(session / "truth" / "rig.yaml");
    core::Rig start = truth;
    if (!start_truth) start.depth_from_thermal = core::ReadRig(session / "rig.yaml").depth_from_thermal;
    const fs::path rig_path = fs::temp_directory_path() / ("targetless_bench_rig_" + std::to_string(::getpid()) + ".yaml");
    core::WriteRig(rig_path, start);
    core::ScanOptions scan_options;
    scan_options.rig_path = rig_path;
    const core::Scan scan = core::Scan::Open(session, scan_options);
    fs::remove(rig_path);
    std::optional<core::Trajectory> trajectory;
    if (use_trajectory) trajectory = scan.groundtruth();

    const double cpu0 = bench::CpuMs();
    const auto t0 = bench::Clock::now();
    const calibrate::TargetlessResult r = calibrate::EstimateTargetlessExtrinsics(scan, trajectory, options);
    const auto t1 = bench::Clock::now();
    const double cpu1 = bench::CpuMs();

    const calibrate::ExtrinsicsEstimate& e = r.estimate;
    const calibrate::ExtrinsicsSigmas sig = calibrate::ErrorInSigmas(e, truth.depth_from_thermal);
    int lines_3d = 0, lines_2d = 0;
    for (const auto& f : r.frames) lines_3d += f.lines_3d, lines_2d += f.lines_2d;
    const double nf = std::max<double>(1, r.frames.size());
    std::printf("session %s  trajectory %s\n", session.c_str(), use_trajectory ? "groundtruth" : "none");
    std::printf("frames %zu  lines/frame 3D %.1f 2D %.1f  matches %d  inliers %.2f  robust sigma %.3f px  rms %.3f px\n",
                r.frames.size(), lines_3d / nf, lines_2d / nf, r.matches, r.inlier_fraction, r.robust_sigma_px,
                e.rms_residual);
    std::printf("start error   %.3f deg  %.2f mm\n", calibrate::RotationErrorDeg(start.depth_from_thermal, truth.depth_from_thermal),
                calibrate::TranslationErrorMm(start.depth_from_thermal, truth.depth_from_thermal));
    const Eigen::Vector3d rs = e.RotationSigmaDeg(), ts = e.TranslationSigmaMm();
    std::printf("final error   %.3f deg  %.2f mm   sigma rot [%.3f %.3f %.3f] deg  trans [%.2f %.2f %.2f] mm\n",
                calibrate::RotationErrorDeg(e.depth_from_camera, truth.depth_from_thermal),
                calibrate::TranslationErrorMm(e.depth_from_camera, truth.depth_from_thermal), rs.x(), rs.y(), rs.z(),
                ts.x(), ts.y(), ts.z());
    const calibrate::Vector6d err = calibrate::ExtrinsicsError(e.depth_from_camera, truth.depth_from_thermal);
    std::printf("error vector  omega [%.3f %.3f %.3f] deg  dt [%.1f %.1f %.1f] mm\n", err[0] * 180 / M_PI,
                err[1] * 180 / M_PI, err[2] * 180 / M_PI, err[3] * 1e3, err[4] * 1e3, err[5] * 1e3);
    std::printf("error in sigmas  rotation %.2f  translation %.2f\n", sig.rotation, sig.translation);
    std::printf("occlusion edge offset %.2f ± %.2f depth px\n", r.edge_offset_px, r.edge_offset_sigma_px);
    std::printf("matches per iteration:");
    for (const int m : r.matches_per_iteration) std::printf(" %d", m);
    std::printf("\ntime  wall %.0f ms  cpu %.0f ms\n", bench::Ms(t0, t1), cpu1 - cpu0);
    if (!diagnostic.empty()) {
      core::WriteImageAtomically(diagnostic, calibrate::DrawTargetlessDiagnostic(scan, r, static_cast<int>(r.frames.size() / 2), options));
    }
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "error: %s\n", ex.what());
    return 1;
  }
  return 0;
}
