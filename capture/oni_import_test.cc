#include "capture/oni_import.h"

#include <cmath>

#include <gtest/gtest.h>

#include "capture/testing/capture_test_support.h"
#include "core/error.h"
#include "core/scan.h"
#include "tests/support.h"

namespace hw::capture {
namespace {

namespace t = testing;

// Recorded once per test binary run: 1 s of the test device through OpenNI2's Recorder
// (66 MB), removed when the process exits (ctest runs every test in its own process: left
// behind, the recordings filled /tmp at 66 MB a test).
const std::filesystem::path& Recording() {
  struct Recorded {
    std::filesystem::path path;
    Recorded()
        : path(std::filesystem::path(::testing::TempDir()) /
               ("heatwave-oni-import-" + std::to_string(::getpid()) + ".oni")) {
      t::RecordDevice(t::kTestDeviceUri, path, 1.0);
    }
    ~Recorded() {
      std::error_code ec;
      std::filesystem::remove(path, ec);
    }
  };
  static const Recorded recorded;
  return recorded.path;
}

// Every recorded frame lands in the scan with the device's exact depth (mm, depth_scale
// 1000) and colour, and the recording's timestamps (µs, rebased per stream to 0) in seconds.
TEST(ImportOni, WritesEveryFrameExactly) {
  const std::filesystem::path scan_folder = hw::test::TestFolder();
  const OniImportSummary s = ImportOni(Recording(), t::TestDeviceRig(), scan_folder);
  EXPECT_GE(s.depth_recorded, 20);
  EXPECT_EQ(s.depth_frames, s.depth_recorded);
  EXPECT_EQ(s.color_frames, s.color_recorded);
  EXPECT_EQ(s.skipped_not_increasing, 0);
  EXPECT_EQ(s.depth_pixels_out_of_range, 0);
  EXPECT_EQ(s.first_depth_s, 0.0);
  EXPECT_NEAR(s.last_depth_s, (s.depth_frames - 1) * t::kTestPeriodUs * 1e-6, 1e-9);

  const core::Scan scan = core::Scan::Open(scan_folder);
  ASSERT_EQ(scan.NumFrames(core::Stream::kDepth), s.depth_frames);
  ASSERT_EQ(scan.NumFrames(core::Stream::kRgb), s.color_frames);
  // The pattern frame of the first recorded frame (the Recorder started mid-stream).
  const cv::Mat first = scan.LoadDepth(0);
  cv::Mat first_mm;
  first.convertTo(first_mm, CV_16UC1, 1000.0);
  int k0 = -1;
  for (int k = 1; k < 1000 && k0 < 0; ++k)
    if (t::DepthMismatches(first_mm, k) == 0) k0 = k;
  ASSERT_GT(k0, 0);
  for (int i = 0; i < s.depth_frames; ++i) {
    EXPECT_NEAR(scan.Timestamp(core::Stream::kDepth, i), i * t::kTestPeriodUs * 1e-6, 5e-7) << i;
    cv::Mat mm;
    scan.LoadDepth(i).convertTo(mm, CV_16UC1, 1000.0);  // exact: integers / 1000 in float, x 1000, rounded
    EXPECT_EQ(t::DepthMismatches(mm, k0 + i), 0) << "depth frame " << i;
  }
  int c0 = -1;
  for (int k = 1; k < 1000 && c0 < 0; ++k)
    if (t::ColorMismatches(scan.LoadRgb(0), k) == 0) c0 = k;
  ASSERT_GT(c0, 0);
  for (int i = 0; i < s.color_frames; ++i) {
    EXPECT_NEAR(scan.Timestamp(core::Stream::kRgb, i), i * t::kTestPeriodUs * 1e-6, 5e-7) << i;
    EXPECT_EQ(t::ColorMismatches(scan.LoadRgb(i), c0 + i), 0) << "colour frame " << i;
  }
}

// A rig without rgb imports depth only and says the colour was left out.
TEST(ImportOni, ARigWithoutRgbImportsDepthOnly) {
  core::Rig rig = t::TestDeviceRig();
  rig.rgb.reset();
  const std::filesystem::path scan_folder = hw::test::TestFolder();
  const OniImportSummary s = ImportOni(Recording(), rig, scan_folder);
  EXPECT_TRUE(s.color_ignored);
  EXPECT_EQ(s.color_frames, 0);
  EXPECT_EQ(s.depth_frames, s.depth_recorded);
  EXPECT_FALSE(std::filesystem::exists(scan_folder / "rgb.txt"));
}

// A rig whose cameras are not the recording's sizes is refused, naming both sizes.
TEST(ImportOni, ARigOfAnotherSizeIsRefused) {
  core::Rig rig = t::TestDeviceRig();
  rig.depth = core::CameraModel::Pinhole(320, 240, 285.0, 285.0);
  try {
    ImportOni(Recording(), rig, hw::test::TestFolder());
    FAIL();
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("depth is 640x480 but the rig's depth camera is 320x240"), std::string::npos)
        << e.what();
  }
  rig = t::TestDeviceRig();
  rig.rgb = core::CameraModel::Pinhole(1280, 1024, 1000, 1000);
  EXPECT_THROW(ImportOni(Recording(), rig, hw::test::TestFolder()), core::InputError);
}

}  // namespace
}  // namespace hw::capture
