#include "capture/openni_source.h"

#include <chrono>
#include <cstdlib>

#include <OpenNI.h>
#include <gtest/gtest.h>

#include "capture/testing/capture_test_support.h"
#include "core/error.h"
#include "tests/support.h"

namespace hw::capture {
namespace {

namespace t = testing;

// The test device is found by enumeration with its modes (the test runtime loads it).
TEST(OpenNiSource, ListsTheTestDeviceWithItsModes) {
  std::string error;
  const std::vector<RgbdDeviceInfo> devices = ListRgbdDevices(&error);
  EXPECT_EQ(error, "");
  const RgbdDeviceInfo* test = nullptr;
  for (const RgbdDeviceInfo& d : devices)
    if (d.uri == t::kTestDeviceUri) test = &d;
  ASSERT_NE(test, nullptr) << "the heatwave test device is not listed";
  ASSERT_EQ(test->modes.size(), 2u);
  EXPECT_EQ(test->modes[0].sensor, "depth");
  EXPECT_EQ(test->modes[0].pixel_format, "depth_1mm");
  EXPECT_EQ(test->modes[0].width, 640);
  EXPECT_EQ(test->modes[1].sensor, "color");
  EXPECT_EQ(test->modes[1].pixel_format, "rgb888");
}

// Live frames carry the device's exact pixels and timestamps; arrival stamps increase.
TEST(OpenNiSource, LiveFramesAreTheDevicesPixelsAndTimestamps) {
  auto source = OpenNiSource::OpenDevice(t::kTestDeviceUri, OpenNiOpenOptions{});
  ASSERT_TRUE(source->has_color());
  source->Start();
  int depth = 0, color = 0;
  double last_arrival = 0;
  while (depth < 8 || color < 8) {
    std::optional<RgbdFrame> f = source->Next(1.0);
    ASSERT_TRUE(f.has_value()) << "no frame within 1 s from a 30 Hz device";
    EXPECT_GE(f->arrival_s, last_arrival);
    last_arrival = f->arrival_s;
    if (f->stream == RgbdFrame::Stream::kDepth) {
      ++depth;
      EXPECT_EQ(f->depth_unit_m, 0.001);
      EXPECT_EQ(f->device_timestamp_us, t::TestDepthTimestampUs(f->frame_index));
      EXPECT_EQ(t::DepthMismatches(f->image, f->frame_index), 0);
    } else {
      ++color;
      EXPECT_EQ(f->device_timestamp_us, t::TestColorTimestampUs(f->frame_index));
      EXPECT_EQ(t::ColorMismatches(f->image, f->frame_index), 0);
    }
  }
  source->Stop();
}

// A mode the device does not have is an InputError listing what it has.
TEST(OpenNiSource, AMissingModeListsTheDevicesModes) {
  OpenNiOpenOptions options;
  options.depth_width = 320;
  options.depth_height = 240;
  try {
    OpenNiSource::OpenDevice(t::kTestDeviceUri, options);
    FAIL() << "expected InputError";
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no depth mode 320x240"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("640x480@30 depth_1mm"), std::string::npos) << e.what();
  }
  EXPECT_THROW(OpenNiSource::OpenDevice("no-such-device", OpenNiOpenOptions{}), core::InputError);
}

// OpenNI2's DummyDevice: recorded through OpenNI2's Recorder, then closed and OpenNI2 shut
// down. Without the pause between stopping and destroying its streams, the driver's
// unjoined producer thread wakes in the unloaded library and the process dies of SIGSEGV
// (every run of a plain stop/destroy/shutdown did here). Runs in a child process because
// shutdown is process-wide.
TEST(OpenNiSource, DummyDeviceRecordsAndClosesWithoutCrashing) {
  const std::filesystem::path oni = hw::test::TestFolder() / "dummy.oni";
  const int code = hw::test::RunInChild(
      [&] {
        t::RecordDevice("Dummy", oni, 0.5, 320, 240);
        openni::OpenNI::shutdown();  // unloads the drivers: the crash happened here
        return std::filesystem::file_size(oni) > 0 ? 0 : 3;
      },
      20);
  EXPECT_EQ(code, 0) << "128 + 11 = 139 is the SIGSEGV of an unjoined driver thread";
}

// Its recording has no cropping record, so OpenNI2's player would drop every frame and a
// reader would wait forever: opening it is an InputError naming the cause, at once.
TEST(OpenNiSource, DummyDeviceRecordingIsRefusedWithTheReason) {
  const std::filesystem::path oni = hw::test::TestFolder() / "dummy.oni";
  t::RecordDevice("Dummy", oni, 0.5, 320, 240);
  const auto start = std::chrono::steady_clock::now();
  try {
    OpenNiSource::OpenRecording(oni);
    FAIL() << "expected InputError";
  } catch (const core::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(oni.string()), std::string::npos) << what;
    EXPECT_NE(what.find("no cropping record"), std::string::npos) << what;
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 2.0);
}

// A recording of the test device plays back completely in manual mode: every frame, in
// order, with the device's pixels; timestamps rebased by the Recorder to the stream's first
// frame.
TEST(OpenNiSource, TestDeviceRecordingPlaysBackEveryFrame) {
  const std::filesystem::path oni = hw::test::TestFolder() / "test.oni";
  t::RecordDevice(t::kTestDeviceUri, oni, 1.0);
  auto playback = OpenNiSource::OpenRecording(oni);
  const int depth_frames = playback->NumRecordedFrames(RgbdFrame::Stream::kDepth);
  const int color_frames = playback->NumRecordedFrames(RgbdFrame::Stream::kColor);
  // 1 s at 30 Hz; a loaded machine may deliver a few frames fewer.
  EXPECT_GE(depth_frames, 20);
  EXPECT_GE(color_frames, 20);
  int depth = 0, color = 0, first_depth_index = -1, first_color_index = -1, last_depth_index = -1;
  while (std::optional<RgbdFrame> f = playback->Next(5.0)) {
    if (f->stream == RgbdFrame::Stream::kDepth) {
      ++depth;
      // The player numbers frames 1..N; the pattern's frame is not in the file, so find it
      // from the first frame and check the rest follow one by one.
      if (first_depth_index < 0) {
        for (int k = 1; k < 1000 && first_depth_index < 0; ++k)
          if (t::DepthMismatches(f->image, k) == 0) first_depth_index = k;
        ASSERT_GT(first_depth_index, 0) << "the first recorded depth frame is no frame of the pattern";
        EXPECT_EQ(f->device_timestamp_us, 0u);
      }
      const int pattern_frame = first_depth_index + f->frame_index - 1;
      EXPECT_EQ(t::DepthMismatches(f->image, pattern_frame), 0) << "depth frame " << f->frame_index;
      EXPECT_EQ(f->device_timestamp_us, uint64_t(f->frame_index - 1) * t::kTestPeriodUs);
      EXPECT_GT(f->frame_index, last_depth_index);
      last_depth_index = f->frame_index;
    } else {
      ++color;
      if (first_color_index < 0) {
        for (int k = 1; k < 1000 && first_color_index < 0; ++k)
          if (t::ColorMismatches(f->image, k) == 0) first_color_index = k;
        ASSERT_GT(first_color_index, 0);
      }
      EXPECT_EQ(t::ColorMismatches(f->image, first_color_index + f->frame_index - 1), 0) << "colour frame " << f->frame_index;
      EXPECT_EQ(f->device_timestamp_us, uint64_t(f->frame_index - 1) * t::kTestPeriodUs);
    }
  }
  EXPECT_EQ(depth, depth_frames);
  EXPECT_EQ(color, color_frames);
}

TEST(OpenNiSource, UnreadableRecordingsAreInputErrors) {
  const std::filesystem::path folder = hw::test::TestFolder();
  EXPECT_THROW(OpenNiSource::OpenRecording(folder / "missing.oni"), core::InputError);
  {
    std::FILE* f = std::fopen((folder / "text.oni").c_str(), "w");
    std::fputs("this is not an OpenNI recording\n", f);
    std::fclose(f);
  }
  EXPECT_THROW(OpenNiSource::OpenRecording(folder / "text.oni"), core::InputError);
}

}  // namespace
}  // namespace hw::capture
