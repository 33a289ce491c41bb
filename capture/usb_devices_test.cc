#include "capture/usb_devices.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <cstring>
#include <set>
#include <stdexcept>

#include "capture/uvc_thermal_camera.h"
#include "core/error.h"

namespace hw::capture {
namespace {

bool KnownThermalCameraAttached() {
  for (const UsbDevice& device : ListUsbDevices()) {
    if (device.known_thermal) return true;
  }
  return false;
}

bool Contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(UsbDevicesTest, ListsTheRealBusesOrSaysWhyNot) {
  std::string error = "stale";
  const std::vector<UsbDevice> devices = ListUsbDevices(&error);
  std::cerr << devices.size() << " USB device(s)" << (error.empty() ? "" : ": " + error) << "\n";
  for (const UsbDevice& device : devices) std::cerr << "  " << DescribeUsbDevice(device) << "\n";
  if (!std::filesystem::exists("/dev/bus/usb") && !std::filesystem::exists("/proc/bus/usb")) {
    // No usbfs (a container): nothing to list, and the error says why instead of the call
    // failing (Debian's udev-based libusb starts and lists nothing; a libusb without udev
    // fails to start).
    EXPECT_TRUE(devices.empty());
    EXPECT_TRUE(Contains(error, "/dev/bus/usb")) << error;
    EXPECT_EQ(UsbAccessProblem(), "/dev/bus/usb does not exist: this system or container exposes no USB devices");
  } else {
    EXPECT_EQ(error, "") << "libusb should start on a machine with /dev/bus/usb";
    EXPECT_EQ(UsbAccessProblem(), "");
  }
  for (size_t i = 0; i < devices.size(); ++i) {
    const UsbDevice& d = devices[i];
    EXPECT_GE(d.bus, 0);
    EXPECT_GE(d.address, 0);
    EXPECT_EQ(d.known_thermal.has_value(), FindKnownThermalCamera(d.vendor_id, d.product_id).has_value());
    if (i > 0) {
      const UsbDevice& p = devices[i - 1];
      EXPECT_TRUE(p.bus < d.bus || (p.bus == d.bus && p.address < d.address)) << "not sorted at " << i;
    }
  }
  EXPECT_EQ(ListUsbDevices(nullptr).size(), devices.size());  // no error pointer: same list
}

TEST(UsbDevicesTest, KnownThermalCameraTable) {
  const std::optional<KnownThermalCamera> lepton = FindKnownThermalCamera(0x1e4e, 0x0100);
  ASSERT_TRUE(lepton.has_value());
  EXPECT_TRUE(Contains(lepton->name, "PureThermal"));
  EXPECT_TRUE(Contains(lepton->name, "Lepton"));
  EXPECT_TRUE(Contains(lepton->resolutions, "160x120"));
  EXPECT_EQ(lepton->fps, 9);
  EXPECT_TRUE(lepton->y16);
  EXPECT_TRUE(lepton->telemetry);

  const std::optional<KnownThermalCamera> boson = FindKnownThermalCamera(0x09cb, 0x4007);
  ASSERT_TRUE(boson.has_value());
  EXPECT_TRUE(Contains(boson->name, "Boson"));
  EXPECT_TRUE(Contains(boson->resolutions, "640x512"));
  EXPECT_TRUE(Contains(boson->resolutions, "320x256"));
  EXPECT_EQ(boson->fps, 60);
  EXPECT_FALSE(boson->telemetry);

  EXPECT_FALSE(FindKnownThermalCamera(0x1e4e, 0x0101).has_value());
  EXPECT_FALSE(FindKnownThermalCamera(0x0100, 0x1e4e).has_value());  // ids not swapped
  std::set<std::pair<int, int>> ids;
  for (const KnownThermalCamera& camera : KnownThermalCameras()) {
    EXPECT_TRUE(ids.insert({camera.vendor_id, camera.product_id}).second) << camera.name;
  }

  const std::string text = DescribeThermalSupport(*lepton);
  EXPECT_TRUE(Contains(text, "(1e4e:0100)")) << text;
  EXPECT_TRUE(Contains(text, "Y16 160x120")) << text;
  EXPECT_TRUE(Contains(text, "9 Hz")) << text;
  EXPECT_TRUE(Contains(text, "FFC state")) << text;
  EXPECT_TRUE(Contains(DescribeThermalSupport(*boson), "(09cb:4007)"));
  EXPECT_TRUE(Contains(DescribeThermalSupport(*boson), "60 Hz"));
}

TEST(UsbDevicesTest, DescribeUsbDevice) {
  UsbDevice device;
  device.bus = 1;
  device.address = 4;
  device.vendor_id = 0x1e4e;
  device.product_id = 0x0100;
  device.manufacturer = "GroupGets";
  device.product = "PureThermal";
  device.serial = "801f0025";
  device.known_thermal = FindKnownThermalCamera(0x1e4e, 0x0100);
  EXPECT_EQ(DescribeUsbDevice(device),
            "bus 001 device 004: 1e4e:0100 GroupGets PureThermal (serial 801f0025) [thermal: " +
                device.known_thermal->name + "]");
  UsbDevice bare;
  bare.bus = 2;
  bare.address = 17;
  bare.vendor_id = 0x8087;
  bare.product_id = 0x0a2b;
  EXPECT_EQ(DescribeUsbDevice(bare), "bus 002 device 017: 8087:0a2b");
}

TEST(UsbDevicesTest, ParseThermalDeviceSpec) {
  EXPECT_EQ(ParseThermalDeviceSpec("auto").kind, ThermalDeviceSpec::Kind::kAuto);
  EXPECT_EQ(ParseThermalDeviceSpec("fake").kind, ThermalDeviceSpec::Kind::kFake);
  const ThermalDeviceSpec lepton = ParseThermalDeviceSpec("1e4e:0100");
  EXPECT_EQ(lepton.kind, ThermalDeviceSpec::Kind::kUsbIds);
  EXPECT_EQ(lepton.vendor_id, 0x1e4e);
  EXPECT_EQ(lepton.product_id, 0x0100);
  EXPECT_EQ(lepton.serial, "");
  const ThermalDeviceSpec boson = ParseThermalDeviceSpec("09CB:4007:ab12:3");
  EXPECT_EQ(boson.vendor_id, 0x09cb);
  EXPECT_EQ(boson.product_id, 0x4007);
  EXPECT_EQ(boson.serial, "ab12:3");
  for (const std::string bad : {"", "Auto", "1e4e", "1e4e:", ":0100", "1e4e:010", "1e4e:01000", "0x1e4e:0100",
                                "1g4e:0100", "1e4e:0100:", "1e4e0100", " 1e4e:0100"}) {
    try {
      ParseThermalDeviceSpec(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(Contains(e.what(), "'" + bad + "'")) << e.what();
      EXPECT_TRUE(Contains(e.what(), "VID:PID")) << e.what();
    }
  }
}

TEST(UsbDevicesTest, LeptonTelemetryRowA) {
  // Row A per the datasheet layout (uvc_thermal_camera.h): 32-bit fields least
  // significant word first.
  uint16_t words[kLeptonTelemetryRowWords] = {};
  words[0] = 0x0e08;                          // revision
  words[1] = 0x2345, words[2] = 0x0001;       // uptime 0x12345 ms
  words[3] = 0x0028, words[4] = 0x0010;       // FFC desired, FFC state 2, bit 20
  words[20] = 0x0002, words[21] = 0x0001;     // frame counter 0x10002
  words[24] = 30015;                          // FPA 300.15 K
  words[30] = 0x1000, words[31] = 0x0001;     // last FFC at 0x11000 ms
  std::optional<LeptonTelemetry> t = ParseLeptonTelemetryRowA(words);
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->uptime_ms, 0x12345u);
  EXPECT_EQ(t->status_bits, 0x00100028u);
  EXPECT_TRUE(t->ffc_desired);
  EXPECT_EQ(t->ffc_state, 2);
  EXPECT_TRUE(t->ffc_in_progress);
  EXPECT_EQ(t->frame_counter, 0x10002u);
  EXPECT_DOUBLE_EQ(t->fpa_temperature_k, 300.15);
  EXPECT_EQ(t->last_ffc_uptime_ms, 0x11000u);
  for (const uint16_t state : {0, 1, 3}) {  // never commanded, imminent, complete
    words[3] = static_cast<uint16_t>(state << 4);
    t = ParseLeptonTelemetryRowA(words);
    ASSERT_TRUE(t.has_value());
    EXPECT_EQ(t->ffc_state, state);
    EXPECT_FALSE(t->ffc_in_progress);
    EXPECT_FALSE(t->ffc_desired);
  }
  const uint16_t zeros[kLeptonTelemetryRowWords] = {};
  EXPECT_FALSE(ParseLeptonTelemetryRowA(zeros).has_value());
}

// A Y16 frame as a PureThermal sends it: `rows` rows of `width` little-endian pixels,
// `step` bytes apart; pixel (x, y) = 1000 + 7 x + 3 y.
std::vector<uint8_t> Y16Wire(int width, int rows, size_t step) {
  std::vector<uint8_t> bytes(step * rows, 0xee);  // padding bytes must not leak in
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < width; ++x) {
      const int value = 1000 + 7 * x + 3 * y;
      bytes[step * y + 2 * x] = static_cast<uint8_t>(value & 0xff);
      bytes[step * y + 2 * x + 1] = static_cast<uint8_t>(value >> 8);
    }
  }
  return bytes;
}

// Writes telemetry row A words (frame counter, FFC state) little-endian at `at`.
void PutRowA(uint8_t* at, uint32_t frame_counter, int ffc_state) {
  std::memset(at, 0, 2 * kLeptonTelemetryRowWords);
  const auto put = [at](int word, uint16_t value) {
    at[2 * word] = static_cast<uint8_t>(value & 0xff);
    at[2 * word + 1] = static_cast<uint8_t>(value >> 8);
  };
  put(0, 0x0e08);
  put(3, static_cast<uint16_t>(ffc_state << 4));
  put(20, static_cast<uint16_t>(frame_counter & 0xffff));
  put(21, static_cast<uint16_t>(frame_counter >> 16));
}

TEST(UsbDevicesTest, DecodeY16FrameWithLepton3Telemetry) {
  // Lepton 3 on PureThermal: 160x122, telemetry row A = first half of row 120.
  const size_t step = 160 * 2;
  std::vector<uint8_t> wire = Y16Wire(160, 122, step);
  PutRowA(wire.data() + step * 120, 0x0001e240, 2);  // counter 123456, FFC in progress
  std::optional<ThermalFrame> frame = DecodeY16Frame(wire.data(), wire.size(), 0, 160, 120, 2);
  ASSERT_TRUE(frame.has_value());
  ASSERT_EQ(frame->raw.rows, 120);
  ASSERT_EQ(frame->raw.cols, 160);
  for (const auto& [x, y] : {std::pair{0, 0}, {159, 0}, {0, 119}, {159, 119}, {80, 60}}) {
    EXPECT_EQ(frame->raw.at<uint16_t>(y, x), 1000 + 7 * x + 3 * y) << x << "," << y;
  }
  EXPECT_EQ(frame->camera_frame_counter, 123456);
  EXPECT_TRUE(frame->ffc_in_progress);
  PutRowA(wire.data() + step * 120, 77, 3);  // FFC complete
  frame = DecodeY16Frame(wire.data(), wire.size(), step, 160, 120, 2);
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->camera_frame_counter, 77);
  EXPECT_FALSE(frame->ffc_in_progress);
  // Truncated transfer: one byte short.
  EXPECT_FALSE(DecodeY16Frame(wire.data(), wire.size() - 1, step, 160, 120, 2).has_value());
}

TEST(UsbDevicesTest, DecodeY16FramePaddedRowsLepton2AndNoTelemetry) {
  // Lepton 2 on PureThermal: 80x63, row A = row 60 exactly; rows padded to 200 bytes.
  const size_t step = 200;
  std::vector<uint8_t> wire = Y16Wire(80, 63, step);
  PutRowA(wire.data() + step * 60, 5, 1);  // FFC imminent, not in progress
  std::optional<ThermalFrame> frame = DecodeY16Frame(wire.data(), wire.size(), step, 80, 60, 3);
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->raw.at<uint16_t>(59, 79), 1000 + 7 * 79 + 3 * 59);
  EXPECT_EQ(frame->camera_frame_counter, 5);
  EXPECT_FALSE(frame->ffc_in_progress);
  // Without telemetry rows (e.g. a Boson's 640x512): no counter, no FFC state.
  const std::vector<uint8_t> plain = Y16Wire(64, 48, 128);
  frame = DecodeY16Frame(plain.data(), plain.size(), 128, 64, 48, 0);
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->camera_frame_counter, -1);
  EXPECT_FALSE(frame->ffc_in_progress);
  EXPECT_EQ(frame->raw.at<uint16_t>(47, 63), 1000 + 7 * 63 + 3 * 47);
  EXPECT_FALSE(DecodeY16Frame(nullptr, 0, 0, 64, 48, 0).has_value());
}

TEST(UsbDevicesTest, OpenFakeThermalCamera) {
  const std::unique_ptr<ThermalCamera> camera = OpenThermalCamera("fake");
  ASSERT_NE(camera, nullptr);
  EXPECT_EQ(camera->Info().width, 160);
  EXPECT_EQ(camera->Info().height, 120);
  EXPECT_EQ(camera->Info().serial, "fake");
  EXPECT_THROW(OpenThermalCamera("1e4e"), std::invalid_argument);
}

TEST(UsbDevicesTest, OpenAutoWithNoCameraAttachedSaysWhatItLookedFor) {
  if (KnownThermalCameraAttached()) GTEST_SKIP() << "a known thermal camera is attached";
  try {
    OpenThermalCamera("auto");
    ADD_FAILURE() << "no exception";
  } catch (const core::InputError& e) {
    const std::string what = e.what();
    std::cerr << what << "\n";
    EXPECT_TRUE(Contains(what, "no thermal camera found on USB (looked for: ")) << what;
    for (const KnownThermalCamera& camera : KnownThermalCameras()) {
      EXPECT_TRUE(Contains(what, camera.name + " " + UsbIdString(camera.vendor_id, camera.product_id))) << what;
    }
    std::string error;
    ListUsbDevices(&error);
    if (!error.empty()) {
      EXPECT_TRUE(Contains(what, error)) << what;
    }
  }
}

TEST(UsbDevicesTest, OpenByIdsWithTheCameraAbsentNamesTheDevice) {
  if (KnownThermalCameraAttached()) GTEST_SKIP() << "a known thermal camera is attached";
  // 1e4e:0100 absent: uvc_init fails (no USB here) or the device is not found; either way
  // an InputError naming the device.
  try {
    OpenThermalCamera("1e4e:0100");
    ADD_FAILURE() << "no exception";
  } catch (const core::InputError& e) {
    const std::string what = e.what();
    std::cerr << what << "\n";
    EXPECT_EQ(what.rfind("usb 1e4e:0100: ", 0), 0u) << what;
    EXPECT_TRUE(Contains(what, "not found on USB") || Contains(what, "uvc_init failed")) << what;
    if (!UsbAccessProblem().empty()) {
      EXPECT_TRUE(Contains(what, UsbAccessProblem())) << what;
    }
  }
}

}  // namespace
}  // namespace hw::capture
