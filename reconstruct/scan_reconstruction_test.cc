// ReconstructScan against the frame-by-frame API it drives: the same poses and volume, with
// each frame prepared ahead on a thread of its own or not.
#include <cstring>
#include <stdexcept>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/scan.h"
#include "reconstruct/reconstruct_test_support.h"
#include "reconstruct/reconstruction.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {
namespace {

using core::Stream;
using test::CachedScan;
using test::TestScanOptions;

TEST(ScanReconstruction, FrameByFrameEqualsWholeScan) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  Reconstruction whole(scan.rig(), test::PipelineTestOptions());
  ScanReconstructionOptions first_ten;
  first_ten.max_frames = 10;
  ReconstructScan(scan, whole, first_ten);

  Reconstruction live(scan.rig(), test::PipelineTestOptions());
  for (int i = 0; i < 10; ++i) {
    if (!scan.FrameExists(Stream::kDepth, i)) continue;
    FrameInput frame = LoadScanFrame(scan, i, true);
    live.AddFrame(frame);
  }
  // The whole scan's frames were prepared ahead, beside the previous frame (on more than one
  // core): the same poses and volume to the bit.
  ASSERT_EQ(live.trajectory().size(), whole.trajectory().size());
  for (size_t i = 0; i < live.trajectory().size(); ++i) {
    const core::PoseError e = core::ComparePoses(live.trajectory().poses()[i].world_from_sensor,
                                                 whole.trajectory().poses()[i].world_from_sensor);
    EXPECT_EQ(e.translation_m, 0.0);
    EXPECT_EQ(e.rotation_rad, 0.0);
  }
  EXPECT_EQ(live.volume().NumBlocks(), whole.volume().NumBlocks());
  int ahead = 0;
  for (const FrameRecord& f : whole.frames()) ahead += f.prepare_ahead_ms > 0;
  for (const FrameRecord& f : live.frames()) EXPECT_EQ(f.prepare_ahead_ms, 0);
  EXPECT_EQ(ahead, ResolveThreads(0) > 1 ? static_cast<int>(whole.frames().size()) : 0);
}

TEST(ScanReconstruction, PreparationIsTheSameOnOneThreadOrAll) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  const Reconstruction reconstruction(scan.rig(), test::PipelineTestOptions());
  const FrameInput frame = LoadScanFrame(scan, 3, true);
  const PreparedFrame one = reconstruction.Prepare(frame, 1), all = reconstruction.Prepare(frame, 0);
  const auto same = [](const cv::Mat& a, const cv::Mat& b) {
    return a.size() == b.size() && a.type() == b.type() &&
           (a.empty() || std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0);
  };
  ASSERT_FALSE(one.rgb_pinhole.empty());
  EXPECT_TRUE(same(one.rgb_pinhole, all.rgb_pinhole));
  EXPECT_TRUE(same(one.pyramid.raw_depth_m, all.pyramid.raw_depth_m));
  ASSERT_EQ(one.pyramid.levels.size(), all.pyramid.levels.size());
  for (size_t l = 0; l < one.pyramid.levels.size(); ++l) {
    EXPECT_TRUE(same(one.pyramid.levels[l].depth_m, all.pyramid.levels[l].depth_m)) << l;
    EXPECT_EQ(one.pyramid.levels[l].map.points.size(), all.pyramid.levels[l].map.points.size()) << l;
    // Bytes, not values: invalid points are NaN.
    const auto same_points = [](const std::vector<Eigen::Vector3f>& a, const std::vector<Eigen::Vector3f>& b) {
      return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Eigen::Vector3f)) == 0;
    };
    EXPECT_TRUE(same_points(one.pyramid.levels[l].map.points, all.pyramid.levels[l].map.points)) << l;
    EXPECT_TRUE(same_points(one.pyramid.levels[l].map.normals, all.pyramid.levels[l].map.normals)) << l;
  }
  // A frame of the wrong size is refused by Prepare as by AddFrame.
  FrameInput bad = frame;
  bad.depth_m = cv::Mat(10, 10, CV_32FC1, cv::Scalar(1.0f));
  EXPECT_THROW(reconstruction.Prepare(bad, 1), std::invalid_argument);
}

// One thread asked for, one thread used: nothing is prepared ahead; nor with prepare_ahead
// off. The poses are the same either way.
TEST(ScanReconstruction, OneThreadOrPrepareAheadOffPreparesInline) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  ReconstructionOptions one_thread = test::PipelineTestOptions();
  one_thread.num_threads = 1;
  ScanReconstructionOptions first_ten;
  first_ten.max_frames = 10;
  Reconstruction single(scan.rig(), one_thread);
  ReconstructScan(scan, single, first_ten);
  ScanReconstructionOptions inline_options = first_ten;
  inline_options.prepare_ahead = false;
  Reconstruction serial(scan.rig(), test::PipelineTestOptions());
  ReconstructScan(scan, serial, inline_options);
  ASSERT_FALSE(single.frames().empty());
  for (const FrameRecord& f : single.frames()) EXPECT_EQ(f.prepare_ahead_ms, 0);
  for (const FrameRecord& f : serial.frames()) EXPECT_EQ(f.prepare_ahead_ms, 0);
  ASSERT_EQ(single.trajectory().size(), serial.trajectory().size());
  for (size_t i = 0; i < single.trajectory().size(); ++i) {
    EXPECT_EQ(core::ComparePoses(single.trajectory().poses()[i].world_from_sensor,
                                 serial.trajectory().poses()[i].world_from_sensor)
                  .translation_m,
              0.0);
  }
}

}  // namespace
}  // namespace hw::reconstruct
