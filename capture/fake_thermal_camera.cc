#include "capture/fake_thermal_camera.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <random>
#include <utility>

#include "core/option_check.h"

namespace hw::capture {

std::string FakeThermalOptions::Check() const {
  if (width < 1 || width > 4096) return core::OptionFail("width", width, "in [1, 4096] px");
  if (height < 1 || height > 4096) return core::OptionFail("height", height, "in [1, 4096] px");
  if (!(fps > 0 && fps <= 1000)) return core::OptionFail("fps", fps, "in (0, 1000] Hz");
  if (num_frames < 0) return core::OptionFail("num_frames", static_cast<double>(num_frames), ">= 0");
  if (ffc_every_frames < 0) {
    return core::OptionFail("ffc_every_frames", static_cast<double>(ffc_every_frames), ">= 0");
  }
  if (ffc_every_frames > 0 && (ffc_frames < 1 || ffc_frames >= ffc_every_frames)) {
    return core::OptionFail("ffc_frames", static_cast<double>(ffc_frames),
                            "in [1, ffc_every_frames) when ffc_every_frames > 0");
  }
  for (const int64_t index : dropped_frames) {
    if (index < 0) return core::OptionFail("dropped_frames[]", static_cast<double>(index), ">= 0");
  }
  if (!(arrival_jitter_s >= 0 && arrival_jitter_s < 1 / fps)) {
    return core::OptionFail("arrival_jitter_s", arrival_jitter_s, "in [0, 1 / fps) s");
  }
  return "";
}

uint16_t FakeThermalRaw(int64_t image_index, int x, int y) {
  assert(image_index >= 0 && x >= 0 && y >= 0);
  return static_cast<uint16_t>(29315 + 100 * (image_index % 256) + (x + 2 * y) % 256);
}

bool FakeThermalInFfc(const FakeThermalOptions& options, int64_t frame_index) {
  if (options.ffc_every_frames <= 0 || frame_index < options.ffc_every_frames) return false;
  return frame_index % options.ffc_every_frames < options.ffc_frames;
}

int64_t FakeThermalImageIndex(const FakeThermalOptions& options, int64_t frame_index) {
  if (!FakeThermalInFfc(options, frame_index)) return frame_index;
  return frame_index - frame_index % options.ffc_every_frames - 1;
}

ThermalFrame FakeThermalExpectedFrame(const FakeThermalOptions& options, int64_t frame_index) {
  ThermalFrame frame;
  frame.raw.create(options.height, options.width, CV_16UC1);
  const int64_t image_index = FakeThermalImageIndex(options, frame_index);
  for (int y = 0; y < options.height; ++y) {
    auto* row = frame.raw.ptr<uint16_t>(y);
    for (int x = 0; x < options.width; ++x) row[x] = FakeThermalRaw(image_index, x, y);
  }
  frame.camera_frame_counter = options.report_frame_counter ? frame_index : -1;
  frame.ffc_in_progress = FakeThermalInFfc(options, frame_index);
  return frame;
}

FakeThermalCamera::FakeThermalCamera(FakeThermalOptions options) : options_(std::move(options)) {
  assert(options_.Check().empty());
}

FakeThermalCamera::~FakeThermalCamera() { Stop(); }

ThermalCameraInfo FakeThermalCamera::Info() const {
  ThermalCameraInfo info;
  info.name = "fake thermal camera";
  info.serial = "fake";
  info.width = options_.width;
  info.height = options_.height;
  info.fps = options_.fps;
  info.format = "Y16";
  info.radiometric = true;
  return info;
}

void FakeThermalCamera::Start(FrameCallback on_frame) {
  assert(!thread_.joinable() && "FakeThermalCamera::Start on a started camera");
  {
    std::lock_guard lock(mutex_);
    stop_requested_ = false;
  }
  thread_ = std::thread(&FakeThermalCamera::Run, this, std::move(on_frame));
}

void FakeThermalCamera::Stop() {
  if (!thread_.joinable()) return;
  assert(thread_.get_id() != std::this_thread::get_id() && "Stop() called from the frame callback");
  {
    std::lock_guard lock(mutex_);
    stop_requested_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

int64_t FakeThermalCamera::FramesDelivered() const {
  std::lock_guard lock(mutex_);
  return frames_delivered_;
}

void FakeThermalCamera::Run(FrameCallback on_frame) {
  using Clock = std::chrono::steady_clock;
  std::vector<int64_t> dropped = options_.dropped_frames;
  std::sort(dropped.begin(), dropped.end());
  std::mt19937 random(options_.seed);
  std::uniform_real_distribution<double> jitter_s(0, options_.arrival_jitter_s);
  const Clock::time_point start = Clock::now();
  for (int64_t i = 0; options_.num_frames == 0 || i < options_.num_frames; ++i) {
    // Built before its due time, as a camera has the frame ready when it sends it.
    const bool drop = std::binary_search(dropped.begin(), dropped.end(), i);
    ThermalFrame frame;
    if (!drop) frame = FakeThermalExpectedFrame(options_, i);
    const double due_s = static_cast<double>(i) / options_.fps +
                         (options_.arrival_jitter_s > 0 ? jitter_s(random) : 0.0);
    const auto due = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(due_s));
    {
      std::unique_lock lock(mutex_);
      if (wake_.wait_until(lock, due, [this] { return stop_requested_; })) return;
    }
    if (drop) continue;
    frame.arrival_s = MonotonicNowS();
    on_frame(std::move(frame));
    std::lock_guard lock(mutex_);
    ++frames_delivered_;
  }
  std::unique_lock lock(mutex_);
  wake_.wait(lock, [this] { return stop_requested_; });
}

}  // namespace hw::capture
