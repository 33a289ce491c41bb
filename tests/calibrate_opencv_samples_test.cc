// Real images: OpenCV's own chessboard samples (Debian package opencv-doc, left01..14.jpg, 9 × 6
// inner corners; left10 is not packaged). heatwave's detections solved by heatwave (mrcal,
// with its outlier rejection) and by cv::calibrateCamera on the corners heatwave kept must
// give the same camera: both then minimise the same reprojection error with the same
// 5-coefficient model, and differ only by mrcal's weak regularisation and the stopping rules.
#include <filesystem>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "calibrate/intrinsics_solver.h"
#include "calibrate/target_detect.h"
#include "core/rig.h"

namespace {

namespace fs = std::filesystem;
using namespace hw;

TEST(CalibrateOpenCvSamples, AgreesWithCalibrateCameraOnTheSameDetections) {
  const fs::path dir = "/usr/share/doc/opencv-doc/examples/data";
  if (!fs::exists(dir / "left01.jpg")) {
    GTEST_SKIP() << "opencv-doc is not installed (scripts/install-deps.sh installs it)";
  }
  core::Target target;
  target.type = core::TargetType::kChessboard;
  target.rows = 6;
  target.cols = 9;
  target.square_m = 0.025;  // unknown for the samples; the intrinsics do not depend on it
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  std::vector<calibrate::ViewObservation> views;
  cv::Size size;
  for (int i = 1; i <= 14; ++i) {
    const fs::path file = dir / cv::format("left%02d.jpg", i);
    if (!fs::exists(file)) continue;
    const cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    size = image.size();
    const calibrate::Detection d = calibrate::DetectChessboard(image, target, {}, file.filename().string());
    if (d.accepted) views.push_back({d.corner_ids, d.pixels});
  }
  ASSERT_GE(views.size(), 12u);  // 13 packaged views, all detected (target_detect_test)

  const calibrate::IntrinsicsResult ours = calibrate::SolveIntrinsics(target, size.width, size.height, views);
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  for (size_t v = 0; v < views.size(); ++v) {
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> pixels;
    for (size_t k = 0; k < views[v].pixels.size(); ++k) {
      if (ours.outlier[v][k]) continue;
      const Eigen::Vector3d& p = corners[static_cast<size_t>(views[v].corner_ids[k])];
      object.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), 0.0f);
      pixels.emplace_back(static_cast<float>(views[v].pixels[k].x()), static_cast<float>(views[v].pixels[k].y()));
    }
    object_points.push_back(object);
    image_points.push_back(pixels);
  }
  cv::Mat k, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  const double cv_rms = cv::calibrateCamera(object_points, image_points, size, k, dist, rvecs, tvecs, 0,
                                            cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 200, 1e-12));
  const core::CameraModel& c = ours.camera;
  const double sigma_fx = std::sqrt(ours.intrinsics_covariance(0, 0));
  const double sigma_cx = std::sqrt(ours.intrinsics_covariance(2, 2));
  // Agreement well inside one reported standard deviation: the two solve one problem.
  EXPECT_NEAR(c.fx, k.at<double>(0, 0), 0.05 * sigma_fx) << "sigma " << sigma_fx;
  EXPECT_NEAR(c.fy, k.at<double>(1, 1), 0.05 * sigma_fx);
  EXPECT_NEAR(c.cx, k.at<double>(0, 2), 0.05 * sigma_cx) << "sigma " << sigma_cx;
  EXPECT_NEAR(c.cy, k.at<double>(1, 2), 0.05 * std::sqrt(ours.intrinsics_covariance(3, 3)));
  // OpenCV's RMS is, like ours, the RMS of the corners' residual norms (over the same inliers).
  EXPECT_NEAR(ours.rms_px, cv_rms, 0.01 * cv_rms);
  RecordProperty("fx_ours", std::to_string(c.fx));
  RecordProperty("fx_opencv", std::to_string(k.at<double>(0, 0)));
  std::printf("%d outliers; heatwave fx %.3f fy %.3f cx %.3f cy %.3f rms %.4f | OpenCV fx %.3f fy %.3f cx %.3f cy %.3f rms %.4f | "
              "sigma fx %.3f cx %.3f\n",
              ours.outliers, c.fx, c.fy, c.cx, c.cy, ours.rms_px, k.at<double>(0, 0), k.at<double>(1, 1), k.at<double>(0, 2),
              k.at<double>(1, 2), cv_rms, sigma_fx, sigma_cx);
}

}  // namespace
