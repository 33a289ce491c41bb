// End-to-end tests of `heatwave reconstruct` and `heatwave eval-trajectory`: outputs, the
// report, and what bad scans, bad outputs and interruptions leave behind.
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/output_folder.h"
#include "core/ply.h"
#include "core/scan.h"
#include "core/trajectory.h"
#include "reconstruct/reconstruct_test_support.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::CountLines;
using hw::test::FreshPath;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) {
  return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args);
}

// Options of every run here: the test scans' 160×120 wants 1 cm voxels.
const std::string kOptions = " --voxel-size 0.01 -q";

fs::path SmoothScan() {
  return hw::reconstruct::test::CachedScan("smooth", hw::reconstruct::test::TestScanOptions());
}

// A copy of the smooth scan to damage.
fs::path CopyOfScan(const std::string& name) {
  const fs::path copy = TestFolder(name);
  fs::copy(SmoothScan(), copy, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  return copy;
}

std::vector<fs::path> Temporaries(const fs::path& folder) {
  std::vector<fs::path> found;
  if (!fs::exists(folder)) return found;
  for (const auto& entry : fs::recursive_directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 1 && name[0] == '.' && name != hw::core::kRunMarkerName) found.push_back(entry.path());
  }
  return found;
}

std::string Read(const fs::path& path) { return hw::core::ReadFile(path, hw::core::kMaxMeshFileBytes); }

TEST(ReconstructCli, WritesTrajectoryModelAndReport) {
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() +
                            " --voxel-size 0.01 --start-at-groundtruth");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ATE RMSE"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Surface"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Shape      registered onto the truth (moved "), std::string::npos) << r.output;
  const hw::core::Trajectory trajectory = hw::core::ReadTumTrajectory(out / "trajectory.txt");
  const hw::core::Scan scan = hw::core::Scan::Open(SmoothScan());
  const int present = scan.NumFrames(hw::core::Stream::kDepth) - scan.NumMissingFrames(hw::core::Stream::kDepth);
  EXPECT_EQ(static_cast<int>(trajectory.size()), present);
  const hw::core::PlyMesh model = hw::core::ReadPly(out / "model.ply");
  EXPECT_TRUE(model.HasNormals());
  EXPECT_TRUE(model.HasColors());
  EXPECT_GT(model.faces.size(), 1000u);
  const std::string json = Read(out / "reconstruct.json");
  for (const char* key : {"\"settings\"", "\"timings\"", "\"memory\"", "\"peak_rss_bytes\"",
                          "\"frames\"", "\"inliers\"", "\"condition\"", "\"warnings\"",
                          "\"surface_to_truth\"", "\"registered\": {\"rotation_deg\": ", "\"constrained_directions\": 6", "\"prepare_ahead\": true", "\"prepare_ahead_ms\": ", "\"mean_prepare_ahead_ms\": ", "\"ate_m\"", "\"mean_track_ms\"", "\"raycasts\"",
                          "\"interval\": 8", "\"reuse_max_motion_m\": 0.04", "\"reuse_max_motion_deg\": 2.5",
                          "\"truncation_noise_sigmas\": 3", "\"noise_quadratic_per_m\": 0.0019", "\"noise_gate_sigmas\": 0",
                          "\"integrate_between_raycasts\": false", "\"integrated\": true",
                          "\"integrated\": false", "\"dynamic\": {\"margin_m\": 0.1", "\"dynamic_pixels\"",
                          "\"carved_points\"", "\"dynamic_frames\"", "\"carved_frames\"",
                          "\"keyframes\": {\"candidates\": 3", "\"prealign\": {\"iterations\": 10", "\"prealign_deg\": ", "\"recovered_from_keyframe\": 0", "\"keyframe\": -1",
                          "\"scales\": 3", "\"photometric_offset\": true", "\"photometric_offset\": ",
                          "\"relocalisation_max_conflict\": 0.03", "\"relocalisations_rejected\": 0",
                          "\"conflict_rejections\": 0", "\"model_conflict\": 0", "\"model_conflict\": null",
                          "\"max_depth_misfit_ratio\": 1", "\"prealign_rejected_by_depth\": false",
                          "\"relocalisations_rejected\": 0, \"prealign_rejected_by_depth\": "}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  // Frames tracked between raycasts keep their pose (above) but are not integrated: said.
  EXPECT_NE(r.output.find("Fusion     depth of "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" of them); decoding"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out / hw::core::kRunMarkerName));
  // Its trajectory evaluates with eval-trajectory too.
  const Result eval = Heatwave("eval-trajectory " + (out / "trajectory.txt").string() + " " +
                               (SmoothScan() / "groundtruth.txt").string() + " --json");
  EXPECT_EQ(eval.exit_code, 0) << eval.output;
}

// Tracking on depth alone can slide along a plain wall without any sign in ICP's figures
// (README, Tracking without colour): a scan tracked so is warned about, one with colour not.
TEST(ReconstructCli, TrackingOnDepthAloneIsWarnedAbout) {
  const std::string warning = "tracked frames aligned on depth alone";
  const fs::path coloured = FreshPath("coloured");
  const Result with_colour = Heatwave("reconstruct " + SmoothScan().string() + " --out " + coloured.string() +
                                      " --voxel-size 0.01 --start-at-groundtruth");
  ASSERT_EQ(with_colour.exit_code, 0) << with_colour.output;
  EXPECT_EQ(with_colour.output.find(warning), std::string::npos) << with_colour.output;
  EXPECT_EQ(with_colour.output.find("on depth alone"), std::string::npos) << with_colour.output;
  EXPECT_NE(Read(coloured / "reconstruct.json").find("\"tracked_depth_only\": 0,"), std::string::npos);
  // Frames with the photometric term are not basin-checked.
  EXPECT_NE(Read(coloured / "reconstruct.json").find("\"basin_checked\": 0,"), std::string::npos);
  EXPECT_EQ(with_colour.output.find("basin check"), std::string::npos) << with_colour.output;

  for (const char* depth_only : {" --no-colour", " --photometric-weight 0"}) {
    const fs::path out = FreshPath("depth-only");
    const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() +
                              " --voxel-size 0.01 --start-at-groundtruth" + depth_only);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string json = Read(out / "reconstruct.json");
    // Every tracked or recovered frame is counted: "N of N tracked frames".
    const auto count = [&](const std::string& key) {
      const size_t at = json.find("\"" + key + "\": ");
      EXPECT_NE(at, std::string::npos) << key;
      return at == std::string::npos ? -1 : std::stoi(json.substr(at + key.size() + 4));
    };
    const int tracked = count("tracked") + count("recovered");
    EXPECT_GT(tracked, 10) << depth_only;
    // Each was basin-checked (ReconstructionOptions::basin_check_m); an unconstrained one is
    // lost, not fused (this scan's ICP runs from the truth at 160×120: few or none).
    EXPECT_EQ(count("basin_checked"), count("tracked") + count("recovered") + count("unconstrained")) << depth_only;
    EXPECT_NE(json.find("\"basin_m\": "), std::string::npos);
    EXPECT_NE(r.output.find("Tracking   basin check: "), std::string::npos) << r.output;
    EXPECT_NE(json.find("\"tracked_depth_only\": " + std::to_string(tracked) + ","), std::string::npos) << depth_only;
    EXPECT_NE(json.find(std::to_string(tracked) + " of " + std::to_string(tracked) + " " + warning), std::string::npos)
        << depth_only << "\n" << r.output;
    // And the summary says it on a line of its own, whatever other warnings come first.
    EXPECT_NE(r.output.find("Tracking   " + std::to_string(tracked) + " of " + std::to_string(tracked) +
                            " frames aligned on depth alone"), std::string::npos) << depth_only << "\n" << r.output;
  }
}

TEST(ReconstructCli, GivenPosesAreFusedNotTracked) {
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() + kOptions +
                            " --poses " + (SmoothScan() / "groundtruth.txt").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const hw::core::Trajectory trajectory = hw::core::ReadTumTrajectory(out / "trajectory.txt");
  const hw::core::Trajectory truth = hw::core::ReadTumTrajectory(SmoothScan() / "groundtruth.txt");
  ASSERT_GT(trajectory.size(), 10u);
  for (const hw::core::TimedPose& p : trajectory.poses()) {
    // The written pose is the given one interpolated at the frame's time (text precision).
    EXPECT_LT((p.world_from_sensor.translation - truth.At(p.timestamp_s)->translation).norm(), 1e-5);
  }
  const std::string json = Read(out / "reconstruct.json");
  EXPECT_NE(json.find("\"status\": \"posed\""), std::string::npos);
  EXPECT_EQ(json.find("\"status\": \"tracked\""), std::string::npos);
  EXPECT_NE(json.find("\"depth_correction\": \"none\""), std::string::npos);
  // A pose file that does not parse: one line naming it, exit 1.
  const fs::path bad = TestFolder() / "poses.txt";
  hw::core::WriteFileAtomically(bad, "1.0 0 0 0 0 0 0\n");
  const Result b = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath("out2").string() +
                            kOptions + " --poses " + bad.string());
  EXPECT_EQ(b.exit_code, 1) << b.output;
  EXPECT_EQ(CountLines(b.output), 1) << b.output;
  EXPECT_NE(b.output.find("poses.txt"), std::string::npos) << b.output;
  // No pose at all, and poses that miss every frame: one line each, exit 1, no output.
  hw::core::WriteFileAtomically(bad, "# nothing\n");
  const fs::path out3 = FreshPath("out3");
  const Result e = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out3.string() + kOptions +
                            " --poses " + bad.string());
  EXPECT_EQ(e.exit_code, 1) << e.output;
  EXPECT_NE(e.output.find("holds no pose"), std::string::npos) << e.output;
  hw::core::WriteFileAtomically(bad, "5000.0 0 0 0 0 0 0 1\n5000.1 0 0 0 0 0 0 1\n");
  const Result f = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out3.string() + kOptions +
                            " --poses " + bad.string());
  EXPECT_EQ(f.exit_code, 1) << f.output;
  EXPECT_EQ(CountLines(f.output), 1) << f.output;
  EXPECT_NE(f.output.find("within the given poses"), std::string::npos) << f.output;
  EXPECT_FALSE(fs::exists(out3));
}

// Each stream is read at exposure times fitted to its frame clock (core/frame_clock.h): the
// trajectory's times are the frames' true exposure times to a fraction of the stamps' jitter
// — for one line through 29 frames, √(2/29) ≈ 0.26 of it on average; this scan's stamps give
// 0.43 (2.05 → 0.88 ms: its slope is 2σ off), which is why the bound is a half — and the
// report says so; --keep-stamps writes the stamps.
TEST(ReconstructCli, FramesAreReadAtTheirFittedExposureTimes) {
  std::map<double, double> exposure_of;  // depth stamp → true exposure time
  std::istringstream lines(Read(SmoothScan() / "truth" / "frame_times.txt"));
  for (std::string line; std::getline(lines, line);) {
    std::istringstream in(line);
    std::string stream;
    double stamp = 0, exposure = 0;
    if (in >> stream >> stamp >> exposure && stream == "depth") exposure_of[stamp] = exposure;
  }
  const hw::core::Scan scan = hw::core::Scan::Open(SmoothScan());
  const auto rms_to_exposure = [&](const hw::core::Trajectory& trajectory) {
    double sum = 0;
    for (size_t i = 0; i < trajectory.size(); ++i) {
      const double stamp = scan.Timestamp(hw::core::Stream::kDepth, static_cast<int>(i));
      const double d = trajectory.poses()[i].timestamp_s - exposure_of.at(stamp);
      sum += d * d;
    }
    return std::sqrt(sum / static_cast<double>(trajectory.size()));
  };
  const std::string poses = " --poses " + (SmoothScan() / "groundtruth.txt").string();
  const fs::path fitted = FreshPath("fitted"), kept = FreshPath("kept");
  const Result a = Heatwave("reconstruct " + SmoothScan().string() + " --out " + fitted.string() + poses +
                            " --voxel-size 0.01");
  ASSERT_EQ(a.exit_code, 0) << a.output;
  EXPECT_NE(a.output.find("Stamps     depth 29.9 Hz, jitter 2.1 ms -> exposure times (±"), std::string::npos)
      << a.output;
  EXPECT_NE(Read(fitted / "reconstruct.json").find("\"stamps\": {\"depth\": {\"regularised\": true"), std::string::npos);
  const Result b = Heatwave("reconstruct " + SmoothScan().string() + " --out " + kept.string() + poses + kOptions +
                            " --keep-stamps");
  ASSERT_EQ(b.exit_code, 0) << b.output;
  const hw::core::Trajectory with_fit = hw::core::ReadTumTrajectory(fitted / "trajectory.txt");
  const hw::core::Trajectory with_stamps = hw::core::ReadTumTrajectory(kept / "trajectory.txt");
  ASSERT_EQ(with_fit.size(), exposure_of.size());
  ASSERT_EQ(with_stamps.size(), exposure_of.size());
  for (size_t i = 0; i < with_stamps.size(); ++i) {
    EXPECT_NEAR(with_stamps.poses()[i].timestamp_s, scan.Timestamp(hw::core::Stream::kDepth, static_cast<int>(i)), 1e-6);
  }
  EXPECT_GT(rms_to_exposure(with_stamps), 0.0015);
  EXPECT_LT(rms_to_exposure(with_fit), 0.5 * rms_to_exposure(with_stamps));
}

// A rig with a depth_correction (`heatwave calibrate depth`) is applied and said so.
TEST(ReconstructCli, RigDepthCorrectionIsAppliedAndReported) {
  hw::core::Rig rig = hw::core::Scan::Open(SmoothScan()).rig();
  rig.depth_correction = hw::core::DepthCorrection::ZeroOver(rig.depth, 5, 4);
  rig.depth_correction->offset_per_m[7] = -0.004;
  const fs::path rig_path = TestFolder() / "rig-corrected.yaml";
  hw::core::WriteRig(rig_path, rig);
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() + " --voxel-size 0.01" +
                            " --rig " + rig_path.string() + " --poses " + (SmoothScan() / "groundtruth.txt").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Depth      corrected with rig.yaml's depth_correction (5 x 4 nodes)"), std::string::npos)
      << r.output;
  EXPECT_NE(Read(out / "reconstruct.json").find("\"depth_correction\": \"rig.yaml, 5 x 4 nodes\""),
            std::string::npos);
  // A wall-only correction leaves ICP's gate fixed; one that includes the depth scale
  // measured on the extrinsics plate widens it to 3 sigmas of the noise by default.
  EXPECT_NE(Read(out / "reconstruct.json").find("\"noise_gate_sigmas\": 0"), std::string::npos);
  rig.depth_correction->plate_affine_per_m = std::array<double, 3>{-0.002, 0, 0};
  hw::core::WriteRig(rig_path, rig);
  const fs::path out_plate = FreshPath("out");
  const Result plate = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out_plate.string() +
                                " --voxel-size 0.01 --start-at-groundtruth --rig " + rig_path.string());
  ASSERT_EQ(plate.exit_code, 0) << plate.output;
  EXPECT_NE(plate.output.find("(5 x 4 nodes, depth scale measured on the plate)"), std::string::npos) << plate.output;
  EXPECT_NE(plate.output.find("ICP gate and Huber threshold widened to 3 sigmas"), std::string::npos) << plate.output;
  EXPECT_NE(Read(out_plate / "reconstruct.json").find("\"noise_gate_sigmas\": 3"), std::string::npos);
}

// --icp-noise-gate reaches the tracker (tracked, not --poses), is said and recorded.
TEST(ReconstructCli, IcpNoiseGateIsUsedAndReported) {
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() +
                            " --voxel-size 0.01 --icp-noise-gate 3 --start-at-groundtruth");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ICP gate and Huber threshold widened to 3 sigmas of the depth noise"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(" 0 lost"), std::string::npos) << r.output;
  EXPECT_NE(Read(out / "reconstruct.json").find("\"noise_gate_sigmas\": 3"), std::string::npos);
}

TEST(ReconstructCli, OutThatIsAFileIsOneLineAndExit1) {
  const fs::path file = TestFolder() / "model.txt";
  hw::core::WriteFileAtomically(file, "not a folder\n");
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + file.string() + kOptions);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("not a folder"), std::string::npos) << r.output;
  EXPECT_EQ(Read(file), "not a folder\n");
}

TEST(ReconstructCli, NonEmptyOutNeedsOverwrite) {
  const fs::path out = TestFolder("out");
  hw::core::WriteFileAtomically(out / "notes.txt", "keep me\n");
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() + kOptions);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(out / hw::core::kRunMarkerName));
  const Result again = Heatwave("reconstruct " + SmoothScan().string() + " --out " + out.string() +
                                kOptions + " --overwrite --max-frames 5");
  EXPECT_EQ(again.exit_code, 0) << again.output;
  EXPECT_EQ(Read(out / "notes.txt"), "keep me\n");
  EXPECT_TRUE(fs::exists(out / "model.ply"));
}

TEST(ReconstructCli, AllZeroDepthIsOneLineExit1AndNoOutput) {
  const fs::path scan = CopyOfScan("zero-scan");
  const hw::core::Scan opened = hw::core::Scan::Open(scan);
  const cv::Mat zero = cv::Mat::zeros(opened.rig().depth.height, opened.rig().depth.width, CV_16UC1);
  for (int i = 0; i < opened.NumFrames(hw::core::Stream::kDepth); ++i) {
    if (opened.FrameExists(hw::core::Stream::kDepth, i)) {
      ASSERT_TRUE(cv::imwrite(opened.FramePath(hw::core::Stream::kDepth, i).string(), zero));
    }
  }
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + kOptions);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("no usable depth"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(ReconstructCli, WrongSizeDepthFrameIsOneLineNamingTheFile) {
  const fs::path scan = CopyOfScan("wrong-size");
  const hw::core::Scan opened = hw::core::Scan::Open(scan);
  const fs::path frame = opened.FramePath(hw::core::Stream::kDepth, 5);
  ASSERT_TRUE(cv::imwrite(frame.string(), cv::Mat::zeros(10, 10, CV_16UC1)));
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + kOptions);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find(frame.filename().string()), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // 8-bit depth: the same.
  ASSERT_TRUE(cv::imwrite(frame.string(), cv::Mat::zeros(opened.rig().depth.height, opened.rig().depth.width, CV_8UC1)));
  const Result r8 = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + kOptions);
  EXPECT_EQ(r8.exit_code, 1) << r8.output;
  EXPECT_EQ(CountLines(r8.output), 1) << r8.output;
}

// The truth mesh the model is measured against (synthetic scans): one nowhere near the model
// leaves the shape unmeasured with a warning, not a registration of nothing; a truncated one
// is one line naming it, exit 1, and no output.
TEST(ReconstructCli, ATruthMeshOutOfReachOrTruncatedIsSaidSo) {
  const fs::path scan = CopyOfScan("far-truth");
  const fs::path truth = scan / "truth" / "scene.ply";
  hw::core::PlyMesh far;
  far.SetPositions({{100, 0, 0}, {101, 0, 0}, {100, 1, 0}});
  far.faces.emplace_back(0, 1, 2);
  hw::core::WritePly(truth, far);
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() +
                            " --voxel-size 0.01 --start-at-groundtruth");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("shape not measured: too few model vertices within 50 mm of"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("Shape      "), std::string::npos) << r.output;
  EXPECT_EQ(Read(out / "reconstruct.json").find("\"registered\""), std::string::npos);

  const std::string bytes = Read(truth);
  hw::core::WriteFileAtomically(truth, bytes.substr(0, bytes.size() - 20));
  const fs::path out2 = FreshPath("out");
  const Result bad = Heatwave("reconstruct " + scan.string() + " --out " + out2.string() +
                              " --start-at-groundtruth" + kOptions);
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_EQ(CountLines(bad.output), 1) << bad.output;
  EXPECT_NE(bad.output.find("scene.ply"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(out2 / "model.ply"));
  EXPECT_FALSE(fs::exists(out2 / "reconstruct.json"));
}

TEST(ReconstructCli, MissingFramesAreSkippedAndCounted) {
  const fs::path scan = CopyOfScan("missing");
  const hw::core::Scan opened = hw::core::Scan::Open(scan);
  const int before = opened.NumMissingFrames(hw::core::Stream::kDepth);
  fs::remove(opened.FramePath(hw::core::Stream::kDepth, 7));
  fs::remove(opened.FramePath(hw::core::Stream::kDepth, 8));
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + " --voxel-size 0.01");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("missing, skipped"), std::string::npos) << r.output;
  const std::string json = Read(out / "reconstruct.json");
  EXPECT_NE(json.find("\"missing\": " + std::to_string(before + 2)), std::string::npos) << json.substr(0, 2000);
}

TEST(ReconstructCli, InterruptedRunLeavesNoOutputFile) {
  const fs::path out = FreshPath("out");
  // A longer scan so the run is still tracking when interrupted.
  const fs::path scan = hw::reconstruct::test::CachedScan(
      "jerky", hw::reconstruct::test::TestScanOptions("equipment-small", hw::fixtures::MotionKind::kJerky, 2.0));
  const Result r = hw::test::RunCommand(
      "bash -c 'set -m; " + std::string(HW_HEATWAVE_EXE) + " reconstruct " + scan.string() + " --out " +
      out.string() + " --voxel-size 0.005 -q & pid=$!; for i in $(seq 1 200); do "
      "[ -e " + (out / hw::core::kRunMarkerName).string() + " ] && break; sleep 0.01; done; sleep 0.3; "
      "kill -INT $pid; wait $pid; echo \"status $?\"'");
  EXPECT_NE(r.output.find("status 130"), std::string::npos) << r.output;
  EXPECT_TRUE(Temporaries(out).empty());
  EXPECT_FALSE(fs::exists(out / "model.ply"));
  EXPECT_FALSE(fs::exists(out / "trajectory.txt"));
  EXPECT_FALSE(fs::exists(out / "reconstruct.json"));
}

TEST(ReconstructCli, TumSequenceWithRigOption) {
  // A TUM RGB-D sequence has no rig.yaml: depth.txt, rgb.txt, the frame folders and
  // groundtruth.txt; the rig comes from --rig.
  const fs::path tum = CopyOfScan("tum");
  const fs::path rig = TestFolder("rig") / "kinect.yaml";
  fs::rename(tum / "rig.yaml", rig);
  fs::remove_all(tum / "truth");
  const fs::path out = FreshPath("out");
  const Result without = Heatwave("reconstruct " + tum.string() + " --out " + out.string() + kOptions);
  EXPECT_EQ(without.exit_code, 1) << without.output;
  EXPECT_NE(without.output.find("rig.yaml"), std::string::npos) << without.output;
  const Result r = Heatwave("reconstruct " + tum.string() + " --rig " + rig.string() + " --out " +
                            out.string() + " --voxel-size 0.01");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ATE RMSE"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("Surface"), std::string::npos) << r.output;  // no truth mesh
  EXPECT_TRUE(fs::exists(out / "model.ply"));
}

TEST(ReconstructCli, BadOptionsAreExit2) {
  // Bool values: true, false, 1 or 0, nothing else.
  for (const char* bad : {" --integrate-between-raycasts 2", " --integrate-between-raycasts -1",
                          " --photometric-offset yes", " --photometric-offset 2", " --drop-unconstrained maybe"}) {
    const Result b = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() + bad);
    EXPECT_EQ(b.exit_code, 2) << bad << ": " << b.output;
  }
  const Result r = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                            " --voxel-size 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("voxel_size_m"), std::string::npos) << r.output;
  const Result interval = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                   " --raycast-interval 0");
  EXPECT_EQ(interval.exit_code, 2) << interval.output;
  EXPECT_NE(interval.output.find("raycast_interval"), std::string::npos) << interval.output;
  const Result motion = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                 " --reuse-max-motion-deg 0");
  EXPECT_EQ(motion.exit_code, 2) << motion.output;
  EXPECT_NE(motion.output.find("reuse_max_motion_deg"), std::string::npos) << motion.output;
  const Result band = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                               " --truncation-noise-sigmas -1");
  EXPECT_EQ(band.exit_code, 2) << band.output;
  EXPECT_NE(band.output.find("truncation_noise_sigmas"), std::string::npos) << band.output;
  const Result window = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                 " --stamp-window 0");
  EXPECT_EQ(window.exit_code, 2) << window.output;
  EXPECT_NE(window.output.find("stamps.window_s"), std::string::npos) << window.output;
  for (const char* basin : {" --basin-check -0.01", " --basin-check 0.5"}) {
    const Result b = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() + basin);
    EXPECT_EQ(b.exit_code, 2) << basin << ": " << b.output;
    EXPECT_NE(b.output.find("basin_check_m"), std::string::npos) << b.output;
  }
  const Result gate = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                               " --icp-noise-gate -1");
  EXPECT_EQ(gate.exit_code, 2) << gate.output;
  EXPECT_NE(gate.output.find("noise_gate_sigmas"), std::string::npos) << gate.output;
  const Result candidates = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                     " --relocalisation-candidates 11");
  EXPECT_EQ(candidates.exit_code, 2) << candidates.output;
  EXPECT_NE(candidates.output.find("keyframes.candidates"), std::string::npos) << candidates.output;
  const Result conflict = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                   " --relocalisation-max-conflict 1.5");
  EXPECT_EQ(conflict.exit_code, 2) << conflict.output;
  EXPECT_NE(conflict.output.find("relocalisation_max_conflict"), std::string::npos) << conflict.output;
  const Result misfit = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                 " --prealign-max-depth-misfit-ratio 0.5");
  EXPECT_EQ(misfit.exit_code, 2) << misfit.output;
  EXPECT_NE(misfit.output.find("prealign.max_depth_misfit_ratio"), std::string::npos) << misfit.output;
  const Result prealign = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                   " --prealign-iterations 51");
  EXPECT_EQ(prealign.exit_code, 2) << prealign.output;
  EXPECT_NE(prealign.output.find("prealign.iterations"), std::string::npos) << prealign.output;
  const Result scales = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                 " --prealign-scales 0");
  EXPECT_EQ(scales.exit_code, 2) << scales.output;
  EXPECT_NE(scales.output.find("prealign.scales"), std::string::npos) << scales.output;
  const Result spacing = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                  " --keyframe-spacing 0");
  EXPECT_EQ(spacing.exit_code, 2) << spacing.output;
  EXPECT_NE(spacing.output.find("keyframes.min_distance_m"), std::string::npos) << spacing.output;
  const Result noise = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                " --icp-noise-depth 0.01");
  EXPECT_EQ(noise.exit_code, 2) << noise.output;
  EXPECT_NE(noise.output.find("noise_reference_depth_m"), std::string::npos) << noise.output;
  const Result scene = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                " --thermal-scene-correction sometimes");
  EXPECT_EQ(scene.exit_code, 2) << scene.output;
  EXPECT_NE(scene.output.find("--thermal-scene-correction"), std::string::npos) << scene.output;
  const Result dynamic = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                  " --dynamic-margin -1");
  EXPECT_EQ(dynamic.exit_code, 2) << dynamic.output;
  EXPECT_NE(dynamic.output.find("dynamic.margin_m"), std::string::npos) << dynamic.output;
  const Result occlusion = Heatwave("reconstruct " + SmoothScan().string() + " --out " + FreshPath().string() +
                                    " --thermal-occlusion-fraction 1");
  EXPECT_EQ(occlusion.exit_code, 2) << occlusion.output;
  EXPECT_NE(occlusion.output.find("occlusion_margin_fraction"), std::string::npos) << occlusion.output;
  EXPECT_EQ(Heatwave("reconstruct " + SmoothScan().string()).exit_code, 2);  // no --out
}

}  // namespace
