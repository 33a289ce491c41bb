#include "cli/scan_info.h"

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/scan_writer.h"
#include "tests/support.h"

namespace hw::cli {
namespace {

using hw::test::Argv;

namespace fs = std::filesystem;

struct Result {
  int code;
  std::string out;
  std::string err;
};

Result RunCli(std::vector<std::string> args) {
  args.insert(args.begin(), "heatwave scan-info");
  Argv argv(args);
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  const int code = RunScanInfo(argv.argc(), argv.argv());
  Result result{code, testing::internal::GetCapturedStdout(),
                testing::internal::GetCapturedStderr()};
  return result;
}

// 10 depth frames at 30 Hz, 4 thermal frames at 9 Hz stamped 40 ms late (alternately raw
// counts and float TIFF), 2 ffc events, ground truth.
fs::path WriteValidScan(const fs::path& folder) {
  core::Rig rig;
  rig.depth_scale = 1000.0;
  rig.depth = core::CameraModel::Pinhole(32, 24, 30.0, 30.0);
  rig.thermal = core::CameraModel::Pinhole(16, 12, 15.0, 15.0);
  rig.depth_from_thermal =
      core::Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0.0, 0.0));
  rig.thermal_settings = core::ThermalSettings{};
  rig.thermal_time_offset_s = -0.04;
  core::ScanWriter writer(folder, rig);
  core::Trajectory trajectory;
  for (int i = 0; i < 10; ++i) {
    writer.AddDepth(i / 30.0, cv::Mat(24, 32, CV_32FC1, cv::Scalar(1.5f)));
    trajectory.Add(i / 30.0, core::Rigid3d::Identity());
  }
  for (int i = 0; i < 4; ++i) {
    writer.AddThermal(
        0.043 + i / 9.0, cv::Mat(12, 16, CV_32FC1, cv::Scalar(35.0f)),
        i % 2 == 0 ? core::ThermalEncoding::kRawCounts16 : core::ThermalEncoding::kFloatTiff);
  }
  writer.AddFfcEvent(0.1);
  writer.AddFfcEvent(0.2);
  writer.SetGroundTruth(trajectory);
  writer.Finish();
  return folder;
}

// Runs a strict RFC 8259 parser (Python's json, on text decoded as strict UTF-8) on `json`;
// "" when it parses, else the parser's complaint.
std::string StrictJsonProblem(const std::string& json) {
  const fs::path file = hw::test::TestFolder("json") / "report.json";
  core::WriteFileAtomically(file, json);
  const hw::test::CommandResult r = hw::test::RunCommand(
      "python3 -c 'import json,sys; json.loads(sys.stdin.buffer.read().decode(\"utf-8\"))' < '" +
      file.string() + "'");
  return r.exit_code == 0 ? "" : r.output + " (exit " + std::to_string(r.exit_code) + ")";
}

TEST(ScanInfo, ValidScanExitsZeroWithASummary) {
  const fs::path scan = WriteValidScan(hw::test::FreshPath());
  const Result r = RunCli({scan.string()});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("OK: valid scan\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("depth        10"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("thermal       4"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no rgb.txt"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Ground truth  10 poses"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("FFC events    2"), std::string::npos) << r.out;
  // The frame clocks reconstruct reads the streams at: 10 depth frames fit one, 4 thermal
  // frames are too few.
  EXPECT_NE(r.out.find("Clock    depth "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("exposure times fitted"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Clock    thermal: stamps used as they are (4 frames, fewer than 10)"), std::string::npos)
      << r.out;
  // One screen: the report fits in 100 columns (lines naming the scan's paths aside) and
  // 40 lines.
  int lines = 0;
  size_t begin = 0;
  for (size_t end; (end = r.out.find('\n', begin)) != std::string::npos; begin = end + 1) {
    ++lines;
    const std::string line = r.out.substr(begin, end - begin);
    if (line.find(scan.string()) != std::string::npos) continue;
    // Columns: UTF-8 code points, i.e. bytes other than continuation bytes 10xxxxxx.
    const auto columns = std::count_if(line.begin(), line.end(), [](char c) {
      return (static_cast<unsigned char>(c) & 0xC0) != 0x80;
    });
    EXPECT_LE(columns, 100) << line;
  }
  EXPECT_GE(lines, 15);
  EXPECT_LE(lines, 40);

  const Result quiet = RunCli({scan.string(), "--quiet"});
  EXPECT_EQ(quiet.code, kExitOk);
  EXPECT_EQ(quiet.out, "");
  EXPECT_EQ(quiet.err, "");
}

TEST(ScanInfo, WarningsAreAllowed) {
  const fs::path scan = WriteValidScan(hw::test::FreshPath());
  fs::remove(scan / "depth" / "0.100000.png");
  const Result r = RunCli({scan.string()});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  EXPECT_NE(r.out.find("Warnings (1):"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("missing file"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("OK: valid scan, 1 warning(s)"), std::string::npos) << r.out;
}

TEST(ScanInfo, InvalidScanExitsOneWithOneLine) {
  const fs::path folder = hw::test::FreshPath();
  const fs::path scan = WriteValidScan(folder);
  fs::remove(scan / "depth.txt");
  Result r = RunCli({scan.string()});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "error: " + (scan / "depth.txt").string() +
                       ": no such file; every scan needs a depth stream index\n");

  r = RunCli({(folder / "nope").string()});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.err.find("no such scan folder"), std::string::npos) << r.err;

  core::WriteFileAtomically(scan / "depth.txt", "0.0 depth/0.000000.png\nzzz\n");
  r = RunCli({scan.string()});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.err.find("depth.txt: line 2: "), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
}

TEST(ScanInfo, ExternalRigForATumFolder) {
  const fs::path folder = hw::test::FreshPath();
  const fs::path scan = WriteValidScan(folder / "scan");
  fs::rename(scan / "rig.yaml", folder / "rig.yaml");
  EXPECT_EQ(RunCli({scan.string()}).code, kExitFailure);
  const Result r = RunCli({scan.string(), "--rig", (folder / "rig.yaml").string()});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  EXPECT_NE(r.out.find("Rig      " + (folder / "rig.yaml").string()), std::string::npos) << r.out;
}

TEST(ScanInfo, BadUsageExitsTwo) {
  const fs::path scan = WriteValidScan(hw::test::FreshPath());
  EXPECT_EQ(RunCli({}).code, kExitUsage);                                  // no SCAN
  EXPECT_EQ(RunCli({scan.string(), "extra"}).code, kExitUsage);            // two folders
  EXPECT_EQ(RunCli({scan.string(), "--max-dt", "abc"}).code, kExitUsage);  // not a number
  Result r = RunCli({scan.string(), "--max-dt", "-0.1"});
  EXPECT_EQ(r.code, kExitUsage);
  EXPECT_EQ(r.err, "error: max_association_dt_s (--max-dt): must be > 0, got -0.100000\n");
  EXPECT_EQ(RunCli({scan.string(), "--gap-factor", "1"}).code, kExitUsage);
  EXPECT_EQ(RunCli({scan.string(), "--threads", "-2"}).code, kExitUsage);
  r = RunCli({"--help"});
  EXPECT_EQ(r.code, kExitOk);
  EXPECT_NE(r.out.find("--check-frames"), std::string::npos);
  EXPECT_EQ(RunCli({scan.string(), "--max-dt", "0.01"}).code, kExitOk);
}

TEST(ScanInfo, CheckFramesReportsUnloadableFrames) {
  const fs::path scan = WriteValidScan(hw::test::FreshPath());
  Result r = RunCli({scan.string(), "--check-frames", "--quiet"});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  EXPECT_EQ(r.err, "");  // quiet: no progress bar
  r = RunCli({scan.string(), "--check-frames"});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  EXPECT_NE(r.out.find("all 14 frames load"), std::string::npos) << r.out;

  core::WriteFileAtomically(scan / "thermal" / "0.154111.tiff", "garbage");
  core::WriteFileAtomically(scan / "depth" / "0.200000.png", "garbage");
  r = RunCli({scan.string(), "--check-frames", "--threads", "2"});
  EXPECT_EQ(r.code, kExitFailure);
  EXPECT_NE(r.out.find("2 of 14 frames cannot be loaded"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find((scan / "thermal" / "0.154111.tiff").string()), std::string::npos);
  EXPECT_NE(r.err.find("error: 2 of 14 frames cannot be loaded; first: " +
                       (scan / "depth" / "0.200000.png").string()),
            std::string::npos)
      << r.err;
  // Without --check-frames the scan is valid: frames are only decoded when asked.
  EXPECT_EQ(RunCli({scan.string(), "--quiet"}).code, kExitOk);
}

TEST(ScanInfo, JsonReport) {
  const fs::path scan = WriteValidScan(hw::test::FreshPath());
  const Result r = RunCli({scan.string(), "--json", "--quiet"});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  for (const std::string& part :
       {std::string("\"valid\": true"), std::string("\"name\": \"depth\""),
        std::string("\"frames\": 10"), std::string("\"frames\": 4"),
        std::string("\"ffc_events\": 2"), std::string("\"groundtruth_poses\": 10"),
        std::string("\"time_offset_s\": -0.04"), std::string("\"warnings\": []"),
        std::string("\"baseline_m\": 0.03")}) {
    EXPECT_NE(r.out.find(part), std::string::npos) << part << " not in\n" << r.out;
  }
  // Balanced braces and brackets, the cheapest check that it parses.
  int depth = 0;
  for (const char c : r.out) {
    if (c == '{' || c == '[') ++depth;
    if (c == '}' || c == ']') --depth;
    ASSERT_GE(depth, 0);
  }
  EXPECT_EQ(depth, 0);
  EXPECT_EQ(StrictJsonProblem(r.out), "") << r.out;
}

TEST(ScanInfo, JsonIsValidUtf8ForAnyPathBytes) {
  // Linux paths are bytes: a folder name that is not UTF-8 and one with a control
  // character must still give JSON a strict parser accepts.
  // Written under a plain name and renamed: ScanWriter puts the folder name in the index
  // files' header comment, where a '\n' would break the scan itself.
  const fs::path scan = hw::test::FreshPath("bad\xff\xfe name\x01\n");
  fs::rename(WriteValidScan(hw::test::FreshPath("plain")), scan);
  fs::remove(scan / "depth" / "0.100000.png");  // a warning naming a path
  core::WriteFileAtomically(scan / "depth" / "0.200000.png", "garbage");  // a frame problem
  const Result r = RunCli({scan.string(), "--json", "--quiet", "--check-frames"});
  EXPECT_EQ(r.code, kExitFailure) << r.err;
  EXPECT_EQ(StrictJsonProblem(r.out), "") << r.out;
  // Each invalid byte is U+FFFD; control characters are \u escapes.
  EXPECT_NE(r.out.find("bad\xEF\xBF\xBD\xEF\xBF\xBD name\\u0001\\u000a"), std::string::npos)
      << r.out;
  // The one-line error on stderr stays one line despite the '\n' in the path.
  EXPECT_EQ(hw::test::CountLines(r.err), 1) << r.err;
}

TEST(ScanInfo, InspectScanTypedApi) {
  const fs::path scan = WriteValidScan(hw::test::FreshPath());
  ScanInfoOptions options;
  EXPECT_NE(options.Check(), "");  // no folder
  options.scan_folder = scan;
  options.quiet = true;
  options.check_frames = true;
  ASSERT_EQ(options.Check(), "");
  const ScanInfoReport report = InspectScan(options);
  EXPECT_TRUE(report.frames_checked);
  EXPECT_EQ(report.total_frames, 14);
  EXPECT_TRUE(report.frame_problems.empty());
  EXPECT_EQ(report.summary.streams[0].frames, 10);
  EXPECT_EQ(report.summary.streams[2].frames, 4);
  // Thermal at 9 Hz on the depth clock 0.003, 0.114, 0.225, 0.336: every depth frame
  // (0..0.3 s) lies within 1/18 s of one (3 ms at least from the threshold).
  EXPECT_EQ(report.summary.streams[2].associated_depth_frames, 10);
  EXPECT_NE(
      FormatScanInfo(report).find("10 of 10 depth frames have a thermal frame within 0.0556 s"),
      std::string::npos);
}

}  // namespace
}  // namespace hw::cli
