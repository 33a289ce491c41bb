// Capture and .oni import throughput, side by side with their floors, on the heatwave test
// OpenNI2 device (640 x 480 depth + colour at 30 Hz) and the fake thermal camera:
//
//   bench_capture_speed [--seconds 10] [--folder DIR]
//
// 1. import-oni vs OpenNI2's player alone on the same recording (the decode every importer
//    pays): ratio of wall times.
// 2. The scan writer (core::ScanWriter: atomic, verified PNG writes) vs plain cv::imwrite of
//    the same frames: ratio, and headroom = frames written per second / frames arriving per
//    second in a capture (depth 30 + colour 30 + thermal 9 Hz).
// 3. A live capture of --seconds: frames dropped, the queue's high-water mark, CPU time.
// Runs with the test OpenNI2 runtime on its library path (built with BUILD_RPATH).

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "bench/bench_timing.h"
#include "capture/capture_session.h"
#include "capture/fake_thermal_camera.h"
#include "capture/oni_import.h"
#include "capture/openni_source.h"
#include "capture/testing/capture_test_support.h"
#include "core/scan_writer.h"

namespace {
namespace fs = std::filesystem;
namespace t = hw::capture::testing;
using hw::bench::Clock;
using hw::bench::Ms;
}  // namespace

int main(int argc, char** argv) {
  double seconds = 10;
  fs::path folder = fs::temp_directory_path() / "heatwave-capture-bench";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--seconds") seconds = std::atof(argv[i + 1]);
    else if (a == "--folder") folder = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: bench_capture_speed [--seconds 10] [--folder DIR]\n");
      return 2;
    }
  }
  fs::remove_all(folder);
  fs::create_directories(folder);
  const hw::core::Rig rig = t::TestDeviceRig();

  // 1. Record, then play back alone and import.
  const fs::path oni = folder / "test.oni";
  t::RecordDevice(t::kTestDeviceUri, oni, seconds);
  std::printf("recording      %s, %.0f MB\n", oni.c_str(), static_cast<double>(fs::file_size(oni)) / 1e6);
  auto t0 = Clock::now();
  int played = 0;
  std::vector<hw::capture::RgbdFrame> frames;  // kept for part 2 (a few hundred MB at most)
  {
    auto playback = hw::capture::OpenNiSource::OpenRecording(oni);
    while (auto f = playback->Next(5.0)) {
      ++played;
      if (frames.size() < 120) frames.push_back(std::move(*f));
    }
  }
  const double play_ms = Ms(t0, Clock::now());
  t0 = Clock::now();
  const hw::capture::OniImportSummary s = hw::capture::ImportOni(oni, rig, folder / "import");
  const double import_ms = Ms(t0, Clock::now());
  std::printf("OpenNI2 player %6d frames %8.0f ms  %6.1f frames/s\n", played, play_ms, 1e3 * played / play_ms);
  std::printf("import-oni     %6d frames %8.0f ms  %6.1f frames/s   ratio import/player %.2f\n",
              s.depth_frames + s.color_frames, import_ms, 1e3 * (s.depth_frames + s.color_frames) / import_ms,
              import_ms / play_ms);

  // 2. The writer against cv::imwrite on the same frames.
  std::vector<cv::Mat> thermal;
  for (int i = 0; i < 36; ++i) thermal.push_back(hw::capture::FakeThermalExpectedFrame({}, i).raw);
  fs::create_directories(folder / "imwrite");
  t0 = Clock::now();
  int n = 0;
  for (const auto& f : frames) {
    cv::Mat out = f.image;
    if (f.stream == hw::capture::RgbdFrame::Stream::kColor) cv::cvtColor(f.image, out, cv::COLOR_RGB2BGR);
    cv::imwrite((folder / "imwrite" / (std::to_string(n++) + ".png")).string(), out);
  }
  for (const cv::Mat& m : thermal) cv::imwrite((folder / "imwrite" / (std::to_string(n++) + ".png")).string(), m);
  const double imwrite_ms = Ms(t0, Clock::now());
  t0 = Clock::now();
  {
    hw::core::ScanWriter writer(folder / "writer", rig);
    int k = 0;
    for (const auto& f : frames) {
      const double ts = 0.001 * ++k;
      if (f.stream == hw::capture::RgbdFrame::Stream::kDepth) {
        cv::Mat m;
        f.image.convertTo(m, CV_32FC1, f.depth_unit_m);
        writer.AddDepth(ts, m);
      } else {
        writer.AddRgb(ts, f.image);
      }
    }
    int j = 0;
    for (const cv::Mat& m : thermal) {
      cv::Mat c;
      m.convertTo(c, CV_32FC1, 0.01, -273.15);
      writer.AddThermal(0.001 * ++j, c);
    }
    writer.Finish();
  }
  const double writer_ms = Ms(t0, Clock::now());
  const double frames_written = static_cast<double>(frames.size() + thermal.size());
  const double arriving_hz = 30 + 30 + 9;
  std::printf("cv::imwrite    %6.0f frames %8.0f ms  %6.1f frames/s\n", frames_written, imwrite_ms, 1e3 * frames_written / imwrite_ms);
  std::printf("ScanWriter     %6.0f frames %8.0f ms  %6.1f frames/s   ratio writer/imwrite %.2f   headroom vs %g Hz arriving: x%.2f (one writer thread)\n",
              frames_written, writer_ms, 1e3 * frames_written / writer_ms, writer_ms / imwrite_ms, arriving_hz,
              1e3 * frames_written / writer_ms / arriving_hz);

  // 3. A live capture.
  {
    auto rgbd = hw::capture::OpenNiSource::OpenDevice(t::kTestDeviceUri, {});
    hw::capture::FakeThermalCamera thermal_camera;
    hw::capture::CaptureOptions options;
    options.duration_s = seconds;
    fs::create_directories(folder / "capture");
    const double cpu0 = hw::bench::CpuMs();
    const auto c = hw::capture::Capture(rgbd.get(), &thermal_camera, rig, folder / "capture", options, [] { return false; });
    const double cpu_ms = hw::bench::CpuMs() - cpu0;
    std::printf("capture        %.1f s: depth %lld rgb %lld thermal %lld written, dropped %lld, queue max %lld, CPU %.0f%% of one core\n",
                c.seconds, static_cast<long long>(c.depth.written), static_cast<long long>(c.rgb.written),
                static_cast<long long>(c.thermal.written),
                static_cast<long long>(c.depth.dropped + c.rgb.dropped + c.thermal.dropped),
                static_cast<long long>(c.max_queue_frames), 100.0 * cpu_ms / (1e3 * c.seconds));
  }
  return 0;
}
