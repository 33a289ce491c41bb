// End-to-end tests of `heatwave devices`, `capture` and `import-oni` with the test OpenNI2
// runtime (HW_OPENNI_TEST_RUNTIME: OpenNI2 with the heatwave test device and DummyDevice),
// the fake thermal camera, and real libusb enumeration.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "capture/testing/capture_test_support.h"
#include "core/rig.h"
#include "core/scan.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
namespace t = hw::capture::testing;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

// heatwave with the test OpenNI2 runtime first on the library path.
Result Heatwave(const std::string& args) {
  return hw::test::RunCommand("LD_LIBRARY_PATH=" HW_OPENNI_TEST_RUNTIME " " HW_HEATWAVE_EXE " " + args);
}

fs::path WriteTestRig(const fs::path& folder) {
  const fs::path path = folder / "rig.yaml";
  hw::core::WriteRig(path, t::TestDeviceRig());
  return path;
}

TEST(CaptureCli, DevicesListsTheTestDeviceAndSaysWhenNoThermalCameraIsFound) {
  const Result r = Heatwave("devices");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("heatwave-test  heatwave test device"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("depth  640x480@30 depth_1mm;"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Thermal cameras (USB video class)"), std::string::npos) << r.output;
  // On a machine with a thermal camera attached its line replaces "none".
  if (r.output.find("[thermal:") == std::string::npos) {
    EXPECT_NE(r.output.find("  none"), std::string::npos) << r.output;
  }
}

// Ctrl-C ends a capture cleanly: exit 0, the summary, and a complete, valid scan.
TEST(CaptureCli, CtrlCStopsTheCaptureWithAValidScan) {
  const fs::path folder = TestFolder();
  const fs::path rig = WriteTestRig(folder);
  const fs::path out = folder / "scan";
  const fs::path log = folder / "log.txt";
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::setenv("LD_LIBRARY_PATH", HW_OPENNI_TEST_RUNTIME, 1);
    const std::string out_arg = out.string(), rig_arg = rig.string();
    FILE* f = std::freopen(log.c_str(), "w", stdout);
    if (f == nullptr) std::_Exit(99);
    ::dup2(STDOUT_FILENO, STDERR_FILENO);
    ::execl(HW_HEATWAVE_EXE, HW_HEATWAVE_EXE, "capture", "--out", out_arg.c_str(), "--rig", rig_arg.c_str(), "--depth",
            t::kTestDeviceUri, "--thermal", "fake", static_cast<char*>(nullptr));
    std::_Exit(98);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_EQ(::kill(pid, SIGINT), 0);
  int status = 0;
  const auto start = std::chrono::steady_clock::now();
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    ASSERT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10)) << "capture did not stop on Ctrl-C";
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const std::string output = hw::test::RunCommand("cat " + log.string()).output;
  ASSERT_TRUE(WIFEXITED(status)) << output;
  EXPECT_EQ(WEXITSTATUS(status), 0) << output;
  EXPECT_NE(output.find("stopped by Ctrl-C"), std::string::npos) << output;
  EXPECT_FALSE(fs::exists(out / ".heatwave-run")) << "the folder is marked incomplete";
  const hw::core::Scan scan = hw::core::Scan::Open(out);
  EXPECT_GT(scan.NumFrames(hw::core::Stream::kDepth), 5);
  EXPECT_GT(scan.NumFrames(hw::core::Stream::kRgb), 5);
  EXPECT_GT(scan.NumFrames(hw::core::Stream::kThermal), 2);
}

TEST(CaptureCli, CaptureForADurationAndBadOptions) {
  const fs::path folder = TestFolder();
  const fs::path rig = WriteTestRig(folder);
  const fs::path out = folder / "scan";
  Result r = Heatwave("capture -q --out " + out.string() + " --rig " + rig.string() +
                      " --depth heatwave-test --thermal fake --duration 1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NO_THROW(hw::core::Scan::Open(out));
  // The folder now holds a scan: refused without --overwrite (exit 2), replaced with it.
  r = Heatwave("capture -q --out " + out.string() + " --rig " + rig.string() + " --depth heatwave-test --thermal none --duration 0.5");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = Heatwave("capture -q --overwrite --out " + out.string() + " --rig " + rig.string() +
               " --depth heatwave-test --thermal none --duration 0.5");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_FALSE(fs::exists(out / "thermal.txt"));
  // Bad options: exit 2, one line naming the option.
  r = Heatwave("capture --out " + (folder / "x").string() + " --rig " + rig.string() + " --thermal 12:34:56:78");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--thermal"), std::string::npos) << r.output;
  r = Heatwave("capture --out " + (folder / "x").string() + " --rig " + rig.string() + " --depth none --thermal none");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  // No such device, rig mismatch: exit 1, one line, no folder.
  r = Heatwave("capture --out " + (folder / "y").string() + " --rig " + rig.string() + " --depth no-such-device --thermal none");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(folder / "y"));
}

TEST(CaptureCli, ImportOniWritesAScanAndRefusesDummyRecordings) {
  const fs::path folder = TestFolder();
  const fs::path rig = WriteTestRig(folder);
  const fs::path oni = folder / "test.oni";
  t::RecordDevice(t::kTestDeviceUri, oni, 0.7);
  Result r = Heatwave("import-oni " + oni.string() + " --rig " + rig.string() + " --out " + (folder / "scan").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("depth     "), std::string::npos) << r.output;
  const hw::core::Scan scan = hw::core::Scan::Open(folder / "scan");
  EXPECT_GE(scan.NumFrames(hw::core::Stream::kDepth), 12);

  const fs::path dummy = folder / "dummy.oni";
  t::RecordDevice("Dummy", dummy, 0.4, 320, 240);
  r = Heatwave("import-oni " + dummy.string() + " --rig " + rig.string() + " --out " + (folder / "dummy-scan").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("no cropping record"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(folder / "dummy-scan"));

  r = Heatwave("import-oni " + (folder / "missing.oni").string() + " --rig " + rig.string() + " --out " +
               (folder / "m").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("missing.oni: no such file"), std::string::npos) << r.output;
}

}  // namespace
