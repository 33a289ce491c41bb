#include "capture/fake_thermal_camera.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include <opencv2/core.hpp>

namespace hw::capture {
namespace {

// Collects what a camera delivers, from its thread.
struct Sink {
  std::mutex mutex;
  std::vector<ThermalFrame> frames;
  ThermalCamera::FrameCallback Callback() {
    return [this](ThermalFrame frame) {
      std::lock_guard lock(mutex);
      frames.push_back(std::move(frame));
    };
  }
  size_t Size() {
    std::lock_guard lock(mutex);
    return frames.size();
  }
};

// Waits until `camera` has delivered `count` frames or timeout_s passed.
bool WaitFrames(const FakeThermalCamera& camera, int64_t count, double timeout_s) {
  const double end_s = MonotonicNowS() + timeout_s;
  while (camera.FramesDelivered() < count) {
    if (MonotonicNowS() > end_s) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() && cv::countNonZero(a != b) == 0;
}

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

TEST(FakeThermalCameraTest, FramesCarryTheKnownContentCountersAndMonotonicStamps) {
  FakeThermalOptions options;
  options.width = 32;
  options.height = 24;
  options.fps = 200;
  options.num_frames = 40;
  FakeThermalCamera camera(options);
  const ThermalCameraInfo info = camera.Info();
  EXPECT_EQ(info.width, 32);
  EXPECT_EQ(info.height, 24);
  EXPECT_EQ(info.fps, 200);
  EXPECT_EQ(info.format, "Y16");
  EXPECT_TRUE(info.radiometric);
  Sink sink;
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 40, 5));
  camera.Stop();
  ASSERT_EQ(sink.frames.size(), 40u);
  for (int i = 0; i < 40; ++i) {
    const ThermalFrame& frame = sink.frames[i];
    ASSERT_EQ(frame.raw.type(), CV_16UC1);
    ASSERT_EQ(frame.raw.cols, 32);
    ASSERT_EQ(frame.raw.rows, 24);
    EXPECT_EQ(frame.camera_frame_counter, i);
    EXPECT_FALSE(frame.ffc_in_progress);
    // Spot values straight from the documented formula, then the whole image.
    EXPECT_EQ(frame.raw.at<uint16_t>(0, 0), 29315 + 100 * i);
    EXPECT_EQ(frame.raw.at<uint16_t>(5, 7), 29315 + 100 * i + 7 + 2 * 5);
    EXPECT_TRUE(SameImage(frame.raw, FakeThermalExpectedFrame(options, i).raw)) << "frame " << i;
    if (i > 0) {
      EXPECT_GT(frame.arrival_s, sink.frames[i - 1].arrival_s);
    }
  }
}

TEST(FakeThermalCameraTest, RawWrapsEvery256ImagesAndStaysAValidTemperature) {
  EXPECT_EQ(FakeThermalRaw(256, 0, 0), FakeThermalRaw(0, 0, 0));
  EXPECT_EQ(FakeThermalRaw(255, 255, 0), 29315 + 25500 + 255);
  EXPECT_NE(FakeThermalRaw(3, 1, 0), FakeThermalRaw(3, 0, 1));  // x and y tell apart
}

TEST(FakeThermalCameraTest, FramesArriveAtTheConfiguredRateNeverEarly) {
  FakeThermalOptions options;
  options.width = 16;
  options.height = 12;
  options.fps = 50;
  options.num_frames = 30;  // 0.58 s
  FakeThermalCamera camera(options);
  Sink sink;
  const double start_s = MonotonicNowS();
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 30, 5));
  camera.Stop();
  ASSERT_EQ(sink.frames.size(), 30u);
  std::vector<double> lateness_s;
  for (int i = 0; i < 30; ++i) {
    // Due times are absolute (Start + i / fps): a frame is never early, and lateness does
    // not accumulate.
    const double due_s = start_s + i / options.fps;
    EXPECT_GE(sink.frames[i].arrival_s, due_s) << "frame " << i;
    lateness_s.push_back(sink.frames[i].arrival_s - due_s);
  }
  // A sleeping thread wakes within ~1 ms on an idle machine; 15 ms leaves room for a
  // loaded 2-core test run without letting a wrong period (>= 20 ms off at frame 1) pass.
  EXPECT_LT(Median(lateness_s), 0.015);
  const double mean_period_s = (sink.frames.back().arrival_s - sink.frames.front().arrival_s) / 29;
  // 3% of the 0.58 s span is 17 ms: the first and last wake-ups' lateness, under load.
  EXPECT_NEAR(mean_period_s, 1 / options.fps, 0.03 / options.fps);
}

TEST(FakeThermalCameraTest, FlatFieldCorrectionsAreFlaggedAndFreezeTheImage) {
  FakeThermalOptions options;
  options.width = 8;
  options.height = 6;
  options.fps = 400;
  options.num_frames = 26;
  options.ffc_every_frames = 10;
  options.ffc_frames = 3;
  FakeThermalCamera camera(options);
  Sink sink;
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 26, 5));
  camera.Stop();
  ASSERT_EQ(sink.frames.size(), 26u);
  for (int i = 0; i < 26; ++i) {
    const bool in_ffc = (i >= 10 && i <= 12) || (i >= 20 && i <= 22);
    EXPECT_EQ(sink.frames[i].ffc_in_progress, in_ffc) << "frame " << i;
    EXPECT_EQ(sink.frames[i].camera_frame_counter, i);
    const int image = i >= 10 && i <= 12 ? 9 : i >= 20 && i <= 22 ? 19 : i;
    EXPECT_EQ(sink.frames[i].raw.at<uint16_t>(0, 0), FakeThermalRaw(image, 0, 0)) << "frame " << i;
  }
}

TEST(FakeThermalCameraTest, DroppedFramesNeverArriveAndLeaveAGapInTheCounter) {
  FakeThermalOptions options;
  options.width = 8;
  options.height = 6;
  options.fps = 100;
  options.num_frames = 20;
  options.dropped_frames = {17, 3, 4};  // any order
  FakeThermalCamera camera(options);
  Sink sink;
  const double start_s = MonotonicNowS();
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 17, 5));
  camera.Stop();
  ASSERT_EQ(sink.frames.size(), 17u);
  std::vector<int64_t> counters;
  for (const ThermalFrame& frame : sink.frames) {
    counters.push_back(frame.camera_frame_counter);
    EXPECT_EQ(frame.raw.at<uint16_t>(0, 0), FakeThermalRaw(frame.camera_frame_counter, 0, 0));
  }
  const std::vector<int64_t> expected = {0, 1, 2, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 18, 19};
  EXPECT_EQ(counters, expected);
  // A dropped frame still takes its time slot: frame 5 is due 50 ms after the start.
  EXPECT_GE(sink.frames[3].arrival_s, start_s + 0.05);
}

TEST(FakeThermalCameraTest, NoFrameCounterWhenNotReported) {
  FakeThermalOptions options;
  options.width = 4;
  options.height = 4;
  options.fps = 500;
  options.num_frames = 3;
  options.report_frame_counter = false;
  FakeThermalCamera camera(options);
  Sink sink;
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 3, 5));
  camera.Stop();
  for (const ThermalFrame& frame : sink.frames) EXPECT_EQ(frame.camera_frame_counter, -1);
}

TEST(FakeThermalCameraTest, StopJoinsQuicklyAndNoCallbackRunsAfterIt) {
  FakeThermalOptions options;
  options.width = 4;
  options.height = 4;
  options.fps = 1;  // the thread sleeps ~1 s between frames: Stop must wake it
  FakeThermalCamera camera(options);
  Sink sink;
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 1, 5));  // frame 0 is due at once
  const double before_s = MonotonicNowS();
  camera.Stop();
  EXPECT_LT(MonotonicNowS() - before_s, 0.1);
  camera.Stop();  // idempotent
  EXPECT_EQ(sink.Size(), 1u);

  // At a high rate, with a callback that takes time: a callback running after Stop
  // returned would see `stopped` set.
  options.fps = 1000;
  FakeThermalCamera fast(options);
  std::atomic<bool> stopped = false;
  std::atomic<int> calls = 0, calls_after_stop = 0;
  fast.Start([&](ThermalFrame) {
    ++calls;
    std::this_thread::sleep_for(std::chrono::microseconds(300));
    if (stopped) ++calls_after_stop;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  fast.Stop();
  stopped = true;
  const int calls_at_stop = calls;
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_GT(calls_at_stop, 10);
  EXPECT_EQ(calls, calls_at_stop);
  EXPECT_EQ(calls_after_stop, 0);
}

TEST(FakeThermalCameraTest, StopWithoutStartAndDestructionWhileStreamingAreSafe) {
  FakeThermalOptions options;
  options.width = 4;
  options.height = 4;
  options.fps = 100;
  {
    FakeThermalCamera idle(options);
    idle.Stop();
  }
  Sink sink;
  {
    FakeThermalCamera streaming(options);
    streaming.Start(sink.Callback());
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
  }  // the destructor stops and joins
  const size_t delivered = sink.Size();
  EXPECT_GE(delivered, 1u);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(sink.Size(), delivered);
}

TEST(FakeThermalCameraTest, ArrivalJitterKeepsOrderAndNeverArrivesEarly) {
  FakeThermalOptions options;
  options.width = 4;
  options.height = 4;
  options.fps = 200;
  options.num_frames = 40;
  options.arrival_jitter_s = 0.004;
  FakeThermalCamera camera(options);
  Sink sink;
  const double start_s = MonotonicNowS();
  camera.Start(sink.Callback());
  ASSERT_TRUE(WaitFrames(camera, 40, 5));
  camera.Stop();
  std::vector<double> lateness_s;
  for (int i = 0; i < 40; ++i) {
    EXPECT_GE(sink.frames[i].arrival_s, start_s + i / options.fps);
    if (i > 0) {
      EXPECT_GT(sink.frames[i].arrival_s, sink.frames[i - 1].arrival_s);
    }
    lateness_s.push_back(sink.frames[i].arrival_s - (start_s + i / options.fps));
  }
  // Uniform jitter in [0, 4 ms]: median 2 ms, plus the wake-up lateness; a camera ignoring
  // the jitter would show a median well under 1 ms on an idle machine, so only the upper
  // side is checked here (a loaded machine only adds lateness).
  EXPECT_LT(Median(lateness_s), 0.015);
}

TEST(FakeThermalCameraTest, CheckNamesTheBadField) {
  const auto problem = [](auto edit) {
    FakeThermalOptions options;
    edit(options);
    return options.Check();
  };
  EXPECT_EQ(FakeThermalOptions{}.Check(), "");
  EXPECT_NE(problem([](auto& o) { o.width = 0; }).find("width"), std::string::npos);
  EXPECT_NE(problem([](auto& o) { o.height = 5000; }).find("height"), std::string::npos);
  EXPECT_NE(problem([](auto& o) { o.fps = 0; }).find("fps"), std::string::npos);
  EXPECT_NE(problem([](auto& o) { o.num_frames = -1; }).find("num_frames"), std::string::npos);
  EXPECT_NE(problem([](auto& o) { o.ffc_every_frames = -2; }).find("ffc_every_frames"), std::string::npos);
  EXPECT_NE(problem([](auto& o) {
              o.ffc_every_frames = 5;
              o.ffc_frames = 5;
            }).find("ffc_frames"),
            std::string::npos);
  EXPECT_NE(problem([](auto& o) { o.dropped_frames = {2, -1}; }).find("dropped_frames"), std::string::npos);
  EXPECT_NE(problem([](auto& o) { o.arrival_jitter_s = 0.2; }).find("arrival_jitter_s"), std::string::npos);
}

}  // namespace
}  // namespace hw::capture
