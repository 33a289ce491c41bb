#include "capture/usb_devices.h"

#include <libusb.h>

#include <algorithm>
#include <filesystem>
#include <system_error>

#include "core/strings.h"

namespace hw::capture {

// USB ids and stream properties, and where they were checked:
// - PureThermal 1 / 2 / Mini (GroupGets boards carrying a FLIR Lepton): 1e4e:0100 is
//   PT_USB_VID / PT_USB_PID of groupgets/purethermal1-uvc-capture (uvctypes.py) and the ids
//   flirpy (LJMUAstroecology/flirpy, flirpy/camera/lepton.py) looks for. Its firmware
//   (groupgets/purethermal1-firmware, uvc_desc_vs_l3.h / uvc_desc_vs_l2.h) offers Y16 at
//   160x120 (Lepton 3.x) or 80x60 (Lepton 2.x), plus a "telemetric" Y16 frame two rows
//   (160x122) or three rows (80x63) taller whose extra rows carry the Lepton telemetry
//   (selecting it makes the firmware enable telemetry: Src/lepton_task.c). Y16 is centikelvin when
//   the Lepton is radiometric (2.5, 3.5) with TLinear on, the firmware's Y16 default.
//   Lepton frames are exported at < 9 Hz (8.7 Hz); the UVC descriptor says 9.
// - FLIR Boson (and Boson+) USB: 09cb:4007, the VID/PID flirpy's boson.py
//   (find_serial_device, and "VendorID_2507 / ProductID_16391" on macOS) matches. Y16 at
//   320x256 or 640x512 by model, 60 Hz (30 or 9 Hz on export-limited models). Y16 is
//   pre-AGC 14-bit counts, not temperatures, except on radiometric models with TLinear
//   enabled. Its FFC state is only on its serial control channel, not in the video.
const std::vector<KnownThermalCamera>& KnownThermalCameras() {
  static const std::vector<KnownThermalCamera> cameras = {
      {0x1e4e, 0x0100, "FLIR Lepton on GroupGets PureThermal (1, 2, Mini)",
       "160x120 (Lepton 3.x), 80x60 (Lepton 2.x)", 9, true,
       "centikelvin on radiometric Lepton 2.5 / 3.5 (TLinear), counts on others", true},
      {0x09cb, 0x4007, "FLIR Boson", "320x256 (Boson 320), 640x512 (Boson 640)", 60, true,
       "counts (pre-AGC 14-bit); centikelvin only on radiometric models with TLinear", false},
  };
  return cameras;
}

std::optional<KnownThermalCamera> FindKnownThermalCamera(uint16_t vendor_id, uint16_t product_id) {
  for (const KnownThermalCamera& camera : KnownThermalCameras()) {
    if (camera.vendor_id == vendor_id && camera.product_id == product_id) return camera;
  }
  return std::nullopt;
}

std::string UsbIdString(uint16_t vendor_id, uint16_t product_id) {
  return core::StringPrintf("%04x:%04x", vendor_id, product_id);
}

std::string DescribeThermalSupport(const KnownThermalCamera& camera) {
  std::string text = camera.name + " (" + UsbIdString(camera.vendor_id, camera.product_id) + "): ";
  text += camera.y16 ? "Y16 " : "no Y16 stream, ";
  text += camera.resolutions + core::StringPrintf(", %g Hz, ", camera.fps) + camera.radiometry;
  text += camera.telemetry ? "; telemetry: frame counter and FFC state"
                           : "; no telemetry in the video (FFC state not reported)";
  return text;
}

namespace {

// The string descriptor `index` of an open device, "" when absent or unreadable.
std::string ReadString(libusb_device_handle* handle, uint8_t index) {
  if (handle == nullptr || index == 0) return "";
  unsigned char buffer[256];
  const int n = libusb_get_string_descriptor_ascii(handle, index, buffer, sizeof(buffer));
  if (n <= 0) return "";
  return core::OneLineMessage(std::string(reinterpret_cast<const char*>(buffer), n));
}

std::string LibusbError(const char* call, int code) {
  return std::string(call) + " failed: " + libusb_strerror(code) + " (" + libusb_error_name(code) + ")";
}

}  // namespace

std::string UsbAccessProblem() {
  std::error_code ignored;
  if (std::filesystem::exists("/dev/bus/usb", ignored)) return "";
  return "/dev/bus/usb does not exist: this system or container exposes no USB devices";
}

std::vector<UsbDevice> ListUsbDevices(std::string* error) {
  if (error != nullptr) error->clear();
  std::vector<UsbDevice> devices;
  libusb_context* context = nullptr;
  // libusb logs its own failures (e.g. no usbfs in a container) to stderr; we report them.
  libusb_set_option(nullptr, LIBUSB_OPTION_LOG_LEVEL, LIBUSB_LOG_LEVEL_NONE);
  if (const int code = libusb_init(&context); code != 0) {
    if (error != nullptr) {
      const std::string hint = UsbAccessProblem();
      *error = LibusbError("libusb_init", code) + (hint.empty() ? "" : " (" + hint + ")");
    }
    return devices;
  }
  libusb_set_option(context, LIBUSB_OPTION_LOG_LEVEL, LIBUSB_LOG_LEVEL_NONE);
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(context, &list);
  if (count < 0) {
    if (error != nullptr) *error = LibusbError("libusb_get_device_list", static_cast<int>(count));
    libusb_exit(context);
    return devices;
  }
  for (ssize_t i = 0; i < count; ++i) {
    libusb_device* device = list[i];
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(device, &descriptor) != 0) continue;
    UsbDevice entry;
    entry.bus = libusb_get_bus_number(device);
    entry.address = libusb_get_device_address(device);
    entry.vendor_id = descriptor.idVendor;
    entry.product_id = descriptor.idProduct;
    // Strings need the device opened; without permission they stay "".
    libusb_device_handle* handle = nullptr;
    if (libusb_open(device, &handle) == 0) {
      entry.manufacturer = ReadString(handle, descriptor.iManufacturer);
      entry.product = ReadString(handle, descriptor.iProduct);
      entry.serial = ReadString(handle, descriptor.iSerialNumber);
      libusb_close(handle);
    }
    entry.known_thermal = FindKnownThermalCamera(entry.vendor_id, entry.product_id);
    devices.push_back(std::move(entry));
  }
  libusb_free_device_list(list, 1);
  libusb_exit(context);
  // Debian's libusb (udev-based) starts even without usbfs and lists nothing: say why.
  if (devices.empty() && error != nullptr) *error = UsbAccessProblem();
  std::sort(devices.begin(), devices.end(), [](const UsbDevice& a, const UsbDevice& b) {
    return a.bus != b.bus ? a.bus < b.bus : a.address < b.address;
  });
  return devices;
}

std::string DescribeUsbDevice(const UsbDevice& device) {
  std::string text = core::StringPrintf("bus %03d device %03d: ", device.bus, device.address) +
                     UsbIdString(device.vendor_id, device.product_id);
  std::string names = device.manufacturer;
  if (!device.product.empty()) names += (names.empty() ? "" : " ") + device.product;
  if (!names.empty()) text += " " + names;
  if (!device.serial.empty()) text += " (serial " + device.serial + ")";
  if (device.known_thermal) text += " [thermal: " + device.known_thermal->name + "]";
  return text;
}

}  // namespace hw::capture
