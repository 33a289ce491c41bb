#pragma once

// What is on the host's USB buses, and which of it is a thermal camera heatwave knows how
// to stream from (UVC, 16-bit raw frames).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hw::capture {

// A USB thermal camera model that streams 16-bit raw frames ("Y16") over the USB video
// class, identified by its USB vendor:product ids.
struct KnownThermalCamera {
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  std::string name;                 // e.g. "FLIR Lepton on GroupGets PureThermal"
  std::string resolutions;          // Y16 image sizes it streams, e.g. "160x120 (Lepton 3.x)"
  double fps = 0;                   // Hz, nominal frame rate of its Y16 stream
  bool y16 = false;                 // streams 16-bit raw frames over UVC
  // Whether the Y16 counts are temperatures (centikelvin), and on which models.
  std::string radiometry;
  bool telemetry = false;           // can append telemetry rows (frame counter, FFC state)
};

// Every thermal camera model heatwave recognises, in the order OpenThermalCamera("auto")
// prefers them.
const std::vector<KnownThermalCamera>& KnownThermalCameras();

// The model with these USB ids, or nullopt.
std::optional<KnownThermalCamera> FindKnownThermalCamera(uint16_t vendor_id, uint16_t product_id);

// "FLIR Lepton on GroupGets PureThermal (1e4e:0100): Y16 160x120 ..., 9 Hz, radiometric on
// Lepton 3.5 ..., telemetry: frame counter and FFC state" (one line).
std::string DescribeThermalSupport(const KnownThermalCamera& camera);

// "1e4e:0100" (lower-case hex, 4 digits each).
std::string UsbIdString(uint16_t vendor_id, uint16_t product_id);

struct UsbDevice {
  int bus = 0;                  // bus number
  int address = 0;              // device address on the bus
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  // Descriptor strings; "" when the device has none or cannot be opened to read them
  // (reading strings needs write access to the device node: udev rules, root).
  std::string manufacturer;
  std::string product;
  std::string serial;
  std::optional<KnownThermalCamera> known_thermal;  // set when the ids are a known camera
};

// Every device on every USB bus, through libusb, in bus/address order. Never throws and
// never aborts: when libusb cannot start or cannot list devices, or the host has no usbfs
// (a container without /dev/bus/usb), returns an empty list and, when `error` is not null,
// sets *error to the reason ("" otherwise, including an empty list on a host with USB).
std::vector<UsbDevice> ListUsbDevices(std::string* error = nullptr);

// "" when the host has a usbfs (/dev/bus/usb), else the reason no USB device can be seen
// (e.g. a container started without USB passthrough). Linux.
std::string UsbAccessProblem();

// "bus 001 device 004: 1e4e:0100 GroupGets PureThermal (serial 8011...) [thermal: FLIR
// Lepton on GroupGets PureThermal]" (one line).
std::string DescribeUsbDevice(const UsbDevice& device);

}  // namespace hw::capture
