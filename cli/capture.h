#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "capture/capture_session.h"
#include "capture/oni_import.h"
#include "capture/openni_source.h"
#include "capture/usb_devices.h"

namespace hw::cli {

// `heatwave devices`: what is connected.
struct DevicesReport {
  std::vector<capture::RgbdDeviceInfo> rgbd;
  std::string rgbd_error;  // why OpenNI2 could not list devices ("" when it could)
  std::vector<capture::UsbDevice> usb;
  std::string usb_error;   // why libusb could not list devices ("" when it could)
};
DevicesReport ListDevices();
// One screen: RGB-D devices with their modes, thermal cameras found on USB with what each
// supports, the other USB devices in one line each, and a clear line when none is found.
std::string FormatDevices(const DevicesReport& report);

// Options of `heatwave capture`.
struct CaptureCommandOptions {
  std::filesystem::path out_folder;   // the scan folder to write
  std::filesystem::path rig_path;     // rig.yaml of this rig (from calibration), copied into the scan
  std::string depth_device = "auto";  // OpenNI2 URI, "auto" (the first device) or "none"
  std::string thermal_device = "auto";  // "auto", "VID:PID[:SERIAL]", "fake" or "none"
  bool color = true;                  // record the RGB-D device's colour stream
  capture::CaptureOptions capture;    // duration, queue, index interval
  bool overwrite = false;             // replace a scan already in out_folder
  bool quiet = false;                 // no progress on stderr
  std::string Check() const;
};

struct CaptureCommandResult {
  capture::CaptureSummary summary;
  std::string depth_uri;       // "" when no RGB-D device
  std::string thermal_name;    // "" when no thermal camera
  std::filesystem::path out_folder;
};

// Opens the devices, records until should_stop() (Ctrl-C) or the duration, and leaves a
// complete scan in out_folder (an OutputFolder run: incomplete until the end). Throws
// UsageError for a non-empty folder without overwrite, core::InputError for the rig, a
// device that cannot be opened or does not match the rig, core::OutputError for writes.
CaptureCommandResult RunCaptureJob(const CaptureCommandOptions& options, const std::function<bool()>& should_stop);
std::string FormatCaptureSummary(const CaptureCommandResult& result);

// Options of `heatwave import-oni`.
struct ImportOniOptions {
  std::filesystem::path oni_path;    // the OpenNI2 recording
  std::filesystem::path rig_path;    // rig.yaml of the rig that recorded it
  std::filesystem::path out_folder;  // the scan folder to write
  bool overwrite = false;
  bool quiet = false;
  std::string Check() const;
};
struct ImportOniResult {
  capture::OniImportSummary summary;
  double seconds = 0;
};
ImportOniResult RunImportOniJob(const ImportOniOptions& options);
std::string FormatImportOniSummary(const ImportOniOptions& options, const ImportOniResult& result);

}  // namespace hw::cli
