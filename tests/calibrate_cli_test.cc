// End-to-end tests of `heatwave calibrate intrinsics` on the fixtures' calibration sessions:
// the solved camera against the session's truth, the QA verdict and exit code, the outputs,
// and what bad inputs do (one line, exit 1, nothing written).
#include <cmath>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/cameramodel_io.h"
#include "core/rig.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) { return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args); }

std::string Read(const fs::path& path) { return hw::core::ReadFile(path, uint64_t{1} << 28); }

// A number following `"key": ` in a JSON text (the first occurrence).
double JsonNumberAfter(const std::string& json, const std::string& key) {
  const size_t at = json.find("\"" + key + "\": ");
  EXPECT_NE(at, std::string::npos) << key;
  return at == std::string::npos ? std::nan("") : std::stod(json.substr(at + key.size() + 4));
}

// The small chessboard session (4 stills of a 7 × 5 board, 320 × 240 colour), rendered once
// per test binary run into its own folder.
fs::path ChessboardSession() {
  static const fs::path folder = [] {
    const fs::path f = TestFolder("chessboard-session");
    const Result r = Heatwave("synth --session intrinsics-chessboard --size small -q --overwrite --out " + f.string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return f;
  }();
  return folder;
}

// A QA profile a 4-still small session can meet.
fs::path WriteLenientProfile(const fs::path& folder) {
  const fs::path path = folder / "qa.yaml";
  hw::core::WriteFileAtomically(path, "version: 1\nmin_views: 3\nmin_coverage: 0.1\nmax_uncertainty_px: 100\n"
                                      "max_rms_px: 1\nmax_worst_px: 10\nmax_view_rms_px: 2\nmax_outlier_fraction: 0.2\n");
  return path;
}

TEST(CalibrateCli, SolvesTheSessionCameraAndGivesAVerdict) {
  const fs::path out = TestFolder() / "out";  // first: it empties this test's folder
  const fs::path session = ChessboardSession();
  // Four views are below the default profile's 10: the camera is solved, written, and FAILS.
  Result r = Heatwave("calibrate intrinsics --images " + session.string() + " --camera rgb --out " + out.string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("FAIL  views"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("error: the camera failed QA: views"), std::string::npos) << r.output;
  for (const char* name : {"intrinsics.json", "camera.cameramodel", "rig.yaml", "diagnostics/residuals.png",
                           "diagnostics/histogram.png", "diagnostics/uncertainty.png"}) {
    EXPECT_TRUE(fs::exists(out / name)) << name;
  }
  const std::string json = Read(out / "intrinsics.json");
  EXPECT_NE(json.find("\"verdict\": \"FAIL\""), std::string::npos);
  // Against the truth: the session's true rgb camera, within 4 reported sigmas (+ 0.5 px
  // for the detector's own bias, which the noise model does not know).
  const hw::core::Rig truth = hw::core::ReadRig(session / "truth" / "rig.yaml");
  const hw::core::Rig solved = hw::core::ReadRig(out / "rig.yaml");
  ASSERT_TRUE(solved.rgb);
  EXPECT_NEAR(solved.rgb->fx, truth.rgb->fx, 0.02 * truth.rgb->fx);
  EXPECT_NEAR(solved.rgb->cx, truth.rgb->cx, 0.03 * truth.rgb->width);
  EXPECT_LT(JsonNumberAfter(json, "rms_px"), 0.5);

  // A profile the session can meet: exit 0.
  r = Heatwave("calibrate intrinsics --images " + session.string() + " --camera rgb --overwrite --profile " +
               WriteLenientProfile(out.parent_path()).string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(Read(out / "intrinsics.json").find("\"verdict\": \"PASS\""), std::string::npos);
}

// The heated-mask session (small, thermal, 16 stills: `synth --views`): the square_grid
// detector's edge scale reaches the detector (another scale, other corners, another focal
// length) and is recorded in intrinsics.json.
TEST(CalibrateCli, TheEdgeScaleReachesTheSquareGridDetector) {
  const fs::path folder = TestFolder();
  const fs::path session = folder / "session";
  Result r = Heatwave("synth --session intrinsics-thermal --size small --views 16 -q --out " + session.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  double fx[2] = {};
  for (int k = 0; k < 2; ++k) {
    const std::string sigma = k == 0 ? "0.8" : "1.5";
    const fs::path out = folder / ("out-" + sigma);
    r = Heatwave("calibrate intrinsics --images " + session.string() + " --camera thermal -q --edge-sigma-px " + sigma +
                 " --profile " + WriteLenientProfile(folder).string() + " --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string json = Read(out / "intrinsics.json");
    EXPECT_NE(json.find("\"edges\": \"steepest\""), std::string::npos);
    EXPECT_DOUBLE_EQ(JsonNumberAfter(json, "edge_sigma_px"), std::stod(sigma));
    fx[k] = hw::core::ReadRig(out / "rig.yaml").thermal->fx;
  }
  EXPECT_NE(fx[0], fx[1]);
}

TEST(CalibrateCli, BadInputsAreOneLineAndWriteNothing) {
  const fs::path folder = TestFolder();  // first: it empties this test's folder
  const fs::path session = ChessboardSession();
  const fs::path out = folder / "out";
  auto run = [&](const std::string& images, const std::string& extra = "") {
    return Heatwave("calibrate intrinsics --images " + images + " --camera rgb -q --out " + out.string() + extra);
  };
  // No image.
  fs::create_directories(folder / "empty");
  Result r = run((folder / "empty").string(), " --target " + (session / "target.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("holds no image"), std::string::npos) << r.output;
  // Images without the target.
  fs::create_directories(folder / "blank");
  for (int i = 0; i < 3; ++i) {
    cv::imwrite((folder / "blank" / ("b" + std::to_string(i) + ".png")).string(), cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)));
  }
  r = run((folder / "blank").string(), " --target " + (session / "target.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("no target found in any of the 3 images"), std::string::npos) << r.output;
  // A target.yaml that contradicts the images.
  hw::core::WriteFileAtomically(folder / "wrong.yaml", "type: chessboard\nrows: 9\ncols: 11\nsquare_m: 0.02\n");
  r = run(session.string(), " --target " + (folder / "wrong.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("does it match the images?"), std::string::npos) << r.output;
  // Too few usable views: two images of the session and a blank one.
  fs::create_directories(folder / "few");
  int copied = 0;
  for (const auto& entry : fs::directory_iterator(session / "rgb")) {
    if (copied < 2) fs::copy(entry.path(), folder / "few" / entry.path().filename());
    ++copied;
  }
  cv::imwrite((folder / "few" / "zz.png").string(), cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)));
  r = run((folder / "few").string(), " --target " + (session / "target.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("too few usable views: 2 of 3 images"), std::string::npos) << r.output;
  // Mixed sizes and an unreadable image.
  cv::imwrite((folder / "few" / "zz.png").string(), cv::Mat(120, 160, CV_8UC1, cv::Scalar(128)));
  r = run((folder / "few").string(), " --target " + (session / "target.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("images of one camera have one size"), std::string::npos) << r.output;
  hw::core::WriteFileAtomically(folder / "few" / "zz.png", "not a png");
  r = run((folder / "few").string(), " --target " + (session / "target.yaml").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("zz.png"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // Bad options.
  EXPECT_EQ(run(session.string(), " --camera infrared").exit_code, 2);
  EXPECT_EQ(run(session.string(), " --model fisheye").exit_code, 2);
  r = run(session.string(), " --edge-sigma-px 0.1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--edge-sigma-px"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(CalibrateCli, SolvesASplinedModelAndCarriesItThroughRigAndCameramodel) {
  const fs::path out = TestFolder() / "out";  // first: it empties this test's folder
  const fs::path session = ChessboardSession();
  hw::core::WriteFileAtomically(out.parent_path() / "qa.yaml",
                                "version: 1\nmin_views: 3\nmin_coverage: 0.1\nmax_uncertainty_px: 100\n"
                                "max_rms_px: 1\nmax_worst_px: 10\nmax_view_rms_px: 2\nmax_outlier_fraction: 0.2\n");
  // A coarse spline: 4 views of a small board constrain few knots.
  const Result r = Heatwave("calibrate intrinsics --images " + session.string() +
                            " --camera rgb --model splined --spline-nx 6 --spline-ny 5 --profile " +
                            (out.parent_path() / "qa.yaml").string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=6_Ny=5_fov_x_deg="), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("Model diff splined vs its opencv8 seed"), std::string::npos) << r.output;
  // rig.yaml and camera.cameramodel carry the same splined camera, bit for bit.
  const hw::core::Rig solved = hw::core::ReadRig(out / "rig.yaml");
  ASSERT_TRUE(solved.rgb);
  EXPECT_EQ(solved.rgb->type, hw::core::CameraModelType::kSplined);
  EXPECT_EQ(solved.rgb->splined.order, 3);
  EXPECT_EQ(solved.rgb->splined.nx, 6);
  EXPECT_EQ(solved.rgb->splined.ny, 5);
  EXPECT_EQ(solved.rgb->distortion.size(), 60u);
  EXPECT_TRUE(hw::core::ReadMrcalCameraModel(out / "camera.cameramodel").camera == *solved.rgb);
  const std::string json = Read(out / "intrinsics.json");
  EXPECT_NE(json.find("\"lens_model\": \"splined\""), std::string::npos);
  EXPECT_NE(json.find("\"splined\": {"), std::string::npos);
  EXPECT_LT(JsonNumberAfter(json, "rms_px"), 0.5);
  // The model difference is reported. Its size is not checked: four views of a 35-corner
  // board do not pin a 60-control spline down (its projection differs from the opencv8
  // seed's by ~20 px over the covered cells at 0.06 px RMS for both), which is what the
  // figure is there to show.
  const std::string difference = json.substr(json.find("\"model_difference\""));
  EXPECT_NE(difference.find("and LENSMODEL_OPENCV8"), std::string::npos);
  EXPECT_GT(JsonNumberAfter(difference, "points"), 100);
  EXPECT_TRUE(std::isfinite(JsonNumberAfter(difference, "rms_px")));

  // Bad spline options: usage errors naming the option, nothing written.
  const fs::path bad = out.parent_path() / "bad";
  for (const std::string& option : {std::string("--spline-nx 3"), std::string("--spline-ny 65"),
                                    std::string("--spline-order 4"), std::string("--spline-fov-deg 180")}) {
    const Result b = Heatwave("calibrate intrinsics --images " + session.string() + " --camera rgb --model splined " +
                              option + " --out " + bad.string());
    EXPECT_EQ(b.exit_code, 2) << option << ": " << b.output;
    EXPECT_NE(b.output.find(option.substr(0, option.find(' ')) + ": must be"), std::string::npos) << b.output;
  }
  // Spline options without the splined model: a usage error, not silently ignored.
  const Result ignored = Heatwave("calibrate intrinsics --images " + session.string() +
                                  " --camera rgb --spline-nx 10 --out " + bad.string());
  EXPECT_EQ(ignored.exit_code, 2) << ignored.output;
  EXPECT_NE(ignored.output.find("apply to --model splined only"), std::string::npos) << ignored.output;
  EXPECT_FALSE(fs::exists(bad));
}

}  // namespace
