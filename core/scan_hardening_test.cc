// Hostile and broken scan folders: special files, decompression bombs, paths leaving the
// folder, foreign line endings, incomplete writes, unreadable folders, non-finite pixels.
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/output_folder.h"
#include "core/scan.h"
#include "core/scan_writer.h"
#include "core/png_test_support.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

Rig SmallRig() {
  Rig rig;
  rig.depth_scale = 1000.0;
  rig.depth = CameraModel::Pinhole(32, 24, 30.0, 30.0);
  rig.rgb = CameraModel::Pinhole(32, 24, 31.0, 31.0);
  rig.thermal = CameraModel::Pinhole(16, 12, 15.0, 15.0);
  rig.depth_from_thermal = Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0, 0));
  rig.thermal_settings = ThermalSettings{};
  return rig;
}

// A real scan: 4 frames per stream at 10 Hz, raw thermal, a ground-truth trajectory.
fs::path WriteSmallScan(const std::string& name = "scan") {
  const fs::path folder = hw::test::TestFolder(name);
  ScanWriter writer(folder, SmallRig());
  Trajectory truth;
  for (int i = 0; i < 4; ++i) {
    const double t = 0.1 * i;
    writer.AddDepth(t, cv::Mat(24, 32, CV_32FC1, cv::Scalar(1.5)));
    writer.AddRgb(t, cv::Mat(24, 32, CV_8UC3, cv::Scalar(10, 20, 30)));
    writer.AddThermal(t, cv::Mat(12, 16, CV_32FC1, cv::Scalar(21.0)));
    truth.Add(t, Rigid3d::Identity());
  }
  writer.AddFfcEvent(0.15);
  writer.SetGroundTruth(truth);
  writer.Finish();
  return folder;
}

// Runs f in a child process (it may hang); returns "" when f threw an InputError
// containing every part, else what happened.
std::string InputErrorInChild(const std::function<void()>& f,
                              std::initializer_list<std::string> parts) {
  const fs::path report = hw::test::FreshPath("child-report.txt");
  const int code = hw::test::RunInChild(
      [&] {
        std::string what;
        try {
          f();
          what = "no error";
        } catch (const InputError& e) {
          what = e.what();
        }
        WriteFileAtomically(report, what);
        return 0;
      },
      10);
  if (code == hw::test::kTimedOut) return "hung (killed after 10 s)";
  if (code != 0) return "child exited with " + std::to_string(code);
  const std::string what = ReadFile(report, kMaxConfigFileBytes);
  fs::remove(report);
  if (what.find('\n') != std::string::npos) return "not one line: " + what;
  for (const std::string& part : parts) {
    if (what.find(part) == std::string::npos) return "'" + part + "' not in: " + what;
  }
  return "";
}

TEST(ScanHardening, SpecialFilesAreRefusedWithoutHanging) {
  for (const std::string file : {"rig.yaml", "depth.txt", "rgb.txt", "thermal.txt", "ffc.txt",
                                 "groundtruth.txt"}) {
    const fs::path folder = WriteSmallScan("fifo-" + file);
    fs::remove(folder / file);
    ASSERT_EQ(::mkfifo((folder / file).c_str(), 0644), 0);
    EXPECT_EQ(InputErrorInChild([&] { Scan::Open(folder); }, {file, "is a FIFO"}), "") << file;
  }
  // --rig naming a FIFO.
  const fs::path folder = WriteSmallScan("fifo-rig-option");
  ASSERT_EQ(::mkfifo((folder / "other-rig.yaml").c_str(), 0644), 0);
  ScanOptions options;
  options.rig_path = folder / "other-rig.yaml";
  EXPECT_EQ(InputErrorInChild([&] { Scan::Open(folder, options); }, {"is a FIFO"}), "");
}

TEST(ScanHardening, DanglingLinksAndLoopsAreErrorsNotAbsentFiles) {
  for (const std::string file : {"rgb.txt", "ffc.txt", "groundtruth.txt", "thermal.txt"}) {
    const fs::path folder = WriteSmallScan("dangling-" + file);
    fs::remove(folder / file);
    fs::create_symlink("nowhere.txt", folder / file);
    EXPECT_EQ(InputErrorInChild([&] { Scan::Open(folder); },
                                {file, "dangling symbolic link", "nowhere.txt"}),
              "")
        << file;
  }
  const fs::path folder = WriteSmallScan("loop");
  fs::remove(folder / "groundtruth.txt");
  fs::create_symlink("groundtruth.txt", folder / "groundtruth.txt");
  EXPECT_EQ(InputErrorInChild([&] { Scan::Open(folder); }, {"symbolic link loop"}), "");
}

TEST(ScanHardening, SpecialFramesAreNamedNotCalledMissing) {
  const fs::path folder = WriteSmallScan();
  const auto frame = [&](const char* stream, int i) {
    return folder / (std::string(stream) + "/" + ScanWriter::FrameFileName(0.1 * i, ".png"));
  };
  fs::remove(frame("depth", 0));
  ASSERT_EQ(::mkfifo(frame("depth", 0).c_str(), 0644), 0);
  fs::remove(frame("depth", 1));
  fs::create_symlink("/dev/zero", frame("depth", 1));
  fs::remove(frame("depth", 2));
  fs::create_symlink(frame("depth", 2).filename(), frame("depth", 2));
  const Scan scan = Scan::Open(folder);
  ASSERT_GE(scan.warnings().size(), 3u);
  EXPECT_THAT(scan.warnings()[0], HasSubstr("is a FIFO"));
  EXPECT_THAT(scan.warnings()[1], HasSubstr("is a character device"));
  EXPECT_THAT(scan.warnings()[2], HasSubstr("symbolic link loop"));
  EXPECT_FALSE(scan.FrameExists(Stream::kDepth, 0));
  EXPECT_EQ(InputErrorInChild([&] { scan.LoadDepth(0); }, {"depth frame 0", "is a FIFO"}), "");
  EXPECT_EQ(InputErrorInChild([&] { scan.LoadDepth(1); }, {"character device"}), "");
  EXPECT_EQ(InputErrorInChild([&] { scan.LoadDepth(2); }, {"symbolic link loop"}), "");
  const std::vector<FrameProblem> problems = CheckFrames(scan);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_THAT(problems[0].message, Not(HasSubstr("missing")));
}

TEST(ScanHardening, OversizedFramesAreRefusedOnTheirHeader) {
  const fs::path folder = WriteSmallScan();
  const Scan scan = Scan::Open(folder);
  WriteFileAtomically(scan.FramePath(Stream::kDepth, 0), hw::test::PngClaiming(30000, 30000, 2));
  WriteFileAtomically(scan.FramePath(Stream::kThermal, 0), hw::test::PngClaiming(30000, 30000, 2));
  const auto start = std::chrono::steady_clock::now();
  for (int repeat = 0; repeat < 4; ++repeat) {
    try {
      scan.LoadDepth(0);
      FAIL() << "loaded a bomb";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("image is 30000x30000, cameras.depth in the rig is 32x24"));
    }
    EXPECT_THROW(scan.LoadThermal(0), InputError);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 1.0);  // decoding each would take ~20 s and 1.8 GB
}

// A sparse 3 GB depth.txt used to be read whole (3.2 GB of memory); it is refused on its size.
TEST(ScanHardening, HugeIndexFilesAreRefusedBeforeReading) {
  const fs::path folder = WriteSmallScan();
  for (const std::string file : {"depth.txt", "groundtruth.txt"}) {
    const uint64_t original = fs::file_size(folder / file);
    fs::resize_file(folder / file, uint64_t{3} << 30);
    const auto start = std::chrono::steady_clock::now();
    try {
      Scan::Open(folder);
      FAIL() << file << " accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(file));
      EXPECT_THAT(e.what(), HasSubstr("more than the 256 MiB"));
    }
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
    fs::resize_file(folder / file, original);
  }
}

TEST(ScanHardening, IndexPathsStayInsideTheScanFolder) {
  const std::string good = "1.0 depth/1.png\n2.0 ./depth/../depth/2.png\n";
  EXPECT_EQ(ParseStreamIndex(good, "depth.txt").size(), 2u);
  for (const std::string bad : {"../outside/f.png", "../../../../etc/passwd", "depth/../../x.png",
                                "a/b/../../../c.png", "depth/..", "."}) {
    try {
      ParseStreamIndex("1.0 " + bad + "\n", "depth.txt");
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("line 1"));
      EXPECT_THAT(e.what(), HasSubstr("inside the scan folder")) << bad;
    }
  }
}

// The same scan with its text files rewritten: BOM, CRLF, CR only.
TEST(ScanHardening, BomAndEveryLineEndingReadTheSame) {
  const fs::path reference_folder = WriteSmallScan("reference");
  const Scan reference = Scan::Open(reference_folder);
  const std::vector<std::pair<std::string, std::string>> variants = {
      {"bom", "\xEF\xBB\xBF"}, {"crlf", ""}, {"cr", ""}, {"bom-cr", "\xEF\xBB\xBF"}};
  for (const auto& [name, prefix] : variants) {
    const fs::path folder = WriteSmallScan(name);
    for (const std::string file : {"depth.txt", "rgb.txt", "thermal.txt", "ffc.txt",
                                   "groundtruth.txt"}) {
      std::string text = ReadFile(folder / file, kMaxIndexFileBytes);
      std::string converted;
      for (const char c : text) {
        if (c != '\n') {
          converted += c;
        } else {
          converted += name.find("crlf") != std::string::npos ? "\r\n"
                       : name.find("cr") != std::string::npos ? "\r"
                                                              : "\n";
        }
      }
      WriteFileAtomically(folder / file, prefix + converted);
    }
    const Scan scan = Scan::Open(folder);
    EXPECT_TRUE(scan.warnings().empty()) << name << ": " << scan.warnings().front();
    for (const Stream stream : kAllStreams) {
      EXPECT_EQ(scan.Timestamps(stream), reference.Timestamps(stream)) << name;
      ASSERT_EQ(scan.NumFrames(stream), 4) << name;
      EXPECT_EQ(scan.Entries(stream)[2].line, reference.Entries(stream)[2].line) << name;
    }
    EXPECT_EQ(scan.ffc_timestamps_s(), reference.ffc_timestamps_s()) << name;
    ASSERT_TRUE(scan.groundtruth());
    EXPECT_EQ(scan.groundtruth()->size(), 4u) << name;
    EXPECT_NO_THROW(scan.LoadDepth(3));
  }
  // Line numbers in messages count CR-only lines as an editor does.
  try {
    ParseStreamIndex("\xEF\xBB\xBF# header\r1.0 a.png\r2.0\r", "depth.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("line 3"));
  }
}

TEST(ScanHardening, PresentButEmptyStreamsAndTrajectoriesWarn) {
  const fs::path folder = WriteSmallScan();
  WriteFileAtomically(folder / "rgb.txt", "# color images\n# nothing yet\n");
  WriteFileAtomically(folder / "groundtruth.txt", "# timestamp tx ty tz qx qy qz qw\n");
  const Scan scan = Scan::Open(folder);
  ASSERT_EQ(scan.warnings().size(), 2u);
  EXPECT_THAT(scan.warnings()[0], HasSubstr("rgb.txt lists no frames"));
  EXPECT_THAT(scan.warnings()[1], HasSubstr("groundtruth.txt holds no poses"));
}

TEST(ScanHardening, IncompleteAndBusyFoldersAreRefused) {
  const fs::path folder = WriteSmallScan();
  {
    OutputFolder run(folder, "heatwave synth");
    try {
      Scan::Open(folder);
      FAIL() << "opened a folder being written";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("being written by another heatwave run"));
      EXPECT_THAT(e.what(), HasSubstr("heatwave synth"));
    }
  }  // the run ends without Commit
  try {
    Scan::Open(folder);
    FAIL() << "opened an incomplete folder";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("incomplete scan"));
  }
  OutputFolder(folder, "heatwave synth").Commit();
  EXPECT_NO_THROW(Scan::Open(folder));
}

TEST(ScanHardening, UnreadableFolderIsPermissionDeniedNotMissing) {
  const fs::path folder = WriteSmallScan();
  fs::permissions(folder, fs::perms::owner_all);  // 0700, owned by us
  // Root reads everything: check as an unprivileged user when we are root.
  const int code = hw::test::RunInChild([&] {
    if (::geteuid() == 0) {
      fs::permissions(folder, fs::perms::none);
      if (::setgid(65534) != 0 || ::setuid(65534) != 0) return 10;
    } else {
      fs::permissions(folder, fs::perms::none);
    }
    try {
      Scan::Open(folder);
      return 11;
    } catch (const InputError& e) {
      const std::string what = e.what();
      if (what.find("permission denied") == std::string::npos) return 12;
      if (what.find("no such") != std::string::npos) return 13;
      return 0;
    }
  });
  fs::permissions(folder, fs::perms::owner_all);
  EXPECT_EQ(code, 0);
}

TEST(ScanHardening, NonFiniteThermalPixelsAreFrameProblems) {
  const fs::path folder = WriteSmallScan();
  const Scan scan = Scan::Open(folder);
  cv::Mat apparent_c(12, 16, CV_32FC1, cv::Scalar(20.0));
  apparent_c.at<float>(3, 4) = std::numeric_limits<float>::quiet_NaN();
  apparent_c.at<float>(5, 6) = std::numeric_limits<float>::infinity();
  const fs::path tiff = folder / "thermal" / "nan.tiff";
  WriteImageAtomically(tiff, apparent_c);
  WriteFileAtomically(folder / "thermal.txt",
                      "0.0 thermal/nan.tiff\n0.1 " +
                          scan.Entries(Stream::kThermal)[1].path + "\n");
  const Scan reopened = Scan::Open(folder);
  try {
    reopened.LoadThermal(0);
    FAIL() << "NaN thermal frame loaded";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("2 of 192 pixels are not finite"));
  }
  const std::vector<FrameProblem> problems = CheckFrames(reopened);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_EQ(problems[0].stream, Stream::kThermal);
}

}  // namespace
}  // namespace hw::core
