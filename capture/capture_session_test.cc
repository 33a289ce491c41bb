#include "capture/capture_session.h"

#include <chrono>
#include <cmath>

#include <gtest/gtest.h>

#include "capture/fake_thermal_camera.h"
#include "capture/testing/capture_test_support.h"
#include "core/error.h"
#include "core/scan.h"
#include "tests/support.h"

namespace hw::capture {
namespace {

namespace t = testing;

FakeThermalOptions FastThermal() {
  FakeThermalOptions o;
  o.fps = 27;               // more frames in a short test than a Lepton's 9 Hz
  o.ffc_every_frames = 12;  // an FFC every ~0.44 s, 3 frames long
  o.ffc_frames = 3;
  return o;
}

// The fake camera's frame index shown by a stored thermal image (apparent °C): the raw
// value at (0, 0) is 29315 + 100 * (index mod 256).
int ImageIndexOf(const cv::Mat& apparent_c) {
  const double raw = (static_cast<double>(apparent_c.at<float>(0, 0)) + 273.15) / 0.01;
  return static_cast<int>(std::lround((raw - 29315.0) / 100.0));
}

// 1.5 s of the test device and the fake thermal camera: a valid scan whose every frame is
// what the devices sent, stamped on arrival on one clock, with the FFC events in ffc.txt.
TEST(Capture, RecordsEveryStreamIntoAValidScan) {
  auto rgbd = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  FakeThermalCamera thermal(FastThermal());
  const std::filesystem::path folder = hw::test::TestFolder();
  CaptureOptions options;
  options.duration_s = 1.5;
  options.index_every_s = 0.5;
  const CaptureSummary s = Capture(rgbd.get(), &thermal, t::TestDeviceRig(), folder, options, [] { return false; });
  EXPECT_FALSE(s.stopped_by_user);
  EXPECT_NEAR(s.seconds, 1.5, 0.2);
  // 30 Hz and 27 Hz for 1.5 s; a loaded 2-core machine may lose a few frames' time.
  EXPECT_GE(s.depth.written, 35);
  EXPECT_GE(s.rgb.written, 35);
  EXPECT_GE(s.thermal.written, 30);
  EXPECT_EQ(s.depth.dropped + s.rgb.dropped + s.thermal.dropped, 0);
  EXPECT_GE(s.ffc_events, 2);

  const core::Scan scan = core::Scan::Open(folder);
  EXPECT_EQ(scan.NumFrames(core::Stream::kDepth), s.depth.written);
  EXPECT_EQ(scan.NumFrames(core::Stream::kRgb), s.rgb.written);
  EXPECT_EQ(scan.NumFrames(core::Stream::kThermal), s.thermal.written);
  EXPECT_EQ(static_cast<int64_t>(scan.ffc_timestamps_s().size()), s.ffc_events);
  // Arrival stamps: seconds since the start, within the capture (plus the frames that
  // arrive while the streams are being stopped: at most a few periods), periods near nominal.
  EXPECT_GE(scan.Timestamp(core::Stream::kDepth, 0), 0.0);
  EXPECT_LE(scan.Timestamp(core::Stream::kDepth, scan.NumFrames(core::Stream::kDepth) - 1), s.seconds + 0.2);
  EXPECT_NEAR(scan.MedianPeriod(core::Stream::kDepth), 1.0 / 30, 0.008);
  EXPECT_NEAR(scan.MedianPeriod(core::Stream::kThermal), 1.0 / 27, 0.008);
  // Content: depth frames are consecutive frames of the pattern (no loss), colour too.
  cv::Mat mm;
  scan.LoadDepth(0).convertTo(mm, CV_16UC1, 1000.0);
  int k0 = -1;
  for (int k = 1; k < 1000 && k0 < 0; ++k)
    if (t::DepthMismatches(mm, k) == 0) k0 = k;
  ASSERT_GT(k0, 0);
  for (int i = 0; i < scan.NumFrames(core::Stream::kDepth); i += 7) {
    scan.LoadDepth(i).convertTo(mm, CV_16UC1, 1000.0);
    EXPECT_EQ(t::DepthMismatches(mm, k0 + i), 0) << i;
  }
  // Thermal: each stored frame is the fake camera's frame, raw counts exact.
  const FakeThermalOptions fake = FastThermal();
  int ffc_frames = 0;
  for (int i = 0; i < scan.NumFrames(core::Stream::kThermal); ++i) {
    const cv::Mat apparent = scan.LoadThermal(i);
    const ThermalFrame expected = FakeThermalExpectedFrame(fake, i);
    ffc_frames += expected.ffc_in_progress;
    ASSERT_EQ(ImageIndexOf(apparent), FakeThermalImageIndex(fake, i) % 256) << "thermal frame " << i;
    for (int y = 0; y < apparent.rows; y += 13)
      for (int x = 0; x < apparent.cols; x += 17) {
        const double raw = (static_cast<double>(apparent.at<float>(y, x)) + 273.15) / 0.01;
        ASSERT_NEAR(raw, expected.raw.at<uint16_t>(y, x), 0.01) << i << " " << x << " " << y;
      }
  }
  EXPECT_GT(ffc_frames, 0);
  // Each FFC event is the time of the first frame flagged in progress.
  for (double t_ffc : scan.ffc_timestamps_s()) {
    const std::optional<int> j = scan.NearestFrame(core::Stream::kThermal, t_ffc, 1e-6);
    ASSERT_TRUE(j.has_value());
    EXPECT_TRUE(FakeThermalInFfc(fake, *j));
    EXPECT_FALSE(FakeThermalInFfc(fake, *j - 1));
  }
}

// The stop flag (Ctrl-C) ends the capture with everything written and indexed.
TEST(Capture, StopsOnRequestWithEverythingFlushed) {
  auto rgbd = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  FakeThermalCamera thermal(FastThermal());
  const std::filesystem::path folder = hw::test::TestFolder();
  const auto start = std::chrono::steady_clock::now();
  const CaptureSummary s = Capture(rgbd.get(), &thermal, t::TestDeviceRig(), folder, CaptureOptions{}, [&] {
    return std::chrono::steady_clock::now() - start > std::chrono::milliseconds(700);
  });
  EXPECT_TRUE(s.stopped_by_user);
  const core::Scan scan = core::Scan::Open(folder);
  EXPECT_EQ(scan.NumFrames(core::Stream::kDepth), s.depth.written);
  EXPECT_EQ(scan.NumFrames(core::Stream::kThermal), s.thermal.written);
  EXPECT_EQ(s.depth.received, s.depth.written);
  EXPECT_EQ(s.thermal.received, s.thermal.written);
  EXPECT_GT(s.depth.written, 10);
}

// A queue of one frame with three streams arriving: frames are dropped and counted, never
// buffered without bound, and what was written is a valid scan.
TEST(Capture, AFullQueueDropsAndCounts) {
  auto rgbd = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  FakeThermalOptions fast = FastThermal();
  fast.fps = 200;
  FakeThermalCamera thermal(fast);
  const std::filesystem::path folder = hw::test::TestFolder();
  CaptureOptions options;
  options.duration_s = 0.8;
  options.max_queued_frames = 1;
  const CaptureSummary s = Capture(rgbd.get(), &thermal, t::TestDeviceRig(), folder, options, [] { return false; });
  EXPECT_EQ(s.max_queue_frames, 1);
  const int64_t dropped = s.depth.dropped + s.rgb.dropped + s.thermal.dropped;
  EXPECT_GT(dropped, 0);
  EXPECT_EQ(s.depth.received + s.rgb.received + s.thermal.received,
            s.depth.written + s.rgb.written + s.thermal.written + dropped);
  const core::Scan scan = core::Scan::Open(folder);
  EXPECT_EQ(scan.NumFrames(core::Stream::kThermal), s.thermal.written);
}

// A camera that stops sending (unplugged: the fake one makes 10 frames, then nothing) ends
// the capture after max_silence_s, naming it; the scan keeps everything recorded.
TEST(Capture, ASilentCameraEndsTheCaptureAndTheScanKeepsWhatWasRecorded) {
  auto rgbd = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  FakeThermalOptions unplugged = FastThermal();
  unplugged.num_frames = 10;  // 0.37 s at 27 Hz
  FakeThermalCamera thermal(unplugged);
  const std::filesystem::path folder = hw::test::TestFolder();
  CaptureOptions options;
  options.duration_s = 10;
  options.max_silence_s = 0.5;
  const CaptureSummary s = Capture(rgbd.get(), &thermal, t::TestDeviceRig(), folder, options, [] { return false; });
  EXPECT_NE(s.device_error.find("thermal camera 'fake thermal camera': no thermal frame for"), std::string::npos)
      << s.device_error;
  // Ended about 0.5 s after the last thermal frame (0.33 s), not after 10 s.
  EXPECT_LT(s.seconds, 2.0);
  EXPECT_GT(s.seconds, 0.8);
  EXPECT_EQ(s.thermal.written, 10);
  const core::Scan scan = core::Scan::Open(folder);
  EXPECT_EQ(scan.NumFrames(core::Stream::kThermal), 10);
  EXPECT_EQ(scan.NumFrames(core::Stream::kDepth), s.depth.written);
  EXPECT_GT(s.depth.written, 15);
}

// A camera that never sends a frame ends the capture after first_frame_timeout_s.
TEST(Capture, ACameraThatNeverSendsEndsTheCapture) {
  auto rgbd = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  FakeThermalOptions dead = FastThermal();
  for (int64_t i = 0; i < 200; ++i) dead.dropped_frames.push_back(i);  // none reaches the host
  FakeThermalCamera thermal(dead);
  CaptureOptions options;
  options.duration_s = 10;
  options.first_frame_timeout_s = 0.6;
  const CaptureSummary s =
      Capture(rgbd.get(), &thermal, t::TestDeviceRig(), hw::test::TestFolder(), options, [] { return false; });
  EXPECT_NE(s.device_error.find("no thermal frame in the first 0.6 s"), std::string::npos) << s.device_error;
  EXPECT_LT(s.seconds, 2.0);
  EXPECT_EQ(s.thermal.written, 0);
}

// Devices that do not match the rig are refused before anything is written.
TEST(Capture, ARigThatDoesNotMatchTheDevicesIsRefused) {
  auto rgbd = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  FakeThermalOptions small = FastThermal();
  small.width = 80;
  small.height = 60;
  FakeThermalCamera thermal(small);
  const std::filesystem::path folder = hw::test::TestFolder();
  try {
    Capture(rgbd.get(), &thermal, t::TestDeviceRig(), folder, CaptureOptions{}, [] { return true; });
    FAIL();
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frames are 80x60 but the rig's thermal camera is 160x120"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(folder / "rig.yaml"));
  EXPECT_FALSE(CaptureOptions{.duration_s = -1}.Check().empty());
  EXPECT_FALSE(CaptureOptions{.max_queued_frames = 0}.Check().empty());
  EXPECT_FALSE(CaptureOptions{.max_silence_s = 0}.Check().empty());
  EXPECT_FALSE(CaptureOptions{.first_frame_timeout_s = -1}.Check().empty());
}

}  // namespace
}  // namespace hw::capture
