// heatwave devices / capture / import-oni: recording real rigs into scan folders.
#include "cli/capture.h"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

#include "capture/thermal_camera.h"
#include "capture/uvc_thermal_camera.h"
#include "cli/command.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/rig.h"
#include "core/strings.h"

namespace hw::cli {

namespace fs = std::filesystem;
using core::StringPrintf;

DevicesReport ListDevices() {
  DevicesReport r;
  r.rgbd = capture::ListRgbdDevices(&r.rgbd_error);
  r.usb = capture::ListUsbDevices(&r.usb_error);
  return r;
}

std::string FormatDevices(const DevicesReport& r) {
  std::string out = "RGB-D devices (OpenNI2)\n";
  if (!r.rgbd_error.empty()) out += "  none: " + r.rgbd_error + "\n";
  else if (r.rgbd.empty()) out += "  none found\n";
  for (const capture::RgbdDeviceInfo& d : r.rgbd) {
    out += StringPrintf("  %s  %s %s", d.uri.c_str(), d.vendor.c_str(), d.name.c_str());
    if (d.usb_vendor_id || d.usb_product_id)
      out += "  (" + capture::UsbIdString(static_cast<uint16_t>(d.usb_vendor_id), static_cast<uint16_t>(d.usb_product_id)) + ")";
    out += "\n";
    if (d.modes.empty()) out += "    modes: unknown (the device could not be opened: busy or no permission)\n";
    std::string sensor;
    for (const capture::RgbdStreamMode& m : d.modes) {
      if (m.sensor != sensor) {
        out += (sensor.empty() ? "" : "\n") + StringPrintf("    %-6s", m.sensor.c_str());
        sensor = m.sensor;
      }
      out += StringPrintf(" %dx%d@%d %s;", m.width, m.height, m.fps, m.pixel_format.c_str());
    }
    if (!d.modes.empty()) out += "\n";
  }
  out += "\nThermal cameras (USB video class)\n";
  int thermal = 0;
  for (const capture::UsbDevice& u : r.usb) {
    if (!u.known_thermal) continue;
    ++thermal;
    out += "  " + capture::DescribeUsbDevice(u) + "\n    " + capture::DescribeThermalSupport(*u.known_thermal) + "\n";
  }
  if (!r.usb_error.empty()) {
    out += "  none: USB could not be listed: " + r.usb_error + "\n";
  } else if (thermal == 0) {
    out += "  none found (looked for:";
    for (const capture::KnownThermalCamera& k : capture::KnownThermalCameras())
      out += " " + k.name + " " + capture::UsbIdString(k.vendor_id, k.product_id) + ";";
    out += ")\n";
  }
  if (r.usb_error.empty()) {
    out += StringPrintf("\nOther USB devices: %d\n", static_cast<int>(r.usb.size()) - thermal);
    for (const capture::UsbDevice& u : r.usb)
      if (!u.known_thermal) out += "  " + capture::DescribeUsbDevice(u) + "\n";
  }
  return out;
}

std::string CaptureCommandOptions::Check() const {
  if (out_folder.empty()) return "out_folder (--out): must be given";
  if (rig_path.empty()) return "rig_path (--rig): must be given";
  if (depth_device.empty()) return "depth_device (--depth): must be a URI, auto or none";
  if (thermal_device.empty()) return "thermal_device (--thermal): must be auto, VID:PID[:SERIAL], fake or none";
  if (depth_device == "none" && thermal_device == "none") return "--depth none and --thermal none: nothing to capture";
  if (thermal_device != "none") {
    try {
      capture::ParseThermalDeviceSpec(thermal_device);
    } catch (const std::invalid_argument& e) {
      return std::string("thermal_device (--thermal): ") + e.what();
    }
  }
  if (std::string c = capture.Check(); !c.empty()) return c;
  return "";
}

CaptureCommandResult RunCaptureJob(const CaptureCommandOptions& o, const std::function<bool()>& should_stop) {
  assert(o.Check().empty());
  const core::Rig rig = core::ReadRig(o.rig_path);
  // Devices first: a rig or device problem leaves no folder behind.
  std::unique_ptr<capture::OpenNiSource> rgbd;
  if (o.depth_device != "none") {
    capture::OpenNiOpenOptions open;
    open.color = o.color && rig.rgb.has_value();
    open.depth_width = rig.depth.width;
    open.depth_height = rig.depth.height;
    open.color_width = rig.rgb ? rig.rgb->width : 0;
    open.color_height = rig.rgb ? rig.rgb->height : 0;
    open.fps = 0;
    rgbd = capture::OpenNiSource::OpenDevice(o.depth_device == "auto" ? "" : o.depth_device, open);
  }
  std::unique_ptr<capture::ThermalCamera> thermal;
  if (o.thermal_device != "none") thermal = capture::OpenThermalCamera(o.thermal_device);

  capture::CheckCaptureRig(rgbd.get(), thermal.get(), rig);
  const std::unique_ptr<core::OutputFolder> folder = PrepareOutputFolder(o.out_folder, o.overwrite, "heatwave capture");
  CaptureCommandResult result;
  result.out_folder = o.out_folder;
  if (rgbd) result.depth_uri = rgbd->uri();
  if (thermal) result.thermal_name = thermal->Info().name;

  // Progress: with a duration, a bar of the frames of the leading stream (depth, else
  // thermal) expected in it; until Ctrl-C, a status line.
  std::unique_ptr<core::ProgressBar> bar;
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  const double lead_fps = rgbd ? rgbd->depth_mode().fps : thermal ? thermal->Info().fps : 0;
  if (o.capture.duration_s > 0 && lead_fps > 0) {
    bar = std::make_unique<core::ProgressBar>(rgbd ? "capture depth" : "capture thermal",
                                              static_cast<int64_t>(std::ceil(o.capture.duration_s * lead_fps)), "frames",
                                              o.quiet);
  }
  double last_line_s = -1e9;
  auto progress = [&](const capture::CaptureSummary& s) {
    if (o.quiet) return;
    if (bar) {
      bar->Set(rgbd ? s.depth.written : s.thermal.written);
      return;
    }
    // Not a terminal: one line every 10 s keeps logs readable.
    if (!tty && s.seconds - last_line_s < 10) return;
    last_line_s = s.seconds;
    std::fprintf(stderr, "%scapture %6.1f s  depth %lld  rgb %lld  thermal %lld  ffc %lld  dropped %lld  (Ctrl-C stops)%s",
                 tty ? "\r" : "", s.seconds, static_cast<long long>(s.depth.written), static_cast<long long>(s.rgb.written),
                 static_cast<long long>(s.thermal.written), static_cast<long long>(s.ffc_events),
                 static_cast<long long>(s.depth.dropped + s.rgb.dropped + s.thermal.dropped), tty ? "" : "\n");
  };
  result.summary = capture::Capture(rgbd.get(), thermal.get(), rig, o.out_folder, o.capture, should_stop, progress);
  if (bar) bar->Finish();
  else if (!o.quiet && tty) std::fprintf(stderr, "\n");
  folder->Commit();
  return result;
}

namespace {

std::string StreamLine(const char* name, const capture::StreamCount& c) {
  const double span = c.last_s - c.first_s;
  const double rate = c.written > 1 && span > 0 ? static_cast<double>(c.written - 1) / span : 0;
  return StringPrintf("%-8s %7lld %7lld %7lld %5lld %9.3f %9.3f %8.2f\n", name, static_cast<long long>(c.received),
                      static_cast<long long>(c.written), static_cast<long long>(c.dropped), static_cast<long long>(c.gaps),
                      c.first_s, c.last_s, rate);
}

}  // namespace

std::string FormatCaptureSummary(const CaptureCommandResult& r) {
  const capture::CaptureSummary& s = r.summary;
  std::string out;
  out += "Scan      " + r.out_folder.string() + "\n";
  out += "Devices   depth: " + (r.depth_uri.empty() ? std::string("none") : r.depth_uri) +
         "; thermal: " + (r.thermal_name.empty() ? std::string("none") : r.thermal_name) + "\n";
  out += StringPrintf("Captured  %.1f s, %s; queue high-water mark %lld frames\n", s.seconds,
                      !s.device_error.empty() ? "stopped early by a device (below)"
                      : s.stopped_by_user   ? "stopped by Ctrl-C"
                                            : "for the requested duration",
                      static_cast<long long>(s.max_queue_frames));
  out += "\n";
  out += StringPrintf("%-8s %7s %7s %7s %5s %9s %9s %8s\n", "Stream", "Arrived", "Written", "Dropped", "Gaps", "First s",
                      "Last s", "Rate Hz");
  out += StreamLine("depth", s.depth);
  out += StreamLine("rgb", s.rgb);
  out += StreamLine("thermal", s.thermal);
  out += StringPrintf("FFC events %lld (ffc.txt)\n", static_cast<long long>(s.ffc_events));
  const int64_t dropped = s.depth.dropped + s.rgb.dropped + s.thermal.dropped;
  if (dropped > 0)
    out += StringPrintf("Warning: %lld frames dropped because the disk did not keep up (raise --queue or use a faster disk)\n",
                        static_cast<long long>(dropped));
  out += "Timestamps: seconds since the capture started, stamped on arrival with one host clock;\n"
         "rig.yaml's time_offset_s holds each stream's latency relative to depth (heatwave calibrate latency).\n";
  return out;
}

std::string ImportOniOptions::Check() const {
  if (oni_path.empty()) return "oni_path: must be given";
  if (rig_path.empty()) return "rig_path (--rig): must be given";
  if (out_folder.empty()) return "out_folder (--out): must be given";
  return "";
}

ImportOniResult RunImportOniJob(const ImportOniOptions& o) {
  assert(o.Check().empty());
  const auto start = std::chrono::steady_clock::now();
  const core::Rig rig = core::ReadRig(o.rig_path);
  capture::CheckOniImport(o.oni_path, rig);  // a bad recording leaves no folder behind
  const std::unique_ptr<core::OutputFolder> folder = PrepareOutputFolder(o.out_folder, o.overwrite, "heatwave import-oni");
  std::unique_ptr<core::ProgressBar> bar;
  ImportOniResult result;
  result.summary = capture::ImportOni(o.oni_path, rig, o.out_folder, [&](int done, int total) {
    if (!bar) bar = std::make_unique<core::ProgressBar>("import", total, "frames", o.quiet);
    bar->Set(done);
  });
  if (bar) bar->Finish();
  folder->Commit();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string FormatImportOniSummary(const ImportOniOptions& o, const ImportOniResult& r) {
  const capture::OniImportSummary& s = r.summary;
  std::string out;
  out += "Recording " + o.oni_path.string() + "\n";
  out += "Scan      " + o.out_folder.string() + StringPrintf("  (%.1f s)\n", r.seconds);
  out += StringPrintf("depth     %d of %d frames, %.6f .. %.6f s\n", s.depth_frames, s.depth_recorded, s.first_depth_s,
                      s.last_depth_s);
  if (s.color_ignored) {
    out += StringPrintf("rgb       %d recorded frames not imported: the rig has no rgb camera\n", s.color_recorded);
  } else if (s.color_recorded > 0) {
    out += StringPrintf("rgb       %d of %d frames, %.6f .. %.6f s\n", s.color_frames, s.color_recorded, s.first_color_s,
                        s.last_color_s);
  }
  if (s.skipped_not_increasing > 0)
    out += StringPrintf("Warning: %d frames skipped: their timestamp did not increase\n", s.skipped_not_increasing);
  if (s.depth_pixels_out_of_range > 0)
    out += StringPrintf("Warning: %d depth pixels beyond the rig's depth_scale range written as no measurement\n",
                        s.depth_pixels_out_of_range);
  out += "Timestamps: OpenNI2's recorder starts every stream at 0, so the depth-to-colour offset of the device\n"
         "is not in the file; set time_offset_s.rgb in rig.yaml (heatwave calibrate latency).\n";
  return out;
}

int RunDevices(int argc, char** argv) {
  CLI::App app(
      "List the RGB-D devices OpenNI2 can open (with their modes) and the thermal cameras on USB (FLIR Lepton on "
      "PureThermal, FLIR Boson, ...; found through libusb) with what each supports. Says so when none is found.\n"
      "Exit code 0 (also when nothing is connected); 2: bad usage.",
      "heatwave devices");
  CommonOptions common;
  AddCommonOptions(app, common);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  return RunGuarded([&] {
    const DevicesReport report = ListDevices();
    if (!common.quiet) std::cout << FormatDevices(report) << std::flush;
    return kExitOk;
  });
}

int RunCapture(int argc, char** argv) {
  CLI::App app(
      "Record a scan folder from a live rig: depth and colour from an OpenNI2 RGB-D device, thermal from a USB "
      "radiometric camera (Y16 through libuvc). Every frame is timestamped on arrival with one monotonic host "
      "clock and written as it arrives (bounded memory); flat-field events go to ffc.txt; rig.yaml is the "
      "given calibration. Ctrl-C stops cleanly with everything flushed (a second Ctrl-C aborts).\n"
      "A device that fails or sends nothing for 2 s (unplugged) ends the capture early: the scan keeps what "
      "was recorded, and the exit code is 1.\n"
      "Exit code 0: scan written; 1: device, rig or write error; 2: bad usage.",
      "heatwave capture");
  CaptureCommandOptions o;
  CommonOptions common;
  app.add_option("--out", o.out_folder, "scan folder to write")->required();
  app.add_option("--rig", o.rig_path, "rig.yaml of this rig (heatwave calibrate), copied into the scan")->required();
  app.add_option("--depth", o.depth_device, "OpenNI2 device URI, auto (the first one) or none")->capture_default_str();
  app.add_option("--thermal", o.thermal_device, "auto (first known camera on USB), VID:PID[:SERIAL], fake or none")
      ->capture_default_str();
  app.add_flag("--no-color", [&](int64_t) { o.color = false; }, "do not record the RGB-D device's colour stream");
  app.add_option("--duration", o.capture.duration_s, "seconds to record (0: until Ctrl-C)")->capture_default_str();
  app.add_option("--queue", o.capture.max_queued_frames,
                 "frames held in memory waiting for the disk; beyond, frames are dropped and counted")
      ->capture_default_str();
  app.add_flag("--overwrite", o.overwrite, "replace a scan already in --out");
  AddCommonOptions(app, common);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  o.quiet = common.quiet;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    core::StopOnInterrupt stop;  // Ctrl-C ends the recording, not the process
    const CaptureCommandResult r = RunCaptureJob(o, [] { return core::StopOnInterrupt::StopRequested(); });
    if (!common.quiet) std::cout << FormatCaptureSummary(r) << std::flush;
    if (!r.summary.device_error.empty()) {
      // The scan holds everything recorded until then; the run still failed.
      PrintError(r.summary.device_error + " — the scan holds the " + StringPrintf("%.1f", r.summary.seconds) +
                 " s recorded before");
      return kExitFailure;
    }
    return kExitOk;
  });
}

int RunImportOni(int argc, char** argv) {
  CLI::App app(
      "Convert an OpenNI2 recording (.oni) into a scan folder through OpenNI2's own player: depth to depth/, "
      "colour to rgb/, the given rig.yaml.\n"
      "Exit code 0: scan written; 1: unreadable recording, rig mismatch or write error; 2: bad usage.",
      "heatwave import-oni");
  ImportOniOptions o;
  CommonOptions common;
  app.add_option("oni", o.oni_path, "the .oni recording")->required();
  app.add_option("--rig", o.rig_path, "rig.yaml of the rig that recorded it")->required();
  app.add_option("--out", o.out_folder, "scan folder to write")->required();
  app.add_flag("--overwrite", o.overwrite, "replace a scan already in --out");
  AddCommonOptions(app, common);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  o.quiet = common.quiet;
  return RunGuarded([&] {
    ThrowIfInvalid(o.Check());
    const ImportOniResult r = RunImportOniJob(o);
    if (!common.quiet) std::cout << FormatImportOniSummary(o, r) << std::flush;
    return kExitOk;
  });
}

}  // namespace hw::cli
