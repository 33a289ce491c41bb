// End-to-end tests of `heatwave eval-trajectory`: exit codes, the report (text and JSON) on
// trajectories with known errors, one-line errors on bad files and options.
#include <cmath>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/trajectory.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::CountLines;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) {
  return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args);
}

std::string Quote(const fs::path& path) { return "'" + path.string() + "'"; }

// A true trajectory (a loop at 30 Hz for 3 s) and the estimate: the same poses in another
// world frame, every position off by +2 mm along the world x axis for even frames and -2 mm
// for odd ones, timestamps 5 ms late. Aligned by the true transform every ATE residual is
// exactly 2 mm; the best fit can only do better, and does so barely: a rigid motion varies
// smoothly along the trajectory, the offsets alternate frame to frame (measured: 1.9998 mm).
// The RPE is exactly 0: poses 30 frames apart have the same offset.
struct Files {
  fs::path estimated, groundtruth;
};
Files WriteTrajectories(const fs::path& folder) {
  hw::core::Trajectory groundtruth, estimated;
  const hw::core::Rigid3d estimate_from_world(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized())),
      Eigen::Vector3d(0.5, -2.0, 1.0));
  for (int k = 0; k < 91; ++k) {
    const double t = k / 30.0;
    const hw::core::Rigid3d pose(
        Eigen::Quaterniond(Eigen::AngleAxisd(0.8 * t, Eigen::Vector3d::UnitY())),
        Eigen::Vector3d(0.5 * std::cos(0.8 * t), 0.3 * std::sin(0.8 * t), 0.1 * t));
    groundtruth.Add(1305031102.0 + t, pose);
    hw::core::Rigid3d off = pose;
    off.translation.x() += (k % 2 == 0 ? 0.002 : -0.002);
    estimated.Add(1305031102.005 + t, estimate_from_world * off);
  }
  Files files{folder / "estimated.txt", folder / "groundtruth.txt"};
  hw::core::WriteTumTrajectory(files.estimated, estimated);
  hw::core::WriteTumTrajectory(files.groundtruth, groundtruth);
  return files;
}

TEST(EvalTrajectoryCli, TextReportOfAKnownError) {
  const Files f = WriteTrajectories(hw::test::TestFolder());
  const Result r = Heatwave("eval-trajectory " + Quote(f.estimated) + " " + Quote(f.groundtruth));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Associated    91 pairs"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ATE (mm)      rmse 2.000  mean 2.000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("RPE over 1 s  61 pose pairs"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("  trans (mm)  rmse 0.000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("groundtruth_from_estimate"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Ground truth  " + f.groundtruth.string() + "  (91 poses)"),
            std::string::npos)
      << r.output;
  // One screen: at most 20 lines, 100 columns (lines naming the files aside).
  EXPECT_LE(CountLines(r.output), 20);
  size_t begin = 0;
  for (size_t end; (end = r.output.find('\n', begin)) != std::string::npos; begin = end + 1) {
    const std::string line = r.output.substr(begin, end - begin);
    if (line.find(f.estimated.string()) == std::string::npos &&
        line.find(f.groundtruth.string()) == std::string::npos) {
      EXPECT_LE(line.size(), 100u) << line;
    }
  }
  // --quiet: nothing on stdout or stderr, still success.
  const Result quiet =
      Heatwave("eval-trajectory " + Quote(f.estimated) + " " + Quote(f.groundtruth) + " -q");
  EXPECT_EQ(quiet.exit_code, 0);
  EXPECT_EQ(quiet.output, "");
}

TEST(EvalTrajectoryCli, JsonParsesAndHoldsTheFigures) {
  const fs::path folder = hw::test::TestFolder();
  const Files f = WriteTrajectories(folder);
  const fs::path json = folder / "report.json";
  const Result run = Heatwave("eval-trajectory " + Quote(f.estimated) + " " + Quote(f.groundtruth) +
                              " --json >" + Quote(json));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(run.output, "");  // stderr: nothing
  // Python's strict parser (RFC 8259, strict UTF-8) reads stdout as it is: nothing but JSON.
  const Result parsed = hw::test::RunCommand(
      "python3 -c 'import json, math, sys\n"
      "d = json.loads(open(sys.argv[1], \"rb\").read().decode(\"utf-8\"))\n"
      "t = d[\"groundtruth_from_estimate\"]\n"
      "print(sorted(d))\n"
      "print(sorted(d[\"ate_m\"]), d[\"ate_m\"][\"count\"], 0.00199 < d[\"ate_m\"][\"rmse\"] <= "
      "0.002)\n"
      "print(d[\"rpe_m\"][\"count\"], d[\"rpe_m\"][\"max\"] < 1e-9, d[\"rpe_deg\"][\"count\"])\n"
      "print(len(t[\"translation_m\"]), len(t[\"rotation_xyzw\"]),\n"
      "      abs(t[\"rotation_deg\"] - math.degrees(0.7)) < 0.01)\n"
      "print(d[\"estimated\"] == sys.argv[2], d[\"associated_pairs\"], d[\"rpe_delta_s\"])' " +
      Quote(json) + " " + Quote(f.estimated));
  EXPECT_EQ(parsed.exit_code, 0) << parsed.output;
  EXPECT_EQ(parsed.output,
            "['associated_pairs', 'ate_m', 'estimated', 'estimated_poses', 'groundtruth', "
            "'groundtruth_from_estimate', 'groundtruth_poses', 'max_time_difference_s', "
            "'rpe_deg', 'rpe_delta_s', 'rpe_m']\n"
            "['count', 'max', 'mean', 'median', 'min', 'rmse', 'std'] 91 True\n"
            "61 True 61\n"
            "3 4 True\n"
            "True 91 1\n");
}

TEST(EvalTrajectoryCli, ErrorsAreOneLineWithTheirExitCode) {
  // The in-process tests (cli/eval_trajectory_test.cc) go through the cases; here the
  // executable's exit codes and stderr for one of each kind.
  const fs::path folder = hw::test::TestFolder();
  const Files f = WriteTrajectories(folder);
  const fs::path missing = folder / "missing.txt";
  Result r = Heatwave("eval-trajectory " + Quote(f.estimated) + " " + Quote(missing));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_EQ(r.output.rfind("error: " + missing.string() + ": ", 0), 0u) << r.output;
  const fs::path malformed = folder / "malformed.txt";
  hw::core::WriteFileAtomically(malformed,
                                "# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n");
  r = Heatwave("eval-trajectory " + Quote(malformed) + " " + Quote(f.groundtruth));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find(malformed.string() + ": line 3"), std::string::npos) << r.output;
}

TEST(EvalTrajectoryCli, TooFewPairsAndBadOptions) {
  const Files f = WriteTrajectories(hw::test::TestFolder());
  const std::string files = Quote(f.estimated) + " " + Quote(f.groundtruth);
  // The estimate is 5 ms late: a 1 ms limit pairs nothing.
  Result r = Heatwave("eval-trajectory " + files + " --max-dt 0.001");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("only 0 pose pair(s)"), std::string::npos) << r.output;
  r = Heatwave("eval-trajectory " + files + " --max-dt -1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(r.output, "error: --max-dt: must be > 0 s, got -1\n");
  r = Heatwave("eval-trajectory " + files + " --bogus");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

TEST(EvalTrajectoryCli, UnwritableStdoutIsExitCode1) {
  const Files f = WriteTrajectories(hw::test::TestFolder());
  for (const std::string& flags : {std::string(""), std::string("--json")}) {
    const Result r = hw::test::RunCommand("(" + std::string(HW_HEATWAVE_EXE) + " eval-trajectory " +
                                          Quote(f.estimated) + " " + Quote(f.groundtruth) + " " +
                                          flags + " >/dev/full)");
    EXPECT_EQ(r.exit_code, 1) << flags << ": " << r.output;
    EXPECT_EQ(r.output, "error: cannot write standard output: No space left on device\n");
  }
}

}  // namespace
