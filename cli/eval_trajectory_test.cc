#include "cli/eval_trajectory.h"

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/trajectory.h"
#include "tests/support.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using hw::test::Argv;
using hw::test::CountLines;

struct Result {
  int code;
  std::string out;
  std::string err;
};

Result RunCli(std::vector<std::string> args) {
  args.insert(args.begin(), "heatwave eval-trajectory");
  Argv argv(args);
  testing::internal::CaptureStdout();
  testing::internal::CaptureStderr();
  const int code = RunEvalTrajectory(argv.argc(), argv.argv());
  Result result{code, testing::internal::GetCapturedStdout(),
                testing::internal::GetCapturedStderr()};
  return result;
}

// A loop at 30 Hz over 3 s as TUM text; `time_offset_s` shifts its clock.
fs::path WriteLoop(const fs::path& path, double time_offset_s) {
  core::Trajectory trajectory;
  for (int k = 0; k < 91; ++k) {
    const double t = k / 30.0;
    trajectory.Add(
        100.0 + t + time_offset_s,
        core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.8 * t, Eigen::Vector3d::UnitY())),
                      Eigen::Vector3d(0.5 * std::cos(0.8 * t), 0.3 * std::sin(0.8 * t), 0.1 * t)));
  }
  core::WriteTumTrajectory(path, trajectory);
  return path;
}

TEST(EvalTrajectoryCommand, SameTrajectoryIsZeroError) {
  const fs::path folder = hw::test::TestFolder();
  const fs::path gt = WriteLoop(folder / "gt.txt", 0.0);
  const fs::path est = WriteLoop(folder / "est.txt", 0.005);
  const Result r = RunCli({est.string(), gt.string()});
  EXPECT_EQ(r.code, kExitOk) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_NE(r.out.find("Associated    91 pairs, |dt| <= 0.02 s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ATE (mm)      rmse 0.000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("RPE over 1 s  61 pose pairs"), std::string::npos) << r.out;
  // --quiet: no report; --json --quiet: the JSON only.
  const Result quiet = RunCli({est.string(), gt.string(), "--quiet"});
  EXPECT_EQ(quiet.code, kExitOk);
  EXPECT_EQ(quiet.out + quiet.err, "");
  const Result json = RunCli({est.string(), gt.string(), "--quiet", "--json"});
  EXPECT_EQ(json.code, kExitOk);
  EXPECT_EQ(json.out.rfind("{\n", 0), 0u) << json.out;
  EXPECT_NE(json.out.find("\"associated_pairs\": 91,"), std::string::npos) << json.out;
  // A shorter RPE interval: poses 0..87 have a partner 3 frames later.
  const Result rpe = RunCli({est.string(), gt.string(), "--rpe-delta", "0.1"});
  EXPECT_NE(rpe.out.find("RPE over 0.1 s 88 pose pairs"), std::string::npos) << rpe.out;
}

TEST(EvalTrajectoryCommand, BadOptionsAreExitCode2WithOneLine) {
  const fs::path gt = WriteLoop(hw::test::TestFolder() / "gt.txt", 0.0);
  EXPECT_EQ(RunCli({"--help"}).code, kExitOk);
  EXPECT_EQ(RunCli({}).code, kExitUsage);
  EXPECT_EQ(RunCli({gt.string()}).code, kExitUsage);
  EXPECT_EQ(RunCli({gt.string(), gt.string(), "--bogus"}).code, kExitUsage);
  EXPECT_EQ(RunCli({gt.string(), gt.string(), "--max-dt", "abc"}).code, kExitUsage);
  EXPECT_EQ(RunCli({gt.string(), gt.string(), "a", "b"}).code, kExitUsage);
  for (const std::vector<std::string>& bad : {std::vector<std::string>{"--max-dt", "0"},
                                              {"--max-dt", "-1"},
                                              {"--max-dt", "nan"},
                                              {"--max-dt", "inf"},
                                              {"--rpe-delta", "0"},
                                              {"--rpe-delta", "-2"}}) {
    const Result r = RunCli({gt.string(), gt.string(), bad[0], bad[1]});
    EXPECT_EQ(r.code, kExitUsage) << bad[0] << " " << bad[1] << ": " << r.err;
    EXPECT_EQ(CountLines(r.err), 1) << r.err;
    EXPECT_EQ(r.err.rfind("error: " + bad[0] + ": must be > 0 s, got ", 0), 0u) << r.err;
    EXPECT_EQ(r.out, "");
  }
}

TEST(EvalTrajectoryCommand, BadInputIsExitCode1WithOneLine) {
  const fs::path folder = hw::test::TestFolder();
  const fs::path gt = WriteLoop(folder / "gt.txt", 0.0);
  const auto expect_failure = [&](const fs::path& est, const fs::path& truth,
                                  const std::string& needle, const std::string& max_dt = "0.02") {
    const Result r = RunCli({est.string(), truth.string(), "--max-dt", max_dt});
    EXPECT_EQ(r.code, kExitFailure) << r.err;
    EXPECT_EQ(CountLines(r.err), 1) << r.err;
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "");
  };
  expect_failure(folder / "missing.txt", gt, (folder / "missing.txt").string() + ": ");
  expect_failure(gt, folder / "missing.txt", (folder / "missing.txt").string() + ": ");
  expect_failure(folder, gt, folder.string());
  core::WriteFileAtomically(folder / "short_line.txt", "0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n");
  expect_failure(folder / "short_line.txt", gt, "short_line.txt: line 2: expected 8 numbers");
  core::WriteFileAtomically(folder / "bad_quaternion.txt", "0 0 0 0 0 0 0 2\n");
  expect_failure(folder / "bad_quaternion.txt", gt, "bad_quaternion.txt: line 1: quaternion");
  core::WriteFileAtomically(folder / "empty.txt", "# no poses\n");
  expect_failure(folder / "empty.txt", gt, "estimated: no poses");
  // 5 ms apart on the clock, 1 ms allowed: nothing pairs. The files are named.
  const fs::path late = WriteLoop(folder / "late.txt", 0.005);
  expect_failure(late, gt, late.string() + " against " + gt.string() + ": only 0 pose pair(s)",
                 "0.001");
  core::WriteFileAtomically(folder / "line.txt",
                            "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n3 3 0 0 0 0 0 1\n");
  expect_failure(folder / "line.txt", folder / "line.txt", "collinear");
}

}  // namespace
}  // namespace hw::cli
