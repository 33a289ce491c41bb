#pragma once

// A real thermal camera over the USB video class (libuvc): FLIR Lepton on a PureThermal
// board, FLIR Boson, or any UVC camera streaming Y16 (16-bit raw) frames.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "capture/thermal_camera.h"

struct uvc_context;
struct uvc_device;
struct uvc_device_handle;
struct uvc_frame;

namespace hw::capture {

// Lepton telemetry row A (FLIR Lepton engineering datasheet, "Telemetry modes"). The
// layout here is the one four independent implementations agree on (the datasheet itself
// was not at hand): groupgets/purethermal1-firmware Inc/lepton.h telemetry_data_l3 (and
// its lepton_task.c reading frame_counter[1] << 16 | frame_counter[0]), flirpy's
// Lepton.decode_telemetry on PureThermal footer rows, leptonic's telemetry.c and the
// Cacophony Project's Lepton reader (FFC state = status bits 5:4, 0b10 = in progress).
// Words are 16-bit; a 32-bit field is two words, least significant first:
//   word 0 revision, 1-2 uptime ms, 3-4 status bits (FFC desired bit 3, FFC state bits 5:4
//   = 0 never commanded, 1 imminent, 2 in progress, 3 complete), 20-21 frame counter,
//   24 FPA temperature (centikelvin), 30-31 uptime ms at the last FFC.
struct LeptonTelemetry {
  uint32_t uptime_ms = 0;
  uint32_t status_bits = 0;
  int ffc_state = 0;             // bits 5:4 of status_bits
  bool ffc_in_progress = false;  // ffc_state == 2
  bool ffc_desired = false;      // bit 3
  uint32_t frame_counter = 0;
  double fpa_temperature_k = 0;
  uint32_t last_ffc_uptime_ms = 0;
};
inline constexpr int kLeptonTelemetryRowWords = 80;
// Parses row A from `words` (kLeptonTelemetryRowWords host-order 16-bit words). Returns
// nullopt for an all-zero row (no telemetry: the camera had it disabled).
std::optional<LeptonTelemetry> ParseLeptonTelemetryRowA(const uint16_t* words);

// Decodes one Y16 frame as the camera sends it: (image_height + telemetry_rows) rows of
// `width` little-endian 16-bit pixels, `step_bytes` apart (0 or less than width * 2 =
// packed). The image rows become ThermalFrame::raw; when the telemetry rows hold at least
// 80 words, their first 80 are Lepton telemetry row A (frame counter, FFC state). Returns
// nullopt when data_bytes is too short (a truncated transfer). arrival_s is left 0.
std::optional<ThermalFrame> DecodeY16Frame(const uint8_t* data, size_t data_bytes, size_t step_bytes, int width,
                                           int image_height, int telemetry_rows);

// Which camera a --thermal option names: "auto" (the first known thermal camera on USB),
// "fake" (FakeThermalCamera with default options), or "VID:PID[:SERIAL]" with 4-digit hex
// ids, e.g. "1e4e:0100".
struct ThermalDeviceSpec {
  enum class Kind { kAuto, kFake, kUsbIds };
  Kind kind = Kind::kAuto;
  uint16_t vendor_id = 0;   // kUsbIds only
  uint16_t product_id = 0;  // kUsbIds only
  std::string serial;       // kUsbIds only; "" = any
};
// Throws std::invalid_argument naming the spec and the accepted forms when malformed (the
// CLI turns it into a usage error).
ThermalDeviceSpec ParseThermalDeviceSpec(const std::string& spec);

class UvcThermalCamera : public ThermalCamera {
 public:
  // Opens the UVC device with these ids (and serial, when not ""), and picks its Y16
  // stream: the largest Y16 frame size, except that a frame 2-3 rows taller than another
  // of the same width is that image plus telemetry rows: on a PureThermal (Lepton) and
  // when `telemetry`, the taller frame is streamed and its extra rows parsed (frame
  // counter, FFC state) and cut off; otherwise the shorter frame is streamed. The frame
  // rate is the frame's default interval. Info().radiometric: a PureThermal whose Lepton
  // reports TLinear on at 0.01 K resolution (queried over the board's extension unit at
  // open, and again by Start when that said no: the firmware may keep the Lepton in low
  // power until a stream starts); false for other cameras (not queried). Throws core::InputError("usb VID:PID", reason)
  // when libuvc cannot start, the device is absent, cannot be opened (permissions: the
  // reason says so) or streams no Y16; the reason carries libuvc's uvc_strerror.
  UvcThermalCamera(uint16_t vendor_id, uint16_t product_id, const std::string& serial = "",
                   bool telemetry = true);
  ~UvcThermalCamera() override;
  UvcThermalCamera(const UvcThermalCamera&) = delete;
  UvcThermalCamera& operator=(const UvcThermalCamera&) = delete;

  ThermalCameraInfo Info() const override { return info_; }
  // Starts libuvc's streaming thread; on_frame runs on it. Frames shorter than negotiated
  // (a transfer cut short) are dropped, like frames lost on USB.
  void Start(FrameCallback on_frame) override;
  // uvc_stop_streaming: joins libuvc's thread, so no callback runs after it returns.
  void Stop() override;

  // Frames libuvc delivered with fewer bytes than negotiated (dropped); from any thread.
  int64_t ShortFrames() const;

 private:
  static void OnUvcFrame(uvc_frame* frame, void* self);
  void HandleFrame(uvc_frame* frame, double arrival_s);
  std::string DeviceName() const;  // "usb 1e4e:0100"

  ThermalCameraInfo info_;
  uvc_context* context_ = nullptr;
  uvc_device* device_ = nullptr;
  uvc_device_handle* handle_ = nullptr;
  struct StreamControl;  // uvc_stream_ctrl_t, kept out of this header
  std::unique_ptr<StreamControl> control_;
  int wire_height_ = 0;      // rows on the wire: info_.height + telemetry rows
  int telemetry_rows_ = 0;
  bool is_pure_thermal_ = false;
  bool streaming_ = false;
  FrameCallback on_frame_;
  mutable std::mutex stats_mutex_;
  int64_t short_frames_ = 0;
};

// The camera a spec names (ParseThermalDeviceSpec): "fake" -> FakeThermalCamera{};
// "VID:PID[:SERIAL]" -> UvcThermalCamera; "auto" -> UvcThermalCamera on the first device of
// ListUsbDevices that is a KnownThermalCamera (KnownThermalCameras order). Throws
// std::invalid_argument for a malformed spec, core::InputError when the camera cannot be
// opened, and for "auto" with none attached: "thermal camera: no thermal camera found on
// USB (looked for: <each known camera and ids>)", plus "; <reason>" when USB could not be
// listed at all (libusb failure, no /dev/bus/usb).
std::unique_ptr<ThermalCamera> OpenThermalCamera(const std::string& spec);

}  // namespace hw::capture
