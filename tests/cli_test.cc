// End-to-end tests of the `heatwave` executable: exit codes, one-line errors, no crash
// on bad input.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::CountLines;
using Result = hw::test::CommandResult;

// Runs the heatwave executable with `args` (already shell-quoted where needed).
Result Heatwave(const std::string& args) {
  return hw::test::RunCommand(std::string(HW_HEATWAVE_EXE) + " " + args);
}

TEST(Cli, UsageAndHelp) {
  EXPECT_EQ(Heatwave("").exit_code, 2);
  EXPECT_EQ(Heatwave("no-such-command").exit_code, 2);
  const Result help = Heatwave("help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("scan-info"), std::string::npos) << help.output;
  EXPECT_EQ(Heatwave("help scan-info").exit_code, 0);
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

}  // namespace
