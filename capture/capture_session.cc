#include "capture/capture_session.h"

#include <cassert>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <atomic>
#include <vector>

#include <opencv2/core.hpp>

#include "capture/thermal_camera.h"
#include "capture/openni_source.h"
#include "core/error.h"
#include "core/scan_writer.h"
#include "core/strings.h"

namespace hw::capture {

std::string CaptureOptions::Check() const {
  if (!(duration_s >= 0) || !std::isfinite(duration_s))
    return core::StringPrintf("duration_s (--duration) %g must be finite and >= 0", duration_s);
  if (max_queued_frames < 1) return core::StringPrintf("max_queued_frames (--queue) %d must be >= 1", max_queued_frames);
  if (!(index_every_s > 0) || !std::isfinite(index_every_s))
    return core::StringPrintf("index_every_s %g must be finite and > 0", index_every_s);
  if (!(max_silence_s > 0) || !std::isfinite(max_silence_s))
    return core::StringPrintf("max_silence_s %g must be finite and > 0", max_silence_s);
  if (!(first_frame_timeout_s > 0) || !std::isfinite(first_frame_timeout_s))
    return core::StringPrintf("first_frame_timeout_s %g must be finite and > 0", first_frame_timeout_s);
  return "";
}

namespace {

enum class Kind { kDepth, kRgb, kThermal };

struct Item {
  Kind kind;
  double t_s;            // scan timestamp
  cv::Mat image;         // as the source delivered it
  double depth_unit_m;   // depth only
  bool ffc_starts;       // thermal only: a flat-field event begins with this frame
};

std::string Size(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// Everything the three threads share, under one mutex.
class Shared {
 public:
  explicit Shared(int capacity) : capacity_(capacity) {}

  // Counts the arrival and queues the frame, or drops it when the queue is full.
  void Push(Item item, double nominal_period_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    StreamCount& c = Count(item.kind);
    ++c.received;
    std::optional<double>& last = last_arrival_[static_cast<int>(item.kind)];
    if (last && nominal_period_s > 0 && item.t_s - *last > 1.5 * nominal_period_s) ++c.gaps;
    last = item.t_s;
    if (static_cast<int>(queue_.size()) >= capacity_) {
      ++c.dropped;
      return;
    }
    if (item.ffc_starts) ++summary_.ffc_events;
    queue_.push_back(std::move(item));
    summary_.max_queue_frames = std::max<int64_t>(summary_.max_queue_frames, static_cast<int64_t>(queue_.size()));
    cv_.notify_one();
  }

  // The next frame, or nullopt once producers are done and the queue is empty.
  std::optional<Item> Pop(double timeout_s) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] { return !queue_.empty() || producers_done_; });
    if (queue_.empty()) return std::nullopt;
    Item item = std::move(queue_.front());
    queue_.pop_front();
    return item;
  }

  void Written(Kind kind, double t_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    StreamCount& c = Count(kind);
    if (c.written == 0) c.first_s = t_s;
    c.last_s = t_s;
    ++c.written;
  }
  void Dropped(Kind kind) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++Count(kind).dropped;
  }

  void ProducersDone() {
    std::lock_guard<std::mutex> lock(mutex_);
    producers_done_ = true;
    cv_.notify_all();
  }
  bool producers_done() {
    std::lock_guard<std::mutex> lock(mutex_);
    return producers_done_;
  }

  // The first error of any thread ends the capture and is rethrown by Capture().
  void Fail(std::exception_ptr error) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!error_) error_ = error;
    failed_ = true;
    cv_.notify_all();
  }
  bool failed() {
    std::lock_guard<std::mutex> lock(mutex_);
    return failed_;
  }
  std::exception_ptr error() {
    std::lock_guard<std::mutex> lock(mutex_);
    return error_;
  }

  // A device failed or fell silent: the capture ends early, normally (the first reason kept).
  void DeviceFailed(const std::string& message) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (summary_.device_error.empty()) summary_.device_error = message;
  }
  bool device_failed() {
    std::lock_guard<std::mutex> lock(mutex_);
    return !summary_.device_error.empty();
  }
  // Scan time of the stream's last arrival, or nullopt before its first.
  std::optional<double> LastArrival(Kind kind) {
    std::lock_guard<std::mutex> lock(mutex_);
    return last_arrival_[static_cast<int>(kind)];
  }

  CaptureSummary Snapshot() {
    std::lock_guard<std::mutex> lock(mutex_);
    return summary_;
  }

 private:
  StreamCount& Count(Kind kind) {
    return kind == Kind::kDepth ? summary_.depth : kind == Kind::kRgb ? summary_.rgb : summary_.thermal;
  }

  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Item> queue_;
  int capacity_;
  bool producers_done_ = false;
  bool failed_ = false;
  std::exception_ptr error_;
  CaptureSummary summary_;
  std::optional<double> last_arrival_[3];
};

}  // namespace

void CheckCaptureRig(const OpenNiSource* rgbd, const ThermalCamera* thermal, const core::Rig& rig) {
  if (rgbd != nullptr) {
    const RgbdStreamMode d = rgbd->depth_mode();
    if (d.width != rig.depth.width || d.height != rig.depth.height)
      throw core::InputError("RGB-D device '" + rgbd->uri() + "'", "depth is " + Size(d.width, d.height) +
                                                                          " but the rig's depth camera is " +
                                                                          Size(rig.depth.width, rig.depth.height));
    if (const auto c = rgbd->color_mode(); c && rig.rgb && (c->width != rig.rgb->width || c->height != rig.rgb->height))
      throw core::InputError("RGB-D device '" + rgbd->uri() + "'", "colour is " + Size(c->width, c->height) +
                                                                          " but the rig's rgb camera is " +
                                                                          Size(rig.rgb->width, rig.rgb->height));
  }
  if (thermal != nullptr) {
    const ThermalCameraInfo info = thermal->Info();
    if (!rig.thermal)
      throw core::InputError("thermal camera '" + info.name + "'", "the rig has no thermal camera to record it as");
    if (info.width != rig.thermal->width || info.height != rig.thermal->height)
      throw core::InputError("thermal camera '" + info.name + "'", "frames are " + Size(info.width, info.height) +
                                                                     " but the rig's thermal camera is " +
                                                                     Size(rig.thermal->width, rig.thermal->height));
  }
}

CaptureSummary Capture(OpenNiSource* rgbd, ThermalCamera* thermal, const core::Rig& rig,
                       const std::filesystem::path& folder, const CaptureOptions& options,
                       const std::function<bool()>& should_stop,
                       const std::function<void(const CaptureSummary&)>& progress) {
  assert(options.Check().empty());
  assert(rgbd != nullptr || thermal != nullptr);
  CheckCaptureRig(rgbd, thermal, rig);
  bool with_rgb = false;
  double depth_period_s = 0, rgb_period_s = 0, thermal_period_s = 0;
  if (rgbd != nullptr) {
    const RgbdStreamMode d = rgbd->depth_mode();
    depth_period_s = d.fps > 0 ? 1.0 / d.fps : 0;
    if (const auto c = rgbd->color_mode(); c && rig.rgb) {
      with_rgb = true;
      rgb_period_s = c->fps > 0 ? 1.0 / c->fps : 0;
    }
  }
  if (thermal != nullptr) {
    const double fps = thermal->Info().fps;
    thermal_period_s = fps > 0 ? 1.0 / fps : 0;
  }

  core::ScanWriter writer(folder, rig);
  Shared shared(options.max_queued_frames);
  const double t0 = MonotonicNowS();
  std::atomic<bool> stop_producers{false};

  // Writer: the only thread that touches the ScanWriter.
  std::thread writer_thread([&] {
    try {
      std::optional<double> last_s[3];
      double last_index_s = MonotonicNowS();
      while (true) {
        std::optional<Item> item = shared.Pop(0.2);
        if (!item) {
          if (shared.producers_done() || shared.failed()) break;
        } else {
          const int k = static_cast<int>(item->kind);
          const double t_s = core::RoundToMicroseconds(item->t_s);
          if (last_s[k] && t_s <= *last_s[k]) {
            shared.Dropped(item->kind);  // two arrivals within a microsecond: keep the first
          } else {
            if (item->kind == Kind::kDepth) {
              cv::Mat depth_m;
              item->image.convertTo(depth_m, CV_32FC1, item->depth_unit_m);
              writer.AddDepth(t_s, depth_m);
            } else if (item->kind == Kind::kRgb) {
              writer.AddRgb(t_s, item->image);
            } else {
              cv::Mat apparent_c;
              item->image.convertTo(apparent_c, CV_32FC1, rig.thermal_settings->raw_scale,
                                    rig.thermal_settings->raw_offset);
              if (item->ffc_starts) writer.AddFfcEvent(t_s);
              writer.AddThermal(t_s, apparent_c);
            }
            last_s[k] = t_s;
            shared.Written(item->kind, t_s);
          }
        }
        if (MonotonicNowS() - last_index_s >= options.index_every_s && writer.NumFrames("depth") + writer.NumFrames("thermal") > 0) {
          writer.Finish();
          last_index_s = MonotonicNowS();
        }
      }
    } catch (...) {
      shared.Fail(std::current_exception());
    }
  });

  // RGB-D reader. The streams start on the calling thread (capture/openni_source.h: a start
  // from a short-lived thread crashed OpenNI2 on the second capture of a process).
  std::thread rgbd_thread;
  if (rgbd != nullptr) {
    try {
      rgbd->Start();
    } catch (const core::InputError& e) {
      shared.DeviceFailed(core::OneLineMessage(e.what()));
    }
    rgbd_thread = std::thread([&] {
      try {
        while (!stop_producers.load()) {
          std::optional<RgbdFrame> frame = rgbd->Next(0.1);
          if (!frame) continue;
          const bool is_depth = frame->stream == RgbdFrame::Stream::kDepth;
          if (!is_depth && !with_rgb) continue;
          shared.Push(Item{is_depth ? Kind::kDepth : Kind::kRgb, frame->arrival_s - t0, std::move(frame->image),
                           frame->depth_unit_m, false},
                      is_depth ? depth_period_s : rgb_period_s);
        }
      } catch (const core::InputError& e) {
        shared.DeviceFailed(core::OneLineMessage(e.what()));
      } catch (...) {
        shared.Fail(std::current_exception());
      }
    });
  }

  // Thermal: frames arrive on the camera's thread.
  bool ffc_before = false;
  if (thermal != nullptr) {
    try {
      thermal->Start([&](ThermalFrame frame) {
        const bool starts = frame.ffc_in_progress && !ffc_before;
        ffc_before = frame.ffc_in_progress;
        shared.Push(Item{Kind::kThermal, frame.arrival_s - t0, std::move(frame.raw), 0.0, starts}, thermal_period_s);
      });
    } catch (const core::InputError& e) {
      shared.DeviceFailed(core::OneLineMessage(e.what()));
    }
  }

  // The calling thread watches the clock and the stop flag.
  bool by_user = false;
  double last_progress = 0;
  // The streams expected to deliver, and who delivers them (for the silence check).
  struct Watched {
    Kind kind;
    const char* stream;
    std::string device;
  };
  std::vector<Watched> watched;
  if (rgbd != nullptr) {
    watched.push_back({Kind::kDepth, "depth", "RGB-D device '" + rgbd->uri() + "'"});
    if (with_rgb) watched.push_back({Kind::kRgb, "colour", "RGB-D device '" + rgbd->uri() + "'"});
  }
  if (thermal != nullptr) watched.push_back({Kind::kThermal, "thermal", "thermal camera '" + thermal->Info().name + "'"});
  while (!shared.failed() && !shared.device_failed()) {
    if (should_stop && should_stop()) {
      by_user = true;
      break;
    }
    const double now_s = MonotonicNowS() - t0;
    if (options.duration_s > 0 && now_s >= options.duration_s) break;
    for (const Watched& w : watched) {
      const std::optional<double> last_s = shared.LastArrival(w.kind);
      if (!last_s && now_s > options.first_frame_timeout_s) {
        shared.DeviceFailed(core::StringPrintf("%s: no %s frame in the first %.1f s", w.device.c_str(), w.stream,
                                               options.first_frame_timeout_s));
      } else if (last_s && now_s - *last_s > options.max_silence_s) {
        shared.DeviceFailed(core::StringPrintf("%s: no %s frame for %.1f s after t = %.3f s (unplugged or stalled?)",
                                               w.device.c_str(), w.stream, now_s - *last_s, *last_s));
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (progress) {
      const double now = MonotonicNowS();
      if (now - last_progress >= 0.5) {
        last_progress = now;
        CaptureSummary s = shared.Snapshot();
        s.seconds = now - t0;
        progress(s);
      }
    }
  }
  const double seconds = MonotonicNowS() - t0;
  // Stop the producers, then let the writer drain the queue.
  if (thermal != nullptr) thermal->Stop();
  stop_producers = true;
  if (rgbd_thread.joinable()) rgbd_thread.join();
  if (rgbd != nullptr) rgbd->Stop();
  shared.ProducersDone();
  writer_thread.join();
  if (std::exception_ptr error = shared.error()) std::rethrow_exception(error);
  writer.Finish();
  CaptureSummary summary = shared.Snapshot();
  summary.seconds = seconds;
  summary.stopped_by_user = by_user;
  return summary;
}

}  // namespace hw::capture
