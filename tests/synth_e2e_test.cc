// End-to-end tests of `heatwave synth`: the executable renders scan folders that open as
// scans, refuses to clobber folders, and maps bad options to exit code 2 with one line.
#include <filesystem>
#include <map>
#include <string>

#include <gtest/gtest.h>

#include <cmath>

#include <Eigen/Core>

#include "core/atomic_file.h"
#include "core/rig.h"
#include "core/scan.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::CountLines;
using hw::test::FreshPath;

// Runs the heatwave executable with `args` (already shell-quoted where needed).
hw::test::CommandResult Heatwave(const std::string& args) {
  return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args);
}
using hw::core::Stream;

std::map<std::string, std::string> ReadTree(const fs::path& folder) {
  std::map<std::string, std::string> files;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    if (entry.is_regular_file()) {
      files[fs::relative(entry.path(), folder).string()] = hw::core::ReadFile(entry.path(), hw::core::kMaxMeshFileBytes);
    }
  }
  return files;
}

TEST(SynthCli, ListsScenesAndSessions) {
  const hw::test::CommandResult r = Heatwave("synth --list");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("equipment-small"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("latency"), std::string::npos) << r.output;
  EXPECT_EQ(Heatwave("synth --help").exit_code, 0);
  EXPECT_EQ(Heatwave("help synth").exit_code, 0);
}

TEST(SynthCli, RendersAScanThatOpens) {
  const fs::path out = FreshPath("scan") / "scan";
  // Regular streams (no stamp jitter, no dropped frames), so counts and periods are exact.
  const hw::test::CommandResult r = Heatwave(
      "synth --scene equipment-small --duration 0.2 --thermal-rate 60 "
      "--perturb-rig --no-jitter --no-drops --out " +
      out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The summary names the streams and the planted regions.
  EXPECT_NE(r.output.find("Hotspots"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("breaker-3"), std::string::npos) << r.output;
  const hw::core::Scan scan = hw::core::Scan::Open(out);
  EXPECT_EQ(scan.NumFrames(Stream::kDepth), 6);
  EXPECT_EQ(scan.NumFrames(Stream::kThermal), 13);
  EXPECT_NEAR(scan.MedianPeriod(Stream::kThermal), 1.0 / 60, 1.1e-6);
  EXPECT_TRUE(scan.groundtruth().has_value());
  EXPECT_TRUE(fs::exists(out / "truth" / "rig.yaml"));
  EXPECT_TRUE(fs::exists(out / "truth" / "scene.ply"));
  EXPECT_TRUE(fs::exists(out / "truth" / "hotspots.yaml"));
  EXPECT_TRUE(fs::exists(out / "truth" / "frame_times.txt"));

  // Same options and seed: the same bytes; --quiet prints nothing.
  const fs::path again = FreshPath("again") / "scan";
  const hw::test::CommandResult q = Heatwave(
      "synth --scene equipment-small --duration 0.2 --thermal-rate 60 "
      "--perturb-rig --no-jitter --no-drops --quiet --out " +
      again.string());
  ASSERT_EQ(q.exit_code, 0) << q.output;
  EXPECT_EQ(q.output, "");
  EXPECT_TRUE(ReadTree(out) == ReadTree(again));
}

TEST(SynthCli, RefusesANonEmptyFolderUnlessOverwrite) {
  const fs::path out = FreshPath("busy");
  hw::core::WriteFileAtomically(out / "notes.txt", "mine\n");
  hw::core::WriteFileAtomically(out / "depth" / "1.000000.png", "stale");
  const std::string args = "synth --scene building-small --duration 0.1 -q --out " + out.string();
  const hw::test::CommandResult refused = Heatwave(args);
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_EQ(CountLines(refused.output), 1) << refused.output;
  EXPECT_NE(refused.output.find("--overwrite"), std::string::npos) << refused.output;
  EXPECT_FALSE(fs::exists(out / "rig.yaml"));

  const hw::test::CommandResult replaced = Heatwave(args + " --overwrite");
  EXPECT_EQ(replaced.exit_code, 0) << replaced.output;
  EXPECT_TRUE(fs::exists(out / "notes.txt"));                // not ours: kept
  EXPECT_FALSE(fs::exists(out / "depth" / "1.000000.png"));  // the old scan's: gone
  EXPECT_EQ(hw::core::Scan::Open(out).NumFrames(Stream::kDepth), 3);

  const fs::path file = FreshPath("file") / "f";
  hw::core::WriteFileAtomically(file, "x");
  const hw::test::CommandResult not_a_folder = Heatwave("synth --scene building-small --out " + file.string());
  EXPECT_EQ(not_a_folder.exit_code, 2) << not_a_folder.output;
  EXPECT_NE(not_a_folder.output.find("not a folder"), std::string::npos) << not_a_folder.output;
}

TEST(SynthCli, BadOptionsAreExitCode2WithOneLine) {
  const std::string out = " --out " + FreshPath("bad").string();
  const std::pair<std::string, std::string> cases[] = {
      {"synth --scene garage" + out, "known: equipment"},
      {"synth --scene equipment-small --duration -1" + out, "duration_s"},
      {"synth --scene equipment-small --thermal-rate 500" + out, "thermal_rate_hz"},
      {"synth --scene equipment-small --trajectory wobbly" + out, "trajectory"},
      {"synth --scene equipment-small --size huge" + out, "size"},
      {"synth --scene equipment-small --session latency" + out, "excludes"},
      {"synth" + out, "--scene or --session"},
      {"synth --scene equipment-small", "--out"},
      {"synth --session latency --perturb-rig" + out, "--perturb-rig"},
      {"synth --session intrinsics-thermal --duration 3" + out, "--duration"},
      {"synth --session tea-time" + out, "known: intrinsics-thermal"},
      {"synth --session latency --rig-seed -1" + out, "--rig-seed"},
      {"synth --session latency --image-scale 0.1" + out, "--image-scale"},
      {"synth --session latency --mask-polarity cold" + out, "--mask-polarity"},
      {"synth --scene equipment-small --mask-polarity cold" + out, "--mask-polarity"},
      {"synth --scene equipment-small --loop-duration 30" + out, "--loop-duration: applies to --trajectory loop"},
      {"synth --scene equipment-small --trajectory loop --path-start -2" + out, "path_start_s"},
      {"synth --session latency --path-start 3" + out, "--path-start"},
      {"synth --scene equipment-small --passer 1.5" + out, "--passer: must be in [0, 1]"},
      {"synth --session latency --passer 0.5" + out, "--passer"},
  };
  for (const auto& [args, needle] : cases) {
    const hw::test::CommandResult r = Heatwave(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << args << "\n" << r.output;
    EXPECT_EQ(r.output.rfind("error: ", 0), 0u) << args << "\n" << r.output;
  }
  EXPECT_FALSE(fs::exists(FreshPath("bad") / "rig.yaml"));
}

// --passer: the scan renders, then the walker is drawn in (the summary says where and in
// how many frames), and the folder is a complete scan again afterwards.
TEST(SynthCli, DrawsAPasserIntoAScan) {
  const fs::path out = FreshPath("passer") / "scan";
  const hw::test::CommandResult r =
      Heatwave("synth --scene equipment-small --duration 2 --seed 3 --passer 0.5 --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Passer     crossing the view at"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("(not in truth/)"), std::string::npos) << r.output;
  const hw::core::Scan scan = hw::core::Scan::Open(out);  // throws if left incomplete
  EXPECT_GT(scan.NumFrames(Stream::kDepth), 0);
  // The same scan without the passer differs in some depth frames, not in truth/.
  const fs::path plain = FreshPath("plain") / "scan";
  ASSERT_EQ(Heatwave("synth --scene equipment-small --duration 2 --seed 3 -q --out " + plain.string()).exit_code, 0);
  const auto with = ReadTree(out), without = ReadTree(plain);
  int depth_changed = 0;
  for (const auto& [name, bytes] : without) {
    if (name.rfind("truth/", 0) == 0) {
      EXPECT_EQ(with.at(name), bytes) << name;
    }
    depth_changed += name.rfind("depth/", 0) == 0 && with.at(name) != bytes;
  }
  EXPECT_GT(depth_changed, 5);
}

// Both polarities of the heated mask from the CLI: at the first hole's centre the camera
// sees the background, on the bar right of it the plate; hot: the plate is the warmer.
TEST(SynthCli, RendersBothMaskPolarities) {
  for (const std::string polarity : {"hot", "cold"}) {
    const fs::path out = FreshPath("mask-" + polarity);
    const hw::test::CommandResult r =
        Heatwave("synth --session intrinsics-thermal --mask-polarity " + polarity + " -q --out " +
                 out.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const hw::core::Scan scan = hw::core::Scan::Open(out);
    const hw::core::Rig truth = hw::core::ReadRig(out / "truth" / "rig.yaml");
    const hw::core::Target target = hw::core::ReadTarget(out / "target.yaml");
    const double t = scan.Timestamp(Stream::kThermal, 0) + truth.thermal_time_offset_s;
    const hw::core::Rigid3d thermal_from_target =
        (scan.groundtruth()->At(t).value() * truth.depth_from_thermal).Inverse();
    const double s = target.square_m, p = target.pitch_m;
    const auto at = [&](double x, double y) {
      const Eigen::Vector2d px = truth.thermal->Project(thermal_from_target * Eigen::Vector3d(x, y, 0));
      return scan.LoadThermal(0).at<float>(static_cast<int>(std::lround(px.y())),
                                           static_cast<int>(std::lround(px.x())));
    };
    const double hole_c = at(s / 2, s / 2), bar_c = at(s + (p - s) / 2, s / 2);
    EXPECT_GT(std::abs(bar_c - hole_c), 10) << polarity;
    EXPECT_EQ(bar_c > hole_c, polarity == "hot") << bar_c << " vs " << hole_c;
  }
}

TEST(SynthCli, RendersACalibrationSession) {
  const fs::path out = FreshPath("session");
  const hw::test::CommandResult r = Heatwave("synth --session intrinsics-thermal -q --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out / "truth" / "rig.yaml"));
  EXPECT_GT(hw::core::Scan::Open(out).NumFrames(Stream::kThermal), 0);
}


// The depth-wall session: depth and colour stills, no thermal; the true rig carries the
// depth correction, the nominal one does not.
TEST(SynthCli, RendersTheDepthWallSession) {
  const fs::path out = FreshPath("depth-wall");
  const hw::test::CommandResult r = Heatwave("synth --session depth-wall --size small -q --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const hw::core::Scan scan = hw::core::Scan::Open(out);
  EXPECT_EQ(scan.NumFrames(Stream::kDepth), 24);
  EXPECT_EQ(scan.NumFrames(Stream::kRgb), 24);
  EXPECT_EQ(scan.NumFrames(Stream::kThermal), 0);
  EXPECT_TRUE(scan.groundtruth().has_value());
  EXPECT_TRUE(hw::core::ReadRig(out / "truth" / "rig.yaml").depth_correction.has_value());
  EXPECT_FALSE(hw::core::ReadRig(out / "rig.yaml").depth_correction.has_value());
}

// One rig family: a session and a scan of one unit (--rig-seed) at one image scale write
// the same truth/rig.yaml and rig.yaml (--perturb-rig), but for the thermal block's scene
// emissivity.
TEST(SynthCli, SessionAndScanOfOneUnitShareTheirRigs) {
  const fs::path session = FreshPath("unit-session"), scan = FreshPath("unit-scan");
  ASSERT_EQ(Heatwave("synth --session latency --rig-seed 5 --duration 0.1 -q --out " +
                     session.string())
                .exit_code,
            0);
  ASSERT_EQ(Heatwave("synth --scene equipment-small --rig-seed 5 --perturb-rig --duration 0.1 "
                     "--image-scale 0.5 -q --out " +
                     scan.string())
                .exit_code,
            0);
  // Scene-dependent fields aside, and the colour readout (sessions render their colour with
  // a global shutter, scans with the sensor's rolling one).
  const auto same_scene = [](const fs::path& file) {
    hw::core::Rig rig = hw::core::ReadRig(file);
    rig.thermal_settings->emissivity = 0.95;
    rig.thermal_settings->reflected_c = 20;
    rig.rgb_readout_s = 0;
    return hw::core::FormatRig(rig);
  };
  for (const std::string name : {"truth/rig.yaml", "rig.yaml"}) {
    EXPECT_EQ(same_scene(session / name), same_scene(scan / name)) << name;
  }
  EXPECT_NE(same_scene(session / "rig.yaml"), same_scene(session / "truth/rig.yaml"));
}

}  // namespace
