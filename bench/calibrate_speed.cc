// heatwave's intrinsics solve (calibrate/intrinsics_solver.h, mrcal, LENSMODEL_OPENCV5) and
// OpenCV's cv::calibrateCamera (5 coefficients k1 k2 p1 p2 k3) side by side on THE SAME
// detections: solve time (best of --repeat, the two alternating and taking turns going
// first), the parameters, the RMS and their differences.
//
//   bench_calibrate_speed --images DIR|GLOB [--rows 6] [--cols 9] [--square 0.025] [--repeat 5]
//   bench_calibrate_speed --synthetic 20 [--target chessboard|square_grid] [--square 0.04] [--repeat 5]
//   either with [--outlier-sigmas 3]: heatwave's outlier threshold (its default; 100 keeps
//   every corner, as OpenCV does, to separate the rejection from the solvers' difference),
//   and [--target-shape 1|0]: heatwave's estimate of the squares' apparent shape (on by
//   default; square_grid only — the time it costs)
//
// --images: every image of a folder (or a cv::glob pattern, e.g. '/data/left*.jpg'), read as
// 8-bit grey, its chessboard (rows x cols inner corners, square metres) found by
// calibrate::DetectChessboard; rejected images are listed and left out. --synthetic N: N
// views x 54 corners of a 9x6 chessboard (or 140 corners of a 7x5 square_grid, 2 cm holes)
// seen by a known opencv5 640x480 camera with
// 0.3 px Gaussian noise per coordinate (as calibrate/intrinsics_solver_test.cc), so the
// bench runs without data and both results can be compared with the truth.
//
// What is timed: SolveIntrinsics as called by `heatwave calibrate intrinsics` (staged
// solve, outlier loop, covariance of the state), and cv::calibrateCamera without its
// optional standard deviations (its own seed, Levenberg-Marquardt, default criteria). Both
// get the same corners; OpenCV takes them as float (its internal format anyway).
// RMS: both are sqrt(sum |r|^2 / N), residual norms in pixels; heatwave's over its inliers
// (also printed over all corners), OpenCV's over all corners.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "bench/bench_timing.h"
#include "calibrate/intrinsics_solver.h"
#include "calibrate/synthetic_views.h"
#include "calibrate/target_detect.h"
#include "core/camera.h"
#include "core/rig.h"
#include "core/transform.h"

namespace {

using hw::bench::Clock;
using hw::bench::Ms;
namespace cal = hw::calibrate;
namespace core = hw::core;

struct Args {
  std::string images;
  int synthetic = 0;
  std::string target = "chessboard";  // --synthetic: chessboard (9 x 6) or square_grid (7 x 5 holes)
  bool target_shape = true;           // heatwave's IntrinsicsOptions::estimate_target_shape
  int rows = 6, cols = 9;
  double square_m = std::numeric_limits<double>::quiet_NaN();  // NaN: per mode's default
  int repeat = 5;
  double outlier_sigmas = 3;  // heatwave's IntrinsicsOptions::outlier_sigmas; 100: none rejected
};

[[noreturn]] void Usage(const char* message) {
  std::fprintf(stderr,
               "%s\nusage: bench_calibrate_speed --images DIR|GLOB [--rows 6] [--cols 9] "
               "[--square 0.025] [--repeat 5]\n"
               "       bench_calibrate_speed --synthetic N [--target chessboard|square_grid] [--square 0.04] [--repeat 5]\n"
               "       either with [--outlier-sigmas 3] (heatwave's rejection; 100: none),\n"
               "       [--target-shape 1|0] (heatwave estimates the squares' apparent shape: square_grid)\n",
               message);
  std::exit(2);
}

Args Parse(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (i + 1 >= argc) Usage(("missing value after " + flag).c_str());
    const char* value = argv[++i];
    if (flag == "--images") args.images = value;
    else if (flag == "--synthetic") args.synthetic = std::atoi(value);
    else if (flag == "--rows") args.rows = std::atoi(value);
    else if (flag == "--cols") args.cols = std::atoi(value);
    else if (flag == "--square") args.square_m = std::atof(value);
    else if (flag == "--repeat") args.repeat = std::atoi(value);
    else if (flag == "--outlier-sigmas") args.outlier_sigmas = std::atof(value);
    else if (flag == "--target") args.target = value;
    else if (flag == "--target-shape") args.target_shape = std::atoi(value) != 0;
    else Usage(("unknown flag " + flag).c_str());
  }
  if (args.images.empty() == (args.synthetic == 0)) Usage("give exactly one of --images, --synthetic");
  if (!args.images.empty() && (args.rows < 2 || args.cols < 2)) Usage("--rows, --cols: >= 2");
  if (args.images.empty() && args.synthetic < 3) Usage("--synthetic: >= 3 views");
  if (args.repeat < 1) Usage("--repeat: >= 1");
  if (args.target != "chessboard" && args.target != "square_grid") Usage("--target: chessboard or square_grid");
  if (std::isnan(args.square_m)) args.square_m = !args.images.empty() ? 0.025 : args.target == "chessboard" ? 0.04 : 0.02;
  if (!(args.square_m > 0)) Usage("--square: > 0 metres");
  return args;
}

struct Problem {
  core::Target target;
  int width = 0, height = 0;
  std::vector<cal::ViewObservation> views;
  bool has_truth = false;
  core::CameraModel truth;
};

// `count` random target poses 0.35-0.6 m away, tilted 10-40° about x and y, rolled up to
// 20°, with every corner in the image; every corner observed with 0.3 px noise.
Problem Synthetic(int count, double square_m, const std::string& target) {
  Problem problem;
  if (target == "square_grid") {  // 7 x 5 holes, pitch 1.75 squares: 140 corners
    problem.target.type = core::TargetType::kSquareGrid;
    problem.target.rows = 5;
    problem.target.cols = 7;
    problem.target.pitch_m = 1.75 * square_m;
  } else {
    problem.target.type = core::TargetType::kChessboard;
    problem.target.rows = 6;
    problem.target.cols = 9;
  }
  problem.target.square_m = square_m;
  problem.truth = cal::test::SyntheticCamera();
  problem.has_truth = true;
  problem.width = problem.truth.width;
  problem.height = problem.truth.height;
  const std::vector<core::Rigid3d> poses =
      cal::test::RandomTargetPoses(problem.truth, problem.target, count, false, 1);
  if (static_cast<int>(poses.size()) < count) {
    std::fprintf(stderr, "no pose keeps a %g m board in the image; try a smaller --square\n", square_m);
    std::exit(1);
  }
  problem.views = cal::test::ObserveTarget(problem.truth, problem.target, poses, 0.3, 2);
  const size_t corners = core::TargetCorners(problem.target).size();
  std::printf("synthetic: %s, %d views x %zu corners, %dx%d, opencv5 truth, 0.3 px noise, "
              "square %g m\n",
              target.c_str(), count, corners, problem.width, problem.height, square_m);
  return problem;
}

Problem FromImages(const Args& args) {
  Problem problem;
  problem.target.type = core::TargetType::kChessboard;
  problem.target.rows = args.rows;
  problem.target.cols = args.cols;
  problem.target.square_m = args.square_m;
  std::vector<cv::String> files;
  if (std::filesystem::is_directory(args.images)) {
    for (const auto& entry : std::filesystem::directory_iterator(args.images)) {
      std::string ext = entry.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".tif" || ext == ".tiff" ||
          ext == ".bmp") {
        files.push_back(entry.path().string());
      }
    }
  } else {
    cv::glob(args.images, files, false);
  }
  std::sort(files.begin(), files.end());
  double detect_ms = 0;
  int accepted = 0;
  for (const cv::String& file : files) {
    const cv::Mat image = cv::imread(file, cv::IMREAD_GRAYSCALE);
    if (image.empty()) {
      std::printf("  %s: unreadable, skipped\n", file.c_str());
      continue;
    }
    const auto t0 = Clock::now();
    const cal::Detection detection = cal::DetectChessboard(image, problem.target, {}, file);
    detect_ms += Ms(t0, Clock::now());
    if (!detection.accepted) {
      std::printf("  %s: rejected (%s)\n", file.c_str(), detection.reason.c_str());
      continue;
    }
    if (problem.width == 0) {
      problem.width = image.cols;
      problem.height = image.rows;
    } else if (image.cols != problem.width || image.rows != problem.height) {
      std::printf("  %s: %dx%d, not %dx%d as the first image, skipped\n", file.c_str(),
                  image.cols, image.rows, problem.width, problem.height);
      continue;
    }
    ++accepted;
    problem.views.push_back({detection.corner_ids, detection.pixels});
  }
  size_t corners = 0;
  for (const cal::ViewObservation& v : problem.views) corners += v.corner_ids.size();
  std::printf("images: %zu files, %d views accepted, %zu corners, %dx%d, chessboard %dx%d "
              "inner corners, square %g m; detection %.0f ms total\n",
              files.size(), accepted, corners, problem.width, problem.height, args.rows,
              args.cols, args.square_m, detect_ms);
  if (accepted < 3) {
    std::fprintf(stderr, "fewer than 3 views: nothing to calibrate\n");
    std::exit(1);
  }
  return problem;
}

struct OpenCvResult {
  core::CameraModel camera;
  double rms_px = 0;
};

OpenCvResult SolveOpenCv(const Problem& problem,
                         const std::vector<std::vector<cv::Point3f>>& object_points,
                         const std::vector<std::vector<cv::Point2f>>& image_points) {
  cv::Mat camera_matrix, distortion;
  std::vector<cv::Mat> rvecs, tvecs;
  OpenCvResult result;
  result.rms_px = cv::calibrateCamera(object_points, image_points,
                                      cv::Size(problem.width, problem.height), camera_matrix,
                                      distortion, rvecs, tvecs);
  core::CameraModel& c = result.camera;
  c.width = problem.width;
  c.height = problem.height;
  c.type = core::CameraModelType::kOpenCV;
  c.fx = camera_matrix.at<double>(0, 0);
  c.fy = camera_matrix.at<double>(1, 1);
  c.cx = camera_matrix.at<double>(0, 2);
  c.cy = camera_matrix.at<double>(1, 2);
  for (int i = 0; i < 5; ++i) c.distortion.push_back(distortion.at<double>(i));
  return result;
}

const char* const kNames[9] = {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"};

}  // namespace

int main(int argc, char** argv) {
  const Args args = Parse(argc, argv);
  const Problem problem = args.images.empty() ? Synthetic(args.synthetic, args.square_m, args.target)
                                              : FromImages(args);

  // The same corners in OpenCV's form.
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(problem.target);
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  for (const cal::ViewObservation& view : problem.views) {
    object_points.emplace_back();
    image_points.emplace_back();
    for (size_t i = 0; i < view.corner_ids.size(); ++i) {
      const Eigen::Vector3d& p = corners[static_cast<size_t>(view.corner_ids[i])];
      object_points.back().emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                        static_cast<float>(p.z()));
      image_points.back().emplace_back(static_cast<float>(view.pixels[i].x()),
                                       static_cast<float>(view.pixels[i].y()));
    }
  }

  cal::IntrinsicsOptions options;
  options.model = cal::LensModel::kOpenCv5;
  options.outlier_sigmas = args.outlier_sigmas;
  options.estimate_target_shape = args.target_shape;
  if (const std::string error = options.Check(); !error.empty()) Usage(error.c_str());
  cal::IntrinsicsResult hw_result;
  OpenCvResult cv_result;
  double hw_best_ms = 1e300, cv_best_ms = 1e300, hw_best_cpu = 1e300, cv_best_cpu = 1e300;
  std::vector<double> hw_ms, cv_ms;
  auto run_hw = [&] {
    const double cpu0 = hw::bench::CpuMs();
    const auto t0 = Clock::now();
    hw_result = cal::SolveIntrinsics(problem.target, problem.width, problem.height,
                                     problem.views, options);
    const double ms = Ms(t0, Clock::now());
    hw_best_cpu = std::min(hw_best_cpu, hw::bench::CpuMs() - cpu0);
    hw_best_ms = std::min(hw_best_ms, ms);
    hw_ms.push_back(ms);
  };
  auto run_cv = [&] {
    const double cpu0 = hw::bench::CpuMs();
    const auto t0 = Clock::now();
    cv_result = SolveOpenCv(problem, object_points, image_points);
    const double ms = Ms(t0, Clock::now());
    cv_best_cpu = std::min(cv_best_cpu, hw::bench::CpuMs() - cpu0);
    cv_best_ms = std::min(cv_best_ms, ms);
    cv_ms.push_back(ms);
  };
  for (int r = 0; r < args.repeat; ++r) {  // alternating; each goes first every other time
    if (r % 2 == 0) {
      run_hw();
      run_cv();
    } else {
      run_cv();
      run_hw();
    }
  }

  // heatwave's RMS over all corners (outliers included), as OpenCV's.
  double sum2 = 0;
  size_t n = 0;
  for (const auto& view : hw_result.residuals_px) {
    for (const Eigen::Vector2d& r : view) sum2 += r.squaredNorm(), ++n;
  }
  const double hw_rms_all = std::sqrt(sum2 / static_cast<double>(n));

  std::printf("\n%zu views, %zu corners, %d repeats (best of), OpenCV %d threads\n",
              problem.views.size(), n, args.repeat, cv::getNumThreads());
  std::printf("%-10s %10s %10s   %s\n", "", "heatwave", "OpenCV", "(ms: best wall, best CPU)");
  std::printf("%-10s %10.2f %10.2f   ratio heatwave/OpenCV %.2f (wall), %.2f (CPU)\n",
              "solve ms", hw_best_ms, cv_best_ms, hw_best_ms / cv_best_ms,
              hw_best_cpu / cv_best_cpu);
  std::printf("%-10s %10.2f %10.2f\n", "CPU ms", hw_best_cpu, cv_best_cpu);
  hw::bench::Summary("  heatwave wall", hw_ms);
  hw::bench::Summary("  OpenCV wall", cv_ms);

  const Eigen::VectorXd hw_params = hw_result.camera.Params();
  const Eigen::VectorXd cv_params = cv_result.camera.Params();
  std::printf("\n%-4s %14s %14s %12s %9s", "", "heatwave", "OpenCV", "hw - cv", "/hw sigma");
  if (problem.has_truth) std::printf(" %12s %12s %12s", "truth", "hw err", "cv err");
  std::printf("\n");
  const Eigen::VectorXd truth = problem.has_truth ? problem.truth.Params() : Eigen::VectorXd();
  for (int i = 0; i < 9; ++i) {
    const double sigma = std::sqrt(hw_result.intrinsics_covariance(i, i));
    const double diff = hw_params(i) - cv_params(i);
    std::printf("%-4s %14.6g %14.6g %12.3g %9.2f", kNames[i], hw_params(i), cv_params(i), diff,
                diff / sigma);
    if (problem.has_truth) {
      std::printf(" %12.6g %12.3g %12.3g", truth(i), hw_params(i) - truth(i),
                  cv_params(i) - truth(i));
    }
    std::printf("\n");
  }
  std::printf("RMS  heatwave %.4f px (inliers; %.4f px all %zu corners, %d outliers), "
              "OpenCV %.4f px (all corners)\n",
              hw_result.rms_px, hw_rms_all, n, hw_result.outliers, cv_result.rms_px);

  // The two cameras compared where it matters: the pixel each projects a ray to. Rays through
  // a 9x7 grid of heatwave's pixels, unprojected by heatwave's camera, projected by OpenCV's.
  double worst = 0, sum = 0;
  int count = 0;
  for (int gy = 0; gy < 7; ++gy) {
    for (int gx = 0; gx < 9; ++gx) {
      const Eigen::Vector2d q((problem.width - 1) * gx / 8.0, (problem.height - 1) * gy / 6.0);
      const auto ray = hw_result.camera.Unproject(q);
      if (!ray) continue;
      const double d = (cv_result.camera.Project(*ray) - q).norm();
      worst = std::max(worst, d);
      sum += d * d;
      ++count;
    }
  }
  std::printf("projection difference over a 9x7 pixel grid (heatwave ray -> OpenCV pixel): "
              "RMS %.3f px, worst %.3f px\n",
              std::sqrt(sum / std::max(count, 1)), worst);
  return 0;
}
