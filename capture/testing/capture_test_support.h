#pragma once

// Shared by the capture/ tests: recordings of the test OpenNI2 device and a rig that
// matches it. The tests run with the test OpenNI2 runtime (capture/CMakeLists.txt:
// HW_OPENNI_TEST_RUNTIME), where OpenNI2 finds the heatwave test device and DummyDevice.

#include <chrono>
#include <filesystem>
#include <thread>

#include <opencv2/core.hpp>

#include "capture/openni_source.h"
#include "capture/testing/test_device_pattern.h"
#include "core/rig.h"

namespace hw::capture::testing {

// A rig with the test device's cameras (depth_scale 1000: one raw unit per millimetre, so
// depth round-trips exactly) and a 160x120 radiometric thermal camera (centikelvin).
inline core::Rig TestDeviceRig() {
  core::Rig rig;
  rig.depth_scale = 1000.0;
  rig.depth = core::CameraModel::Pinhole(kTestWidth, kTestHeight, 570.0, 570.0);
  rig.rgb = core::CameraModel::Pinhole(kTestWidth, kTestHeight, 525.0, 525.0);
  rig.thermal = core::CameraModel::Pinhole(160, 120, 150.0, 150.0);
  rig.thermal_settings = core::ThermalSettings{};
  return rig;
}

// Records `seconds` of the device `uri` (depth and colour at `width`x`height`) through
// OpenNI2's Recorder into `oni_path`, then closes everything. Returns nothing; the file's
// frame counts are what OpenRecording reports.
inline void RecordDevice(const std::string& uri, const std::filesystem::path& oni_path, double seconds,
                         int width = kTestWidth, int height = kTestHeight) {
  OpenNiOpenOptions options;
  options.depth_width = options.color_width = width;
  options.depth_height = options.color_height = height;
  auto source = OpenNiSource::OpenDevice(uri, options);
  source->Start();
  source->StartRecording(oni_path);
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) source->Next(0.05);  // keep the streams drained
  source->StopRecording();
  source->Stop();
}

// Number of pixels of a depth image (CV_16UC1, millimetres) that differ from the pattern.
inline int DepthMismatches(const cv::Mat& depth_mm, int frame) {
  int bad = 0;
  for (int y = 0; y < depth_mm.rows; ++y)
    for (int x = 0; x < depth_mm.cols; ++x) bad += depth_mm.at<uint16_t>(y, x) != TestDepthMm(frame, x, y);
  return bad;
}

// Same for a colour image (CV_8UC3, RGB order).
inline int ColorMismatches(const cv::Mat& rgb, int frame) {
  int bad = 0;
  for (int y = 0; y < rgb.rows; ++y)
    for (int x = 0; x < rgb.cols; ++x) {
      uint8_t expected[3];
      TestColorRgb(frame, x, y, expected);
      const cv::Vec3b v = rgb.at<cv::Vec3b>(y, x);
      bad += v[0] != expected[0] || v[1] != expected[1] || v[2] != expected[2];
    }
  return bad;
}

}  // namespace hw::capture::testing
