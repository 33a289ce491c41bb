#pragma once

// A synthetic thermal camera for tests: frames whose content is a known function of the
// frame index, paced by the real clock, with the artefacts of a real camera (flat-field
// corrections that freeze the image, frames lost on the way to the host).

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "capture/thermal_camera.h"

namespace hw::capture {

struct FakeThermalOptions {
  int width = 160;         // px, in [1, 4096] (default: a Lepton 3.5)
  int height = 120;        // px, in [1, 4096]
  double fps = 9;          // Hz, in (0, 1000]: frame i is due at Start + i / fps
  // Frames the camera makes, >= 0; 0 = endless (until Stop). After the last one the
  // camera's thread idles until Stop.
  int64_t num_frames = 0;
  // A flat-field correction starts at every frame index k * ffc_every_frames (k >= 1) and
  // lasts ffc_frames frames: those frames are flagged ffc_in_progress and repeat the image
  // of the frame before the FFC (a real camera's shutter freezes the picture).
  // ffc_every_frames >= 0 (0 = never); ffc_frames in [1, ffc_every_frames) when FFCs happen.
  int64_t ffc_every_frames = 0;
  int64_t ffc_frames = 3;
  // Frame indices the camera makes but the host never receives (lost on USB): no callback,
  // and the camera_frame_counter of the next frame jumps. Each >= 0.
  std::vector<int64_t> dropped_frames;
  // true: camera_frame_counter = the frame index (like Lepton telemetry); false: -1 (like a
  // camera without telemetry).
  bool report_frame_counter = true;
  // Each frame is delivered up to this much later than its due time, s, in [0, 1 / fps):
  // uniform, from `seed` (USB and scheduling jitter). 0 = on time (as the OS allows).
  double arrival_jitter_s = 0;
  uint32_t seed = 1;
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// The raw value (centikelvin) of pixel (x, y) of image `image_index`:
//   29315 + 100 * (image_index mod 256) + (x + 2 y) mod 256
// i.e. 20 °C plus 1 K per image (wrapping every 256 images) plus a ramp that tells x from
// y. Stays in [29315, 55070]: valid uint16 and a plausible temperature for a radiometric
// camera.
uint16_t FakeThermalRaw(int64_t image_index, int x, int y);

// The index of the image frame `frame_index` shows: the frame itself, or during an FFC the
// last frame before it.
int64_t FakeThermalImageIndex(const FakeThermalOptions& options, int64_t frame_index);

// Whether frame `frame_index` falls inside an FFC.
bool FakeThermalInFfc(const FakeThermalOptions& options, int64_t frame_index);

// The whole frame the fake camera sends as frame `frame_index` (raw, counter, FFC flag;
// arrival_s = 0): what a test compares received frames with.
ThermalFrame FakeThermalExpectedFrame(const FakeThermalOptions& options, int64_t frame_index);

class FakeThermalCamera : public ThermalCamera {
 public:
  // Asserts options.Check() is empty (callers validate user options first).
  explicit FakeThermalCamera(FakeThermalOptions options = {});
  ~FakeThermalCamera() override;
  FakeThermalCamera(const FakeThermalCamera&) = delete;
  FakeThermalCamera& operator=(const FakeThermalCamera&) = delete;

  ThermalCameraInfo Info() const override;
  // Never throws InputError (no device); starts the camera's thread.
  void Start(FrameCallback on_frame) override;
  // Wakes the camera's thread and joins it (returns within a few ms).
  void Stop() override;

  // Frames delivered so far (callbacks returned); safe from any thread.
  int64_t FramesDelivered() const;

 private:
  void Run(FrameCallback on_frame);

  const FakeThermalOptions options_;
  std::thread thread_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_requested_ = false;
  int64_t frames_delivered_ = 0;
};

}  // namespace hw::capture
