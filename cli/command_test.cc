#include "cli/command.h"

#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "tests/support.h"

namespace hw::cli {
namespace {

using hw::test::Argv;

TEST(Command, TableHasUniqueNamesAndSummaries) {
  std::set<std::string> names;
  for (const Command& c : Commands()) {
    EXPECT_TRUE(names.insert(c.name).second) << "duplicate command " << c.name;
    EXPECT_NE(c.run, nullptr);
    EXPECT_GT(std::string(c.summary).size(), 10u) << c.name;
  }
  EXPECT_TRUE(names.count("help"));
  EXPECT_TRUE(names.count("scan-info"));
}

TEST(Command, EveryCommandHasHelpAndRejectsUnknownOptions) {
  for (const Command& c : Commands()) {
    testing::internal::CaptureStdout();
    Argv help({std::string("heatwave ") + c.name, "--help"});
    EXPECT_EQ(c.run(help.argc(), help.argv()), kExitOk) << c.name;
    const std::string out = testing::internal::GetCapturedStdout();
    EXPECT_NE(out.find("--help"), std::string::npos) << c.name << ": " << out;

    testing::internal::CaptureStderr();
    Argv bad({std::string("heatwave ") + c.name, "--no-such-option"});
    EXPECT_EQ(c.run(bad.argc(), bad.argv()), kExitUsage) << c.name;
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find("--help"), std::string::npos) << c.name << ": " << err;
  }
}

TEST(Command, HelpListsCommandsAndUnknownIsUsageError) {
  testing::internal::CaptureStdout();
  Argv list({"heatwave help"});
  EXPECT_EQ(RunHelp(list.argc(), list.argv()), kExitOk);
  const std::string out = testing::internal::GetCapturedStdout();
  for (const Command& c : Commands()) EXPECT_NE(out.find(c.name), std::string::npos);

  testing::internal::CaptureStderr();
  Argv unknown({"heatwave help", "no-such-command"});
  EXPECT_EQ(RunHelp(unknown.argc(), unknown.argv()), kExitUsage);
  EXPECT_NE(testing::internal::GetCapturedStderr().find("no-such-command"), std::string::npos);
}

TEST(Command, HelpHelpShowsHelpsOwnUsage) {
  testing::internal::CaptureStdout();
  Argv help_help({"heatwave help", "help"});
  EXPECT_EQ(RunHelp(help_help.argc(), help_help.argv()), kExitOk);
  const std::string out = testing::internal::GetCapturedStdout();
  EXPECT_NE(out.find("heatwave help"), std::string::npos) << out;
  EXPECT_NE(out.find("--help"), std::string::npos) << out;
}

TEST(Command, RunGuardedErrorsAreOneLine) {
  // A library's what() may span lines or carry control characters (a path with a '\n');
  // scripts read exactly one line per error.
  testing::internal::CaptureStderr();
  EXPECT_EQ(RunGuarded([]() -> int { throw std::runtime_error("first\nsecond\r\tthird\x01\x7f\n"); }),
            kExitFailure);
  EXPECT_EQ(RunGuarded([]() -> int { throw core::InputError("a\nb/rig.yaml", "line 1:\nbad"); }),
            kExitFailure);
  EXPECT_EQ(RunGuarded([]() -> int {
              ThrowIfInvalid("x: must be\n> 0");
              return kExitOk;
            }),
            kExitUsage);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_EQ(err,
            "error: first second  third??\n"
            "error: a b/rig.yaml: line 1: bad\n"
            "error: x: must be > 0\n");
}

TEST(Command, RunGuardedMapsErrorsToExitCodes) {
  testing::internal::CaptureStderr();
  EXPECT_EQ(RunGuarded([] { return kExitOk; }), kExitOk);
  EXPECT_EQ(RunGuarded([]() -> int { throw core::InputError("scan/rig.yaml", "bad"); }),
            kExitFailure);
  EXPECT_EQ(RunGuarded([]() -> int { throw core::OutputError("out.ply", "disk full"); }),
            kExitFailure);
  EXPECT_EQ(RunGuarded([]() -> int {
              ThrowIfInvalid("voxel_m: must be > 0, got 0", "options: ");
              return kExitOk;
            }),
            kExitUsage);
  EXPECT_EQ(RunGuarded([]() -> int { throw std::runtime_error("boom"); }), kExitFailure);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("error: scan/rig.yaml: bad\n"), std::string::npos) << err;
  EXPECT_NE(err.find("error: cannot write out.ply: disk full\n"), std::string::npos) << err;
  EXPECT_NE(err.find("error: options: voxel_m: must be > 0, got 0\n"), std::string::npos) << err;
  EXPECT_NO_THROW(ThrowIfInvalid(""));
}

}  // namespace
}  // namespace hw::cli
