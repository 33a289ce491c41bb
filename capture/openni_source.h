#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace hw::capture {

// RGB-D input through OpenNI2 (Debian's libopenni2: PrimeSense/Asus/Kinect-1 class devices,
// and .oni recordings through OpenNI2's own player).
//
// Two defects of OpenNI2 2.2 are handled here (found with its DummyDevice driver):
// - Closing: DummyDevice's stream stop() only clears a flag and never joins its producer
//   thread (which sleeps 33 ms between frames); destroying the stream and then
//   OpenNI::shutdown() unloading the driver leaves that thread to wake in freed memory and
//   unmapped code: a SIGSEGV at exit. So streams are stopped, then given kStreamQuiesceS
//   to let such threads see the flag and leave, before they are destroyed; and
//   OpenNI::shutdown() is never called (the process' exit releases the drivers).
// - Playback: in manual playback (speed -1) the player reads the next frame only when poked
//   by OpenNI::waitForAnyStream(), never by VideoStream::readFrame(), so a plain readFrame()
//   waits forever; and the player silently drops every frame of a stream whose recording
//   has no cropping record (the Recorder writes one only for drivers that implement the
//   cropping property; DummyDevice does not). Playback here always waits with a timeout,
//   checks the cropping property up front, and turns either case into an InputError.
// - Playback teardown: the player thread (PlayerDevice::MainLoop) walks its stream list
//   without its lock, at full speed once the file has ended, while destroying a stream
//   removes it from that list without the lock: destroying the streams of a finished
//   playback crashed about one run in fifteen under load. Streams are stopped first; the
//   thread then only checks the list every 10 ms (sleeping between), and the streams are
//   destroyed kPlayerQuiesceS later, inside such a sleep.
// And one observed without a root cause (libOpenNI2 has no symbols): a stream started from
// a thread created after an earlier session's reading thread had ended crashed in
// oniStreamStart (SIGSEGV; two captures in one process). Start() belongs on the thread
// that owns the source; Capture() starts streams on its calling thread.

inline constexpr double kStreamQuiesceS = 0.1;
inline constexpr double kPlayerQuiesceS = 0.035;

struct RgbdStreamMode {
  std::string sensor;        // "depth" | "color" | "ir"
  int width = 0, height = 0;  // px
  int fps = 0;               // Hz
  std::string pixel_format;  // "depth_1mm", "depth_100um", "rgb888", "yuv422", "yuyv", "gray8", "gray16", "jpeg", ...
};

struct RgbdDeviceInfo {
  std::string uri, vendor, name;
  int usb_vendor_id = 0, usb_product_id = 0;
  std::vector<RgbdStreamMode> modes;
};

// The RGB-D devices OpenNI2 can open now (its drivers enumerate USB). Never throws: when
// OpenNI2 cannot start, returns an empty list and sets *error to its reason.
std::vector<RgbdDeviceInfo> ListRgbdDevices(std::string* error);

struct RgbdFrame {
  enum class Stream { kDepth, kColor };
  Stream stream = Stream::kDepth;
  // Depth: CV_16UC1 in units of depth_unit_m (0 = no measurement). Colour: CV_8UC3, RGB order.
  cv::Mat image;
  double depth_unit_m = 0.001;
  uint64_t device_timestamp_us = 0;  // the device's (or recording's) clock
  int frame_index = 0;               // the device's frame number
  double arrival_s = 0;              // MonotonicNowS() when read (live devices)
};

struct OpenNiOpenOptions {
  bool color = true;          // open the colour stream when the device has one
  int depth_width = 640;      // px; the depth mode must match exactly (the rig's depth camera)
  int depth_height = 480;     // px
  int color_width = 640;      // px; 0 = the device's first colour mode
  int color_height = 480;     // px
  int fps = 30;               // Hz; 0 = any
  std::string Check() const;
};

// An open OpenNI2 device or .oni recording with its depth (and colour) stream. Not
// thread-safe: one thread reads. Destruction stops and closes everything safely.
class OpenNiSource {
 public:
  // Opens a live device ("" = the first one). Throws core::InputError naming the device
  // and OpenNI2's reason, or listing the supported modes when none matches.
  static std::unique_ptr<OpenNiSource> OpenDevice(const std::string& uri, const OpenNiOpenOptions& options);
  // Opens a recording for playback frame by frame (manual speed, no repeat). Throws
  // core::InputError naming the file when OpenNI2 cannot open it, it has no depth stream,
  // or its streams cannot be played (see the header comment).
  static std::unique_ptr<OpenNiSource> OpenRecording(const std::filesystem::path& oni_path);
  ~OpenNiSource();

  std::string uri() const;
  bool has_color() const;
  RgbdStreamMode depth_mode() const;
  std::optional<RgbdStreamMode> color_mode() const;
  // Recordings: the frames each stream holds (0 for an absent stream).
  int NumRecordedFrames(RgbdFrame::Stream stream) const;

  // Live devices: starts the streams. Recordings are started when opened.
  void Start();
  // The next frame of any stream, waiting up to timeout_s. Live: nullopt on timeout.
  // Recording: nullopt once every stream has delivered all its frames; a stall longer
  // than timeout_s before that throws core::InputError naming the file and the counts.
  std::optional<RgbdFrame> Next(double timeout_s);
  // Stops the streams (then waits kStreamQuiesceS). Idempotent.
  void Stop();

  // Records what the streams deliver, from now on, into `oni_path` through OpenNI2's
  // Recorder (depth lossless; colour lossless unless lossy_color). Throws InputError.
  void StartRecording(const std::filesystem::path& oni_path, bool lossy_color = false);
  // Stops the streams (as Stop()), then flushes and closes the recording. Idempotent.
  // The streams go first because OpenNI2's Recorder deadlocked when destroyed while a
  // driver thread was delivering a frame (DummyDevice, about one run in three: the
  // recorder's thread spinning, the caller and the driver thread blocked on its locks).
  void StopRecording();

  struct Impl;

 private:
  explicit OpenNiSource(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hw::capture
