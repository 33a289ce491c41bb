#pragma once

// Synthetic scans shared by the reconstruction tests. ctest runs every TEST in its own
// process, in parallel: a scan is rendered once into the build tree (under a file lock) and
// reused by every test and rerun, since rendering is deterministic for given options.

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/output_folder.h"
#include "fixtures/synth_scan.h"

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

// Newest modification time of the fixtures libraries: a scan rendered before them may no
// longer be what the fixtures render.
inline fs::file_time_type FixturesBuildTime() {
  // Not {}: libstdc++'s file clock counts from 2174, so real times are negative.
  fs::file_time_type newest = fs::file_time_type::min();
  for (const auto& entry : fs::directory_iterator(fs::path(HW_BINARY_DIR) / "fixtures")) {
    if (entry.path().extension() == ".a") newest = std::max(newest, entry.last_write_time());
  }
  return newest;
}

// The folder of the scan `options` renders, under <build>/test-data/<name>, rendered now if
// it is not there yet, a previous render did not finish, or the fixtures were rebuilt since.
inline fs::path CachedScan(const std::string& name, const fixtures::SynthScanOptions& options) {
  const fs::path root = fs::path(HW_BINARY_DIR) / "test-data";
  fs::create_directories(root);
  const fs::path folder = root / name;
  const int lock = ::open((root / (name + ".lock")).c_str(), O_CREAT | O_RDWR | O_CLOEXEC, 0644);
  EXPECT_GE(lock, 0);
  ::flock(lock, LOCK_EX);
  const bool complete = fs::exists(folder / "depth.txt") &&
                        core::ProbeFolderRun(folder).state == core::FolderRunState::kComplete &&
                        fs::last_write_time(folder / "depth.txt") > FixturesBuildTime();
  if (!complete) {
    fs::remove_all(folder);
    core::OutputFolder out(folder, "reconstruct test scan");
    fixtures::SynthesizeScan(options, folder);
    out.Commit();
  }
  ::flock(lock, LOCK_UN);
  ::close(lock);
  return folder;
}

}  // namespace hw::reconstruct::test
