#pragma once

// The thermal camera as capture/ sees it: a source that pushes raw 16-bit frames, each
// stamped on arrival with the host's monotonic clock. Implementations: UvcThermalCamera
// (a real camera over USB video class, capture/uvc_thermal_camera.h) and
// FakeThermalCamera (a synthetic one for tests, capture/fake_thermal_camera.h).

#include <cstdint>
#include <functional>
#include <string>

#include <opencv2/core/mat.hpp>

namespace hw::capture {

// Host monotonic clock used for every stream's arrival stamps: seconds of
// std::chrono::steady_clock since its (arbitrary, boot-related) epoch. Every stream of a
// capture session stamps with this one clock, so stamps of different streams compare.
double MonotonicNowS();

struct ThermalFrame {
  // CV_16UC1, height x width of ThermalCameraInfo: the raw counts as the camera sends them
  // (a radiometric FLIR Lepton 3.5 / Boson in TLinear mode: centikelvin, i.e. kelvin * 100;
  // other cameras: uncalibrated counts). Telemetry rows, when the camera appends any, are
  // removed. The Mat owns its pixels (the callback may keep it).
  cv::Mat raw;
  // MonotonicNowS() when the frame arrived on the host (taken first thing in the driver's
  // callback; the camera's own exposure happened earlier by its latency).
  double arrival_s = 0;
  // The camera's own frame counter when it reports one (Lepton telemetry), else -1. A gap
  // in it is a frame the camera made and the host never got.
  int64_t camera_frame_counter = -1;
  // The camera reports its shutter closed / a flat-field correction running: the image is
  // frozen or shows the shutter, not the scene. Always false for cameras that report no
  // FFC state in their video stream.
  bool ffc_in_progress = false;
};

struct ThermalCameraInfo {
  std::string name;          // human-readable, e.g. "FLIR Lepton on PureThermal" or "fake"
  std::string serial;        // USB serial string, "" when unreadable
  uint16_t vendor_id = 0;    // USB ids (0 for the fake camera)
  uint16_t product_id = 0;
  int width = 0;             // px, of ThermalFrame::raw
  int height = 0;            // px, of ThermalFrame::raw (telemetry rows excluded)
  double fps = 0;            // Hz, the nominal frame rate negotiated with the camera
  std::string format;        // pixel format on the wire, e.g. "Y16"
  bool radiometric = false;  // raw counts are centikelvin (see ThermalFrame::raw)
};

// A thermal camera delivering frames on its own thread (push model).
//
// Threads: Start() and Stop() are called from one controlling thread; on_frame runs on the
// camera's thread, one frame at a time, in arrival order. on_frame should return quickly
// (a slow callback makes the camera drop frames) and must not throw (an exception on the
// camera's thread terminates the program) nor call Stop().
class ThermalCamera {
 public:
  using FrameCallback = std::function<void(ThermalFrame)>;
  virtual ~ThermalCamera() = default;

  // What the camera streams; valid from construction (the device is opened and the stream
  // negotiated by the constructor or factory).
  virtual ThermalCameraInfo Info() const = 0;

  // Starts streaming to on_frame. Throws core::InputError naming the device and the reason
  // when the camera refuses (unplugged, busy, no permission). Calling Start on a started
  // camera is a bug (assert).
  virtual void Start(FrameCallback on_frame) = 0;

  // Stops streaming. Idempotent; after it returns no callback runs and none will. Never
  // throws.
  virtual void Stop() = 0;
};

}  // namespace hw::capture
