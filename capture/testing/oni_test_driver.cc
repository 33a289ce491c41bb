// An OpenNI2 driver module for tests: one device, URI "heatwave-test", streaming 640x480
// depth (1 mm) and RGB888 colour at 30 Hz whose every pixel and timestamp is a known
// function of the frame number (capture/testing/test_device_pattern.h).
//
// Why it exists: OpenNI2's bundled DummyDevice cannot produce a recording that OpenNI2's own
// player plays back. Its streams do not implement ONI_STREAM_PROPERTY_CROPPING, so the
// Recorder writes no "xnCropping" record, and the player (PlayerStream::OnNewDataCallback)
// drops every frame of a stream whose source lacks that property: readFrame() then waits
// forever. This device answers the properties a real PrimeSense device answers (video
// mode, cropping, mirroring, field of view, maximum depth), so the Recorder writes a
// complete file; and, unlike DummyDevice, its stop() joins its producer thread, so closing
// it never leaves a thread running in an unloaded library.
//
// Built as a MODULE named libHeatwaveTestDevice.so.0 (OpenNI2 2.2 loads "lib*.so.0" from
// the OpenNI2/Drivers folder next to the libOpenNI2 it was loaded as; see
// capture/CMakeLists.txt for the test runtime folder).
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <new>
#include <string>
#include <thread>

#define XN_NEW(type, arg) new (std::nothrow) type(arg)
#define XN_DELETE(p) delete (p)
#include <Driver/OniDriverAPI.h>

#include "capture/testing/test_device_pattern.h"

namespace {

namespace t = hw::capture::testing;

template <typename T>
OniStatus Put(void* data, int* size, const T& value) {
  if (*size != static_cast<int>(sizeof(T))) return ONI_STATUS_BAD_PARAMETER;
  std::memcpy(data, &value, sizeof(T));
  return ONI_STATUS_OK;
}

class TestStream : public oni::driver::StreamBase {
 public:
  explicit TestStream(OniSensorType type) : type_(type) {}
  ~TestStream() override { stop(); }

  OniVideoMode Mode() const {
    OniVideoMode mode{};
    mode.pixelFormat = type_ == ONI_SENSOR_DEPTH ? ONI_PIXEL_FORMAT_DEPTH_1_MM : ONI_PIXEL_FORMAT_RGB888;
    mode.resolutionX = t::kTestWidth;
    mode.resolutionY = t::kTestHeight;
    mode.fps = t::kTestFps;
    return mode;
  }

  OniStatus start() override {
    if (thread_.joinable()) return ONI_STATUS_OK;
    running_ = true;
    thread_ = std::thread([this] { Run(); });
    return ONI_STATUS_OK;
  }

  // Joins the producer: no frame is raised after stop() returns.
  void stop() override {
    running_ = false;
    if (thread_.joinable()) thread_.join();
  }

  OniStatus getProperty(int id, void* data, int* size) override {
    switch (id) {
      case ONI_STREAM_PROPERTY_VIDEO_MODE: return Put(data, size, Mode());
      case ONI_STREAM_PROPERTY_CROPPING: {
        OniCropping cropping{};
        cropping.enabled = FALSE;
        cropping.width = t::kTestWidth;
        cropping.height = t::kTestHeight;
        return Put(data, size, cropping);
      }
      case ONI_STREAM_PROPERTY_MIRRORING: return Put<OniBool>(data, size, FALSE);
      case ONI_STREAM_PROPERTY_HORIZONTAL_FOV: return Put<float>(data, size, 58.0f * float(M_PI) / 180.0f);
      case ONI_STREAM_PROPERTY_VERTICAL_FOV: return Put<float>(data, size, 45.0f * float(M_PI) / 180.0f);
      case ONI_STREAM_PROPERTY_MAX_VALUE: return Put<int>(data, size, type_ == ONI_SENSOR_DEPTH ? 10000 : 255);
      case ONI_STREAM_PROPERTY_MIN_VALUE: return Put<int>(data, size, 0);
      case ONI_STREAM_PROPERTY_STRIDE:
        return Put<int>(data, size, t::kTestWidth * (type_ == ONI_SENSOR_DEPTH ? 2 : 3));
      default: return ONI_STATUS_NOT_SUPPORTED;
    }
  }

  OniStatus setProperty(int id, const void* data, int size) override {
    if (id == ONI_STREAM_PROPERTY_CROPPING && size == sizeof(OniCropping)) {
      return static_cast<const OniCropping*>(data)->enabled ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
    }
    if (id == ONI_STREAM_PROPERTY_MIRRORING && size == sizeof(OniBool)) {
      return *static_cast<const OniBool*>(data) ? ONI_STATUS_NOT_SUPPORTED : ONI_STATUS_OK;
    }
    if (id == ONI_STREAM_PROPERTY_VIDEO_MODE && size == sizeof(OniVideoMode)) {
      const auto* mode = static_cast<const OniVideoMode*>(data);
      const OniVideoMode ours = Mode();
      return mode->pixelFormat == ours.pixelFormat && mode->resolutionX == ours.resolutionX &&
                     mode->resolutionY == ours.resolutionY && mode->fps == ours.fps
                 ? ONI_STATUS_OK
                 : ONI_STATUS_NOT_SUPPORTED;
    }
    return ONI_STATUS_NOT_SUPPORTED;
  }

  OniBool isPropertySupported(int id) override {
    switch (id) {
      case ONI_STREAM_PROPERTY_VIDEO_MODE: case ONI_STREAM_PROPERTY_CROPPING:
      case ONI_STREAM_PROPERTY_MIRRORING: case ONI_STREAM_PROPERTY_HORIZONTAL_FOV:
      case ONI_STREAM_PROPERTY_VERTICAL_FOV: case ONI_STREAM_PROPERTY_MAX_VALUE:
      case ONI_STREAM_PROPERTY_MIN_VALUE: case ONI_STREAM_PROPERTY_STRIDE: return TRUE;
      default: return FALSE;
    }
  }

 private:
  // Real-time pacing at 30 Hz; frame numbers from 1.
  void Run() {
    using clock = std::chrono::steady_clock;
    const auto start = clock::now();
    for (int frame = 1; running_; ++frame) {
      std::this_thread::sleep_until(start + std::chrono::microseconds(t::kTestPeriodUs) * (frame - 1));
      if (!running_) break;
      OniFrame* f = getServices().acquireFrame();
      if (f == nullptr) continue;
      const OniVideoMode mode = Mode();
      f->frameIndex = frame;
      f->videoMode = mode;
      f->width = mode.resolutionX;
      f->height = mode.resolutionY;
      f->cropOriginX = f->cropOriginY = 0;
      f->croppingEnabled = FALSE;
      f->sensorType = type_;
      if (type_ == ONI_SENSOR_DEPTH) {
        f->timestamp = t::TestDepthTimestampUs(frame);
        f->stride = mode.resolutionX * 2;
        f->dataSize = f->stride * mode.resolutionY;
        auto* depth = static_cast<uint16_t*>(f->data);
        for (int y = 0; y < mode.resolutionY; ++y)
          for (int x = 0; x < mode.resolutionX; ++x) depth[y * mode.resolutionX + x] = t::TestDepthMm(frame, x, y);
      } else {
        f->timestamp = t::TestColorTimestampUs(frame);
        f->stride = mode.resolutionX * 3;
        f->dataSize = f->stride * mode.resolutionY;
        auto* rgb = static_cast<uint8_t*>(f->data);
        for (int y = 0; y < mode.resolutionY; ++y)
          for (int x = 0; x < mode.resolutionX; ++x) t::TestColorRgb(frame, x, y, rgb + 3 * (y * mode.resolutionX + x));
      }
      raiseNewFrame(f);
      getServices().releaseFrame(f);
    }
  }

  OniSensorType type_;
  std::atomic<bool> running_{false};
  std::thread thread_;
};

class TestDevice : public oni::driver::DeviceBase {
 public:
  explicit TestDevice(int /*unused*/) {
    for (int i = 0; i < 2; ++i) {
      modes_[i].pixelFormat = i == 0 ? ONI_PIXEL_FORMAT_DEPTH_1_MM : ONI_PIXEL_FORMAT_RGB888;
      modes_[i].resolutionX = t::kTestWidth;
      modes_[i].resolutionY = t::kTestHeight;
      modes_[i].fps = t::kTestFps;
      sensors_[i].sensorType = i == 0 ? ONI_SENSOR_DEPTH : ONI_SENSOR_COLOR;
      sensors_[i].numSupportedVideoModes = 1;
      sensors_[i].pSupportedVideoModes = &modes_[i];
    }
  }
  OniStatus getSensorInfoList(OniSensorInfo** sensors, int* count) override {
    *sensors = sensors_;
    *count = 2;
    return ONI_STATUS_OK;
  }
  oni::driver::StreamBase* createStream(OniSensorType type) override {
    if (type != ONI_SENSOR_DEPTH && type != ONI_SENSOR_COLOR) return nullptr;
    return new (std::nothrow) TestStream(type);
  }
  void destroyStream(oni::driver::StreamBase* stream) override { delete stream; }

 private:
  OniVideoMode modes_[2]{};
  OniSensorInfo sensors_[2]{};
};

class TestDriver : public oni::driver::DriverBase {
 public:
  explicit TestDriver(OniDriverServices* services) : DriverBase(services) {
    std::memset(&info_, 0, sizeof(info_));
    std::strncpy(info_.uri, t::kTestDeviceUri, ONI_MAX_STR - 1);
    std::strncpy(info_.vendor, "heatwave", ONI_MAX_STR - 1);
    std::strncpy(info_.name, "test device", ONI_MAX_STR - 1);
  }
  // Announced at start-up, as a plugged-in device is, so that enumeration lists it.
  OniStatus initialize(oni::driver::DeviceConnectedCallback connected,
                       oni::driver::DeviceDisconnectedCallback disconnected,
                       oni::driver::DeviceStateChangedCallback changed, void* cookie) override {
    DriverBase::initialize(connected, disconnected, changed, cookie);
    deviceConnected(&info_);
    return ONI_STATUS_OK;
  }
  oni::driver::DeviceBase* deviceOpen(const char* uri, const char* /*mode*/) override {
    if (std::strcmp(uri, t::kTestDeviceUri) != 0) return nullptr;
    if (device_ == nullptr) device_ = new (std::nothrow) TestDevice(0);
    return device_;
  }
  void deviceClose(oni::driver::DeviceBase* device) override {
    if (device == device_) {
      delete device_;
      device_ = nullptr;
    }
  }
  OniStatus tryDevice(const char* uri) override {
    return std::strcmp(uri, t::kTestDeviceUri) == 0 ? ONI_STATUS_OK : ONI_STATUS_ERROR;
  }
  void shutdown() override {
    delete device_;
    device_ = nullptr;
  }

 private:
  OniDeviceInfo info_;
  TestDevice* device_ = nullptr;
};

}  // namespace

ONI_EXPORT_DRIVER(TestDriver);
