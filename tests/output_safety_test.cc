// What the executable leaves behind when runs collide, are interrupted or hit a full disk:
// never a mixed folder, a half file under a final name, or a stray temporary; always a
// folder that says it is incomplete.
#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/image_io.h"
#include "core/output_folder.h"
#include "core/scan.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::FreshPath;

const std::string kExe = HW_HEATWAVE_EXE;

hw::test::CommandResult Heatwave(const std::string& args) {
  return hw::test::RunCommand(kExe + " " + args);
}

// Runs a bash script (job control and `ulimit` as bash has them; /bin/sh may be dash).
hw::test::CommandResult RunBash(const std::string& script) {
  const fs::path file = FreshPath("script.sh");
  hw::core::WriteFileAtomically(file, script);
  return hw::test::RunCommand("bash " + file.string());
}

// Hidden temporaries of atomic writes (".<stem>.tmp<pid>-<n><ext>") anywhere below folder.
std::vector<std::string> Temporaries(const fs::path& folder) {
  std::vector<std::string> found;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".tmp") != std::string::npos) found.push_back(entry.path().string());
  }
  return found;
}

// Every image file under its final name decodes completely.
void ExpectEveryImageWhole(const fs::path& folder) {
  int images = 0;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".png" && ext != ".tiff") continue;
    ++images;
    EXPECT_NO_THROW(hw::core::ReadImage(entry.path())) << entry.path();
  }
  EXPECT_GT(images, 0);
}

TEST(OutputSafety, TwoRunsIntoOneFolderDoNotMix) {
  const fs::path out = FreshPath("shared") / "scan";
  // Both start together; the folder lock lets one through and stops the other at once
  // (or, if the first has already finished, the second finds a non-empty folder).
  const std::string run = kExe + " synth --scene equipment-small --duration 1 -q --out " +
                          out.string() + " --seed ";
  const hw::test::CommandResult both = RunBash(
      "(" + run + "1; echo \"exit-a $?\") & (" + run + "2; echo \"exit-b $?\") & wait");
  const bool a_ok = both.output.find("exit-a 0") != std::string::npos;
  const bool b_ok = both.output.find("exit-b 0") != std::string::npos;
  EXPECT_NE(a_ok, b_ok) << both.output;
  EXPECT_TRUE(both.output.find("another heatwave run is writing it") != std::string::npos ||
              both.output.find("folder is not empty") != std::string::npos)
      << both.output;
  // The folder holds exactly the winner's scan: byte-identical to a run of that seed alone.
  const fs::path alone = FreshPath("alone") / "scan";  // same name: index headers carry it
  ASSERT_EQ(Heatwave("synth --scene equipment-small --duration 1 -q --out " + alone.string() +
                     " --seed " + (a_ok ? "1" : "2"))
                .exit_code,
            0);
  for (const auto& entry : fs::recursive_directory_iterator(alone)) {
    if (!entry.is_regular_file()) continue;
    const fs::path relative = fs::relative(entry.path(), alone);
    EXPECT_EQ(hw::core::ReadFile(out / relative, hw::core::kMaxMeshFileBytes),
              hw::core::ReadFile(entry.path(), hw::core::kMaxMeshFileBytes))
        << relative;
  }
  EXPECT_EQ(hw::core::FolderSizeBytes(out), hw::core::FolderSizeBytes(alone));
}

TEST(OutputSafety, InterruptedRunIsCleanAndSaysIncomplete) {
  for (const std::string signal_name : {"INT", "TERM"}) {
    const fs::path out = FreshPath("interrupted-" + signal_name);
    // Start a long run, wait until frames are being written, interrupt it.
    const hw::test::CommandResult r = RunBash(
        "set -m; " + kExe + " synth --scene equipment-small --duration 30 -q --out " + out.string() +
        " & pid=$!; for i in $(seq 1 400); do "
        "[ $(ls " + out.string() + "/depth 2>/dev/null | wc -l) -ge 3 ] && break; sleep 0.02; done; "
        "kill -" + signal_name + " $pid; wait $pid; echo \"status $?\"");
    const int signal_number = signal_name == "INT" ? 2 : 15;
    EXPECT_NE(r.output.find("status " + std::to_string(128 + signal_number)), std::string::npos)
        << r.output;
    EXPECT_TRUE(Temporaries(out).empty()) << Temporaries(out).front();
    EXPECT_TRUE(fs::exists(out / hw::core::kRunMarkerName));
    const hw::test::CommandResult info = Heatwave("scan-info " + out.string());
    EXPECT_EQ(info.exit_code, 1) << info.output;
    EXPECT_NE(info.output.find("incomplete scan"), std::string::npos) << info.output;
    EXPECT_EQ(hw::test::CountLines(info.output), 1) << info.output;
    // Writing it again replaces it with a complete scan.
    const hw::test::CommandResult again =
        Heatwave("synth --scene equipment-small --duration 0.2 -q --overwrite --out " +
                 out.string());
    EXPECT_EQ(again.exit_code, 0) << again.output;
    EXPECT_EQ(Heatwave("scan-info " + out.string() + " --check-frames").exit_code, 0);
  }
}

// `ulimit -f` fails writes past a size exactly as a full disk does.
TEST(OutputSafety, FullDiskLeavesNoHalfFileUnderAFinalName) {
  const fs::path out = FreshPath("full");
  const hw::test::CommandResult r = RunBash(
      "ulimit -f 4; " + kExe + " synth --scene equipment-small --duration 1 -q --out " +
      out.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("File too large"), std::string::npos) << r.output;
  EXPECT_TRUE(Temporaries(out).empty()) << Temporaries(out).front();
  ExpectEveryImageWhole(out);
  const hw::test::CommandResult info = Heatwave("scan-info " + out.string());
  EXPECT_EQ(info.exit_code, 1) << info.output;
  EXPECT_NE(info.output.find("incomplete scan"), std::string::npos) << info.output;
}

TEST(OutputSafety, OverwriteRemovesStaleUnindexedFrames) {
  const fs::path out = FreshPath("stale");
  ASSERT_EQ(Heatwave("synth --scene equipment-small --duration 0.5 -q --out " + out.string())
                .exit_code,
            0);
  hw::core::WriteFileAtomically(out / "depth" / "99.000000.png", "stale, unindexed");
  hw::core::WriteFileAtomically(out / "thermal" / "old.png", "stale");
  ASSERT_EQ(Heatwave("synth --scene equipment-small --duration 0.2 -q --overwrite --out " +
                     out.string())
                .exit_code,
            0);
  EXPECT_FALSE(fs::exists(out / "depth" / "99.000000.png"));
  EXPECT_FALSE(fs::exists(out / "thermal" / "old.png"));
  const hw::core::Scan scan = hw::core::Scan::Open(out);
  int files = 0;
  for (const auto& entry : fs::directory_iterator(out / "depth")) files += entry.is_regular_file();
  EXPECT_EQ(files, scan.NumFrames(hw::core::Stream::kDepth));
}

// libpng, libtiff and OpenCV print their own lines on stderr; frames are decoded with our
// handlers, so -q leaves exactly heatwave's one error line.
TEST(OutputSafety, CorruptFramesGiveOneLineAndNoDecoderChatter) {
  const fs::path out = FreshPath("corrupt") / "scan";
  ASSERT_EQ(Heatwave("synth --scene equipment-small --duration 0.3 -q --thermal-format tiff "
                     "--out " + out.string())
                .exit_code,
            0);
  const hw::core::Scan scan = hw::core::Scan::Open(out);
  const auto truncate = [](const fs::path& path, size_t bytes) {
    const std::string data = hw::core::ReadFile(path, hw::core::kMaxFrameFileBytes);
    hw::core::WriteFileAtomically(path, data.substr(0, std::min(bytes, data.size())));
  };
  truncate(scan.FramePath(hw::core::Stream::kDepth, 0), 3000);
  truncate(scan.FramePath(hw::core::Stream::kThermal, 0), 300);
  hw::core::WriteFileAtomically(scan.FramePath(hw::core::Stream::kRgb, 1), "junk");
  const hw::test::CommandResult r = Heatwave("scan-info " + out.string() + " --check-frames -q");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_EQ(r.output.rfind("error: 3 of ", 0), 0u) << r.output;
  EXPECT_NE(r.output.find("file is truncated"), std::string::npos) << r.output;
}

TEST(OutputSafety, SeedAndRoomsAreValidated) {
  const std::string out = " --out " + FreshPath("never").string();
  for (const std::string seed : {"-1", "18446744073709551616", "1e3", "", "0x10", " 5"}) {
    const hw::test::CommandResult r =
        Heatwave("synth --scene equipment-small --seed '" + seed + "'" + out);
    EXPECT_EQ(r.exit_code, 2) << seed << ": " << r.output;
    EXPECT_NE(r.output.find("--seed: must be a whole number"), std::string::npos) << r.output;
  }
  EXPECT_EQ(Heatwave("synth --list --seed 18446744073709551615").exit_code, 0);
  const hw::test::CommandResult rooms = Heatwave("synth --scene equipment-small --rooms 4" + out);
  EXPECT_EQ(rooms.exit_code, 2) << rooms.output;
  EXPECT_NE(rooms.output.find("--rooms: applies to the 'large' scene only"), std::string::npos)
      << rooms.output;
  EXPECT_FALSE(fs::exists(FreshPath("never")));
}

}  // namespace
