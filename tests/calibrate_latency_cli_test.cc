// End-to-end tests of `heatwave calibrate latency` on the fixtures' latency session: the
// offsets written to rig.yaml against the session's truth, the QA verdict and exit code,
// the outputs, and what bad inputs do (one line, exit 1 or 2, nothing written).
#include <cmath>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/rig.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) { return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args); }

std::string Read(const fs::path& path) { return hw::core::ReadFile(path, uint64_t{1} << 28); }

// The small latency session lengthened to 1.5 s (1.5 swings of the disc) at a quarter of
// the full image size (depth and colour 160 × 120, thermal 80 × 60), rendered once per test
// binary run.
fs::path LatencySession() {
  static const fs::path folder = [] {
    const fs::path f = TestFolder("latency-session");
    const Result r = Heatwave("synth --session latency --size small --duration 1.5 --image-scale 0.25 -q --overwrite --out " +
                              f.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return f;
  }();
  return folder;
}

TEST(CalibrateLatencyCli, WritesTheTrueOffsetsAndAVerdict) {
  const fs::path out = TestFolder() / "out";  // first: it empties this test's folder
  const fs::path session = LatencySession();
  Result r = Heatwave("calibrate latency --scan " + session.string() + " --out " + out.string() + " --max-sigma-ms 10");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("PASS  rgb_sigma_ms"), std::string::npos) << r.output;
  for (const char* name : {"latency.json", "rig.yaml", "diagnostics/signals.png"}) EXPECT_TRUE(fs::exists(out / name)) << name;
  const std::string json = Read(out / "latency.json");
  EXPECT_NE(json.find("\"sign_convention\": \"t_depth_clock = t_stream + time_offset_s"), std::string::npos);
  EXPECT_NE(json.find("\"verdict\": \"PASS\""), std::string::npos);
  // Against the truth. The nominal rig.yaml is 10 ms off on each clock; at this image size
  // the session gives σ ≈ 1–1.5 ms, so 3 ms (2σ–3σ) tells a calibrated clock from the
  // nominal one on any seed. Everything else in the rig is the input's.
  const hw::core::Rig truth = hw::core::ReadRig(session / "truth" / "rig.yaml");
  const hw::core::Rig nominal = hw::core::ReadRig(session / "rig.yaml");
  hw::core::Rig solved = hw::core::ReadRig(out / "rig.yaml");
  EXPECT_NEAR(solved.rgb_time_offset_s, truth.rgb_time_offset_s, 0.003);
  EXPECT_NEAR(solved.thermal_time_offset_s, truth.thermal_time_offset_s, 0.003);
  EXPECT_GT(std::abs(nominal.thermal_time_offset_s - truth.thermal_time_offset_s), 0.009);
  solved.rgb_time_offset_s = nominal.rgb_time_offset_s;
  solved.thermal_time_offset_s = nominal.thermal_time_offset_s;
  EXPECT_EQ(hw::core::FormatRig(solved), hw::core::FormatRig(nominal));

  // An existing calibration is not replaced without --overwrite (exit 2, untouched).
  r = Heatwave("calibrate latency -q --scan " + session.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--overwrite"), std::string::npos) << r.output;
  // A threshold no recording meets: written, FAIL, exit 1.
  r = Heatwave("calibrate latency --overwrite --max-sigma-ms 0.001 --scan " + session.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("FAIL  rgb_sigma_ms"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error: the latency calibration failed QA: rgb_sigma_ms, thermal_sigma_ms"), std::string::npos)
      << r.output;
  EXPECT_NE(Read(out / "latency.json").find("\"verdict\": \"FAIL\""), std::string::npos);
}

TEST(CalibrateLatencyCli, BadInputsAreOneLineAndWriteNothing) {
  const fs::path folder = TestFolder();  // first: it empties this test's folder
  const fs::path session = LatencySession();
  const fs::path out = folder / "out";
  // No thermal stream.
  const fs::path copy = folder / "no-thermal";
  fs::copy(session, copy, fs::copy_options::recursive);
  fs::remove(copy / "thermal.txt");
  Result r = Heatwave("calibrate latency -q --scan " + copy.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("no thermal stream"), std::string::npos) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // No scan there.
  r = Heatwave("calibrate latency -q --scan " + (folder / "nothing").string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_FALSE(fs::exists(out));
  // Bad options.
  EXPECT_EQ(Heatwave("calibrate latency -q --max-sigma-ms 0 --scan " + session.string() + " --out " + out.string()).exit_code, 2);
  EXPECT_EQ(Heatwave("calibrate latency -q --max-offset -1 --scan " + session.string() + " --out " + out.string()).exit_code, 2);
  EXPECT_EQ(Heatwave("calibrate latency -q --out " + out.string()).exit_code, 2);
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
