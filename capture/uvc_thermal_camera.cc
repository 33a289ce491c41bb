#include "capture/uvc_thermal_camera.h"

#include <libuvc/libuvc.h>

#include <bit>
#include <cassert>
#include <cstring>
#include <stdexcept>
#include <utility>
#include <vector>

#include "capture/fake_thermal_camera.h"
#include "capture/usb_devices.h"
#include "core/error.h"
#include "core/strings.h"

namespace hw::capture {

// ---------------------------------------------------------------- Lepton telemetry

std::optional<LeptonTelemetry> ParseLeptonTelemetryRowA(const uint16_t* words) {
  bool any = false;
  for (int i = 0; i < kLeptonTelemetryRowWords; ++i) any = any || words[i] != 0;
  if (!any) return std::nullopt;
  const auto dword = [words](int i) { return static_cast<uint32_t>(words[i]) | static_cast<uint32_t>(words[i + 1]) << 16; };
  LeptonTelemetry t;
  t.uptime_ms = dword(1);
  t.status_bits = dword(3);
  t.ffc_desired = (t.status_bits >> 3) & 1;
  t.ffc_state = static_cast<int>((t.status_bits >> 4) & 3);
  t.ffc_in_progress = t.ffc_state == 2;
  t.frame_counter = dword(20);
  t.fpa_temperature_k = words[24] / 100.0;
  t.last_ffc_uptime_ms = dword(30);
  return t;
}

// ---------------------------------------------------------------- spec

namespace {

bool ParseHexId(const std::string& text, uint16_t* id) {
  if (text.size() != 4) return false;
  unsigned value = 0;
  for (const char c : text) {
    int digit;
    if (c >= '0' && c <= '9') digit = c - '0';
    else if (c >= 'a' && c <= 'f') digit = c - 'a' + 10;
    else if (c >= 'A' && c <= 'F') digit = c - 'A' + 10;
    else return false;
    value = value * 16 + static_cast<unsigned>(digit);
  }
  *id = static_cast<uint16_t>(value);
  return true;
}

}  // namespace

ThermalDeviceSpec ParseThermalDeviceSpec(const std::string& spec) {
  ThermalDeviceSpec parsed;
  if (spec == "auto") return parsed;
  if (spec == "fake") {
    parsed.kind = ThermalDeviceSpec::Kind::kFake;
    return parsed;
  }
  const auto fail = [&spec]() -> ThermalDeviceSpec {
    throw std::invalid_argument("thermal camera '" + core::OneLineMessage(spec) +
                                "': expected auto, fake, or VID:PID[:SERIAL] with 4-digit hex USB ids "
                                "(e.g. 1e4e:0100)");
  };
  const size_t colon = spec.find(':');
  if (colon == std::string::npos) return fail();
  const size_t colon2 = spec.find(':', colon + 1);
  parsed.kind = ThermalDeviceSpec::Kind::kUsbIds;
  if (!ParseHexId(spec.substr(0, colon), &parsed.vendor_id)) return fail();
  const std::string pid = colon2 == std::string::npos ? spec.substr(colon + 1) : spec.substr(colon + 1, colon2 - colon - 1);
  if (!ParseHexId(pid, &parsed.product_id)) return fail();
  if (colon2 != std::string::npos) {
    parsed.serial = spec.substr(colon2 + 1);
    if (parsed.serial.empty()) return fail();
  }
  return parsed;
}

// ---------------------------------------------------------------- UvcThermalCamera

struct UvcThermalCamera::StreamControl {
  uvc_stream_ctrl_t ctrl{};
};

namespace {

std::string UvcError(const char* call, uvc_error_t code) {
  std::string text = std::string(call) + " failed: " + uvc_strerror(code);
  if (code == UVC_ERROR_ACCESS) {
    text += " (no permission on the USB device node: add a udev rule granting your user access, "
            "or unplug and replug after installing one)";
  } else if (code == UVC_ERROR_BUSY) {
    text += " (another program, or the kernel's uvcvideo driver, holds the camera)";
  }
  return text;
}

struct Y16Frame {
  int width = 0, height = 0;
  uint32_t interval_100ns = 0;  // the frame's default interval
};

// Whether the Lepton behind a PureThermal streams centikelvin: TLinear enabled with 0.01 K
// resolution. PureThermal firmware exposes the Lepton CCI attributes as UVC extension-unit
// controls, unit 5 = RAD module (RAD_UNIT_ID in groupgets/purethermal1-uvc-capture
// uvctypes.py), selector = (command offset >> 2) + 1 (usbd_uvc.c of
// groupgets/purethermal1-firmware maps GET_CUR of selector cs to offset (cs - 1) << 2);
// Lepton SDK LEP_CID_RAD_TLINEAR_ENABLE_STATE = RAD base + 0xC0 -> 49, _RESOLUTION = + 0xC4
// -> 50 (LEP_RAD_RESOLUTION_0_01 = 1). 4-byte little-endian values. A non-radiometric
// Lepton (the firmware answers zeros) or a failed request gives false.
bool PureThermalReportsCentikelvin(uvc_device_handle_t* handle) {
  constexpr uint8_t kRadUnit = 5, kTLinearEnable = 49, kTLinearResolution = 50;
  const auto get = [handle](uint8_t selector, uint32_t* value) {
    uint8_t bytes[4] = {};
    if (uvc_get_ctrl(handle, kRadUnit, selector, bytes, 4, UVC_GET_CUR) != 4) return false;
    *value = bytes[0] | bytes[1] << 8 | bytes[2] << 16 | static_cast<uint32_t>(bytes[3]) << 24;
    return true;
  };
  uint32_t enabled = 0, resolution = 0;
  return get(kTLinearEnable, &enabled) && enabled == 1 && get(kTLinearResolution, &resolution) && resolution == 1;
}

bool IsY16(const uvc_format_desc_t* format) {
  return format->bDescriptorSubtype == UVC_VS_FORMAT_UNCOMPRESSED &&
         std::memcmp(format->guidFormat, "Y16 ", 4) == 0;
}

}  // namespace

std::string UvcThermalCamera::DeviceName() const { return "usb " + UsbIdString(info_.vendor_id, info_.product_id); }

UvcThermalCamera::UvcThermalCamera(uint16_t vendor_id, uint16_t product_id, const std::string& serial,
                                   bool telemetry)
    : control_(std::make_unique<StreamControl>()) {
  info_.vendor_id = vendor_id;
  info_.product_id = product_id;
  info_.format = "Y16";
  const std::optional<KnownThermalCamera> known = FindKnownThermalCamera(vendor_id, product_id);
  info_.name = known ? known->name : "UVC camera " + UsbIdString(vendor_id, product_id);
  // Releases what the constructor acquired so far, then throws.
  const auto fail = [this](const std::string& reason) {
    if (handle_ != nullptr) uvc_close(handle_);
    if (device_ != nullptr) uvc_unref_device(device_);
    if (context_ != nullptr) uvc_exit(context_);
    handle_ = nullptr;
    device_ = nullptr;
    context_ = nullptr;
    throw core::InputError(DeviceName(), reason);
  };

  if (const uvc_error_t code = uvc_init(&context_, nullptr); code < 0) {
    context_ = nullptr;
    fail(UvcError("uvc_init", code) + " (no USB access here?)");
  }
  if (const uvc_error_t code =
          uvc_find_device(context_, &device_, vendor_id, product_id, serial.empty() ? nullptr : serial.c_str());
      code < 0) {
    device_ = nullptr;
    std::string reason = code == UVC_ERROR_NO_DEVICE
                             ? "not found on USB" + (serial.empty() ? std::string() : " with serial " + serial)
                             : UvcError("uvc_find_device", code);
    if (const std::string hint = UsbAccessProblem(); !hint.empty()) reason += " (" + hint + ")";
    fail(reason);
  }
  if (const uvc_error_t code = uvc_open(device_, &handle_); code < 0) {
    handle_ = nullptr;
    fail(UvcError("uvc_open", code));
  }
  uvc_device_descriptor_t* descriptor = nullptr;
  if (uvc_get_device_descriptor(device_, &descriptor) == UVC_SUCCESS) {
    if (descriptor->serialNumber != nullptr) info_.serial = core::OneLineMessage(descriptor->serialNumber);
    if (!known && descriptor->product != nullptr) info_.name = core::OneLineMessage(descriptor->product);
    uvc_free_device_descriptor(descriptor);
  }
  is_pure_thermal_ = known && known->telemetry;
  if (is_pure_thermal_) info_.radiometric = PureThermalReportsCentikelvin(handle_);

  // Every Y16 frame size the camera offers.
  std::vector<Y16Frame> frames;
  for (const uvc_format_desc_t* format = uvc_get_format_descs(handle_); format != nullptr; format = format->next) {
    if (!IsY16(format)) continue;
    for (const uvc_frame_desc_t* frame = format->frame_descs; frame != nullptr; frame = frame->next) {
      Y16Frame y16{frame->wWidth, frame->wHeight, frame->dwDefaultFrameInterval};
      if (y16.interval_100ns == 0 && frame->intervals != nullptr) y16.interval_100ns = frame->intervals[0];
      if (y16.interval_100ns == 0) y16.interval_100ns = frame->dwMinFrameInterval;
      if (y16.width > 0 && y16.height > 0 && y16.interval_100ns > 0) frames.push_back(y16);
    }
  }
  if (frames.empty()) fail("the camera offers no Y16 (16-bit raw) stream");
  // Largest image; when it is 2-3 rows taller than another frame of the same width, it is
  // that image plus telemetry rows (PureThermal: 160x120 / 160x122, 80x60 / 80x63).
  Y16Frame image = frames[0];
  for (const Y16Frame& f : frames) {
    if (static_cast<int64_t>(f.width) * f.height > static_cast<int64_t>(image.width) * image.height) image = f;
  }
  Y16Frame wire = image;
  for (const Y16Frame& base : frames) {
    const int extra = image.height - base.height;
    if (base.width == image.width && (extra == 2 || extra == 3)) {
      // The real image is the shorter frame. Only the Lepton's extra rows are known
      // telemetry; another camera's (e.g. a Boson's) are not parsed, so not streamed.
      wire = telemetry && known && known->telemetry ? image : base;
      image = base;
      break;
    }
  }
  telemetry_rows_ = wire.height - image.height;
  info_.width = image.width;
  info_.height = image.height;
  wire_height_ = wire.height;
  // libuvc matches frame rates as 10^7 / interval in whole Hz.
  const int fps = static_cast<int>(10000000 / wire.interval_100ns);
  info_.fps = 1e7 / wire.interval_100ns;
  if (const uvc_error_t code = uvc_get_stream_ctrl_format_size(handle_, &control_->ctrl, UVC_FRAME_FORMAT_GRAY16,
                                                               wire.width, wire.height, fps);
      code < 0) {
    fail(UvcError("uvc_get_stream_ctrl_format_size", code) +
         core::StringPrintf(" (Y16 %dx%d at %d Hz)", wire.width, wire.height, fps));
  }
}

UvcThermalCamera::~UvcThermalCamera() {
  Stop();
  if (handle_ != nullptr) uvc_close(handle_);
  if (device_ != nullptr) uvc_unref_device(device_);
  if (context_ != nullptr) uvc_exit(context_);
}

void UvcThermalCamera::Start(FrameCallback on_frame) {
  assert(!streaming_ && "UvcThermalCamera::Start on a started camera");
  on_frame_ = std::move(on_frame);
  if (const uvc_error_t code = uvc_start_streaming(handle_, &control_->ctrl, &UvcThermalCamera::OnUvcFrame, this, 0);
      code < 0) {
    on_frame_ = nullptr;
    throw core::InputError(DeviceName(), UvcError("uvc_start_streaming", code));
  }
  streaming_ = true;
  // The PureThermal firmware keeps the Lepton in low power while no stream runs, when its
  // attributes may read as zeros: ask again now that it streams.
  if (is_pure_thermal_ && !info_.radiometric) info_.radiometric = PureThermalReportsCentikelvin(handle_);
}

void UvcThermalCamera::Stop() {
  if (!streaming_) return;
  uvc_stop_streaming(handle_);  // joins libuvc's callback thread
  streaming_ = false;
  on_frame_ = nullptr;
}

int64_t UvcThermalCamera::ShortFrames() const {
  std::lock_guard lock(stats_mutex_);
  return short_frames_;
}

void UvcThermalCamera::OnUvcFrame(uvc_frame* frame, void* self) {
  const double arrival_s = MonotonicNowS();  // first: everything after adds latency
  static_cast<UvcThermalCamera*>(self)->HandleFrame(frame, arrival_s);
}

std::optional<ThermalFrame> DecodeY16Frame(const uint8_t* data, size_t data_bytes, size_t step_bytes, int width,
                                           int image_height, int telemetry_rows) {
  assert(width > 0 && image_height > 0 && telemetry_rows >= 0);
  const size_t row_bytes = static_cast<size_t>(width) * 2;
  const size_t step = step_bytes >= row_bytes ? step_bytes : row_bytes;
  const int rows = image_height + telemetry_rows;
  if (data == nullptr || data_bytes < step * static_cast<size_t>(rows - 1) + row_bytes) return std::nullopt;
  ThermalFrame out;
  out.raw.create(image_height, width, CV_16UC1);
  for (int y = 0; y < image_height; ++y) {
    const uint8_t* p = data + step * y;
    auto* row = out.raw.ptr<uint16_t>(y);
    if constexpr (std::endian::native == std::endian::little) {
      std::memcpy(row, p, row_bytes);
    } else {
      for (int x = 0; x < width; ++x) row[x] = static_cast<uint16_t>(p[2 * x] | p[2 * x + 1] << 8);
    }
  }
  if (row_bytes * telemetry_rows >= kLeptonTelemetryRowWords * 2) {
    // Row A starts the first row after the image (telemetry as a footer); it spans wire
    // rows when they are narrower than 80 px.
    uint16_t words[kLeptonTelemetryRowWords];
    const uint8_t* row_a = data + step * image_height;
    for (int i = 0; i < kLeptonTelemetryRowWords; ++i) {
      const size_t offset = static_cast<size_t>(2 * i);
      const uint8_t* p = row_a + (offset / row_bytes) * step + offset % row_bytes;
      words[i] = static_cast<uint16_t>(p[0] | p[1] << 8);  // Y16 is little-endian
    }
    if (const std::optional<LeptonTelemetry> t = ParseLeptonTelemetryRowA(words)) {
      out.camera_frame_counter = t->frame_counter;
      out.ffc_in_progress = t->ffc_in_progress;
    }
  }
  return out;
}

void UvcThermalCamera::HandleFrame(uvc_frame* frame, double arrival_s) {
  std::optional<ThermalFrame> out;
  if (static_cast<int>(frame->width) == info_.width && static_cast<int>(frame->height) == wire_height_) {
    out = DecodeY16Frame(static_cast<const uint8_t*>(frame->data), frame->data_bytes, frame->step, info_.width,
                         info_.height, telemetry_rows_);
  }
  if (!out) {
    std::lock_guard lock(stats_mutex_);
    ++short_frames_;
    return;
  }
  out->arrival_s = arrival_s;
  on_frame_(std::move(*out));
}

// ---------------------------------------------------------------- factory

std::unique_ptr<ThermalCamera> OpenThermalCamera(const std::string& spec) {
  const ThermalDeviceSpec parsed = ParseThermalDeviceSpec(spec);
  switch (parsed.kind) {
    case ThermalDeviceSpec::Kind::kFake:
      return std::make_unique<FakeThermalCamera>();
    case ThermalDeviceSpec::Kind::kUsbIds:
      return std::make_unique<UvcThermalCamera>(parsed.vendor_id, parsed.product_id, parsed.serial);
    case ThermalDeviceSpec::Kind::kAuto:
      break;
  }
  std::string usb_error;
  const std::vector<UsbDevice> devices = ListUsbDevices(&usb_error);
  for (const KnownThermalCamera& camera : KnownThermalCameras()) {
    const UsbDevice* first = nullptr;
    int count = 0;
    for (const UsbDevice& device : devices) {
      if (device.vendor_id == camera.vendor_id && device.product_id == camera.product_id) {
        if (first == nullptr) first = &device;
        ++count;
      }
    }
    // The serial picks one of several identical cameras; with one, any serial matches (and
    // a serial libusb could not read must not exclude it).
    if (first != nullptr) {
      return std::make_unique<UvcThermalCamera>(first->vendor_id, first->product_id, count > 1 ? first->serial : "");
    }
  }
  std::string looked_for;
  for (const KnownThermalCamera& camera : KnownThermalCameras()) {
    looked_for += (looked_for.empty() ? "" : ", ") + camera.name + " " + UsbIdString(camera.vendor_id, camera.product_id);
  }
  std::string reason = "no thermal camera found on USB (looked for: " + looked_for + ")";
  if (!usb_error.empty()) reason += "; " + usb_error;
  throw core::InputError("thermal camera", reason);
}

}  // namespace hw::capture
