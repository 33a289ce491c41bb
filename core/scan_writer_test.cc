#include "core/scan_writer.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <system_error>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/scan.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;

std::string Sci(double value) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3e", value);
  return buf;
}

// A small rig (small images keep the tests fast): depth and rgb 32x24, thermal 16x12.
Rig TestRig(double depth_scale = 1000.0) {
  Rig rig;
  rig.depth_scale = depth_scale;
  rig.depth = CameraModel::Pinhole(32, 24, 30.0, 30.0);
  rig.rgb = CameraModel::Pinhole(32, 24, 31.0, 31.0);
  rig.depth_from_rgb = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.025, 0, 0));
  rig.thermal = CameraModel::Pinhole(16, 12, 15.0, 15.0);
  rig.depth_from_thermal = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0.04, 0));
  rig.thermal_settings = ThermalSettings{};
  return rig;
}

TEST(ScanWriter, DepthRoundTripWithinHalfARawUnit) {
  const fs::path folder = hw::test::FreshPath();
  const Rig rig = TestRig(5000.0);  // TUM's scale: 0.2 mm per unit, range up to 13.1 m
  ScanWriter writer(folder, rig);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> depth(0.3f, 13.0f);
  cv::Mat depth_m(24, 32, CV_32FC1);
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 32; ++x) depth_m.at<float>(y, x) = depth(rng);
  }
  // Not measurements: written as 0 and read back as 0.
  depth_m.at<float>(0, 0) = 0.0f;
  depth_m.at<float>(0, 1) = std::numeric_limits<float>::quiet_NaN();
  depth_m.at<float>(0, 2) = -1.0f;
  depth_m.at<float>(0, 3) = std::numeric_limits<float>::infinity();
  // Beyond 65535 / 5000 = 13.107 m: dropped to 0 and counted.
  depth_m.at<float>(0, 4) = 13.2f;
  depth_m.at<float>(0, 5) = 100.0f;
  // The last representable value.
  depth_m.at<float>(0, 6) = 65535.0f / 5000.0f;
  EXPECT_EQ(writer.AddDepth(0.0, depth_m), 2);
  writer.Finish();

  const Scan scan = Scan::Open(folder);
  ASSERT_EQ(scan.NumFrames(Stream::kDepth), 1);
  const cv::Mat back = scan.LoadDepth(0);
  ASSERT_EQ(back.type(), CV_32FC1);
  ASSERT_EQ(back.size(), depth_m.size());
  double max_error_m = 0;
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 32; ++x) {
      const float in = depth_m.at<float>(y, x);
      const float out = back.at<float>(y, x);
      if (y == 0 && x <= 5) {
        EXPECT_EQ(out, 0.0f) << x;
        continue;
      }
      max_error_m = std::max(max_error_m, std::abs(static_cast<double>(out - in)));
    }
  }
  // Rounding to the nearest raw unit: |error| <= 0.5 / depth_scale (+ float rounding of
  // metres near 13 m, ~1e-6).
  RecordProperty("max_depth_error_m", Sci(max_error_m));
  EXPECT_LE(max_error_m, 0.5 / 5000.0 + 2e-6);
  EXPECT_GT(max_error_m, 0.1 / 5000.0);  // it really is quantised
  EXPECT_NEAR(back.at<float>(0, 6), 13.107f, 1e-6);
  // The file holds what scan-format.md says: uint16 raw units.
  const cv::Mat raw = cv::imread((folder / "depth/0.000000.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(raw.type(), CV_16UC1);
  EXPECT_EQ(raw.at<uint16_t>(0, 6), 65535);
  EXPECT_EQ(raw.at<uint16_t>(5, 5),
            std::lround(static_cast<double>(depth_m.at<float>(5, 5)) * 5000.0));
}

TEST(ScanWriter, RgbRoundTripIsExactAndFilesAreBgr) {
  const fs::path folder = hw::test::FreshPath();
  ScanWriter writer(folder, TestRig());
  cv::Mat rgb(24, 32, CV_8UC3);
  cv::randu(rgb, 0, 256);
  rgb.at<cv::Vec3b>(0, 0) = cv::Vec3b(255, 10, 0);  // red in RGB order
  writer.AddRgb(1.0, rgb);
  writer.AddDepth(1.0, cv::Mat::zeros(24, 32, CV_32FC1));
  writer.Finish();
  const Scan scan = Scan::Open(folder);
  const cv::Mat back = scan.LoadRgb(0);
  ASSERT_EQ(back.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(back, rgb, cv::NORM_INF), 0.0);
  EXPECT_EQ(back.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 10, 0));
  // On disk the PNG is an ordinary sRGB PNG, which OpenCV decodes as BGR.
  const cv::Mat file = cv::imread((folder / "rgb/1.000000.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(file.at<cv::Vec3b>(0, 0), cv::Vec3b(0, 10, 255));
}

TEST(ScanWriter, ThermalRawCountsWithinHalfRawScale) {
  const fs::path folder = hw::test::FreshPath();
  const Rig rig = TestRig();
  ScanWriter writer(folder, rig);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> temperature(-40.0f, 300.0f);
  cv::Mat apparent_c(12, 16, CV_32FC1);
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 16; ++x) apparent_c.at<float>(y, x) = temperature(rng);
  }
  // Outside [0, 65535] counts = [-273.15, 382.2] °C: saturated like a camera.
  apparent_c.at<float>(0, 0) = -300.0f;
  apparent_c.at<float>(0, 1) = 500.0f;
  EXPECT_EQ(writer.AddThermal(2.0, apparent_c, ThermalEncoding::kRawCounts16), 2);
  writer.AddDepth(2.0, cv::Mat::zeros(24, 32, CV_32FC1));
  writer.Finish();
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.FramePath(Stream::kThermal, 0).extension(), ".png");
  const cv::Mat back = scan.LoadThermal(0);
  ASSERT_EQ(back.type(), CV_32FC1);
  double max_error_c = 0;
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 16; ++x) {
      if (y == 0 && x < 2) continue;
      max_error_c = std::max(
          max_error_c,
          std::abs(static_cast<double>(back.at<float>(y, x) - apparent_c.at<float>(y, x))));
    }
  }
  // raw_scale / 2 = 0.005 °C, plus float rounding near 300 °C (~3e-5).
  RecordProperty("max_thermal_error_c", Sci(max_error_c));
  EXPECT_LE(max_error_c, 0.005 + 5e-5);
  EXPECT_GT(max_error_c, 0.001);  // quantised indeed
  EXPECT_NEAR(back.at<float>(0, 0), -273.15f, 1e-4);
  EXPECT_NEAR(back.at<float>(0, 1), 65535 * 0.01 - 273.15, 1e-3);
}

TEST(ScanWriter, ThermalFloatTiffIsExact) {
  const fs::path folder = hw::test::FreshPath();
  ScanWriter writer(folder, TestRig());
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> temperature(-100.0f, 2000.0f);
  cv::Mat apparent_c(12, 16, CV_32FC1);
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 16; ++x) apparent_c.at<float>(y, x) = temperature(rng);
  }
  apparent_c.at<float>(0, 0) = 1e-30f;
  apparent_c.at<float>(0, 1) = -1234.5678f;
  EXPECT_EQ(writer.AddThermal(3.0, apparent_c, ThermalEncoding::kFloatTiff), 0);
  writer.AddDepth(3.0, cv::Mat::zeros(24, 32, CV_32FC1));
  writer.Finish();
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.FramePath(Stream::kThermal, 0).filename(), "3.000000.tiff");
  const cv::Mat back = scan.LoadThermal(0);
  ASSERT_EQ(back.type(), CV_32FC1);
  EXPECT_EQ(cv::norm(back, apparent_c, cv::NORM_INF), 0.0);
}

TEST(ScanWriter, TimestampsRoundTripToTheMicrosecond) {
  const fs::path folder = hw::test::FreshPath();
  ScanWriter writer(folder, TestRig());
  const cv::Mat depth = cv::Mat::ones(24, 32, CV_32FC1);
  const cv::Mat thermal = cv::Mat(12, 16, CV_32FC1, cv::Scalar(25.0f));
  // TUM-like epoch times: 1.3e9 s, where a double resolves 2.4e-7 s.
  std::vector<double> times;
  for (int i = 0; i < 20; ++i) times.push_back(1305031102.175304 + i * 0.0333331234);
  for (const double t : times) {
    writer.AddDepth(t, depth);
    writer.AddThermal(t + 0.0123456789, thermal);
  }
  writer.AddFfcEvent(1305031102.5000004);
  writer.AddFfcEvent(1305031103.25);
  writer.Finish();
  const Scan scan = Scan::Open(folder);
  ASSERT_EQ(scan.NumFrames(Stream::kDepth), 20);
  ASSERT_EQ(scan.NumFrames(Stream::kThermal), 20);
  double max_error_s = 0;
  for (int i = 0; i < 20; ++i) {
    const double t = times[static_cast<size_t>(i)];
    max_error_s = std::max(max_error_s, std::abs(scan.Timestamp(Stream::kDepth, i) - t));
    max_error_s =
        std::max(max_error_s, std::abs(scan.Timestamp(Stream::kThermal, i) - (t + 0.0123456789)));
    // The index value and the file name carry the same 6 decimals.
    EXPECT_EQ(scan.FramePath(Stream::kDepth, i).filename().string(),
              ScanWriter::FormatTimestamp(scan.Timestamp(Stream::kDepth, i)) + ".png");
  }
  RecordProperty("max_timestamp_error_s", Sci(max_error_s));
  EXPECT_LE(max_error_s, 0.5e-6 + 3e-7);  // rounding to 6 decimals + double resolution at 1.3e9
  ASSERT_EQ(scan.ffc_timestamps_s().size(), 2u);
  EXPECT_NEAR(scan.ffc_timestamps_s()[0], 1305031102.5, 3e-7);
  EXPECT_NEAR(scan.ffc_timestamps_s()[1], 1305031103.25, 3e-7);
}

TEST(ScanWriter, IndexFilesHaveTumHeaderAndOnlyWrittenStreams) {
  const fs::path folder = hw::test::FreshPath();
  ScanWriter writer(folder, TestRig());
  writer.AddDepth(0.5, cv::Mat::ones(24, 32, CV_32FC1));
  writer.Finish();
  EXPECT_TRUE(fs::exists(folder / "rig.yaml"));
  EXPECT_FALSE(fs::exists(folder / "rgb.txt"));  // no rgb frames added
  EXPECT_FALSE(fs::exists(folder / "thermal.txt"));
  EXPECT_FALSE(fs::exists(folder / "ffc.txt"));
  EXPECT_FALSE(fs::exists(folder / "groundtruth.txt"));
  const std::string text = ReadFile(folder / "depth.txt", kMaxMeshFileBytes);
  // Three '#' lines, then the frame.
  size_t pos = 0;
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(text[pos], '#') << text;
    pos = text.find('\n', pos) + 1;
  }
  EXPECT_EQ(text.substr(pos), "0.500000 depth/0.500000.png\n");
  // Rig round trip through the folder.
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.rig().depth, TestRig().depth);
  ASSERT_TRUE(scan.rig().thermal);
  EXPECT_EQ(*scan.rig().thermal, *TestRig().thermal);
  EXPECT_EQ(scan.NumFrames(Stream::kRgb), 0);  // a camera without an index: no frames
  EXPECT_FALSE(scan.HasIndex(Stream::kRgb));
  // No temporary files left behind by the atomic writes.
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    EXPECT_NE(entry.path().filename().string()[0], '.') << entry.path();
  }
}

TEST(ScanWriter, FinishCanBeCalledAgainAfterMoreFrames) {
  const fs::path folder = hw::test::FreshPath();
  ScanWriter writer(folder, TestRig());
  const cv::Mat depth = cv::Mat::ones(24, 32, CV_32FC1);
  writer.AddDepth(0.0, depth);
  writer.Finish();
  EXPECT_EQ(Scan::Open(folder).NumFrames(Stream::kDepth), 1);
  writer.AddDepth(0.1, depth);
  writer.AddDepth(0.2, depth);
  writer.Finish();
  EXPECT_EQ(Scan::Open(folder).NumFrames(Stream::kDepth), 3);
  EXPECT_EQ(writer.NumFrames("depth"), 3);
}

TEST(ScanWriter, GroundTruthRoundTrip) {
  const fs::path folder = hw::test::FreshPath();
  ScanWriter writer(folder, TestRig());
  writer.AddDepth(0.0, cv::Mat::ones(24, 32, CV_32FC1));
  Trajectory trajectory;
  for (int i = 0; i < 10; ++i) {
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(0, 1, 0)));
    trajectory.Add(0.1 * i, Rigid3d(q, Eigen::Vector3d(0.01 * i, 0.5, -0.2 * i)));
  }
  writer.SetGroundTruth(trajectory);
  writer.Finish();
  const Scan scan = Scan::Open(folder);
  ASSERT_TRUE(scan.groundtruth());
  ASSERT_EQ(scan.groundtruth()->size(), 10u);
  for (size_t i = 0; i < 10; ++i) {
    const PoseError error = ComparePoses(scan.groundtruth()->poses()[i].world_from_sensor,
                                         trajectory.poses()[i].world_from_sensor);
    EXPECT_LT(error.rotation_rad, 1e-9);
    EXPECT_LT(error.translation_m, 1e-9);
  }
}

TEST(ScanWriter, UnwritableFolderIsOutputError) {
  const fs::path folder = hw::test::FreshPath();
  fs::create_directories(folder);
  WriteFileAtomically(folder / "file", "x");
  // A folder cannot be created below a regular file.
  EXPECT_THROW(ScanWriter(folder / "file" / "scan", TestRig()), OutputError);
}

TEST(ScanWriter, FileNamesAreSixDecimalTimestamps) {
  EXPECT_EQ(ScanWriter::FrameFileName(1.5, ".png"), "1.500000.png");
  EXPECT_EQ(ScanWriter::FrameFileName(1305031102.175304, ".tiff"), "1305031102.175304.tiff");
  EXPECT_EQ(ScanWriter::FormatTimestamp(0.0000004), "0.000000");
  EXPECT_EQ(ScanWriter::FormatTimestamp(0.0000006), "0.000001");
}

}  // namespace
}  // namespace hw::core
