#include "core/depth_correction.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/rig.h"
#include "core/rig_test_support.h"

namespace hw::core {
namespace {

CameraModel Kinect() {
  CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.type = CameraModelType::kOpenCV;
  camera.fx = camera.fy = 570;
  camera.cx = 319.5;
  camera.cy = 239.5;
  camera.distortion = {0.05, -0.1, 0, 0};
  return camera;
}

// A field linear in x and y is reproduced exactly by bilinear interpolation.
DepthCorrection Planar(const CameraModel& camera, double a, double bx, double by) {
  DepthCorrection c = DepthCorrection::ZeroOver(camera, 5, 4);
  c.AddAffine(a, bx, by);
  return c;
}

TEST(DepthCorrection, GridCoversTheImageAndInterpolatesBilinearly) {
  const CameraModel camera = Kinect();
  const DepthCorrection c = Planar(camera, -0.004, 0.002, -0.003);
  ASSERT_EQ(c.Check(), "");
  // Every pixel's ray lies inside the grid (the corners, bowed by distortion, included).
  for (const auto& [u, v] : {std::pair{0.0, 0.0}, {639.0, 0.0}, {0.0, 479.0}, {639.0, 479.0},
                             {319.5, 0.0}, {0.0, 239.5}}) {
    const Eigen::Vector3d ray = *camera.Unproject({u, v});
    EXPECT_GE(ray.x(), c.x_range[0]);
    EXPECT_LE(ray.x(), c.x_range[1]);
    EXPECT_GE(ray.y(), c.y_range[0]);
    EXPECT_LE(ray.y(), c.y_range[1]);
  }
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, {0.31, -0.2}, {-0.5, 0.37}}) {
    EXPECT_NEAR(c.OffsetAt(x, y), -0.004 + 0.002 * x - 0.003 * y, 1e-15);
  }
  // Clamped beyond the border: the border's value.
  EXPECT_NEAR(c.OffsetAt(5.0, 0.0), c.OffsetAt(c.x_range[1], 0.0), 1e-15);
  EXPECT_NEAR(c.OffsetAt(0.0, -5.0), c.OffsetAt(0.0, c.y_range[0]), 1e-15);
}

// AddAffine on a field that is not affine: the field everywhere (between nodes too) gains
// exactly the affine function; the nodes at the grid's corners gain its corner values.
TEST(DepthCorrection, AddAffineAddsThatFieldEverywhere) {
  DepthCorrection c = DepthCorrection::ZeroOver(Kinect(), 6, 5);
  for (size_t k = 0; k < c.offset_per_m.size(); ++k) c.offset_per_m[k] = 0.001 * std::sin(1.7 * k);
  const DepthCorrection before = c;
  c.AddAffine(-0.0023, 0.0004, -0.0008);
  for (const auto& [x, y] : {std::pair{0.0, 0.0}, {0.31, -0.2}, {-0.5, 0.37}, {c.x_range[0], c.y_range[1]}}) {
    EXPECT_NEAR(c.OffsetAt(x, y) - before.OffsetAt(x, y), -0.0023 + 0.0004 * x - 0.0008 * y, 1e-15);
  }
  EXPECT_NEAR(c.offset_per_m.back() - before.offset_per_m.back(),
              -0.0023 + 0.0004 * c.x_range[1] - 0.0008 * c.y_range[1], 1e-15);
  EXPECT_EQ(c.Check(), "");
}

TEST(DepthCorrection, CorrectionInvertsAnInverseDepthOffset) {
  const CameraModel camera = Kinect();
  const DepthCorrection c = Planar(camera, -0.0047, 0.001, 0.0);
  // A point at z_true read with inverse depth 1/z_true + δ comes back to z_true.
  for (const double z_true : {0.5, 2.0, 3.5, 5.0}) {
    const double x = 0.4, y = -0.3;
    const double z_measured = 1 / (1 / z_true + c.OffsetAt(x, y));
    EXPECT_NEAR(c.Correct(z_measured, x, y), z_true, 1e-12 * z_true);
  }
  EXPECT_EQ(c.Correct(0.0, 0, 0), 0.0);
  // A positive δ large enough to send the point past infinity drops it.
  DepthCorrection far = Planar(camera, 0.5, 0, 0);
  EXPECT_EQ(far.Correct(2.5, 0, 0), 0.0);
  EXPECT_NEAR(far.Correct(1.0, 0, 0), 2.0, 1e-12);
}

TEST(DepthCorrection, MapAndImageCorrectionAgreeWithThePointFormula) {
  const CameraModel camera = Kinect();
  const DepthCorrection c = Planar(camera, -0.004, 0.003, 0.002);
  const cv::Mat map = DepthOffsetMap(c, camera);
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(3.0f));
  depth.at<float>(10, 10) = 0;
  depth.at<float>(11, 10) = std::nanf("");
  CorrectDepth(map, &depth);
  EXPECT_EQ(depth.at<float>(10, 10), 0.0f);
  EXPECT_TRUE(std::isnan(depth.at<float>(11, 10)));
  for (const auto& [u, v] : {std::pair{0, 0}, {639, 479}, {320, 100}}) {
    const Eigen::Vector3d ray = *camera.Unproject({double(u), double(v)});
    EXPECT_NEAR(depth.at<float>(v, u), c.Correct(3.0, ray.x(), ray.y()), 2e-6);
  }
}

TEST(DepthCorrection, RigYamlRoundTripAndErrors) {
  Rig rig = rig_test::MakeRig(true, true);
  rig.depth_correction = Planar(rig.depth, -0.004, 0.003, 0.002);
  rig.depth_correction->offset_per_m[3] = 1.0 / 3.0;
  const std::string text = FormatRig(rig);
  const Rig back = ParseRig(text, "rig.yaml");
  ASSERT_TRUE(back.depth_correction.has_value());
  EXPECT_EQ(back.depth_correction->nx, 5);
  EXPECT_EQ(back.depth_correction->ny, 4);
  EXPECT_EQ(back.depth_correction->x_range, rig.depth_correction->x_range);
  EXPECT_EQ(back.depth_correction->y_range, rig.depth_correction->y_range);
  EXPECT_EQ(back.depth_correction->offset_per_m, rig.depth_correction->offset_per_m);
  EXPECT_FALSE(back.depth_correction->plate_affine_per_m.has_value());
  EXPECT_FALSE(back.depth_correction->ScaleMeasured());
  // The plate's affine part, when one was folded in, reads back exactly.
  rig.depth_correction->plate_affine_per_m = std::array<double, 3>{-0.0023397988360435128, 0, 1.0 / 3e4};
  const Rig with_plate = ParseRig(FormatRig(rig), "rig.yaml");
  ASSERT_TRUE(with_plate.depth_correction->plate_affine_per_m.has_value());
  EXPECT_EQ(*with_plate.depth_correction->plate_affine_per_m, *rig.depth_correction->plate_affine_per_m);
  EXPECT_TRUE(with_plate.depth_correction->ScaleMeasured());
  rig.depth_correction->plate_affine_per_m = std::array<double, 3>{0, 0.001, 0};  // tilts only
  EXPECT_FALSE(ParseRig(FormatRig(rig), "rig.yaml").depth_correction->ScaleMeasured());
  rig.depth_correction->plate_affine_per_m.reset();
  // Without the block, a rig reads back without one.
  rig.depth_correction.reset();
  EXPECT_FALSE(ParseRig(FormatRig(rig), "rig.yaml").depth_correction.has_value());

  const auto error_of = [&](const std::string& block) {
    try {
      ParseRig(FormatRig(rig) + block, "rig.yaml");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [0, 1], y_range: [0, 1], "
                     "offset_per_m: [0, 0, 0]}\n")
                .find("depth_correction.offset_per_m: must hold nx*ny = 4 values, got 3"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 1, ny: 2, x_range: [0, 1], y_range: [0, 1], "
                     "offset_per_m: [0, 0]}\n")
                .find("depth_correction.nx: must be in [2, 256], got 1"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [1, 0], y_range: [0, 1], "
                     "offset_per_m: [0, 0, 0, 0]}\n")
                .find("depth_correction.x_range: must be [lo, hi]"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [0, 1], y_range: [0, 1], "
                     "offset_per_m: [0, 0, 0, 0], plate_affine_per_m: [0, 0]}\n")
                .find("depth_correction.plate_affine_per_m"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [0, 1], y_range: [0, 1], "
                     "offset_per_m: [0, 0, 0, 0], plate_affine_per_m: [0, 3, 0]}\n")
                .find("depth_correction.plate_affine_per_m[1]: must be finite with |value| <= 1"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [0, 1], y_range: [0, 1], "
                     "offset_per_m: [0, 0, 2, 0]}\n")
                .find("depth_correction.offset_per_m[2]: must be finite with |value| <= 1"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [0, 1], y_range: [0, 1]}\n")
                .find("offset_per_m"),
            std::string::npos);
  EXPECT_NE(error_of("depth_correction: {nx: 2, ny: 2, x_range: [0, 1], y_range: [0, 1], "
                     "offset_per_m: [0, 0, 0, 0], order: 3}\n")
                .find("order"),
            std::string::npos);
}

}  // namespace
}  // namespace hw::core
