#include "core/output_folder.h"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

TEST(OutputFolder, OneRunAtATime) {
  const fs::path dir = hw::test::FreshPath("out");
  OutputFolder first(dir, "heatwave synth");
  EXPECT_TRUE(fs::is_directory(dir));
  EXPECT_TRUE(first.IsEmpty());  // the marker does not count
  EXPECT_EQ(ProbeFolderRun(dir).state, FolderRunState::kBeingWritten);
  try {
    OutputFolder second(dir, "heatwave synth");
    FAIL() << "a second run took the folder";
  } catch (const OutputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("another heatwave run is writing it"));
    EXPECT_THAT(e.what(), HasSubstr("pid " + std::to_string(::getpid())));
    EXPECT_THAT(e.what(), HasSubstr("heatwave synth"));
  }
  // Another process is refused the same way (flock is per open file, not per process).
  const int code = hw::test::RunInChild([&] {
    try {
      OutputFolder other(dir, "child");
      return 1;
    } catch (const OutputError&) {
      return 0;
    }
  });
  EXPECT_EQ(code, 0);
}

TEST(OutputFolder, UnfinishedRunLeavesTheFolderIncomplete) {
  const fs::path dir = hw::test::FreshPath("out");
  {
    OutputFolder run(dir, "heatwave synth");
    WriteFileAtomically(dir / "rig.yaml", "x");
    EXPECT_FALSE(run.IsEmpty());
  }  // no Commit: failed or interrupted
  const FolderRun probe = ProbeFolderRun(dir);
  EXPECT_EQ(probe.state, FolderRunState::kIncomplete);
  EXPECT_THAT(probe.detail, HasSubstr("heatwave synth"));
  // A killed run (no destructor at all) reads the same: the kernel drops the lock.
  const fs::path killed = hw::test::FreshPath("killed");
  EXPECT_EQ(hw::test::RunInChild([&] {
              OutputFolder run(killed, "heatwave synth");
              ::_exit(3);
              return 0;
            }),
            3);
  EXPECT_EQ(ProbeFolderRun(killed).state, FolderRunState::kIncomplete);
  // The next run takes it over; committing makes it complete.
  OutputFolder again(dir, "heatwave synth");
  EXPECT_EQ(ProbeFolderRun(dir).state, FolderRunState::kBeingWritten);
  again.Commit();
  EXPECT_FALSE(fs::exists(dir / kRunMarkerName));
  EXPECT_EQ(ProbeFolderRun(dir).state, FolderRunState::kComplete);
  OutputFolder after_commit(dir, "heatwave synth");  // free again
}

TEST(OutputFolder, AbandonLeavesTheFolderAsItWas) {
  const fs::path dir = hw::test::FreshPath("out");
  OutputFolder(dir, "first").Commit();
  {
    OutputFolder refused(dir, "second");
    refused.Abandon();
  }
  EXPECT_EQ(ProbeFolderRun(dir).state, FolderRunState::kComplete);
  { OutputFolder unfinished(dir, "third"); }
  {
    OutputFolder refused(dir, "fourth");
    refused.Abandon();  // the marker was there before: the folder stays incomplete
  }
  EXPECT_EQ(ProbeFolderRun(dir).state, FolderRunState::kIncomplete);
}

TEST(OutputFolder, RemoveTakesOnlyTheNamedEntries) {
  const fs::path dir = hw::test::FreshPath("out");
  OutputFolder run(dir, "test");
  WriteFileAtomically(dir / "depth" / "1.png", "x");
  WriteFileAtomically(dir / "depth.txt", "x");
  WriteFileAtomically(dir / "notes.txt", "keep");
  run.Remove({"depth", "depth.txt", "absent.txt"});
  EXPECT_FALSE(fs::exists(dir / "depth"));
  EXPECT_FALSE(fs::exists(dir / "depth.txt"));
  EXPECT_TRUE(fs::exists(dir / "notes.txt"));
  EXPECT_FALSE(run.IsEmpty());
}

TEST(OutputFolder, HostileMarkersFailWithoutHanging) {
  const fs::path fifo_dir = hw::test::TestFolder("fifo");
  ASSERT_EQ(::mkfifo((fifo_dir / kRunMarkerName).c_str(), 0644), 0);
  const int code = hw::test::RunInChild([&] {
    if (ProbeFolderRun(fifo_dir).state != FolderRunState::kIncomplete) return 1;
    try {
      OutputFolder run(fifo_dir, "test");
      return 2;
    } catch (const OutputError& e) {
      return std::string(e.what()).find("not a regular file") != std::string::npos ? 0 : 3;
    }
  });
  EXPECT_EQ(code, 0) << (code == hw::test::kTimedOut ? "hung" : "");
  // A regular file where the folder should be.
  const fs::path file = hw::test::TestFolder("file") / "scan";
  WriteFileAtomically(file, "x");
  EXPECT_THROW(OutputFolder(file, "test"), OutputError);
}

}  // namespace
}  // namespace hw::core
