#pragma once

// Synthetic scans shared by the reconstruction tests. ctest runs every TEST in its own
// process, in parallel: a scan is rendered once into the build tree (under a file lock) and
// reused by every test and rerun, since rendering is deterministic for given options.

#include <filesystem>
#include <string>
#include <vector>

#include "fixtures/cached_test_data.h"
#include "fixtures/synth_scan.h"
#include "core/scan.h"
#include "reconstruct/reconstruction.h"
#include "reconstruct/trajectory_eval.h"

namespace hw::reconstruct::test {

namespace fs = std::filesystem;

// 160×120 depth and colour (80×60 thermal), `duration_s` of the given scene and motion, with
// every sensor effect on (noise, holes, edge artefacts, jitter, dropped frames).
inline fixtures::SynthScanOptions TestScanOptions(const std::string& scene = "equipment-small",
                                                  fixtures::MotionKind motion = fixtures::MotionKind::kSmooth,
                                                  double duration_s = 1.0) {
  fixtures::SynthScanOptions o = fixtures::SynthScanOptions::Small(scene);
  o.image_scale = 0.25;
  o.duration_s = duration_s;
  o.motion = motion;
  o.write_thermal = false;
  o.seed = 11;
  return o;
}

// The folder of the scan `options` renders, under <build>/test-data/<name>, rendered now if
// it is not there yet, a previous render did not finish, or the fixtures were rebuilt since.
inline fs::path CachedScan(const std::string& name, const fixtures::SynthScanOptions& options) {
  return fixtures::test::CachedTestData(name, "depth.txt", [&](const fs::path& folder) {
    fixtures::SynthesizeScan(options, folder);
  });
}

// The pipeline at the test scans' 160×120: voxels of 1 cm (a 640×480 frame's pixel at 1 m
// is 1.75 mm; at 160×120, 7 mm — finer voxels would hold single noisy pixels).
inline ReconstructionOptions PipelineTestOptions() {
  ReconstructionOptions o;
  o.tsdf.voxel_size_m = 0.01;
  o.tsdf.truncation_m = 0.04;
  o.mesh.min_component_triangles = 20;
  return o;
}

// What a whole-scan test run produced: the trajectory's evaluation against groundtruth.txt,
// the frame records, the fused poses (one per fused frame, in order) and the mesh.
struct Outcome {
  TrajectoryEval eval;
  std::vector<FrameRecord> frames;
  std::vector<core::TimedPose> poses;
  TriangleMesh mesh;
};

// Reconstructs the scan (ReconstructScan, from its groundtruth pose unless told otherwise)
// and evaluates it. The scan must have groundtruth.txt.
inline Outcome ReconstructAndEvaluate(const core::Scan& scan, const ReconstructionOptions& options,
                                      bool start_at_groundtruth = true) {
  Reconstruction reconstruction(scan.rig(), options);
  ScanReconstructionOptions scan_options;
  scan_options.start_at_groundtruth = start_at_groundtruth;
  ReconstructScan(scan, reconstruction, scan_options);
  Outcome run;
  run.eval = EvaluateTrajectory(reconstruction.trajectory(), *scan.groundtruth(), {});
  run.frames = reconstruction.frames();
  run.poses = reconstruction.trajectory().poses();
  run.mesh = reconstruction.ExtractMesh();
  return run;
}

}  // namespace hw::reconstruct::test
