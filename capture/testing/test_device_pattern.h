#pragma once

// What the heatwave test OpenNI2 device (capture/testing/oni_test_driver.cc) streams, as
// functions of the frame number and pixel, so that tests can check every imported or
// captured pixel and timestamp exactly. Header-only: the driver module and the tests share it.

#include <cstdint>

namespace hw::capture::testing {

inline constexpr const char* kTestDeviceUri = "heatwave-test";
inline constexpr int kTestWidth = 640;
inline constexpr int kTestHeight = 480;
inline constexpr int kTestFps = 30;
// Device clock (µs) of frame 1 of each stream, and the frame period. Colour is exposed 5 ms
// after depth, as on a PrimeSense device without frame sync.
inline constexpr uint64_t kTestDepthStartUs = 1'000'000;
inline constexpr uint64_t kTestColorStartUs = 1'005'000;
inline constexpr uint64_t kTestPeriodUs = 33'333;

// Frame numbers start at 1, as OpenNI2's do.
inline uint64_t TestDepthTimestampUs(int frame) { return kTestDepthStartUs + uint64_t(frame - 1) * kTestPeriodUs; }
inline uint64_t TestColorTimestampUs(int frame) { return kTestColorStartUs + uint64_t(frame - 1) * kTestPeriodUs; }

// Depth in millimetres: a ramp between 0.5 m and 4.5 m that moves with the frame, with
// holes (0 = no measurement) on a sparse moving lattice, as a Kinect leaves them.
inline uint16_t TestDepthMm(int frame, int x, int y) {
  if ((x * 7 + y * 13 + frame * 5) % 61 == 0) return 0;
  return static_cast<uint16_t>(500 + (x * 3 + y * 5 + frame * 11) % 4000);
}

// Colour, RGB.
inline void TestColorRgb(int frame, int x, int y, uint8_t rgb[3]) {
  rgb[0] = static_cast<uint8_t>((x + frame * 3) & 0xff);
  rgb[1] = static_cast<uint8_t>((y * 2 + frame) & 0xff);
  rgb[2] = static_cast<uint8_t>((x ^ y ^ frame) & 0xff);
}

}  // namespace hw::capture::testing
