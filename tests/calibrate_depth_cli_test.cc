// End-to-end tests of `heatwave calibrate depth` on the fixtures' depth-wall session: the
// field written to rig.yaml against the session's truth, the QA verdict and exit code, the
// outputs, and what bad inputs do (one line, exit 1 or 2, nothing written).
#include <cmath>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/rig.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) { return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args); }

std::string Read(const fs::path& path) { return hw::core::ReadFile(path, uint64_t{1} << 28); }

// The small depth-wall session (24 stills, depth 320 × 240), rendered once per binary run.
fs::path WallSession() {
  static const fs::path folder = [] {
    const fs::path f = TestFolder("depth-wall-session");
    const Result r = Heatwave("synth --session depth-wall --size small -q --overwrite --out " + f.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return f;
  }();
  return folder;
}

TEST(CalibrateDepthCli, WritesTheFieldAndAVerdict) {
  const fs::path out = TestFolder() / "out";  // first: it empties this test's folder
  const fs::path session = WallSession();
  // The true depth camera (the nominal rig's intrinsics are a unit's factory values, off by
  // up to 2 % of the width: the field would be found shifted by as much).
  const fs::path truth_rig = session / "truth" / "rig.yaml";
  Result r = Heatwave("calibrate depth --scan " + session.string() + " --rig " + truth_rig.string() + " --out " +
                      out.string() + " --max-sigma-mm 5");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Planes     24 of 24 frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("PASS  sigma_mm_at_3m"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("the rig's earlier depth_correction is replaced"), std::string::npos) << r.output;
  for (const char* name : {"depth_correction.json", "rig.yaml", "diagnostics/field.png", "diagnostics/sigma.png"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  EXPECT_EQ(cv::imread((out / "diagnostics" / "field.png").string()).cols, 640);  // 320 px doubled
  const std::string json = Read(out / "depth_correction.json");
  EXPECT_NE(json.find("\"verdict\": \"PASS\""), std::string::npos);
  EXPECT_NE(json.find("\"unobservable\": "), std::string::npos);
  // The field against the truth at the nodes, both without their affine part: a coarse
  // check (the session test compares over the pixels); 0.001 /m is 9 mm at 3 m, a tenth of
  // the bowl's depth there.
  const hw::core::Rig truth = hw::core::ReadRig(truth_rig);
  const hw::core::Rig solved = hw::core::ReadRig(out / "rig.yaml");
  ASSERT_TRUE(solved.depth_correction && truth.depth_correction);
  const hw::core::DepthCorrection& s = *solved.depth_correction;
  const hw::core::DepthCorrection& t = *truth.depth_correction;
  ASSERT_EQ(s.nx, t.nx);
  ASSERT_EQ(s.x_range, t.x_range);
  // The affine part of the truth at the nodes (least squares over 1, x, y), removed.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> g;
  for (int k = 0; k < t.nx * t.ny; ++k) {
    g.emplace_back(1, t.x_range[0] + (t.x_range[1] - t.x_range[0]) * (k % t.nx) / (t.nx - 1),
                   t.y_range[0] + (t.y_range[1] - t.y_range[0]) * (k / t.nx) / (t.ny - 1));
    a += g.back() * g.back().transpose();
    b += g.back() * t.offset_per_m[k];
  }
  const Eigen::Vector3d affine = a.ldlt().solve(b);
  double sum_error = 0, sum_truth = 0;
  for (int k = 0; k < t.nx * t.ny; ++k) {
    const double truth_k = t.offset_per_m[k] - affine.dot(g[k]);
    sum_error += std::pow(s.offset_per_m[k] - truth_k, 2);
    sum_truth += truth_k * truth_k;
  }
  EXPECT_LT(std::sqrt(sum_error / (t.nx * t.ny)), 0.001);
  EXPECT_LT(sum_error, 0.1 * sum_truth);

  // An existing calibration is not replaced without --overwrite (exit 2, untouched).
  r = Heatwave("calibrate depth -q --scan " + session.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--overwrite"), std::string::npos) << r.output;
  // A threshold no recording meets: written, FAIL, exit 1.
  r = Heatwave("calibrate depth --overwrite --max-sigma-mm 0.01 --scan " + session.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("FAIL  sigma_mm_at_3m"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error: the depth calibration failed QA: sigma_mm_at_3m"), std::string::npos) << r.output;
  EXPECT_NE(Read(out / "depth_correction.json").find("\"verdict\": \"FAIL\""), std::string::npos);
}

TEST(CalibrateDepthCli, BadInputsAreOneLineAndWriteNothing) {
  const fs::path folder = TestFolder();  // first: it empties this test's folder
  const fs::path session = WallSession();
  const fs::path out = folder / "out";
  // Depth frames of scattered points (a sensor looking at clutter, not a wall): no plane.
  const fs::path copy = folder / "no-wall";
  fs::copy(session, copy, fs::copy_options::recursive);
  cv::RNG random(7);
  for (const auto& entry : fs::directory_iterator(copy / "depth")) {
    cv::Mat depth(240, 320, CV_16UC1);
    random.fill(depth, cv::RNG::UNIFORM, 2500, 20000);  // 0.5 to 4 m at 5000 units per metre
    cv::imwrite(entry.path().string(), depth);
  }
  Result r = Heatwave("calibrate depth -q --scan " + copy.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("0 of 24 depth frames show a usable plane, at least 6 are needed"), std::string::npos)
      << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // No depth stream.
  fs::remove(copy / "depth.txt");
  r = Heatwave("calibrate depth -q --scan " + copy.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // Bad options.
  r = Heatwave("calibrate depth -q --nx 1 --scan " + session.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--nx: must be in [2, 256], got 1"), std::string::npos) << r.output;
  EXPECT_EQ(Heatwave("calibrate depth -q --max-sigma-mm 0 --scan " + session.string() + " --out " + out.string()).exit_code, 2);
  EXPECT_EQ(Heatwave("calibrate depth -q --step 0 --scan " + session.string() + " --out " + out.string()).exit_code, 2);
  EXPECT_EQ(Heatwave("calibrate depth -q --out " + out.string()).exit_code, 2);
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
