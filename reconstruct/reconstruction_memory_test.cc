// Reconstruction::ReleaseVolume: the volume's memory goes back once the mesh is out, and
// nothing else the reconstruction holds changes.

#include <gtest/gtest.h>

#include "core/scan.h"
#include "reconstruct/reconstruct_test_support.h"
#include "reconstruct/reconstruction.h"

namespace hw::reconstruct {
namespace {

TEST(Reconstruction, ReleasingTheVolumeFreesItsBlocksAndKeepsTheTrajectory) {
  const core::Scan scan = core::Scan::Open(test::CachedScan("smooth", test::TestScanOptions()));
  ReconstructionOptions options;
  options.tsdf.voxel_size_m = 0.01;
  options.tsdf.truncation_m = 0.04;
  Reconstruction reconstruction(scan.rig(), options);
  ScanReconstructionOptions scan_options;
  scan_options.start_at_groundtruth = true;
  ReconstructScan(scan, reconstruction, scan_options);
  const size_t blocks = reconstruction.volume().NumBlocks();
  const size_t bytes = reconstruction.volume().MemoryBytes();
  ASSERT_GT(blocks, 100u);
  const std::vector<core::TimedPose> poses = reconstruction.trajectory().poses();
  const size_t frames = reconstruction.frames().size();
  ASSERT_FALSE(reconstruction.ExtractMesh().positions.empty());

  reconstruction.ReleaseVolume();
  EXPECT_EQ(reconstruction.volume().NumBlocks(), 0u);
  // What is left is the empty index: under 1 % of what the blocks took.
  EXPECT_LT(reconstruction.volume().MemoryBytes(), bytes / 100) << bytes;
  EXPECT_TRUE(reconstruction.ExtractMesh().positions.empty());
  ASSERT_EQ(reconstruction.trajectory().poses().size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(reconstruction.trajectory().poses()[i].timestamp_s, poses[i].timestamp_s);
    EXPECT_TRUE(reconstruction.trajectory().poses()[i].world_from_sensor.translation ==
                poses[i].world_from_sensor.translation);
  }
  EXPECT_EQ(reconstruction.frames().size(), frames);
}

}  // namespace
}  // namespace hw::reconstruct
