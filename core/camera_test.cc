#include "core/camera.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace hw::core {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

CameraModel OpenCVModel(int width, int height, double fx, double fy, double cx, double cy,
                        std::vector<double> distortion) {
  CameraModel model;
  model.width = width;
  model.height = height;
  model.type = CameraModelType::kOpenCV;
  model.fx = fx;
  model.fy = fy;
  model.cx = cx;
  model.cy = cy;
  model.distortion = std::move(distortion);
  return model;
}

struct NamedModel {
  std::string name;
  CameraModel model;
};

// Realistic lenses. Each is one-to-one over its whole image (checked by the round trips), and
// the distorted radius of the image corners is given for scale.
std::vector<NamedModel> TestModels() {
  return {
      {"pinhole", CameraModel::Pinhole(640, 480, 525, 525)},
      // Mild RGB lens, 4 coefficients.
      {"rgb_4", OpenCVModel(640, 480, 525, 523, 321.2, 238.7, {0.1, -0.2, 0.001, -0.0008})},
      // TUM RGB-D freiburg1 RGB camera, 5 coefficients (k3 = 1.16).
      {"tum_fr1_5", OpenCVModel(640, 480, 517.3, 516.5, 318.6, 255.3,
                                {0.2624, -0.9531, -0.0054, 0.0026, 1.1633})},
      // Wide-angle rational model, 8 coefficients; corners at distorted radius ~1.0,
      // undistorted radius ~1.9 (62 degrees off axis).
      {"wide_8", OpenCVModel(640, 480, 400, 401, 322.5, 236.0,
                             {0.35, 0.02, 2e-4, -3e-4, 0.0005, 0.75, 0.08, 0.002})},
      // Thermal-like strong barrel, 5 coefficients; folds over at distorted radius ~0.89,
      // corners at ~0.74.
      {"thermal_5",
       OpenCVModel(640, 512, 554, 556, 317.8, 258.4, {-0.35, 0.12, 1e-3, -5e-4, -0.02})},
  };
}

CameraModel ThermalModel() { return TestModels().back().model; }

// Pixels every `step` pixels over the whole image, including its outer edges at -0.5 and
// width - 0.5 (the last row and column reach them exactly).
std::vector<Eigen::Vector2d> PixelGrid(const CameraModel& model, double step) {
  std::vector<double> xs, ys;
  for (double x = -0.5; x < model.width - 0.5; x += step) xs.push_back(x);
  xs.push_back(model.width - 0.5);
  for (double y = -0.5; y < model.height - 0.5; y += step) ys.push_back(y);
  ys.push_back(model.height - 0.5);
  std::vector<Eigen::Vector2d> pixels;
  for (double y : ys) {
    for (double x : xs) pixels.emplace_back(x, y);
  }
  return pixels;
}

// Points in the camera frame at several depths whose projections cover the whole image: a
// grid over the box of undistorted normalised coordinates spanned by the image border, kept
// when the point projects inside the image.
std::vector<Eigen::Vector3d> PointsCoveringImage(const CameraModel& model) {
  Eigen::Vector2d lo(kInf, kInf), hi(-kInf, -kInf);
  for (const Eigen::Vector2d& pixel : PixelGrid(model, 8)) {
    const bool on_border = pixel.x() == -0.5 || pixel.y() == -0.5 ||
                           pixel.x() == model.width - 0.5 || pixel.y() == model.height - 0.5;
    if (!on_border) continue;
    const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
    if (!ray) continue;
    lo = lo.cwiseMin(ray->head<2>());
    hi = hi.cwiseMax(ray->head<2>());
  }
  std::vector<Eigen::Vector3d> points;
  constexpr int kSteps = 80;
  const std::vector<double> depths_m = {0.3, 1.7, 4.9};
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; j <= kSteps; ++j) {
      const Eigen::Vector2d xy = lo + (hi - lo).cwiseProduct(Eigen::Vector2d(i, j) / kSteps);
      const double z_m = depths_m[static_cast<size_t>(i + j) % depths_m.size()];
      const Eigen::Vector3d point(xy.x() * z_m, xy.y() * z_m, z_m);
      if (model.IsInImage(model.Project(point))) points.push_back(point);
    }
  }
  return points;
}

cv::Mat CvK(const CameraModel& model) {
  return (cv::Mat_<double>(3, 3) << model.fx, 0, model.cx, 0, model.fy, model.cy, 0, 0, 1);
}

cv::Mat CvDistortion(const CameraModel& model) {
  cv::Mat distortion(1, static_cast<int>(model.distortion.size()), CV_64F);
  for (size_t i = 0; i < model.distortion.size(); ++i) {
    distortion.at<double>(0, static_cast<int>(i)) = model.distortion[i];
  }
  return distortion;
}

// Reference for the physical branch, independent of the library's certificate: a dense scan
// of the segment from the centre to the undistorted point, along which the physical branch
// keeps orientation (det J > 0) all the way.
bool DenselyOnPhysicalBranch(const CameraModel& model, const Eigen::Vector2d& xy) {
  for (int i = 1; i <= 1000; ++i) {
    Eigen::Matrix2d J;
    model.Distort(xy * (i / 1000.0), &J);
    if (!(J.determinant() > 0)) return false;
  }
  return true;
}

void Report(const std::string& what, const std::string& model, double value) {
  std::cout << "[ measured ] " << what << " " << model << ": " << value << "\n";
}

TEST(CameraModelTypeTest, NamesRoundTripAndUnknownNamesAreRejected) {
  for (CameraModelType type : {CameraModelType::kPinhole, CameraModelType::kOpenCV}) {
    EXPECT_EQ(ParseCameraModelType(CameraModelTypeName(type)), type);
  }
  EXPECT_EQ(CameraModelTypeName(CameraModelType::kPinhole), "pinhole");
  EXPECT_EQ(CameraModelTypeName(CameraModelType::kOpenCV), "opencv");
  for (const char* name : {"", "Pinhole", "OPENCV", "opencv ", "fisheye", "pinhole\n"}) {
    EXPECT_EQ(ParseCameraModelType(name), std::nullopt) << "'" << name << "'";
  }
}

TEST(CameraModelTest, PinholeFactoryPutsPrincipalPointAtImageCentre) {
  const CameraModel model = CameraModel::Pinhole(640, 480, 525, 520);
  EXPECT_EQ(model.width, 640);
  EXPECT_EQ(model.height, 480);
  EXPECT_EQ(model.type, CameraModelType::kPinhole);
  EXPECT_EQ(model.fx, 525);
  EXPECT_EQ(model.fy, 520);
  EXPECT_EQ(model.cx, 319.5);
  EXPECT_EQ(model.cy, 239.5);
  EXPECT_TRUE(model.distortion.empty());
  EXPECT_EQ(model.Check(), "");
  EXPECT_EQ(CameraModel::Pinhole(7, 5, 1, 1).cx, 3.0);
}

TEST(CameraModelTest, CheckAcceptsEveryTestModel) {
  for (const auto& [name, model] : TestModels()) EXPECT_EQ(model.Check(), "") << name;
}

TEST(CameraModelTest, CheckNamesFieldValueAndConstraint) {
  struct Case {
    std::function<void(CameraModel&)> mutate;
    std::string message;
  };
  const std::vector<Case> cases = {
      {[](CameraModel& m) { m.width = 0; }, "width: must be in [1, 16384] px, got 0"},
      {[](CameraModel& m) { m.width = -640; }, "width: must be in [1, 16384] px, got -640"},
      {[](CameraModel& m) { m.height = 0; }, "height: must be in [1, 16384] px, got 0"},
      {[](CameraModel& m) { m.fx = -525; }, "fx: must be in [1, 1e6] px, got -525"},
      {[](CameraModel& m) { m.fx = 0; }, "fx: must be in [1, 1e6] px, got 0"},
      {[](CameraModel& m) { m.fy = -0.1; }, "fy: must be in [1, 1e6] px, got -0.1"},
      {[](CameraModel& m) { m.fx = kNaN; }, "fx: must be finite, got nan"},
      {[](CameraModel& m) { m.fy = kInf; }, "fy: must be finite, got inf"},
      {[](CameraModel& m) { m.cx = kNaN; }, "cx: must be finite, got nan"},
      {[](CameraModel& m) { m.cy = -kInf; }, "cy: must be finite, got -inf"},
      {[](CameraModel& m) {
         m.distortion = {0.1, 0, 0};
       },
       "distortion: opencv needs 4, 5 or 8 coefficients, got 3"},
      {[](CameraModel& m) { m.distortion = {}; },
       "distortion: opencv needs 4, 5 or 8 coefficients, got 0"},
      {[](CameraModel& m) { m.distortion.resize(6); },
       "distortion: opencv needs 4, 5 or 8 coefficients, got 6"},
      {[](CameraModel& m) { m.distortion.resize(14); },
       "distortion: opencv needs 4, 5 or 8 coefficients, got 14"},
      {[](CameraModel& m) { m.distortion[4] = kNaN; }, "distortion[4]: must be finite, got nan"},
      {[](CameraModel& m) { m.distortion[0] = -kInf; }, "distortion[0]: must be finite, got -inf"},
      {[](CameraModel& m) { m.type = CameraModelType::kPinhole; },
       "distortion: pinhole needs 0 coefficients, got 5"},
      // Values no camera has; each loaded from rig.yaml before: a denormal focal length
      // makes 1/fx inf, a billion-pixel width overflows width * height.
      {[](CameraModel& m) { m.fx = 1e-320; }, "fx: must be in [1, 1e6] px, got 1e-320"},
      {[](CameraModel& m) { m.fy = 0.999; }, "fy: must be in [1, 1e6] px, got 0.999"},
      {[](CameraModel& m) { m.fx = 1.0000001e6; }, "fx: must be in [1, 1e6] px, got 1000000.1"},
      {[](CameraModel& m) { m.width = 1000000000; },
       "width: must be in [1, 16384] px, got 1000000000"},
      {[](CameraModel& m) { m.height = 16385; }, "height: must be in [1, 16384] px, got 16385"},
      {[](CameraModel& m) { m.cx = 1e300; },
       "cx: must be in [-width, 2 width] = [-640, 1280] px, got 1e300"},
      {[](CameraModel& m) { m.cx = -640.5; },
       "cx: must be in [-width, 2 width] = [-640, 1280] px, got -640.5"},
      {[](CameraModel& m) { m.cy = 1024.5; },
       "cy: must be in [-height, 2 height] = [-512, 1024] px, got 1024.5"},
      {[](CameraModel& m) { m.distortion[2] = 1e300; },
       "distortion[2]: must be in [-10000, 10000], got 1e300"},
      {[](CameraModel& m) { m.distortion[0] = -10000.5; },
       "distortion[0]: must be in [-10000, 10000], got -10000.5"},
  };
  for (const Case& c : cases) {
    CameraModel model = ThermalModel();
    ASSERT_EQ(model.Check(), "");
    c.mutate(model);
    EXPECT_EQ(model.Check(), c.message);
  }
  CameraModel pinhole = CameraModel::Pinhole(640, 480, 525, 525);
  pinhole.distortion = {0, 0, 0, 0};
  EXPECT_EQ(pinhole.Check(), "distortion: pinhole needs 0 coefficients, got 4");
  EXPECT_EQ(CameraModel().Check(), "width: must be in [1, 16384] px, got 0");
  // The edges themselves are cameras.
  const std::vector<std::function<void(CameraModel&)>> edges = {
      [](CameraModel& m) { m.fx = 1; },
      [](CameraModel& m) { m.fy = 1e6; },
      [](CameraModel& m) { m.width = CameraModel::kMaxSidePx; },
      [](CameraModel& m) { m.cx = -640; },
      [](CameraModel& m) { m.cy = 1024; },
      [](CameraModel& m) {
        m.distortion = {-1e4, 1e4, 5e-324, -1e-300, 0};
      },
  };
  for (const auto& mutate : edges) {
    CameraModel model = ThermalModel();
    mutate(model);
    EXPECT_EQ(model.Check(), "");
  }
  EXPECT_EQ(CameraModel::Pinhole(1, 1, 1, 1).Check(), "");
  EXPECT_EQ(CameraModel::Pinhole(16384, 16384, 1e6, 1e6).Check(), "");
}

TEST(UndistortOptionsTest, CheckNamesFieldValueAndConstraint) {
  EXPECT_EQ(UndistortOptions().Check(), "");
  UndistortOptions options;
  options.max_iterations = 0;
  EXPECT_EQ(options.Check(), "max_iterations: must be > 0, got 0");
  options = {};
  options.tolerance_px = 0;
  EXPECT_EQ(options.Check(), "tolerance_px: must be > 0 and finite, got 0");
  options.tolerance_px = -1e-3;
  EXPECT_EQ(options.Check(), "tolerance_px: must be > 0 and finite, got -0.001");
  options.tolerance_px = kNaN;
  EXPECT_EQ(options.Check(), "tolerance_px: must be > 0 and finite, got nan");
  options.tolerance_px = kInf;
  EXPECT_EQ(options.Check(), "tolerance_px: must be > 0 and finite, got inf");
}

TEST(CameraModelTest, ParamsOrderAndSetParamsRoundTrip) {
  CameraModel model = ThermalModel();
  const Eigen::VectorXd params = model.Params();
  ASSERT_EQ(params.size(), 9);
  ASSERT_EQ(model.NumParams(), 9);
  EXPECT_EQ(params[0], model.fx);
  EXPECT_EQ(params[1], model.fy);
  EXPECT_EQ(params[2], model.cx);
  EXPECT_EQ(params[3], model.cy);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(params[4 + i], model.distortion[static_cast<size_t>(i)]);

  Eigen::VectorXd changed = params;
  for (int i = 0; i < changed.size(); ++i) changed[i] += 0.25 * (i + 1);
  model.SetParams(changed);
  EXPECT_EQ(model.Params(), changed);
  EXPECT_EQ(model.fx, params[0] + 0.25);
  EXPECT_EQ(model.distortion[4], params[8] + 2.25);
  model.SetParams(params);
  EXPECT_EQ(model, ThermalModel());

  EXPECT_EQ(CameraModel::Pinhole(640, 480, 525, 525).Params(),
            Eigen::Vector4d(525, 525, 319.5, 239.5));
}

TEST(CameraModelTest, KMatrix) {
  const CameraModel model = ThermalModel();
  Eigen::Matrix3d expected;
  expected << 554, 0, 317.8, 0, 556, 258.4, 0, 0, 1;
  EXPECT_EQ(model.K(), expected);
}

TEST(CameraModelTest, EqualityComparesEveryField) {
  const CameraModel base = ThermalModel();
  EXPECT_TRUE(base == ThermalModel());
  const std::vector<std::function<void(CameraModel&)>> changes = {
      [](CameraModel& m) { m.width += 1; },
      [](CameraModel& m) { m.height += 1; },
      [](CameraModel& m) { m.type = CameraModelType::kPinhole; },
      [](CameraModel& m) { m.fx += 1e-9; },
      [](CameraModel& m) { m.fy += 1e-9; },
      [](CameraModel& m) { m.cx += 1e-9; },
      [](CameraModel& m) { m.cy += 1e-9; },
      [](CameraModel& m) { m.distortion[2] += 1e-12; },
      [](CameraModel& m) { m.distortion.push_back(0); },
  };
  for (size_t i = 0; i < changes.size(); ++i) {
    CameraModel changed = base;
    changes[i](changed);
    EXPECT_FALSE(changed == base) << "change " << i;
  }
}

TEST(CameraModelTest, IsInImageUsesPixelEdges) {
  const CameraModel model = CameraModel::Pinhole(640, 480, 525, 525);
  EXPECT_TRUE(model.IsInImage({-0.5, -0.5}));
  EXPECT_TRUE(model.IsInImage({639.499, 479.499}));
  EXPECT_TRUE(model.IsInImage({319.5, 239.5}));
  EXPECT_FALSE(model.IsInImage({639.5, 0}));
  EXPECT_FALSE(model.IsInImage({0, 479.5}));
  EXPECT_FALSE(model.IsInImage({-0.5000001, 0}));
  EXPECT_FALSE(model.IsInImage({0, -0.5000001}));
  EXPECT_FALSE(model.IsInImage({kNaN, 0}));
  EXPECT_FALSE(model.IsInImage({0, kNaN}));
  EXPECT_FALSE(model.IsInImage({kInf, 0}));
}

TEST(CameraModelTest, ProjectMatchesHandComputedValues) {
  const CameraModel pinhole = CameraModel::Pinhole(640, 480, 525, 500);
  const Eigen::Vector2d pixel = pinhole.Project({1.0, -0.5, 2.0});
  EXPECT_DOUBLE_EQ(pixel.x(), 525 * 0.5 + 319.5);
  EXPECT_DOUBLE_EQ(pixel.y(), 500 * -0.25 + 239.5);

  // x = 0.5, y = 0.25: r2 = 0.3125.
  CameraModel model = OpenCVModel(640, 480, 500, 400, 320, 240, {0.1, 0.01, 0, 0});
  const double r2 = 0.3125;
  const double radial = 1 + 0.1 * r2 + 0.01 * r2 * r2;
  Eigen::Vector2d expected(500 * 0.5 * radial + 320, 400 * 0.25 * radial + 240);
  EXPECT_NEAR((model.Project({1.0, 0.5, 2.0}) - expected).norm(), 0, 1e-12);
  // Tangential only: x' = x + 2 p1 x y + p2 (r2 + 2 x^2), y' = y + p1 (r2 + 2 y^2) + 2 p2 x y.
  model.distortion = {0, 0, 0.01, 0.02};
  expected = {500 * (0.5 + 2 * 0.01 * 0.125 + 0.02 * (r2 + 0.5)) + 320,
              400 * (0.25 + 0.01 * (r2 + 0.125) + 2 * 0.02 * 0.125) + 240};
  EXPECT_NEAR((model.Project({1.0, 0.5, 2.0}) - expected).norm(), 0, 1e-12);
  // Rational: radial = (1 + k1 r2) / (1 + k4 r2).
  model.distortion = {0.1, 0, 0, 0, 0, 0.3, 0, 0};
  const double rational = (1 + 0.1 * r2) / (1 + 0.3 * r2);
  expected = {500 * 0.5 * rational + 320, 400 * 0.25 * rational + 240};
  EXPECT_NEAR((model.Project({1.0, 0.5, 2.0}) - expected).norm(), 0, 1e-12);
}

TEST(CameraModelTest, ProjectAgreesWithOpenCV) {
  for (const auto& [name, model] : TestModels()) {
    const std::vector<Eigen::Vector3d> points = PointsCoveringImage(model);
    ASSERT_GT(points.size(), 3000u) << name;
    std::vector<cv::Point3d> cv_points;
    for (const Eigen::Vector3d& p : points) cv_points.emplace_back(p.x(), p.y(), p.z());
    std::vector<cv::Point2d> cv_pixels;
    cv::projectPoints(cv_points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), CvK(model),
                      CvDistortion(model), cv_pixels);
    ASSERT_EQ(cv_pixels.size(), points.size());
    double max_error_px = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector2d pixel = model.Project(points[i]);
      max_error_px =
          std::max(max_error_px, (pixel - Eigen::Vector2d(cv_pixels[i].x, cv_pixels[i].y)).norm());
    }
    Report("max |Project - cv::projectPoints| px", name, max_error_px);
    EXPECT_LT(max_error_px, 1e-9) << name;
  }
}

// OpenCV iterates a fixed point until its own reprojection error is below kCvEpsilonPx; the
// disagreement left is OpenCV's (measured <= 6e-12 px here), so 1e-9 px leaves a wide margin
// while still catching any real difference in the model.
constexpr int kCvIterations = 1000;
constexpr double kCvEpsilonPx = 1e-12;

TEST(CameraModelTest, UnprojectAgreesWithOpenCVUndistortPoints) {
  for (const auto& [name, model] : TestModels()) {
    const std::vector<Eigen::Vector2d> pixels = PixelGrid(model, 8);
    std::vector<cv::Point2d> cv_pixels;
    for (const Eigen::Vector2d& p : pixels) cv_pixels.emplace_back(p.x(), p.y());
    std::vector<cv::Point2d> cv_normalised;
    cv::undistortPoints(cv_pixels, cv_normalised, CvK(model), CvDistortion(model), cv::noArray(),
                        cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS,
                                         kCvIterations, kCvEpsilonPx));
    ASSERT_EQ(cv_normalised.size(), pixels.size());
    double max_error_px = 0;
    for (size_t i = 0; i < pixels.size(); ++i) {
      const std::optional<Eigen::Vector3d> ray = model.Unproject(pixels[i]);
      ASSERT_TRUE(ray.has_value()) << name << " pixel " << pixels[i].transpose();
      // Normalised difference expressed in pixels through the focal lengths.
      const Eigen::Vector2d difference_px =
          (ray->head<2>() - Eigen::Vector2d(cv_normalised[i].x, cv_normalised[i].y))
              .cwiseProduct(Eigen::Vector2d(model.fx, model.fy));
      max_error_px = std::max(max_error_px, difference_px.norm());
    }
    Report("max |Unproject - cv::undistortPoints| px", name, max_error_px);
    EXPECT_LT(max_error_px, 1e-9) << name;
  }
}

TEST(CameraModelTest, UnprojectThenProjectReturnsThePixelEverywhereInTheImage) {
  for (const auto& [name, model] : TestModels()) {
    const std::vector<Eigen::Vector2d> pixels = PixelGrid(model, 4);
    double max_error_px = 0;
    for (const Eigen::Vector2d& pixel : pixels) {
      const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
      ASSERT_TRUE(ray.has_value()) << name << " pixel " << pixel.transpose();
      EXPECT_EQ(ray->z(), 1.0);
      for (double depth_m : {0.25, 3.0}) {
        max_error_px = std::max(max_error_px, (model.Project(*ray * depth_m) - pixel).norm());
      }
    }
    Report("max |Project(Unproject(pixel)) - pixel| px", name, max_error_px);
    EXPECT_LT(max_error_px, 1e-9) << name;
    // Beyond the 1e-9 px required: Undistort stops below tolerance_px = 1e-10 px and takes
    // one more Newton step, which leaves rounding error only (measured <= 3e-13 px).
    EXPECT_LT(max_error_px, 1e-11) << name;
  }
}

TEST(CameraModelTest, ProjectThenUnprojectReturnsTheRayEverywhereInTheImage) {
  for (const auto& [name, model] : TestModels()) {
    const std::vector<Eigen::Vector3d> points = PointsCoveringImage(model);
    ASSERT_GT(points.size(), 3000u) << name;
    double max_error_px = 0;
    for (const Eigen::Vector3d& point : points) {
      const std::optional<Eigen::Vector3d> ray = model.Unproject(model.Project(point));
      ASSERT_TRUE(ray.has_value()) << name << " point " << point.transpose();
      // Ray error on the z = 1 plane, in (undistorted) pixels through the focal lengths.
      const Eigen::Vector2d error_px = (ray->head<2>() - point.head<2>() / point.z())
                                           .cwiseProduct(Eigen::Vector2d(model.fx, model.fy));
      max_error_px = std::max(max_error_px, error_px.norm());
    }
    Report("max |Unproject(Project(point)) - ray| px", name, max_error_px);
    EXPECT_LT(max_error_px, 1e-9) << name;
  }
}

// Central differences: error ~ h^2 |f'''| / 6 (truncation) + eps |f| / h (rounding). The
// steps below keep both well under the tolerances for these smooth, O(1)-curvature maps.
TEST(CameraModelTest, DistortJacobiansMatchFiniteDifferences) {
  constexpr double kStep = 1e-6;  // normalised units and coefficients are O(1): rounding 2e-10
  constexpr double kTolerance = 1e-8;
  for (const auto& [name, model] : TestModels()) {
    double max_error = 0;
    for (const Eigen::Vector2d& pixel : PixelGrid(model, 40)) {
      const Eigen::Vector2d xy = model.Unproject(pixel)->head<2>();
      Eigen::Matrix2d J_xy;
      Eigen::Matrix<double, 2, Eigen::Dynamic> J_dist;
      model.Distort(xy, &J_xy, &J_dist);
      ASSERT_EQ(J_dist.cols(), static_cast<Eigen::Index>(model.distortion.size()));
      for (int i = 0; i < 2; ++i) {
        Eigen::Vector2d step = Eigen::Vector2d::Zero();
        step[i] = kStep;
        const Eigen::Vector2d numeric =
            (model.Distort(xy + step) - model.Distort(xy - step)) / (2 * kStep);
        max_error = std::max(max_error, (numeric - J_xy.col(i)).cwiseAbs().maxCoeff());
      }
      for (size_t i = 0; i < model.distortion.size(); ++i) {
        CameraModel plus = model, minus = model;
        plus.distortion[i] += kStep;
        minus.distortion[i] -= kStep;
        const Eigen::Vector2d numeric = (plus.Distort(xy) - minus.Distort(xy)) / (2 * kStep);
        max_error = std::max(
            max_error, (numeric - J_dist.col(static_cast<Eigen::Index>(i))).cwiseAbs().maxCoeff());
      }
    }
    Report("max |Distort Jacobian - finite difference|", name, max_error);
    EXPECT_LT(max_error, kTolerance) << name;
  }
}

TEST(CameraModelTest, ProjectJacobiansMatchFiniteDifferences) {
  for (const auto& [name, model] : TestModels()) {
    double max_relative_error = 0;
    const std::vector<Eigen::Vector3d> points = PointsCoveringImage(model);
    for (size_t n = 0; n < points.size(); n += 37) {
      const Eigen::Vector3d& point = points[n];
      Eigen::Matrix<double, 2, 3> J_point;
      Eigen::Matrix<double, 2, Eigen::Dynamic> J_params;
      const Eigen::Vector2d pixel = model.Project(point, &J_point, &J_params);
      ASSERT_EQ(pixel, model.Project(point));  // Jacobians do not change the value
      ASSERT_EQ(J_params.cols(), model.NumParams());
      // Entries are up to ~f / z ~ 2000 px/m and ~f ~ 500 px per unit coefficient; a step of
      // 1e-6 relative to the variable gives rounding ~1e-7 px/unit, far below 1e-6 relative.
      const auto compare = [&](const Eigen::Vector2d& numeric, const Eigen::Vector2d& analytic) {
        const double error = (numeric - analytic).cwiseAbs().maxCoeff();
        max_relative_error =
            std::max(max_relative_error, error / (1 + analytic.cwiseAbs().maxCoeff()));
      };
      for (int i = 0; i < 3; ++i) {
        const double step = 1e-6 * std::max(1.0, std::abs(point[i]));
        Eigen::Vector3d delta = Eigen::Vector3d::Zero();
        delta[i] = step;
        compare((model.Project(point + delta) - model.Project(point - delta)) / (2 * step),
                J_point.col(i));
      }
      const Eigen::VectorXd params = model.Params();
      for (int i = 0; i < model.NumParams(); ++i) {
        const double step = 1e-6 * std::max(1.0, std::abs(params[i]));
        CameraModel plus = model, minus = model;
        Eigen::VectorXd shifted = params;
        shifted[i] += step;
        plus.SetParams(shifted);
        shifted[i] -= 2 * step;
        minus.SetParams(shifted);
        compare((plus.Project(point) - minus.Project(point)) / (2 * step), J_params.col(i));
      }
    }
    Report("max relative |Project Jacobian - finite difference|", name, max_relative_error);
    EXPECT_LT(max_relative_error, 1e-6) << name;
  }
}

TEST(CameraModelTest, JacobiansOfPinholeAreExact) {
  const CameraModel model = CameraModel::Pinhole(640, 480, 525, 500);
  Eigen::Matrix<double, 2, 3> J_point;
  Eigen::Matrix<double, 2, Eigen::Dynamic> J_params;
  model.Project({1.0, -0.5, 2.0}, &J_point, &J_params);
  Eigen::Matrix<double, 2, 3> expected_point;
  expected_point << 525 / 2.0, 0, -525 * 1.0 / 4, 0, 500 / 2.0, 500 * 0.5 / 4;
  EXPECT_NEAR((J_point - expected_point).norm(), 0, 1e-12);
  Eigen::Matrix<double, 2, 4> expected_params;
  expected_params << 0.5, 0, 1, 0, 0, -0.25, 0, 1;
  ASSERT_EQ(J_params.cols(), 4);
  EXPECT_NEAR((J_params - expected_params).norm(), 0, 1e-12);
  Eigen::Matrix2d J_xy;
  Eigen::Matrix<double, 2, Eigen::Dynamic> J_dist;
  EXPECT_EQ(model.Distort({0.3, -0.2}, &J_xy, &J_dist), Eigen::Vector2d(0.3, -0.2));
  EXPECT_EQ(J_xy, Eigen::Matrix2d::Identity());
  EXPECT_EQ(J_dist.cols(), 0);
}

TEST(CameraModelTest, UndistortInvertsDistort) {
  const CameraModel model = ThermalModel();
  double max_error = 0;
  for (const Eigen::Vector2d& xy : {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.3, -0.2),
                                    Eigen::Vector2d(-0.9, 0.6), Eigen::Vector2d(1.1, 0)}) {
    const std::optional<Eigen::Vector2d> undistorted = model.Undistort(model.Distort(xy));
    ASSERT_TRUE(undistorted.has_value()) << xy.transpose();
    // The final Newton step takes the error from below tolerance_px (1e-10 px, ~2e-13 here)
    // to rounding level (measured 4e-16).
    EXPECT_NEAR((*undistorted - xy).norm(), 0, 1e-14) << xy.transpose();
    max_error = std::max(max_error, (*undistorted - xy).norm());
  }
  Report("max |Undistort(Distort(xy)) - xy|", "thermal_5", max_error);
}

TEST(CameraModelTest, UnprojectConvergesMillionsOfPixelsOut) {
  // The TUM lens never folds (k3 > 0 dominates): a pixel 1e7 px out has a physical preimage,
  // but Distort there is only accurate to ~1e-9 px, above tolerance_px = 1e-10.
  const CameraModel model = TestModels()[2].model;
  ASSERT_EQ(TestModels()[2].name, "tum_fr1_5");
  const Eigen::Vector2d pixel(-3e6, 9e6);
  const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
  ASSERT_TRUE(ray.has_value());
  EXPECT_LT((model.Project(*ray) - pixel).norm(), 1e-13 * pixel.norm());
}

TEST(CameraModelTest, UnprojectFailsInsteadOfReturningAnUnphysicalPreimage) {
  // Radial-only thermal lens, so wrong preimages can be built exactly along a line:
  // rd(r) = r (1 - 0.35 r^2 + 0.12 r^4 - 0.02 r^6) rises to 0.8904 at r = 1.55, falls
  // through 0 and on to -infinity.
  const CameraModel model =
      OpenCVModel(640, 512, 554, 554, 319.5, 255.5, {-0.35, 0.12, 0, 0, -0.02});
  const auto rd = [](double r) {
    const double u = r * r;
    return r * (1 - 0.35 * u + 0.12 * u * u - 0.02 * u * u * u);
  };
  const auto solve = [&](double target, double lo, double hi) {  // bisection, rd decreasing
    for (int i = 0; i < 200; ++i) {
      const double mid = (lo + hi) / 2;
      (rd(mid) > target ? lo : hi) = mid;
    }
    return (lo + hi) / 2;
  };
  const Eigen::Vector2d direction = Eigen::Vector2d(3, -1).normalized();
  // Beyond the fold: no physical preimage, but one through the centre on the far side.
  {
    const double target = 2.0;
    const double r = solve(-target, 1.6, 10);
    ASSERT_NEAR(model.Distort(-r * direction).x(), target * direction.x(), 1e-12);
    ASSERT_NEAR(model.Distort(-r * direction).y(), target * direction.y(), 1e-12);
    const Eigen::Vector2d pixel =
        Eigen::Vector2d(model.cx, model.cy) + model.fx * target * direction;
    EXPECT_EQ(model.Unproject(pixel), std::nullopt);
  }
  // Inside the image (rd = 0.5) there are unphysical preimages too, one beyond the fold on the
  // same side (built here) and one on the far side; Unproject finds the physical one.
  {
    const double target = 0.5;
    const double wrong_r = solve(target, 1.55, 10);
    ASSERT_NEAR((model.Distort(wrong_r * direction) - target * direction).norm(), 0, 1e-12);
    const std::optional<Eigen::Vector3d> ray =
        model.Unproject(Eigen::Vector2d(model.cx, model.cy) + model.fx * target * direction);
    ASSERT_TRUE(ray.has_value());
    EXPECT_LT(ray->head<2>().norm(), 1.55);
    EXPECT_NEAR(rd(ray->head<2>().norm()), target, 1e-12);
  }
  // Just past the fold radius: no physical preimage, and none is made up.
  EXPECT_EQ(model.Undistort(0.9 * direction), std::nullopt);
}

TEST(CameraModelTest, UnprojectRejectsAPreimageBeyondASecondFold) {
  // rd(r) = r (1 - 0.6 r^2 + 0.15 r^4) rises to 0.551 at r = 0.934, dips to 0.536 at
  // r = 1.236 and rises again: rd = 1 has only the unphysical preimage r = 1.75, where the
  // map keeps orientation and the radial factor is positive; only the segment shows the fold.
  const CameraModel model = OpenCVModel(640, 480, 500, 500, 319.5, 239.5, {-0.6, 0.15, 0, 0});
  const Eigen::Vector2d direction = Eigen::Vector2d(-1, 2).normalized();
  double lo = 1.236, hi = 3;  // bisection on the increasing outer branch
  for (int i = 0; i < 200; ++i) {
    const double mid = (lo + hi) / 2;
    (model.Distort(mid * direction).norm() < 1 ? lo : hi) = mid;
  }
  const Eigen::Vector2d wrong = lo * direction;
  Eigen::Matrix2d J;
  ASSERT_NEAR((model.Distort(wrong, &J) - direction).norm(), 0, 1e-12);
  ASSERT_GT(J.determinant(), 0);
  EXPECT_EQ(model.Undistort(direction), std::nullopt);
  EXPECT_EQ(model.Unproject(Eigen::Vector2d(319.5, 239.5) + 500 * direction), std::nullopt);
}

TEST(CameraModelTest, UnprojectRejectsAPreimageThroughTheCentre) {
  // rd(r) = r (1 - r^2): a pixel at distorted radius 1000 has a preimage at r = 10.03 on the
  // far side of the centre, where det J > 0 again; the radial factor is negative there.
  const CameraModel model = OpenCVModel(640, 480, 500, 500, 319.5, 239.5, {-1, 0, 0, 0});
  const Eigen::Vector2d direction = Eigen::Vector2d(0.6, 0.8);
  double lo = 1, hi = 20;  // r - r^3 = -1000 on the decreasing branch
  for (int i = 0; i < 200; ++i) {
    const double mid = (lo + hi) / 2;
    (mid - mid * mid * mid > -1000 ? lo : hi) = mid;
  }
  Eigen::Matrix2d J;
  ASSERT_NEAR((model.Distort(-lo * direction, &J) - 1000 * direction).norm(), 0, 1e-9);
  ASSERT_GT(J.determinant(), 0);
  EXPECT_EQ(model.Undistort(1000 * direction), std::nullopt);
}

TEST(CameraModelTest, UnprojectFarOutsideTheImageFailsOrIsRight) {
  const CameraModel model = ThermalModel();
  int failures = 0, successes = 0;
  for (double v = -3.0 * model.height; v <= 4.0 * model.height; v += 41) {
    for (double u = -3.0 * model.width; u <= 4.0 * model.width; u += 41) {
      const Eigen::Vector2d pixel(u, v);
      const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
      const double distorted_radius =
          Eigen::Vector2d((u - model.cx) / model.fx, (v - model.cy) / model.fy).norm();
      if (!ray) {
        ++failures;
        continue;
      }
      ++successes;
      // The fold is at distorted radius ~0.89 (tangential terms move it by < 0.01).
      EXPECT_LT(distorted_radius, 0.91) << pixel.transpose();
      EXPECT_LT((model.Project(*ray) - pixel).norm(), 1e-9) << pixel.transpose();
      EXPECT_TRUE(DenselyOnPhysicalBranch(model, ray->head<2>())) << pixel.transpose();
    }
  }
  std::cout << "[ measured ] far grid: " << failures << " nullopt, " << successes << " solved\n";
  EXPECT_GT(failures, 1000);
  EXPECT_GT(successes, 300);
}

// Fuzz-style: random lenses (valid by Check(), coefficients far beyond realistic ones) and
// random pixels up to three image sizes away. Unproject must return nullopt or a ray that
// reprojects onto the pixel from the physical branch; never a wrong ray, never a crash.
TEST(CameraModelTest, UnprojectOnRandomLensesFailsOrIsRight) {
  std::mt19937 random(20240611);
  std::uniform_real_distribution<double> unit(-1, 1);
  int failures = 0, successes = 0;
  for (int lens = 0; lens < 200; ++lens) {
    const int num_coefficients = std::array<int, 3>{4, 5, 8}[static_cast<size_t>(lens % 3)];
    std::vector<double> distortion(static_cast<size_t>(num_coefficients));
    const std::array<double, 8> scales = {1, 0.5, 0.02, 0.02, 0.2, 1, 0.5, 0.2};
    for (size_t i = 0; i < distortion.size(); ++i) distortion[i] = scales[i] * unit(random);
    const CameraModel model =
        OpenCVModel(640, 480, 400 + 200 * unit(random), 400 + 200 * unit(random),
                    320 + 20 * unit(random), 240 + 20 * unit(random), distortion);
    ASSERT_EQ(model.Check(), "");
    for (int n = 0; n < 30; ++n) {
      const Eigen::Vector2d pixel(320 + 3 * 640 * unit(random), 240 + 3 * 480 * unit(random));
      const std::optional<Eigen::Vector3d> ray = model.Unproject(pixel);
      if (!ray) {
        ++failures;
        continue;
      }
      ++successes;
      EXPECT_LT((model.Project(*ray) - pixel).norm(), 1e-9)
          << "lens " << lens << " pixel " << pixel.transpose();
      EXPECT_TRUE(DenselyOnPhysicalBranch(model, ray->head<2>()))
          << "lens " << lens << " pixel " << pixel.transpose();
    }
  }
  std::cout << "[ measured ] random lenses: " << failures << " nullopt, " << successes
            << " solved\n";
  EXPECT_GT(failures, 500);
  EXPECT_GT(successes, 500);
}

// Completeness on random lenses with realistic tangential terms: any point well inside the
// unfolded region (80% of the distance to the first fold along its direction, checked
// densely, and up to 72 degrees off axis) is recovered, even where Newton from the distorted
// point alone would diverge or land on another branch.
TEST(CameraModelTest, UndistortOnRandomLensesRecoversEveryUnfoldedPoint) {
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(-1, 1);
  std::uniform_real_distribution<double> fraction(0, 0.8);
  int checked = 0;
  for (int lens = 0; lens < 100; ++lens) {
    const int num_coefficients = std::array<int, 3>{4, 5, 8}[static_cast<size_t>(lens % 3)];
    std::vector<double> distortion(static_cast<size_t>(num_coefficients));
    const std::array<double, 8> scales = {1, 0.5, 0.002, 0.002, 0.2, 1, 0.5, 0.2};
    for (size_t i = 0; i < distortion.size(); ++i) distortion[i] = scales[i] * unit(random);
    const CameraModel model = OpenCVModel(640, 480, 500, 500, 320, 240, distortion);
    for (int n = 0; n < 20; ++n) {
      const Eigen::Vector2d direction = Eigen::Vector2d(unit(random), unit(random)).normalized();
      double fold_r = 3;
      for (int i = 1; i <= 600; ++i) {
        Eigen::Matrix2d J;
        model.Distort(direction * (i * 0.005), &J);
        if (!(J.determinant() > 0)) {
          fold_r = i * 0.005;
          break;
        }
      }
      const Eigen::Vector2d xy = direction * fold_r * fraction(random);
      const Eigen::Vector2d xy_distorted = model.Distort(xy);
      if (xy_distorted.norm() > 10) continue;  // 5000 px out: beyond any use
      ++checked;
      const std::optional<Eigen::Vector2d> undistorted = model.Undistort(xy_distorted);
      ASSERT_TRUE(undistorted.has_value()) << "lens " << lens << " xy " << xy.transpose();
      EXPECT_LT((*undistorted - xy).norm(), 1e-9 * (1 + xy.norm()))
          << "lens " << lens << " xy " << xy.transpose();
    }
  }
  std::cout << "[ measured ] unfolded points recovered: " << checked << "\n";
  EXPECT_GT(checked, 1500);
}

TEST(CameraModelTest, LensFoldingInsideTheImageFailsAtTheCorners) {
  // TUM freiburg2 RGB truncated to 4 coefficients: rd peaks at 0.663, corners are at 0.79.
  const CameraModel model =
      OpenCVModel(640, 480, 520.9, 521.0, 325.1, 249.7, {0.2312, -0.7849, -0.0033, -0.0001});
  EXPECT_EQ(model.Unproject({-0.5, -0.5}), std::nullopt);
  EXPECT_EQ(model.Unproject({639.5, 479.5}), std::nullopt);
  EXPECT_TRUE(model.Unproject({325.1, 249.7}).has_value());
  EXPECT_TRUE(model.Unproject({100, 249.7}).has_value());
}

TEST(CameraModelTest, UnprojectFailsOnNonFiniteInputOrTooFewIterations) {
  const CameraModel model = ThermalModel();
  EXPECT_EQ(model.Unproject({kNaN, 10}), std::nullopt);
  EXPECT_EQ(model.Unproject({10, kInf}), std::nullopt);
  EXPECT_EQ(CameraModel::Pinhole(640, 480, 525, 525).Unproject({kNaN, 10}), std::nullopt);
  UndistortOptions one_iteration;
  one_iteration.max_iterations = 1;
  EXPECT_EQ(model.Unproject({0, 0}, one_iteration), std::nullopt);
  UndistortOptions loose;
  loose.tolerance_px = 0.5;
  const std::optional<Eigen::Vector3d> ray = model.Unproject({0, 0}, loose);
  ASSERT_TRUE(ray.has_value());
  EXPECT_LT((model.Project(*ray) - Eigen::Vector2d(0, 0)).norm(), 0.5);
}

TEST(CameraModelTest, PinholeUnprojectIsExact) {
  const CameraModel model = CameraModel::Pinhole(640, 480, 525, 500);
  const std::optional<Eigen::Vector3d> ray = model.Unproject({319.5 + 525, 239.5 - 250});
  ASSERT_TRUE(ray.has_value());
  EXPECT_EQ(*ray, Eigen::Vector3d(1, -0.5, 1));
}

TEST(CameraModelTest, ScaledMatchesScalingPixelEdges) {
  for (const auto& [name, model] : TestModels()) {
    EXPECT_EQ(model.Scaled(1), model) << name;
    for (double factor : {0.5, 0.25, 2.0, 1.0 / 3}) {
      const CameraModel scaled = model.Scaled(factor);
      EXPECT_EQ(scaled.width, static_cast<int>(std::lround(model.width * factor)));
      EXPECT_EQ(scaled.height, static_cast<int>(std::lround(model.height * factor)));
      EXPECT_EQ(scaled.type, model.type);
      EXPECT_EQ(scaled.distortion, model.distortion);
      EXPECT_EQ(scaled.Check(), "");
      double max_error_px = 0;
      for (const Eigen::Vector3d& point : PointsCoveringImage(model)) {
        const Eigen::Vector2d expected =
            (model.Project(point) + Eigen::Vector2d(0.5, 0.5)) * factor - Eigen::Vector2d(0.5, 0.5);
        max_error_px = std::max(max_error_px, (scaled.Project(point) - expected).norm());
      }
      EXPECT_LT(max_error_px, 1e-9) << name << " x" << factor;
    }
  }
  // Image edges map to image edges: 640 px -> 320 px, left edge -0.5 stays -0.5.
  const CameraModel half = CameraModel::Pinhole(640, 480, 525, 525).Scaled(0.5);
  EXPECT_EQ(half.width, 320);
  EXPECT_EQ(half.height, 240);
  EXPECT_EQ(half.fx, 262.5);
  EXPECT_EQ(half.cx, 159.5);
  EXPECT_EQ(half.cy, 119.5);
  EXPECT_EQ(CameraModel::Pinhole(640, 480, 525, 525).Scaled(1.0 / 3).width, 213);
}

}  // namespace
}  // namespace hw::core
