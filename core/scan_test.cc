#include "core/scan.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/scan_test_support.h"
#include "core/scan_writer.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using test::IndexText;
using test::Stamp;
using test::TestRig;
using test::Times;
using test::WriteIndexOnlyScan;
using test::WriteText;

Rig DepthOnlyRig() {
  Rig rig = TestRig();
  rig.rgb.reset();
  rig.thermal.reset();
  rig.thermal_settings.reset();
  rig.depth_from_rgb = Rigid3d::Identity();
  rig.depth_from_thermal = Rigid3d::Identity();
  return rig;
}

// Expects `f` to throw InputError whose message contains every one of `parts`.
void ExpectInputError(const std::function<void()>& f, std::initializer_list<std::string> parts) {
  try {
    f();
    ADD_FAILURE() << "no InputError; expected one containing '" << *parts.begin() << "'";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find('\n'), std::string::npos) << "not one line: " << what;
    for (const std::string& part : parts) {
      EXPECT_NE(what.find(part), std::string::npos) << "'" << part << "' not in: " << what;
    }
  }
}

// ---------------------------------------------------------------------------------------
// Index parsing

TEST(StreamIndex, ParsesCommentsBlankLinesTabsAndCrLf) {
  const std::string text =
      "# color images\n"
      "# file: 'rgbd_dataset_freiburg1_xyz.bag'\n"
      "# timestamp filename\n"
      "1305031102.175304 rgb/1305031102.175304.png\n"
      "\n"
      "   \t\n"
      "1305031102.211214\trgb/1305031102.211214.png\r\n"
      "  1305031102.243211   rgb/a#b.png   # a comment after the fields\n"
      "1305031102.5 rgb/x.png";  // no final newline
  const std::vector<IndexEntry> entries = ParseStreamIndex(text, "rgb.txt");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_DOUBLE_EQ(entries[0].timestamp_s, 1305031102.175304);
  EXPECT_EQ(entries[0].path, "rgb/1305031102.175304.png");
  EXPECT_EQ(entries[0].line, 4);
  EXPECT_EQ(entries[1].path, "rgb/1305031102.211214.png");  // CR stripped
  EXPECT_EQ(entries[1].line, 7);
  EXPECT_EQ(entries[2].path, "rgb/a#b.png");  // '#' inside a field is part of it
  EXPECT_EQ(entries[3].line, 9);
  EXPECT_DOUBLE_EQ(entries[3].timestamp_s, 1305031102.5);
  EXPECT_TRUE(ParseStreamIndex("", "x.txt").empty());
  EXPECT_TRUE(ParseStreamIndex("# only a comment\n\n", "x.txt").empty());
}

TEST(StreamIndex, EveryMalformedLineNamesFileAndLine) {
  struct Case {
    std::string text;
    std::string expected;  // in the message, after "depth.txt: line N: "
    int line;
  };
  const std::vector<Case> cases = {
      {"1.0\n", "expected 'timestamp path', got 1 field", 1},
      {"# c\n1.0 a.png b.png\n", "got 3 field", 2},
      {"abc depth/a.png\n", "bad timestamp 'abc'", 1},
      {"1.0x depth/a.png\n", "bad timestamp '1.0x'", 1},
      {"nan depth/a.png\n", "bad timestamp 'nan'", 1},
      {"inf depth/a.png\n", "bad timestamp 'inf'", 1},
      {"1e999 depth/a.png\n", "bad timestamp", 1},
      {"0x10 depth/a.png\n", "bad timestamp", 1},
      {"1,5 depth/a.png\n", "bad timestamp", 1},
      {"1.0 /abs/depth.png\n", "must be relative", 1},
      {"1.0 depth/a\x01.png\n", "control character 0x01", 1},
      {"1.0 depth/a.png\n\n2.0 depth/b\x7f.png\n", "control character 0x7f", 3},
      {"1.0 a.png\n2.0 b.png\n1.5 c.png\n", "timestamp 1.500000 is not after 2.000000 on line 2",
       3},
      {"1.0 a.png\n1.0 b.png\n", "not after", 2},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    ExpectInputError([&] { ParseStreamIndex(c.text, "scan/depth.txt"); },
                     {"scan/depth.txt: line " + std::to_string(c.line) + ": ", c.expected});
  }
}

TEST(StreamIndex, LongTokensAreShortenedInMessages) {
  const std::string token(500, 'z');
  try {
    ParseStreamIndex(token + " a.png\n", "d.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_LT(std::string(e.what()).size(), 120u) << e.what();
  }
}

TEST(StreamIndex, ReadMissingFileIsInputError) {
  ExpectInputError([] { ReadStreamIndex("/nonexistent/heatwave/depth.txt"); },
                   {"/nonexistent/heatwave/depth.txt"});
}

TEST(FfcEvents, ParsesAndRejectsMalformedLines) {
  const std::vector<double> events =
      ParseFfcEvents("# ffc\n# x\n# t\n1.5\n\n2.25 # shutter\n", "ffc.txt");
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0], 1.5);
  EXPECT_EQ(events[1], 2.25);
  ExpectInputError([] { ParseFfcEvents("1.0 2.0\n", "ffc.txt"); },
                   {"ffc.txt: line 1", "expected one timestamp"});
  ExpectInputError([] { ParseFfcEvents("1.0\nfoo\n", "ffc.txt"); }, {"line 2", "bad timestamp"});
  ExpectInputError([] { ParseFfcEvents("2.0\n1.0\n", "ffc.txt"); }, {"line 2", "not after"});
}

// Truncated prefixes and random byte mutations of a valid index: the parser returns or
// throws InputError, never crashes; what it returns satisfies the format's invariants.
TEST(StreamIndex, FuzzNeverCrashes) {
  const std::string valid =
      "# depth maps\n# file: 'x'\n# timestamp filename\n"
      "1305031102.160407 depth/1305031102.160407.png\n"
      "1305031102.194330 depth/1305031102.194330.png\n"
      "\n1305031102.226738\tdepth/1305031102.226738.png # c\r\n"
      "1305031102.262886 depth/1305031102.262886.png\n";
  int returned = 0, thrown = 0;
  const auto check = [&](const std::string& text) {
    try {
      const std::vector<IndexEntry> entries = ParseStreamIndex(text, "fuzz.txt");
      for (size_t i = 0; i < entries.size(); ++i) {
        ASSERT_TRUE(std::isfinite(entries[i].timestamp_s));
        ASSERT_FALSE(entries[i].path.empty());
        ASSERT_FALSE(fs::path(entries[i].path).is_absolute());
        if (i > 0) {
          ASSERT_GT(entries[i].timestamp_s, entries[i - 1].timestamp_s);
        }
      }
      ++returned;
    } catch (const InputError& e) {
      ASSERT_NE(std::string(e.what()).find("fuzz.txt: "), std::string::npos);
      ++thrown;
    }
    try {
      ParseFfcEvents(text, "fuzz.txt");
    } catch (const InputError&) {
    }
  };
  for (size_t n = 0; n <= valid.size(); ++n) check(valid.substr(0, n));
  std::mt19937 rng(12345);
  for (int k = 0; k < 4000; ++k) {
    std::string text = valid;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const size_t pos = rng() % text.size();
      const char byte = static_cast<char>(rng() % 256);
      switch (rng() % 3) {
        case 0:
          text[pos] = byte;
          break;
        case 1:
          text.insert(text.begin() + static_cast<std::ptrdiff_t>(pos), byte);
          break;
        default:
          text.erase(pos, 1);
          break;
      }
    }
    check(text);
  }
  // Both outcomes occur, so the test exercises both paths.
  EXPECT_GT(returned, 100);
  EXPECT_GT(thrown, 100);
}

// ---------------------------------------------------------------------------------------
// Opening

TEST(ScanOpen, FolderRigAndDepthIndexProblemsAreInputErrors) {
  const fs::path folder = hw::test::TestFolder();
  ExpectInputError([&] { Scan::Open(folder / "nope"); }, {"nope", "no such scan folder"});
  WriteText(folder / "file", "x");
  ExpectInputError([&] { Scan::Open(folder / "file"); }, {"is not a folder"});

  const fs::path scan = folder / "scan";
  fs::create_directories(scan);
  ExpectInputError([&] { Scan::Open(scan); }, {(scan / "rig.yaml").string(), "--rig"});
  ScanOptions options;
  options.rig_path = folder / "missing.yaml";
  ExpectInputError([&] { Scan::Open(scan, options); }, {"missing.yaml", "no such file"});

  WriteText(scan / "rig.yaml", "version: 1\ndepth_scale: -3\n");
  EXPECT_THROW(Scan::Open(scan), InputError);  // ReadRig's message, tested in rig_test

  WriteRig(scan / "rig.yaml", TestRig());
  ExpectInputError([&] { Scan::Open(scan); }, {"depth.txt", "needs a depth stream index"});
  WriteText(scan / "depth.txt", "# nothing\n");
  ExpectInputError([&] { Scan::Open(scan); }, {"depth.txt", "no frames"});
  WriteText(scan / "depth.txt", "1.0 depth/1.png\n0.5 depth/2.png\n");
  ExpectInputError([&] { Scan::Open(scan); }, {"depth.txt: line 2", "not after"});
  WriteText(scan / "depth.txt", "1.0 depth/1.png\n");
  EXPECT_NO_THROW(Scan::Open(scan));

  WriteText(scan / "rgb.txt", "1.0 rgb/1.png\n2.0\n");
  ExpectInputError([&] { Scan::Open(scan); }, {"rgb.txt: line 2"});
  fs::remove(scan / "rgb.txt");
  WriteText(scan / "groundtruth.txt", "1.0 0 0 0 0 0 0\n");
  ExpectInputError([&] { Scan::Open(scan); }, {"groundtruth.txt"});
  fs::remove(scan / "groundtruth.txt");
  WriteText(scan / "ffc.txt", "x\n");
  ExpectInputError([&] { Scan::Open(scan); }, {"ffc.txt: line 1"});
}

TEST(ScanOpen, StreamIndexWithoutItsCameraNamesBoth) {
  const fs::path folder = hw::test::TestFolder();
  WriteIndexOnlyScan(folder, DepthOnlyRig(), {1.0}, {}, {});
  WriteText(folder / "thermal.txt", "1.0 thermal/1.png\n");
  ExpectInputError(
      [&] { Scan::Open(folder); },
      {(folder / "thermal.txt").string(), (folder / "rig.yaml").string(), "cameras.thermal"});
  fs::remove(folder / "thermal.txt");
  WriteText(folder / "rgb.txt", "1.0 rgb/1.png\n");
  ExpectInputError([&] { Scan::Open(folder); }, {"rgb.txt", "cameras.rgb"});
  fs::remove(folder / "rgb.txt");
  WriteText(folder / "ffc.txt", "1.0\n");
  ExpectInputError([&] { Scan::Open(folder); }, {"ffc.txt", "cameras.thermal"});
  fs::remove(folder / "ffc.txt");
  // The other way round is fine: cameras without indexes have no frames.
  WriteIndexOnlyScan(folder, TestRig(), {1.0}, {}, {});
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.NumFrames(Stream::kRgb), 0);
  EXPECT_EQ(scan.NumFrames(Stream::kThermal), 0);
  EXPECT_FALSE(scan.AssociatedFrame(0, Stream::kThermal));
  EXPECT_FALSE(scan.NearestFrame(Stream::kThermal, 1.0, 1.0));
}

TEST(ScanOpen, OptionsCheck) {
  ScanOptions options;
  EXPECT_EQ(options.Check(), "");
  options.max_association_dt_s = 0.0;
  EXPECT_NE(options.Check().find("max_association_dt_s"), std::string::npos);
  options.max_association_dt_s = NAN;
  EXPECT_NE(options.Check().find("max_association_dt_s"), std::string::npos);
  options.max_association_dt_s = 0.01;
  EXPECT_EQ(options.Check(), "");
  options.gap_factor = 1.0;
  EXPECT_NE(options.Check().find("gap_factor: must be > 1"), std::string::npos);
  options.gap_factor = 1.5;
  options.stamps.window_s = -1;
  EXPECT_NE(options.Check().find("stamps.window_s"), std::string::npos);
}


// ---------------------------------------------------------------------------------------
// Clocks and association

TEST(ScanAssociation, ThermalClockOffsetShiftsPairs) {
  // Depth and thermal at 30 Hz; the thermal camera stamps each frame 40 ms after its
  // exposure, which rig.yaml states as time_offset_s.thermal = -0.040 (scan-format.md).
  const std::vector<double> depth = Times(30, 100.0, 1.0 / 30.0);
  std::vector<double> thermal;
  for (const double t : depth) thermal.push_back(t + 0.040);
  for (const double offset_s : {-0.040, 0.0}) {
    SCOPED_TRACE(offset_s);
    const fs::path folder = hw::test::TestFolder() / (offset_s == 0 ? "zero" : "offset");
    Rig rig = TestRig();
    rig.thermal_time_offset_s = offset_s;
    WriteIndexOnlyScan(folder, rig, depth, {}, thermal);
    const Scan scan = Scan::Open(folder);
    EXPECT_DOUBLE_EQ(scan.TimeOffset(Stream::kThermal), offset_s);
    EXPECT_DOUBLE_EQ(scan.Timestamp(Stream::kThermal, 3), std::stod(Stamp(thermal[3])));
    EXPECT_DOUBLE_EQ(scan.DepthClockTime(Stream::kThermal, 3),
                     std::stod(Stamp(thermal[3])) + offset_s);
    EXPECT_NEAR(scan.MaxAssociationDt(Stream::kThermal), 0.5 / 30.0, 1e-6);
    for (int d = 0; d < 30; ++d) {
      const std::optional<int> j = scan.AssociatedFrame(d, Stream::kThermal);
      if (offset_s != 0) {
        // On the depth clock thermal frame k is exactly depth frame k.
        ASSERT_TRUE(j) << d;
        EXPECT_EQ(*j, d);
      } else if (d == 0) {
        // Without the offset, thermal frame k (stamped at depth k + 0.040) lies 6.7 ms after
        // depth frame k + 1: depth frame 0 has no partner within 16.7 ms...
        EXPECT_FALSE(j);
      } else {
        // ...and every later depth frame d is paired with the wrong thermal frame, d - 1.
        ASSERT_TRUE(j) << d;
        EXPECT_EQ(*j, d - 1);
      }
    }
    EXPECT_EQ(scan.NumAssociatedDepthFrames(Stream::kThermal), offset_s != 0 ? 30 : 29);
  }
}

TEST(ScanAssociation, DefaultThresholdIsHalfTheSlowerPeriod) {
  // 30 Hz depth over 2 s, 9 Hz thermal starting later, ending earlier.
  const fs::path folder = hw::test::TestFolder();
  const std::vector<double> depth = Times(60, 0.0, 1.0 / 30.0);
  // (0.31: no depth frame lies exactly half-way between two thermal frames, a tie.)
  const std::vector<double> thermal = Times(12, 0.31, 1.0 / 9.0);
  const std::vector<double> rgb = Times(60, 0.001, 1.0 / 30.0);
  WriteIndexOnlyScan(folder, TestRig(), depth, rgb, thermal);
  const Scan scan = Scan::Open(folder);
  const double max_dt = 0.5 / 9.0;
  EXPECT_NEAR(scan.MaxAssociationDt(Stream::kThermal), max_dt, 1e-6);
  EXPECT_NEAR(scan.MaxAssociationDt(Stream::kRgb), 0.5 / 30.0, 1e-6);
  int paired = 0;
  for (int d = 0; d < 60; ++d) {
    const double t = scan.DepthClockTime(Stream::kDepth, d);
    // Brute force: the nearest thermal frame, if within max_dt.
    int best = -1;
    for (int j = 0; j < 12; ++j) {
      if (best < 0 || std::abs(scan.DepthClockTime(Stream::kThermal, j) - t) <
                          std::abs(scan.DepthClockTime(Stream::kThermal, best) - t)) {
        best = j;
      }
    }
    const bool within = std::abs(scan.DepthClockTime(Stream::kThermal, best) - t) <= max_dt;
    const std::optional<int> j = scan.AssociatedFrame(d, Stream::kThermal);
    ASSERT_EQ(j.has_value(), within) << d;
    if (j) {
      EXPECT_EQ(*j, best);
      EXPECT_LE(std::abs(scan.DepthClockTime(Stream::kThermal, *j) - t), max_dt);
      ++paired;
    }
    ASSERT_TRUE(scan.AssociatedFrame(d, Stream::kRgb));  // rgb 1 ms after depth
    EXPECT_EQ(*scan.AssociatedFrame(d, Stream::kRgb), d);
  }
  EXPECT_EQ(paired, scan.NumAssociatedDepthFrames(Stream::kThermal));
  // Thermal covers 0.31 - 1.5322 s, +- 0.0556 s: depth frames 8 (0.2667) to 47 (1.5667).
  EXPECT_EQ(paired, 40);

  // The inverse view: each thermal frame's own time on the depth clock, and its nearest
  // depth frame.
  const std::vector<double> thermal_on_depth = scan.DepthClockTimes(Stream::kThermal);
  ASSERT_EQ(thermal_on_depth.size(), 12u);
  EXPECT_NEAR(thermal_on_depth[1], 0.31 + 1.0 / 9.0, 1e-6);
  const std::optional<int> d = scan.NearestFrame(Stream::kDepth, thermal_on_depth[1], 0.02);
  ASSERT_TRUE(d);
  EXPECT_EQ(*d, 13);  // 0.4211 s: depth 12 is 0.4000, depth 13 is 0.4333
  EXPECT_FALSE(scan.NearestFrame(Stream::kDepth, thermal_on_depth[1], 0.005));
  EXPECT_FALSE(scan.NearestFrame(Stream::kDepth, 10.0, 1.0));

  // An explicit threshold replaces the default.
  ScanOptions options;
  options.max_association_dt_s = 0.005;
  const Scan strict = Scan::Open(folder, options);
  EXPECT_EQ(strict.MaxAssociationDt(Stream::kThermal), 0.005);
  EXPECT_EQ(strict.NumAssociatedDepthFrames(Stream::kRgb), 60);
  for (int k = 0; k < 60; ++k) {
    if (const auto j = strict.AssociatedFrame(k, Stream::kThermal)) {
      EXPECT_LE(std::abs(strict.DepthClockTime(Stream::kThermal, *j) -
                         strict.DepthClockTime(Stream::kDepth, k)),
                0.005);
    }
  }
  // Within 5 ms, a thermal frame can be nearest to at most one 30 Hz depth frame.
  EXPECT_LE(strict.NumAssociatedDepthFrames(Stream::kThermal), 12);
}

TEST(ScanAssociation, SingleFramesPairOnlyAtEqualTimesAndDisjointStreamsWarn) {
  const fs::path folder = hw::test::TestFolder();
  WriteIndexOnlyScan(folder, TestRig(), {5.0}, {5.0}, {5.5});
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.MaxAssociationDt(Stream::kRgb), kTimestampResolutionS);
  EXPECT_EQ(scan.AssociatedFrame(0, Stream::kRgb), 0);
  EXPECT_FALSE(scan.AssociatedFrame(0, Stream::kThermal));
  bool warned = false;
  for (const std::string& w : scan.warnings()) {
    if (w.find("thermal: no frame is within") != std::string::npos) {
      warned = true;
      EXPECT_NE(w.find("time_offset_s.thermal"), std::string::npos) << w;
    }
  }
  EXPECT_TRUE(warned);
}

// ---------------------------------------------------------------------------------------
// TUM RGB-D sequence with an external rig

TEST(ScanTum, OpensWithExternalRigAndDepthScale5000) {
  const fs::path root = hw::test::TestFolder();
  const fs::path tum = root / "rgbd_dataset_freiburg1_xyz";
  fs::create_directories(tum / "rgb");
  fs::create_directories(tum / "depth");
  const std::vector<double> rgb_times = {1305031102.175304, 1305031102.211214, 1305031102.243211};
  const std::vector<double> depth_times = {1305031102.160407, 1305031102.194330, 1305031102.226738};
  std::string rgb_txt =
      "# color images\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n";
  std::string depth_txt =
      "# depth maps\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n# timestamp filename\n";
  for (size_t i = 0; i < 3; ++i) {
    const std::string rgb_name = "rgb/" + Stamp(rgb_times[i]) + ".png";
    const std::string depth_name = "depth/" + Stamp(depth_times[i]) + ".png";
    rgb_txt += Stamp(rgb_times[i]) + " " + rgb_name + "\n";
    depth_txt += Stamp(depth_times[i]) + " " + depth_name + "\n";
    cv::Mat bgr(24, 32, CV_8UC3, cv::Scalar(10, 20, 30 + static_cast<int>(i)));  // B G R
    ASSERT_TRUE(cv::imwrite((tum / rgb_name).string(), bgr));
    cv::Mat raw(24, 32, CV_16UC1, cv::Scalar(5000 * (i + 1)));  // 1, 2, 3 m
    raw.at<uint16_t>(0, 0) = 0;
    raw.at<uint16_t>(0, 1) = 1;
    ASSERT_TRUE(cv::imwrite((tum / depth_name).string(), raw));
  }
  WriteText(tum / "rgb.txt", rgb_txt);
  WriteText(tum / "depth.txt", depth_txt);
  WriteText(tum / "groundtruth.txt",
            "# ground truth trajectory\n# file: 'rgbd_dataset_freiburg1_xyz.bag'\n"
            "# timestamp tx ty tz qx qy qz qw\n"
            "1305031098.6659 1.3563 0.6305 1.6380 0.6132 0.5962 -0.3311 -0.3986\n"
            "1305031098.6758 1.3543 0.6306 1.6360 0.6129 0.5966 -0.3316 -0.3980\n"
            "1305031102.6758 1.3543 0.6306 1.6360 0.6129 0.5966 -0.3316 -0.3980\n");
  // The rig as a user writes it for the Freiburg 1 Kinect (sizes reduced for the test).
  const std::string rig_yaml =
      "version: 1\n"
      "depth_scale: 5000.0\n"
      "cameras:\n"
      "  depth:\n"
      "    width: 32\n    height: 24\n    model: pinhole\n"
      "    fx: 51.7\n    fy: 51.6\n    cx: 15.5\n    cy: 11.5\n    distortion: []\n"
      "  rgb:\n"
      "    width: 32\n    height: 24\n    model: opencv\n"
      "    fx: 51.7\n    fy: 51.6\n    cx: 15.5\n    cy: 11.5\n"
      "    distortion: [0.2624, -0.9531, -0.0054, 0.0026, 1.1633]\n"
      "extrinsics:\n"
      "  depth_from_rgb: { q_xyzw: [0, 0, 0, 1], t_m: [0.0, 0.0, 0.0] }\n"
      "time_offset_s:\n"
      "  rgb: 0.0\n";
  WriteText(root / "fr1.yaml", rig_yaml);

  ExpectInputError([&] { Scan::Open(tum); }, {"rig.yaml", "--rig"});
  ScanOptions options;
  options.rig_path = root / "fr1.yaml";
  const Scan scan = Scan::Open(tum, options);
  EXPECT_EQ(scan.rig_path(), root / "fr1.yaml");
  EXPECT_EQ(scan.rig().depth_scale, 5000.0);
  EXPECT_TRUE(scan.warnings().empty()) << scan.warnings()[0];
  ASSERT_EQ(scan.NumFrames(Stream::kDepth), 3);
  ASSERT_EQ(scan.NumFrames(Stream::kRgb), 3);
  EXPECT_FALSE(scan.HasIndex(Stream::kThermal));
  EXPECT_DOUBLE_EQ(scan.Timestamp(Stream::kRgb, 1), 1305031102.211214);
  for (int i = 0; i < 3; ++i) {
    const cv::Mat depth_m = scan.LoadDepth(i);
    EXPECT_EQ(depth_m.at<float>(0, 0), 0.0f);  // no measurement
    EXPECT_FLOAT_EQ(depth_m.at<float>(0, 1), 1.0f / 5000.0f);
    EXPECT_FLOAT_EQ(depth_m.at<float>(10, 10), static_cast<float>(i + 1));
    const cv::Mat rgb = scan.LoadRgb(i);
    EXPECT_EQ(rgb.at<cv::Vec3b>(5, 5), cv::Vec3b(static_cast<uchar>(30 + i), 20, 10));
  }
  // The real first frames of fr1/xyz: rgb lags depth by 15-17 ms, about half a frame, so
  // nearest-in-time pairing gives depth 0 -> rgb 0 (14.9 ms), 1 -> 1 (16.9 ms, below the
  // 17.0 ms threshold = half rgb's median period), 2 -> 1 (15.5 ms, nearer than rgb 2 at
  // 16.5 ms).
  EXPECT_NEAR(scan.MaxAssociationDt(Stream::kRgb), 0.5 * 0.033953, 1e-6);
  EXPECT_EQ(scan.AssociatedFrame(0, Stream::kRgb), 0);
  EXPECT_EQ(scan.AssociatedFrame(1, Stream::kRgb), 1);
  EXPECT_EQ(scan.AssociatedFrame(2, Stream::kRgb), 1);
  ASSERT_TRUE(scan.groundtruth());
  EXPECT_EQ(scan.groundtruth()->size(), 3u);
  const ScanSummary summary = SummarizeScan(scan);
  EXPECT_EQ(summary.groundtruth_poses, 3);
  EXPECT_EQ(summary.cameras.size(), 2u);
  EXPECT_EQ(summary.cameras[1].model, "opencv");
  EXPECT_EQ(summary.cameras[1].distortion_coefficients, 5);
}

// ---------------------------------------------------------------------------------------
// Frames: missing files, gaps, bad images

// A scan with real frames written by ScanWriter: depth 30 Hz, thermal raw counts.
fs::path WriteSmallScan(const fs::path& folder, int frames = 6) {
  ScanWriter writer(folder, TestRig());
  for (int i = 0; i < frames; ++i) {
    const double t = 10.0 + i / 30.0;
    writer.AddDepth(t, cv::Mat(24, 32, CV_32FC1, cv::Scalar(1.0f + 0.1f * static_cast<float>(i))));
    writer.AddRgb(t, cv::Mat(24, 32, CV_8UC3, cv::Scalar(1, 2, 3)));
    writer.AddThermal(t, cv::Mat(12, 16, CV_32FC1, cv::Scalar(30.0f)));
  }
  writer.Finish();
  return folder;
}

TEST(ScanFrames, MissingFilesAndGapsAreWarningsAndTheScanLoads) {
  const fs::path folder = hw::test::TestFolder();
  // Depth: 30 Hz with one 0.5 s gap between frames 9 and 10.
  std::vector<double> depth = Times(10, 0.0, 1.0 / 30.0);
  for (const double t : Times(10, 0.8, 1.0 / 30.0)) depth.push_back(t);
  {
    ScanWriter writer(folder, TestRig());
    for (const double t : depth) writer.AddDepth(t, cv::Mat::ones(24, 32, CV_32FC1));
    writer.Finish();
  }
  const fs::path missing = folder / ("depth/" + Stamp(depth[4]) + ".png");
  fs::remove(missing);
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.NumFrames(Stream::kDepth), 20);
  EXPECT_EQ(scan.NumMissingFrames(Stream::kDepth), 1);
  EXPECT_FALSE(scan.FrameExists(Stream::kDepth, 4));
  EXPECT_TRUE(scan.FrameExists(Stream::kDepth, 5));
  ASSERT_EQ(scan.warnings().size(), 2u);
  EXPECT_NE(scan.warnings()[0].find("missing file " + missing.string()), std::string::npos)
      << scan.warnings()[0];
  EXPECT_NE(scan.warnings()[0].find("line 8"), std::string::npos) << scan.warnings()[0];
  EXPECT_NE(scan.warnings()[1].find("gap of 0.500 s between " + Stamp(depth[9])), std::string::npos)
      << scan.warnings()[1];
  // The other frames load; the missing one throws naming its path.
  EXPECT_NO_THROW(scan.LoadDepth(3));
  ExpectInputError([&] { scan.LoadDepth(4); }, {missing.string(), "missing depth frame 4"});
}

TEST(ScanFrames, ManyMissingFilesAreSummarised) {
  const fs::path folder = hw::test::TestFolder();
  WriteIndexOnlyScan(folder, TestRig(), Times(50, 0, 0.1), {}, {});
  const Scan scan = Scan::Open(folder);
  EXPECT_EQ(scan.NumMissingFrames(Stream::kDepth), 50);
  // Five listed, then one line for the rest.
  ASSERT_EQ(scan.warnings().size(), 6u);
  EXPECT_NE(scan.warnings()[5].find("45 more missing files (50 of 50)"), std::string::npos)
      << scan.warnings()[5];
}

TEST(ScanFrames, CorruptWrongTypeAndWrongSizeFramesAreInputErrors) {
  const fs::path folder = WriteSmallScan(hw::test::TestFolder());
  const Scan scan = Scan::Open(folder);
  ASSERT_TRUE(scan.warnings().empty()) << scan.warnings()[0];
  EXPECT_FLOAT_EQ(scan.LoadDepth(2).at<float>(3, 3), 1.2f);
  EXPECT_EQ(scan.LoadRgb(2).at<cv::Vec3b>(3, 3), cv::Vec3b(1, 2, 3));
  EXPECT_NEAR(scan.LoadThermal(2).at<float>(3, 3), 30.0f, 0.005);

  // Garbage bytes.
  const fs::path depth0 = scan.FramePath(Stream::kDepth, 0);
  WriteText(depth0, "this is not a PNG");
  ExpectInputError([&] { scan.LoadDepth(0); }, {depth0.string(), "cannot decode depth frame 0"});
  // A truncated PNG.
  const fs::path depth1 = scan.FramePath(Stream::kDepth, 1);
  const std::string bytes = ReadFile(depth1, kMaxMeshFileBytes);
  WriteText(depth1, bytes.substr(0, bytes.size() / 2));
  ExpectInputError([&] { scan.LoadDepth(1); }, {depth1.string()});
  // 8-bit depth.
  const fs::path depth2 = scan.FramePath(Stream::kDepth, 2);
  ASSERT_TRUE(cv::imwrite(depth2.string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(9))));
  ExpectInputError([&] { scan.LoadDepth(2); },
                   {depth2.string(), "16-bit unsigned 1-channel, got 8-bit unsigned 1-channel"});
  // Wrong size.
  const fs::path depth3 = scan.FramePath(Stream::kDepth, 3);
  ASSERT_TRUE(cv::imwrite(depth3.string(), cv::Mat(12, 16, CV_16UC1, cv::Scalar(9))));
  ExpectInputError([&] { scan.LoadDepth(3); },
                   {depth3.string(), "image is 16x12, cameras.depth in the rig is 32x24"});
  // 16-bit colour.
  const fs::path rgb0 = scan.FramePath(Stream::kRgb, 0);
  ASSERT_TRUE(cv::imwrite(rgb0.string(), cv::Mat(24, 32, CV_16UC3, cv::Scalar(9, 9, 9))));
  ExpectInputError([&] { scan.LoadRgb(0); }, {rgb0.string(), "8-bit"});
  const fs::path rgb1 = scan.FramePath(Stream::kRgb, 1);
  ASSERT_TRUE(cv::imwrite(rgb1.string(), cv::Mat(20, 32, CV_8UC3, cv::Scalar(9, 9, 9))));
  ExpectInputError([&] { scan.LoadRgb(1); }, {rgb1.string(), "cameras.rgb"});
  // Grey and BGRA colour frames are accepted and converted.
  const fs::path rgb2 = scan.FramePath(Stream::kRgb, 2);
  ASSERT_TRUE(cv::imwrite(rgb2.string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(77))));
  EXPECT_EQ(scan.LoadRgb(2).at<cv::Vec3b>(0, 0), cv::Vec3b(77, 77, 77));
  const fs::path rgb3 = scan.FramePath(Stream::kRgb, 3);
  ASSERT_TRUE(cv::imwrite(rgb3.string(), cv::Mat(24, 32, CV_8UC4, cv::Scalar(1, 2, 3, 4))));
  EXPECT_EQ(scan.LoadRgb(3).at<cv::Vec3b>(0, 0), cv::Vec3b(3, 2, 1));
  // 8-bit thermal, wrong-size thermal.
  const fs::path thermal0 = scan.FramePath(Stream::kThermal, 0);
  ASSERT_TRUE(cv::imwrite(thermal0.string(), cv::Mat(12, 16, CV_8UC1, cv::Scalar(9))));
  ExpectInputError([&] { scan.LoadThermal(0); },
                   {thermal0.string(), "16-bit unsigned (raw counts) or 32-bit float"});
  const fs::path thermal1 = scan.FramePath(Stream::kThermal, 1);
  ASSERT_TRUE(cv::imwrite(thermal1.string(), cv::Mat(24, 32, CV_16UC1, cv::Scalar(9))));
  ExpectInputError([&] { scan.LoadThermal(1); }, {thermal1.string(), "cameras.thermal"});
  // A folder where a frame should be.
  const fs::path thermal2 = scan.FramePath(Stream::kThermal, 2);
  fs::remove(thermal2);
  fs::create_directories(thermal2);
  ExpectInputError([&] { scan.LoadThermal(2); },
                   {thermal2.string(), "unusable thermal frame 2", "is a folder"});

  // CheckFrames finds exactly these, in order, on any number of threads.
  for (const int threads : {1, 3}) {
    int calls = 0;
    const std::vector<FrameProblem> problems = CheckFrames(
        scan, [&] { ++calls; }, threads);
    EXPECT_EQ(calls, 18);
    EXPECT_EQ(TotalFrames(scan), 18);
    ASSERT_EQ(problems.size(), 9u);
    const std::vector<std::pair<Stream, int>> expected = {
        {Stream::kDepth, 0},   {Stream::kDepth, 1},   {Stream::kDepth, 2},
        {Stream::kDepth, 3},   {Stream::kRgb, 0},     {Stream::kRgb, 1},
        {Stream::kThermal, 0}, {Stream::kThermal, 1}, {Stream::kThermal, 2}};
    for (size_t k = 0; k < problems.size(); ++k) {
      EXPECT_EQ(problems[k].stream, expected[k].first) << k;
      EXPECT_EQ(problems[k].index, expected[k].second) << k;
      EXPECT_EQ(problems[k].path, scan.FramePath(problems[k].stream, problems[k].index));
      EXPECT_NE(problems[k].message.find(problems[k].path.string()), std::string::npos);
    }
  }
}

// ---------------------------------------------------------------------------------------
// Summary

TEST(ScanSummary, NumbersOfASyntheticFolder) {
  const fs::path folder = hw::test::TestFolder();
  // Depth 30 Hz, 0..2 s, with frames 30..32 dropped (one gap of 4 periods = 0.1333 s).
  std::vector<double> depth;
  for (int i = 0; i < 61; ++i) {
    if (i < 30 || i > 32) depth.push_back(i / 30.0);
  }
  // Rgb 15 Hz; thermal 9 Hz, stamped 40 ms late, offset -0.040 (and 3 ms off the depth
  // grid, so that no depth frame is exactly half-way between two thermal frames).
  const std::vector<double> rgb = Times(31, 0.0, 1.0 / 15.0);
  const std::vector<double> thermal = Times(18, 0.043, 1.0 / 9.0);
  Rig rig = TestRig();
  rig.thermal_time_offset_s = -0.040;
  rig.rgb_time_offset_s = 0.002;
  WriteIndexOnlyScan(folder, rig, depth, rgb, thermal);
  WriteText(folder / "ffc.txt", "# ffc\n0.5\n1.5\n1.9\n");
  Trajectory trajectory;
  for (int i = 0; i < 11; ++i) trajectory.Add(0.2 * i, Rigid3d::Identity());
  WriteTumTrajectory(folder / "groundtruth.txt", trajectory);

  const Scan scan = Scan::Open(folder);
  const ScanSummary summary = SummarizeScan(scan);
  EXPECT_EQ(summary.folder, folder);
  EXPECT_EQ(summary.rig_path, folder / "rig.yaml");
  EXPECT_EQ(summary.depth_scale, 1000.0);
  ASSERT_EQ(summary.streams.size(), 3u);

  const StreamSummary& d = summary.streams[0];
  EXPECT_EQ(d.stream, Stream::kDepth);
  EXPECT_TRUE(d.has_index);
  EXPECT_EQ(d.frames, 58);
  EXPECT_NEAR(d.start_s, 0.0, 1e-6);
  EXPECT_NEAR(d.end_s, 2.0, 1e-6);
  EXPECT_NEAR(d.span_s, 2.0, 1e-6);
  // Timestamps carry 1e-6 s: a 33.3 ms period is known to ~3e-5 relative.
  EXPECT_NEAR(d.median_rate_hz, 30.0, 30.0 * 6e-5);
  EXPECT_EQ(d.gaps, 1);
  EXPECT_NEAR(d.largest_interval_s, 4.0 / 30.0, 2e-6);
  EXPECT_EQ(d.missing_files, 58);  // index-only scan
  EXPECT_EQ(d.time_offset_s, 0.0);

  const StreamSummary& r = summary.streams[1];
  EXPECT_EQ(r.frames, 31);
  EXPECT_NEAR(r.median_rate_hz, 15.0, 15.0 * 6e-5);
  EXPECT_NEAR(r.span_s, 2.0, 2e-6);
  EXPECT_EQ(r.gaps, 0);
  EXPECT_EQ(r.time_offset_s, 0.002);
  EXPECT_NEAR(r.max_association_dt_s, 0.5 / 15.0, 1e-6);
  // Each depth frame has an rgb frame within 33 ms (rgb at 2 ms + k/15 on the depth clock).
  EXPECT_EQ(r.associated_depth_frames, 58);

  const StreamSummary& t = summary.streams[2];
  EXPECT_EQ(t.frames, 18);
  EXPECT_NEAR(t.median_rate_hz, 9.0, 9.0 * 6e-5);
  EXPECT_NEAR(t.start_s, 0.043, 1e-6);
  EXPECT_EQ(t.time_offset_s, -0.040);
  EXPECT_NEAR(t.max_association_dt_s, 0.5 / 9.0, 1e-6);
  // On the depth clock thermal is at 0.003 + k/9, k = 0..17 (0.003..1.892 s); a depth
  // frame is paired iff one lies within 1/18 s: depth frames up to 1.947 s, i.e. d <= 58,
  // less the 3 dropped ones.
  int expected_pairs = 0;
  for (const double td : depth) {
    bool near = false;
    for (const double tt : thermal) near = near || std::abs(tt - 0.040 - td) <= 1.0 / 18.0;
    expected_pairs += near ? 1 : 0;
  }
  EXPECT_EQ(t.associated_depth_frames, expected_pairs);
  EXPECT_EQ(t.associated_depth_frames, 56);

  ASSERT_EQ(summary.cameras.size(), 3u);
  EXPECT_EQ(summary.cameras[0].name, "depth");
  EXPECT_EQ(summary.cameras[0].baseline_m, 0.0);
  EXPECT_EQ(summary.cameras[1].name, "rgb");
  EXPECT_NEAR(summary.cameras[1].baseline_m, 0.025, 1e-12);
  EXPECT_NEAR(summary.cameras[1].time_offset_s, 0.002, 1e-15);
  EXPECT_EQ(summary.cameras[2].name, "thermal");
  EXPECT_EQ(summary.cameras[2].model, "pinhole");
  EXPECT_EQ(summary.cameras[2].width, 16);
  EXPECT_EQ(summary.cameras[2].height, 12);
  EXPECT_NEAR(summary.cameras[2].baseline_m, 0.05, 1e-12);
  EXPECT_NEAR(summary.cameras[2].rotation_deg, 10.0, 1e-9);
  ASSERT_TRUE(summary.thermal_settings);
  EXPECT_EQ(summary.thermal_settings->raw_scale, 0.01);
  EXPECT_TRUE(summary.has_groundtruth);
  EXPECT_EQ(summary.groundtruth_poses, 11);
  EXPECT_NEAR(summary.groundtruth_span_s, 2.0, 1e-9);
  EXPECT_EQ(summary.ffc_events, 3);
  EXPECT_EQ(summary.warnings, scan.warnings());
  // 5 + 1 missing-file lines for each of 3 streams, 1 gap line.
  EXPECT_EQ(summary.warnings.size(), 19u);
}

TEST(ScanSummary, MedianPeriodAndGaps) {
  EXPECT_EQ(MedianPeriod({}), 0.0);
  EXPECT_EQ(MedianPeriod({1.0}), 0.0);
  EXPECT_DOUBLE_EQ(MedianPeriod({0.0, 1.0, 3.0}), 1.5);  // even count of periods: mean of 1, 2
  EXPECT_DOUBLE_EQ(MedianPeriod({0.0, 1.0, 2.0, 10.0}), 1.0);
  const GapStats gaps = FindGaps({0.0, 1.0, 2.0, 3.6, 4.6, 7.0}, 1.5);
  EXPECT_EQ(gaps.count, 2);  // 1.6 > 1.5 and 2.4 > 1.5
  EXPECT_DOUBLE_EQ(gaps.largest_s, 2.4);
  ASSERT_EQ(gaps.gaps.size(), 2u);
  EXPECT_EQ(gaps.gaps[0].first, 2.0);
  EXPECT_EQ(gaps.gaps[1].second, 7.0);
  EXPECT_EQ(FindGaps({0.0, 1.0, 2.0, 3.5}, 1.5).count, 0);  // 1.5 is not > 1.5
}

}  // namespace
}  // namespace hw::core
