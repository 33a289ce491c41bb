// End-to-end tests of the `heatwave` executable: exit codes, one-line errors, no crash
// on bad input.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/atomic_file.h"
#include "core/scan_writer.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::CountLines;
using Result = hw::test::CommandResult;

// Runs the heatwave executable with `args` (already shell-quoted where needed).
Result Heatwave(const std::string& args) {
  return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args);
}

// The same with stdout sent to `redirect` (e.g. ">/dev/full"); the output is stderr only.
// The subshell keeps stderr on the pipe RunCommand reads.
Result HeatwaveStdoutTo(const std::string& args, const std::string& redirect) {
  return hw::test::RunCommand("(" HW_HEATWAVE_EXE " " + args + " " + redirect +
                              ")");
}

// A small valid scan: 5 depth frames at 30 Hz, no other stream.
fs::path WriteScan(const fs::path& folder) {
  hw::core::Rig rig;
  rig.depth_scale = 1000.0;
  rig.depth = hw::core::CameraModel::Pinhole(32, 24, 30.0, 30.0);
  hw::core::ScanWriter writer(folder, rig);
  for (int i = 0; i < 5; ++i) {
    writer.AddDepth(i / 30.0, cv::Mat(24, 32, CV_32FC1, cv::Scalar(1.5f)));
  }
  writer.Finish();
  return folder;
}

TEST(Cli, UsageAndHelp) {
  EXPECT_EQ(Heatwave("").exit_code, 2);
  EXPECT_EQ(Heatwave("no-such-command").exit_code, 2);
  const Result help = Heatwave("help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("scan-info"), std::string::npos) << help.output;
  EXPECT_EQ(Heatwave("help scan-info").exit_code, 0);
  const Result help_help = Heatwave("help help");
  EXPECT_EQ(help_help.exit_code, 0) << help_help.output;
  EXPECT_NE(help_help.output.find("heatwave help"), std::string::npos) << help_help.output;
  EXPECT_EQ(Heatwave("help --help").exit_code, 0);
  const Result help_unknown = Heatwave("help no-such-command");
  EXPECT_EQ(help_unknown.exit_code, 2);
  EXPECT_EQ(CountLines(help_unknown.output), 1) << help_unknown.output;
  EXPECT_EQ(Heatwave("scan-info --help").exit_code, 0);
  const Result version = Heatwave("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_NE(version.output.find("heatwave "), std::string::npos);
}

TEST(Cli, BadOptionsAreExitCode2) {
  const Result r = Heatwave("scan-info");  // missing the positional SCAN
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(Heatwave("scan-info /tmp --bogus").exit_code, 2);
}

TEST(Cli, MissingScanIsOneClearLine) {
  const fs::path dir = hw::test::FreshPath("scan");
  const Result r = Heatwave("scan-info " + dir.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_EQ(r.output.rfind("error: ", 0), 0u) << r.output;
  EXPECT_NE(r.output.find(dir.string()), std::string::npos) << r.output;
}

TEST(Cli, MalformedRigIsOneClearLineNamingKey) {
  const fs::path dir = hw::test::TestFolder("scan");
  hw::core::WriteFileAtomically(dir / "depth.txt", "");
  hw::core::WriteFileAtomically(dir / "rig.yaml",
                                "version: 1\ndepth_scale: 1000.0\ncameras:\n  depth:\n"
                                "    width: 640\n    height: 480\n    model: pinhole\n"
                                "    fx: -525.0\n    fy: 525.0\n    cx: 319.5\n    cy: 239.5\n"
                                "    distortion: []\nextrinsics: {}\ntime_offset_s: {}\n");
  const Result r = Heatwave("scan-info " + dir.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("rig.yaml"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("fx"), std::string::npos) << r.output;
}

TEST(Cli, UnwritableStdoutIsExitCode1) {
  // Output lost to a full disk or a closed pipe must not look like success: every command,
  // whatever it printed, exits 1 with one line naming the reason.
  const fs::path scan = WriteScan(hw::test::FreshPath("scan"));
  for (const std::string& args :
       {std::string("scan-info ") + scan.string() + " --json", std::string("scan-info ") +
        scan.string(), std::string("help"), std::string("help help"), std::string("help scan-info"),
        std::string("--help"), std::string("--version"), std::string("version"),
        std::string("scan-info --help"), std::string("synth --list")}) {
    const Result r = HeatwaveStdoutTo(args, ">/dev/full");
    EXPECT_EQ(r.exit_code, 1) << args << ": " << r.output;
    EXPECT_EQ(r.output, "error: cannot write standard output: No space left on device\n") << args;
  }
  const Result closed = HeatwaveStdoutTo("version", ">&-");
  EXPECT_EQ(closed.exit_code, 1) << closed.output;
  EXPECT_EQ(closed.output, "error: cannot write standard output: Bad file descriptor\n");
  // Failures keep their own exit code and single error line.
  EXPECT_EQ(HeatwaveStdoutTo("scan-info " + scan.string() + " --bogus", ">/dev/full").exit_code, 2);
  const Result missing = HeatwaveStdoutTo("scan-info " + scan.string() + "/nope", ">/dev/full");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_EQ(CountLines(missing.output), 1) << missing.output;
  EXPECT_NE(missing.output.find("no such scan folder"), std::string::npos) << missing.output;
}

TEST(Cli, UnwritableStdoutIsCaughtMidRun) {
  // A report longer than stdio's buffer fails while the command runs, not at the final
  // flush (which then succeeds on an empty buffer): the reason must still be reported.
  fs::path folder = hw::test::FreshPath("scan");
  for (int i = 0; i < 14; ++i) folder /= std::string(200, static_cast<char>('a' + i));
  const fs::path scan = WriteScan(folder);
  fs::remove(scan / "depth" / "0.033333.png");  // warnings naming the long path
  fs::remove(scan / "depth" / "0.066667.png");
  const Result full = Heatwave("scan-info " + scan.string());
  ASSERT_EQ(full.exit_code, 0) << full.output;
  ASSERT_GT(full.output.size(), 8192u);
  const Result r = HeatwaveStdoutTo("scan-info " + scan.string(), ">/dev/full");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output, "error: cannot write standard output: No space left on device\n");
}

}  // namespace
