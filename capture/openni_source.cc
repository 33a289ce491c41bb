#include "capture/openni_source.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <mutex>
#include <sstream>
#include <thread>

#include <OpenNI.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/thermal_camera.h"
#include "core/error.h"

namespace hw::capture {

namespace {

bool SameMode(const openni::VideoMode& a, const openni::VideoMode& b) {
  return a.getPixelFormat() == b.getPixelFormat() && a.getResolutionX() == b.getResolutionX() &&
         a.getResolutionY() == b.getResolutionY() && a.getFps() == b.getFps();
}

// Sets the mode only when it differs: drivers with one fixed mode (DummyDevice) refuse
// the call even for the mode they have.
bool SetMode(openni::VideoStream& stream, const openni::VideoMode& mode) {
  return SameMode(stream.getVideoMode(), mode) || stream.setVideoMode(mode) == openni::STATUS_OK;
}

// OpenNI::initialize once per process; never shut down (see the header).
const std::string& InitializeOpenNi() {
  static std::once_flag once;
  static std::string error;
  std::call_once(once, [] {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) {
      error = std::string("OpenNI2 did not start: ") + openni::OpenNI::getExtendedError();
      // OpenNI2 pads its messages with tabs and newlines.
      error.erase(std::remove_if(error.begin(), error.end(), [](char c) { return c == '\n' || c == '\t'; }),
                  error.end());
    }
  });
  return error;
}

std::string ExtendedError() {
  std::string text = openni::OpenNI::getExtendedError();
  std::replace_if(text.begin(), text.end(), [](char c) { return c == '\n' || c == '\t'; }, ' ');
  while (!text.empty() && text.front() == ' ') text.erase(text.begin());
  while (!text.empty() && text.back() == ' ') text.pop_back();
  return text.empty() ? "no reason given" : text;
}

std::string FormatName(openni::PixelFormat format) {
  switch (format) {
    case openni::PIXEL_FORMAT_DEPTH_1_MM: return "depth_1mm";
    case openni::PIXEL_FORMAT_DEPTH_100_UM: return "depth_100um";
    case openni::PIXEL_FORMAT_SHIFT_9_2: return "shift_9_2";
    case openni::PIXEL_FORMAT_SHIFT_9_3: return "shift_9_3";
    case openni::PIXEL_FORMAT_RGB888: return "rgb888";
    case openni::PIXEL_FORMAT_YUV422: return "yuv422";
    case openni::PIXEL_FORMAT_YUYV: return "yuyv";
    case openni::PIXEL_FORMAT_GRAY8: return "gray8";
    case openni::PIXEL_FORMAT_GRAY16: return "gray16";
    case openni::PIXEL_FORMAT_JPEG: return "jpeg";
    default: return "format_" + std::to_string(static_cast<int>(format));
  }
}

std::string SensorName(openni::SensorType type) {
  switch (type) {
    case openni::SENSOR_DEPTH: return "depth";
    case openni::SENSOR_COLOR: return "color";
    default: return "ir";
  }
}

RgbdStreamMode ModeOf(openni::SensorType type, const openni::VideoMode& mode) {
  return {SensorName(type), mode.getResolutionX(), mode.getResolutionY(), mode.getFps(),
          FormatName(mode.getPixelFormat())};
}

bool IsDepthFormat(openni::PixelFormat f) {
  return f == openni::PIXEL_FORMAT_DEPTH_1_MM || f == openni::PIXEL_FORMAT_DEPTH_100_UM;
}
bool IsColorFormat(openni::PixelFormat f) {
  return f == openni::PIXEL_FORMAT_RGB888 || f == openni::PIXEL_FORMAT_YUV422 || f == openni::PIXEL_FORMAT_YUYV ||
         f == openni::PIXEL_FORMAT_GRAY8 || f == openni::PIXEL_FORMAT_JPEG;
}

std::string ListModes(const openni::SensorInfo* info, openni::SensorType type) {
  std::ostringstream out;
  if (info == nullptr) return "none";
  const auto& modes = info->getSupportedVideoModes();
  for (int i = 0; i < modes.getSize(); ++i) {
    const RgbdStreamMode m = ModeOf(type, modes[i]);
    out << (i ? ", " : "") << m.width << "x" << m.height << "@" << m.fps << " " << m.pixel_format;
  }
  return out.str();
}

}  // namespace

std::string OpenNiOpenOptions::Check() const {
  if (depth_width <= 0 || depth_height <= 0)
    return "depth size " + std::to_string(depth_width) + "x" + std::to_string(depth_height) + " must be positive";
  if (color_width < 0 || color_height < 0) return "color size must be >= 0";
  if (fps < 0) return "fps " + std::to_string(fps) + " must be >= 0";
  return "";
}

std::vector<RgbdDeviceInfo> ListRgbdDevices(std::string* error) {
  std::vector<RgbdDeviceInfo> devices;
  const std::string& init_error = InitializeOpenNi();
  if (!init_error.empty()) {
    if (error) *error = init_error;
    return devices;
  }
  openni::Array<openni::DeviceInfo> list;
  openni::OpenNI::enumerateDevices(&list);
  for (int i = 0; i < list.getSize(); ++i) {
    RgbdDeviceInfo info;
    info.uri = list[i].getUri();
    info.vendor = list[i].getVendor();
    info.name = list[i].getName();
    info.usb_vendor_id = list[i].getUsbVendorId();
    info.usb_product_id = list[i].getUsbProductId();
    // The modes need the device open; a device busy elsewhere is still listed.
    openni::Device device;
    if (device.open(info.uri.c_str()) == openni::STATUS_OK) {
      for (const auto type : {openni::SENSOR_DEPTH, openni::SENSOR_COLOR, openni::SENSOR_IR}) {
        const openni::SensorInfo* sensor = device.getSensorInfo(type);
        if (sensor == nullptr) continue;
        const auto& modes = sensor->getSupportedVideoModes();
        for (int m = 0; m < modes.getSize(); ++m) info.modes.push_back(ModeOf(type, modes[m]));
      }
      device.close();
    }
    devices.push_back(std::move(info));
  }
  return devices;
}

struct OpenNiSource::Impl {
  openni::Device device;
  openni::VideoStream depth, color;
  bool has_color = false;
  bool is_file = false;
  bool started = false;
  std::string uri;
  std::filesystem::path file;
  int recorded[2] = {0, 0};   // recordings: frames per stream
  int delivered[2] = {0, 0};  // recordings: frames read so far
  std::unique_ptr<openni::Recorder> recorder;

  ~Impl() {
    StopStreams();  // before the recorder: see StopRecording()
    if (recorder) {
      recorder->stop();
      recorder->destroy();
    }
    // Only now may the driver free them (see the header: DummyDevice's threads).
    depth.destroy();
    if (has_color) color.destroy();
    device.close();
  }

  void StopStreams() {
    if (!started) return;
    started = false;
    depth.stop();
    if (has_color) color.stop();
    // Live: let DummyDevice-like producer threads see their flag. Recording: let the
    // player thread go from spinning over its stream list to sleeping between checks.
    std::this_thread::sleep_for(std::chrono::duration<double>(is_file ? kPlayerQuiesceS : kStreamQuiesceS));
  }

  // Converts one read frame. Throws InputError for a format we cannot store.
  RgbdFrame Convert(openni::VideoFrameRef& ref, RgbdFrame::Stream stream) const {
    RgbdFrame frame;
    frame.stream = stream;
    frame.arrival_s = MonotonicNowS();
    frame.device_timestamp_us = ref.getTimestamp();
    frame.frame_index = ref.getFrameIndex();
    const int w = ref.getWidth(), h = ref.getHeight();
    const openni::PixelFormat format = ref.getVideoMode().getPixelFormat();
    const auto* data = static_cast<const uint8_t*>(ref.getData());
    const int stride = ref.getStrideInBytes();
    const std::string where = is_file ? file.string() : uri;
    if (stream == RgbdFrame::Stream::kDepth) {
      if (!IsDepthFormat(format))
        throw core::InputError(where, "depth in pixel format " + FormatName(format) +
                                          " (only depth_1mm and depth_100um are metric)");
      frame.depth_unit_m = format == openni::PIXEL_FORMAT_DEPTH_1_MM ? 0.001 : 0.0001;
      frame.image = cv::Mat(h, w, CV_16UC1, const_cast<uint8_t*>(data), stride).clone();
      return frame;
    }
    switch (format) {
      case openni::PIXEL_FORMAT_RGB888:
        frame.image = cv::Mat(h, w, CV_8UC3, const_cast<uint8_t*>(data), stride).clone();
        break;
      case openni::PIXEL_FORMAT_YUV422:  // OpenNI's YUV422 is UYVY
        cv::cvtColor(cv::Mat(h, w, CV_8UC2, const_cast<uint8_t*>(data), stride), frame.image, cv::COLOR_YUV2RGB_UYVY);
        break;
      case openni::PIXEL_FORMAT_YUYV:
        cv::cvtColor(cv::Mat(h, w, CV_8UC2, const_cast<uint8_t*>(data), stride), frame.image, cv::COLOR_YUV2RGB_YUYV);
        break;
      case openni::PIXEL_FORMAT_GRAY8:
        cv::cvtColor(cv::Mat(h, w, CV_8UC1, const_cast<uint8_t*>(data), stride), frame.image, cv::COLOR_GRAY2RGB);
        break;
      case openni::PIXEL_FORMAT_JPEG: {
        const cv::Mat bytes(1, ref.getDataSize(), CV_8UC1, const_cast<uint8_t*>(data));
        cv::Mat bgr = cv::imdecode(bytes, cv::IMREAD_COLOR);
        if (bgr.empty() || bgr.cols != w || bgr.rows != h)
          throw core::InputError(where, "colour frame " + std::to_string(frame.frame_index) + " is not a decodable JPEG");
        cv::cvtColor(bgr, frame.image, cv::COLOR_BGR2RGB);
        break;
      }
      default:
        throw core::InputError(where, "colour in pixel format " + FormatName(format) + " is not supported");
    }
    return frame;
  }
};

OpenNiSource::OpenNiSource(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
OpenNiSource::~OpenNiSource() = default;

std::unique_ptr<OpenNiSource> OpenNiSource::OpenDevice(const std::string& uri, const OpenNiOpenOptions& options) {
  const std::string& init_error = InitializeOpenNi();
  const std::string name = uri.empty() ? "the first RGB-D device" : "RGB-D device '" + uri + "'";
  if (!init_error.empty()) throw core::InputError(name, init_error);
  auto impl = std::make_unique<Impl>();
  if (impl->device.open(uri.empty() ? openni::ANY_DEVICE : uri.c_str()) != openni::STATUS_OK)
    throw core::InputError(name, "OpenNI2 could not open it: " + ExtendedError());
  impl->uri = impl->device.getDeviceInfo().getUri();
  const std::string where = "RGB-D device '" + impl->uri + "'";

  // Picks the mode of `type` matching size, fps and a usable format; nullopt when none.
  auto pick = [&](openni::SensorType type, int width, int height) -> std::optional<openni::VideoMode> {
    const openni::SensorInfo* info = impl->device.getSensorInfo(type);
    if (info == nullptr) return std::nullopt;
    const auto& modes = info->getSupportedVideoModes();
    std::optional<openni::VideoMode> best;
    for (int i = 0; i < modes.getSize(); ++i) {
      const openni::VideoMode& m = modes[i];
      const bool usable = type == openni::SENSOR_DEPTH ? IsDepthFormat(m.getPixelFormat()) : IsColorFormat(m.getPixelFormat());
      if (!usable) continue;
      if (width > 0 && (m.getResolutionX() != width || m.getResolutionY() != height)) continue;
      if (options.fps > 0 && m.getFps() != options.fps) continue;
      // Prefer 1 mm depth and RGB888 colour (no conversion).
      const bool preferred = m.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM || m.getPixelFormat() == openni::PIXEL_FORMAT_RGB888;
      if (!best || preferred) best = m;
      if (preferred) break;
    }
    return best;
  };

  const auto depth_mode = pick(openni::SENSOR_DEPTH, options.depth_width, options.depth_height);
  if (!depth_mode) {
    throw core::InputError(where, "no depth mode " + std::to_string(options.depth_width) + "x" +
                                      std::to_string(options.depth_height) + (options.fps ? "@" + std::to_string(options.fps) : "") +
                                      " in depth_1mm or depth_100um (the rig's depth camera); it offers: " +
                                      ListModes(impl->device.getSensorInfo(openni::SENSOR_DEPTH), openni::SENSOR_DEPTH));
  }
  if (impl->depth.create(impl->device, openni::SENSOR_DEPTH) != openni::STATUS_OK)
    throw core::InputError(where, "could not create the depth stream: " + ExtendedError());
  if (!SetMode(impl->depth, *depth_mode))
    throw core::InputError(where, "could not set the depth mode: " + ExtendedError());
  if (options.color && impl->device.hasSensor(openni::SENSOR_COLOR)) {
    const auto color_mode = pick(openni::SENSOR_COLOR, options.color_width, options.color_height);
    if (!color_mode) {
      throw core::InputError(where, "no colour mode " + std::to_string(options.color_width) + "x" +
                                        std::to_string(options.color_height) + " (the rig's rgb camera); it offers: " +
                                        ListModes(impl->device.getSensorInfo(openni::SENSOR_COLOR), openni::SENSOR_COLOR));
    }
    if (impl->color.create(impl->device, openni::SENSOR_COLOR) != openni::STATUS_OK ||
        !SetMode(impl->color, *color_mode))
      throw core::InputError(where, "could not create the colour stream: " + ExtendedError());
    impl->has_color = true;
  }
  // Frames as the camera sees them: OpenNI2 viewers often leave mirroring on, and a
  // registered (depth-to-colour warped) depth image is not the depth camera's any more.
  // Both are device settings that persist; drivers without them refuse, which is fine.
  impl->depth.setMirroringEnabled(false);
  if (impl->has_color) impl->color.setMirroringEnabled(false);
  if (impl->device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
    impl->device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_OFF);
  return std::unique_ptr<OpenNiSource>(new OpenNiSource(std::move(impl)));
}

std::unique_ptr<OpenNiSource> OpenNiSource::OpenRecording(const std::filesystem::path& oni_path) {
  const std::string& init_error = InitializeOpenNi();
  if (!init_error.empty()) throw core::InputError(oni_path.string(), init_error);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(oni_path, ec))
    throw core::InputError(oni_path.string(), "no such file");
  auto impl = std::make_unique<Impl>();
  impl->is_file = true;
  impl->file = oni_path;
  const std::string where = oni_path.string();
  if (impl->device.open(oni_path.c_str()) != openni::STATUS_OK)
    throw core::InputError(where, "OpenNI2 could not open it as a recording: " + ExtendedError());
  impl->uri = impl->device.getDeviceInfo().getUri();
  openni::PlaybackControl* playback = impl->device.getPlaybackControl();
  if (playback == nullptr) throw core::InputError(where, "OpenNI2 opened it but not as a recording");
  playback->setRepeatEnabled(false);
  playback->setSpeed(-1.0f);  // manual: one frame per poke of waitForAnyStream
  if (!impl->device.hasSensor(openni::SENSOR_DEPTH) ||
      impl->depth.create(impl->device, openni::SENSOR_DEPTH) != openni::STATUS_OK)
    throw core::InputError(where, "the recording has no depth stream");
  impl->has_color = impl->device.hasSensor(openni::SENSOR_COLOR) &&
                    impl->color.create(impl->device, openni::SENSOR_COLOR) == openni::STATUS_OK;
  impl->recorded[0] = playback->getNumberOfFrames(impl->depth);
  impl->recorded[1] = impl->has_color ? playback->getNumberOfFrames(impl->color) : 0;
  if (impl->recorded[0] <= 0) throw core::InputError(where, "the recording's depth stream holds no frame");
  // The player drops every frame of a stream without a cropping record (see the header).
  for (int s = 0; s < (impl->has_color ? 2 : 1); ++s) {
    openni::VideoStream& stream = s == 0 ? impl->depth : impl->color;
    OniCropping cropping;
    int size = sizeof(cropping);
    if (stream.getProperty(ONI_STREAM_PROPERTY_CROPPING, &cropping, &size) != openni::STATUS_OK) {
      throw core::InputError(where, std::string("its ") + (s == 0 ? "depth" : "colour") +
                                        " stream has no cropping record, so OpenNI2's player would drop all "
                                        "its frames (a recording of a driver without cropping support, such "
                                        "as OpenNI2's DummyDevice)");
    }
  }
  if (impl->depth.start() != openni::STATUS_OK || (impl->has_color && impl->color.start() != openni::STATUS_OK))
    throw core::InputError(where, "could not start playback: " + ExtendedError());
  impl->started = true;
  return std::unique_ptr<OpenNiSource>(new OpenNiSource(std::move(impl)));
}

std::string OpenNiSource::uri() const { return impl_->uri; }
bool OpenNiSource::has_color() const { return impl_->has_color; }
RgbdStreamMode OpenNiSource::depth_mode() const { return ModeOf(openni::SENSOR_DEPTH, impl_->depth.getVideoMode()); }
std::optional<RgbdStreamMode> OpenNiSource::color_mode() const {
  if (!impl_->has_color) return std::nullopt;
  return ModeOf(openni::SENSOR_COLOR, impl_->color.getVideoMode());
}
int OpenNiSource::NumRecordedFrames(RgbdFrame::Stream stream) const {
  return impl_->recorded[stream == RgbdFrame::Stream::kDepth ? 0 : 1];
}

void OpenNiSource::Start() {
  if (impl_->started) return;
  const std::string where = "RGB-D device '" + impl_->uri + "'";
  if (impl_->depth.start() != openni::STATUS_OK) throw core::InputError(where, "could not start depth: " + ExtendedError());
  impl_->started = true;
  if (impl_->has_color && impl_->color.start() != openni::STATUS_OK)
    throw core::InputError(where, "could not start colour: " + ExtendedError());
}

std::optional<RgbdFrame> OpenNiSource::Next(double timeout_s) {
  Impl& im = *impl_;
  assert(im.started);
  openni::VideoStream* streams[2];
  RgbdFrame::Stream kinds[2];
  int n = 0;
  for (int s = 0; s < (im.has_color ? 2 : 1); ++s) {
    if (im.is_file && im.delivered[s] >= im.recorded[s]) continue;  // this stream is done
    streams[n] = s == 0 ? &im.depth : &im.color;
    kinds[n++] = s == 0 ? RgbdFrame::Stream::kDepth : RgbdFrame::Stream::kColor;
  }
  if (n == 0) return std::nullopt;
  int ready = -1;
  const int timeout_ms = std::max(1, static_cast<int>(timeout_s * 1000.0 + 0.5));
  const openni::Status status = openni::OpenNI::waitForAnyStream(streams, n, &ready, timeout_ms);
  if (status != openni::STATUS_OK || ready < 0) {
    if (!im.is_file) return std::nullopt;
    throw core::InputError(im.file.string(), "playback stalled after " + std::to_string(im.delivered[0]) + " of " +
                                                 std::to_string(im.recorded[0]) + " depth and " + std::to_string(im.delivered[1]) +
                                                 " of " + std::to_string(im.recorded[1]) + " colour frames");
  }
  openni::VideoFrameRef ref;
  if (streams[ready]->readFrame(&ref) != openni::STATUS_OK || !ref.isValid()) {
    throw core::InputError(im.is_file ? im.file.string() : "RGB-D device '" + im.uri + "'",
                           "could not read a frame: " + ExtendedError());
  }
  const int s = kinds[ready] == RgbdFrame::Stream::kDepth ? 0 : 1;
  ++im.delivered[s];
  return im.Convert(ref, kinds[ready]);
}

void OpenNiSource::Stop() { impl_->StopStreams(); }

void OpenNiSource::StartRecording(const std::filesystem::path& oni_path, bool lossy_color) {
  Impl& im = *impl_;
  const std::string where = oni_path.string();
  if (im.recorder) throw core::InputError(where, "a recording is already running");
  auto recorder = std::make_unique<openni::Recorder>();
  if (recorder->create(oni_path.c_str()) != openni::STATUS_OK)
    throw core::InputError(where, "OpenNI2 could not create the recording: " + ExtendedError());
  if (recorder->attach(im.depth, false) != openni::STATUS_OK ||
      (im.has_color && recorder->attach(im.color, lossy_color) != openni::STATUS_OK))
    throw core::InputError(where, "OpenNI2 could not attach the streams: " + ExtendedError());
  if (recorder->start() != openni::STATUS_OK) throw core::InputError(where, "OpenNI2 could not start recording: " + ExtendedError());
  im.recorder = std::move(recorder);
}

void OpenNiSource::StopRecording() {
  if (!impl_->recorder) return;
  impl_->StopStreams();
  impl_->recorder->stop();
  impl_->recorder->destroy();  // joins the recorder's thread, which writes the seek tables
  impl_->recorder.reset();
}

}  // namespace hw::capture
