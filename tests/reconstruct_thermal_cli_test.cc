// End-to-end tests of `heatwave reconstruct` with a thermal stream: temperature on every model
// vertex, the report, and what bad thermal frames, emissivity files and options do.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
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

const std::string kOptions = " --voxel-size 0.01 -q";

// The smooth test scan with its thermal stream (80×60, the standard camera's errors).
fs::path ThermalScan() {
  hw::fixtures::SynthScanOptions o = hw::reconstruct::test::TestScanOptions();
  o.write_thermal = true;
  return hw::reconstruct::test::CachedScan("smooth-thermal", o);
}

fs::path CopyOfThermalScan(const std::string& name) {
  const fs::path copy = TestFolder(name);
  fs::copy(ThermalScan(), copy, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  return copy;
}

std::string Read(const fs::path& path) { return hw::core::ReadFile(path, hw::core::kMaxMeshFileBytes); }

TEST(ReconstructThermalCli, EveryVertexHasTemperatureOrIsMarkedUnobserved) {
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + ThermalScan().string() + " --out " + out.string() +
                            " --voxel-size 0.01 --start-at-groundtruth --emissivity-from-truth");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Thermal"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("offline"), std::string::npos) << r.output;
  const hw::core::PlyMesh model = hw::core::ReadPly(out / "model.ply");
  for (const char* name : {"temperature_c", "temperature_apparent_c", "temperature_confidence",
                           "temperature_views", "temperature_std_c", "temperature_footprint_m",
                           "temperature_view_x", "temperature_view_y", "temperature_view_z"}) {
    ASSERT_NE(model.Find(name), nullptr) << name;
  }
  // Where each vertex was seen from (point + view vector, a mean of camera centres) lies in
  // the box of the trajectory's positions, widened by the rig's 5 cm depth-to-thermal lever
  // arm and 1 cm for the vertex's offset from the voxels it reads.
  const hw::core::Trajectory trajectory = hw::core::ReadTumTrajectory(out / "trajectory.txt");
  Eigen::AlignedBox3d cameras;
  for (const hw::core::TimedPose& p : trajectory.poses()) cameras.extend(p.world_from_sensor.translation);
  cameras.min() -= Eigen::Vector3d::Constant(0.06);
  cameras.max() += Eigen::Vector3d::Constant(0.06);
  const auto& view_x = model.Get("temperature_view_x").values;
  const auto& view_y = model.Get("temperature_view_y").values;
  const auto& view_z = model.Get("temperature_view_z").values;
  const auto& x = model.Get("x").values;
  const auto& y = model.Get("y").values;
  const auto& z = model.Get("z").values;
  int seen_from_the_path = 0, with_view = 0;
  const auto& footprint = model.Get("temperature_footprint_m").values;
  const auto& t = model.Get("temperature_c").values;
  const auto& apparent = model.Get("temperature_apparent_c").values;
  const auto& views = model.Get("temperature_views").values;
  const auto& confidence = model.Get("temperature_confidence").values;
  int observed = 0, unobserved = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    if (views[i] > 0) {
      ++observed;
      // A plant room: nothing below freezing or above 150 °C.
      EXPECT_TRUE(t[i] > 0 && t[i] < 150) << i << " " << t[i];
      EXPECT_TRUE(std::isfinite(apparent[i]));
      EXPECT_GT(confidence[i], 0);
      EXPECT_LE(confidence[i], 1);
      // A 300 px focal length from 0.4 m to 4 m: 1.3 to 13 mm across, at most √10 times
      // that along a grazing slope.
      EXPECT_TRUE(footprint[i] > 1e-3 && footprint[i] < 0.05) << i << " " << footprint[i];
      const Eigen::Vector3d view(view_x[i], view_y[i], view_z[i]);
      ASSERT_TRUE(view.allFinite()) << i;
      ++with_view;
      seen_from_the_path += cameras.contains(Eigen::Vector3d(x[i], y[i], z[i]) + view);
    } else {
      ++unobserved;
      EXPECT_TRUE(std::isnan(t[i])) << "unobserved vertex " << i << " has " << t[i];
      EXPECT_TRUE(std::isnan(apparent[i]));
      EXPECT_EQ(confidence[i], 0);
      EXPECT_TRUE(std::isnan(footprint[i]));
      EXPECT_TRUE(std::isnan(view_x[i]) && std::isnan(view_y[i]) && std::isnan(view_z[i]));
    }
  }
  EXPECT_EQ(seen_from_the_path, with_view);
  // The thermal camera sees less than the depth camera (narrower view, 40 ms behind), so
  // most of the model but not all of it has a temperature.
  EXPECT_GT(observed, static_cast<int>(t.size()) / 2);
  const std::string json = Read(out / "reconstruct.json");
  for (const char* key : {"\"thermal\"", "\"recency_bias\"", "\"fraction_fused\"", "\"truth_evaluation\"",
                          "\"rmse_uniform_k\"", "\"rmse_affine_k\"", "\"time_since_ffc_s\"", "\"mean_confidence\"",
                          "\"occlusion_margin_m\": 0.1", "\"rays_occluded\"", "\"live_depth_frames\"", "\"occluded\"",
                          "\"live_depth\": true", "\"by_view_quality\"", "\"confidence_from\"",
                          "\"reflections\": {", "\"operator_apparent_c\": 32", "\"mirror_traced\"",
                          "\"mirror_operator\"", "\"mean_reflect_ms\"", "\"compared_resolved\"",
                          "\"rmse_resolved_affine_k\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
  // The resolved subset is the uniform one less what a thermal pixel mixes across steps:
  // never larger, and on this small scan's 0.5–2 m views most of it.
  const auto count = [&json](const std::string& key) {
    const size_t at = json.find("\"" + key + "\": ");
    return at == std::string::npos ? -1 : std::stoi(json.substr(at + key.size() + 4));
  };
  EXPECT_GT(count("compared_resolved"), count("compared_uniform") / 2);
  EXPECT_LE(count("compared_resolved"), count("compared_uniform"));
}

// A 10 Hz depth stream (a slower sensor, or a capture that could not keep up): given poses
// and thermal frames are interpolated across three depth periods, not a fixed 0.1 s that
// is less than one period plus jitter (half the frames of such a scan found no pose).
TEST(ReconstructThermalCli, SlowDepthStreamStillPosesEveryFrame) {
  hw::fixtures::SynthScanOptions o = hw::reconstruct::test::TestScanOptions();
  o.write_thermal = true;
  o.duration_s = 2;
  o.depth_rate_hz = 10;
  o.thermal_rate_hz = 9;
  o.timing.drop_probability = o.timing.burst_probability = 0;  // jitter only
  const fs::path scan = hw::reconstruct::test::CachedScan("slow-depth-thermal", o);
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + " --poses " +
                            (scan / "groundtruth.txt").string() + " --start-at-groundtruth" + kOptions);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json json = nlohmann::json::parse(Read(out / "reconstruct.json"));
  EXPECT_EQ(json["summary"]["unposed"].get<int>(), 0);
  EXPECT_EQ(json["summary"]["posed"].get<int>(), 20);
  const nlohmann::json& thermal = json["thermal"]["summary"];
  // Every thermal frame between the first and the last depth frame gets a pose; at most
  // the one before the first depth frame does not (the frozen FFC frames are not counted).
  EXPECT_LE(thermal["no_pose"].get<int>(), 1) << thermal.dump();
  EXPECT_GE(thermal["fused"].get<int>(), thermal["frames"].get<int>() - 1 - thermal["frozen"].get<int>() -
                                             thermal["after_end"].get<int>()) << thermal.dump();
  EXPECT_NEAR(json["thermal"]["settings"]["max_pose_gap_s"].get<double>(), 0.3, 0.01);
}

// Frame selection (--thermal-frame-interval, 0.09 s by default): the frames with a pose
// (frozen ones do not count) fall into windows — a window opens with a frame and holds those
// less than 0.09 s after it — and one frame per window is fused, the others skipped, none
// left held at the end; the model still has temperature where fusing every frame (0) gave it
// (a 30 Hz sweep's consecutive frames see the same surface).
TEST(ReconstructThermalCli, FrameIntervalFusesOneFrameInEachWindow) {
  const std::string base = "reconstruct " + ThermalScan().string() + " --poses " +
                           (ThermalScan() / "groundtruth.txt").string() + " --start-at-groundtruth --voxel-size 0.01";
  const fs::path every = FreshPath("every"), windowed = FreshPath("windowed");
  const Result r0 = Heatwave(base + " --out " + every.string() + " --thermal-frame-interval 0");
  ASSERT_EQ(r0.exit_code, 0) << r0.output;
  const Result r = Heatwave(base + " --out " + windowed.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j0 = nlohmann::json::parse(Read(every / "reconstruct.json"))["thermal"];
  const nlohmann::json j = nlohmann::json::parse(Read(windowed / "reconstruct.json"))["thermal"];
  EXPECT_EQ(j0["settings"]["frame_interval_s"].get<double>(), 0.0);
  EXPECT_EQ(j["settings"]["frame_interval_s"].get<double>(), 0.09);
  EXPECT_EQ(j0["summary"]["skipped"].get<int>(), 0);
  // The candidates (every frame fused or without surface at interval 0) and their windows.
  std::vector<double> candidates_s;
  for (const nlohmann::json& f : j0["frames"]) {
    const std::string status = f["status"].get<std::string>();
    if (status == "fused" || status == "no-surface") candidates_s.push_back(f["timestamp_s"].get<double>());
  }
  ASSERT_GE(candidates_s.size(), 9u) << j0["summary"].dump();
  int windows = 0;
  double start_s = -1e300;
  for (double t : candidates_s) {
    if (t >= start_s + 0.09) {
      ++windows;
      start_s = t;
    }
  }
  const int fused = j["summary"]["fused"].get<int>() + j["summary"]["no_surface"].get<int>();
  EXPECT_EQ(fused, windows) << j["summary"].dump();
  EXPECT_LT(fused, static_cast<int>(candidates_s.size()));
  EXPECT_EQ(j["summary"]["skipped"].get<int>(), static_cast<int>(candidates_s.size()) - fused) << j["summary"].dump();
  EXPECT_EQ(j["summary"]["frozen"].get<int>(), j0["summary"]["frozen"].get<int>());
  int skipped = 0;
  for (const nlohmann::json& f : j["frames"]) {
    EXPECT_NE(f["status"].get<std::string>(), "held");
    if (f["status"].get<std::string>() == "skipped") {
      ++skipped;
      EXPECT_EQ(f["rays"].get<int>(), 0);  // never cast
    }
    EXPECT_GE(f["frame_confidence"].get<double>(), 0);
    EXPECT_LE(f["frame_confidence"].get<double>(), 1);
  }
  EXPECT_EQ(skipped, j["summary"]["skipped"].get<int>());
  EXPECT_NE(r.output.find("skipped"), std::string::npos) << r.output;
  auto observed = [](const fs::path& out) {
    const hw::core::PlyMesh model = hw::core::ReadPly(out / "model.ply");
    int n = 0;
    for (double v : model.Get("temperature_views").values) n += v > 0;
    return n;
  };
  const int observed0 = observed(every), observed1 = observed(windowed);
  EXPECT_GT(observed1, observed0 * 9 / 10) << observed0 << " " << observed1;
  EXPECT_LE(observed1, observed0);
}

// The background stage (on by default; --no-thermal-background): each fused thermal frame's shading and splatting run
// beside the depth pipeline — here tracking and integrating the next frames — and give the
// same model, trajectory and per-frame records as inline, byte for byte.
TEST(ReconstructThermalCli, TheBackgroundStageGivesTheSameModel) {
  const std::string base = "reconstruct " + ThermalScan().string() + " --start-at-groundtruth --voxel-size 0.01";
  const fs::path inline_out = FreshPath("inline"), background_out = FreshPath("background");
  const Result r0 = Heatwave(base + " --out " + inline_out.string() + " --no-thermal-background");
  ASSERT_EQ(r0.exit_code, 0) << r0.output;
  const Result r = Heatwave(base + " --out " + background_out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r0.output.find("beside the depth pipeline"), std::string::npos) << r0.output;
  EXPECT_NE(r.output.find("beside the depth pipeline"), std::string::npos) << r.output;
  EXPECT_EQ(Read(inline_out / "model.ply"), Read(background_out / "model.ply"));
  EXPECT_EQ(Read(inline_out / "trajectory.txt"), Read(background_out / "trajectory.txt"));
  const nlohmann::json j0 = nlohmann::json::parse(Read(inline_out / "reconstruct.json"))["thermal"];
  const nlohmann::json j = nlohmann::json::parse(Read(background_out / "reconstruct.json"))["thermal"];
  EXPECT_FALSE(j0["settings"]["background"].get<bool>());
  EXPECT_TRUE(j["settings"]["background"].get<bool>());
  EXPECT_EQ(j0["summary"], j["summary"]);
  ASSERT_EQ(j0["frames"].size(), j["frames"].size());
  int fused = 0;
  for (size_t i = 0; i < j["frames"].size(); ++i) {
    nlohmann::json a = j0["frames"][i], b = j["frames"][i];
    fused += a["status"] == "fused";
    for (nlohmann::json* f : {&a, &b}) f->erase("raycast_ms"), f->erase("reflect_ms"), f->erase("fuse_ms");
    EXPECT_EQ(a, b) << "frame " << i;
  }
  EXPECT_GE(fused, 5);
}

TEST(ReconstructThermalCli, ScanWithoutThermalFramesWarnsAndWritesNoTemperature) {
  // A rig with a thermal camera whose stream was not recorded.
  const fs::path scan = CopyOfThermalScan("no-thermal-frames");
  fs::remove(scan / "thermal.txt");
  fs::remove_all(scan / "thermal");
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + " --voxel-size 0.01");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(Read(out / "reconstruct.json").find("the scan has no thermal frames: the model is written without temperature"),
            std::string::npos);
  const hw::core::PlyMesh model = hw::core::ReadPly(out / "model.ply");
  EXPECT_EQ(model.Find("temperature_c"), nullptr);
}

TEST(ReconstructThermalCli, WrongSizeThermalFrameIsOneLineNamingTheFile) {
  const fs::path scan = CopyOfThermalScan("thermal-wrong-size");
  const hw::core::Scan opened = hw::core::Scan::Open(scan);
  const fs::path frame = opened.FramePath(hw::core::Stream::kThermal, 3);
  ASSERT_TRUE(cv::imwrite(frame.string(), cv::Mat::zeros(7, 9, CV_16UC1)));
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + scan.string() + " --out " + out.string() + kOptions);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find(frame.filename().string()), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(ReconstructThermalCli, BadEmissivityFileIsOneLineNamingFileAndLine) {
  const fs::path file = TestFolder() / "emissivity.yaml";
  hw::core::WriteFileAtomically(file,
                                "version: 1\n"
                                "regions:\n"
                                "  - name: boss\n"
                                "    emissivity: 1.2\n"
                                "    sphere: { centre_m: [0, 0, 1], radius_m: 0.05 }\n");
  const fs::path out = FreshPath("out");
  const Result r = Heatwave("reconstruct " + ThermalScan().string() + " --out " + out.string() + kOptions +
                            " --emissivity " + file.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("emissivity.yaml"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("line 4"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // A valid one is used and named in the report.
  hw::core::WriteFileAtomically(file,
                                "version: 1\n"
                                "regions:\n"
                                "  - name: boss\n"
                                "    emissivity: 0.3\n"
                                "    law: metal\n"
                                "    sphere: { centre_m: [0, 0, 1], radius_m: 0.05 }\n");
  const Result ok = Heatwave("reconstruct " + ThermalScan().string() + " --out " + out.string() + kOptions +
                             " --emissivity " + file.string() + " --max-frames 10");
  ASSERT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(Read(out / "reconstruct.json").find("emissivity.yaml: 1 regions"), std::string::npos);
}

TEST(ReconstructThermalCli, BadThermalOptionsAreExit2) {
  const std::string base = "reconstruct " + ThermalScan().string() + " --out " + FreshPath("out").string() + kOptions;
  for (const char* bad : {" --thermal-method median", " --recency-bias 1.5", " --confidence-powers 1,1,1",
                          " --confidence-powers 1,1,-1,1,1", " --emissivity-from-truth",
                          " --min-ray-confidence 1", " --thermal-frame-interval -1",
                          " --thermal-frame-interval 2", " --operator-size 0.4", " --operator-size 0.4,-1",
                          " --operator-distance 0", " --operator-c -300", " --thermal-reflections maybe"}) {
    const Result r = Heatwave(base + bad);
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.output;
  }
  // The message names the option's field and its constraint.
  const Result r = Heatwave(base + " --operator-distance 0");
  EXPECT_NE(r.output.find("reflections.operator_distance_m: must be in (0, 5] m, got 0"), std::string::npos)
      << r.output;
}

}  // namespace
