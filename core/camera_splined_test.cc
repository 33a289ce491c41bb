// CameraModel's splined model (mrcal's LENSMODEL_SPLINED_STEREOGRAPHIC) against mrcal
// itself: projection, Jacobians, unprojection, scaling, Check.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "core/camera.h"
#include "core/camera_mrcal.h"
#include "core/splined_test_support.h"

namespace hw::core {
namespace {

using test::SplinedTestCamera;

// Splined test cameras: the default (16 x 13 cubic, 80 degrees across a 66-degree image),
// a quadratic one, and a wide one (fov_x 120 degrees on 115, corners 70 degrees off axis).
std::vector<CameraModel> TestCameras() {
  return {SplinedTestCamera(),
          SplinedTestCamera(640, 512, 554, {2, 10, 9, 66}, -0.12),
          SplinedTestCamera(800, 600, 380, {3, 20, 15, 120}, -0.03)};
}

// Pixels every `step` pixels over the image, edges (-0.5, width - 0.5) included.
std::vector<Eigen::Vector2d> PixelGrid(const CameraModel& camera, double step) {
  std::vector<Eigen::Vector2d> pixels;
  for (double y = -0.5;; y = std::min(y + step, camera.height - 0.5)) {
    for (double x = -0.5;; x = std::min(x + step, camera.width - 0.5)) {
      pixels.emplace_back(x, y);
      if (x == camera.width - 0.5) break;
    }
    if (y == camera.height - 0.5) break;
  }
  return pixels;
}

Eigen::Vector2d MrcalPixel(const CameraModel& camera, const Eigen::Vector3d& p) {
  const mrcal_lensmodel_t lensmodel = MrcalLensModel(camera);
  const Eigen::VectorXd intrinsics = camera.Params();
  const mrcal_point3_t point{{p.x(), p.y(), p.z()}};
  mrcal_point2_t q{};
  EXPECT_TRUE(mrcal_project(&q, nullptr, nullptr, &point, 1, &lensmodel, intrinsics.data()));
  return {q.x, q.y};
}

TEST(SplinedCameraTest, NameRoundTrips) {
  EXPECT_EQ(CameraModelTypeName(CameraModelType::kSplined), "splined");
  EXPECT_EQ(ParseCameraModelType("splined"), CameraModelType::kSplined);
}

TEST(SplinedCameraTest, ProjectIsMrcalProject) {
  for (const CameraModel& camera : TestCameras()) {
    ASSERT_EQ(camera.Check(), "");
    double worst_px = 0;
    for (const Eigen::Vector2d& pixel : PixelGrid(camera, 16)) {
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(pixel);
      ASSERT_TRUE(ray) << pixel.transpose();
      for (const double z_m : {0.4, 3.0}) {
        const Eigen::Vector3d p = *ray * z_m;
        worst_px = std::max(worst_px, (camera.Project(p) - MrcalPixel(camera, p)).norm());
      }
    }
    // Same arithmetic up to mrcal's f (u + du) + c against ours f (u + du) + c with u from
    // (x/z, y/z, 1) instead of (x, y, z): rounding only.
    EXPECT_LT(worst_px, 1e-9) << camera.splined.nx;
  }
}

TEST(SplinedCameraTest, SplineReproducesTheSampledSurface) {
  // The controls are a smooth cubic surface du(u) sampled at the knots; the spline through
  // them is close to it (a cubic B-spline smooths a cubic by O(h^2 du'') ~ 1e-4 here). A
  // wrong control order (x/y or row/column swapped) would be off by ~du itself, 1e-2.
  const CameraModel camera = SplinedTestCamera();
  double worst = 0;
  for (const Eigen::Vector2d& pixel : PixelGrid(camera, 32)) {
    const Eigen::Vector2d xy = camera.Unproject(pixel)->head<2>();
    const Eigen::Vector2d u = xy * 2 / (1 + std::sqrt(1 + xy.squaredNorm()));
    const double r2 = u.squaredNorm();
    const Eigen::Vector2d du(-0.08 * u.x() * r2 + 2e-3 * u.x() * u.y() + 1e-3 * (r2 + 2 * u.x() * u.x()),
                             -0.08 * u.y() * r2 + 1e-3 * (r2 + 2 * u.y() * u.y()) + 2e-3 * u.x() * u.y());
    worst = std::max(worst, (camera.Distort(xy) - (u + du)).norm());
  }
  std::printf("splined 16 x 13: max |Distort - (u + du(u))| = %.2e\n", worst);
  EXPECT_LT(worst, 3e-3);
}

TEST(SplinedCameraTest, JacobiansMatchFiniteDifferences) {
  for (const CameraModel& camera : TestCameras()) {
    double worst = 0;
    const Eigen::VectorXd params = camera.Params();
    for (const Eigen::Vector2d& pixel : PixelGrid(camera, 97)) {
      const Eigen::Vector3d p = *camera.Unproject(pixel) * 1.3;
      Eigen::Matrix<double, 2, 3> J_point;
      Eigen::Matrix<double, 2, Eigen::Dynamic> J_params;
      const Eigen::Vector2d q = camera.Project(p, &J_point, &J_params);
      ASSERT_EQ(q, camera.Project(p));
      ASSERT_EQ(J_params.cols(), camera.NumParams());
      // Entries up to f / z ~ 700 px/m and f ~ 500 px per control: central differences with
      // a step of 1e-6 are exact for the (piecewise cubic) spline up to rounding, ~1e-7 px.
      const auto compare = [&](const Eigen::Vector2d& numeric, const Eigen::Vector2d& analytic) {
        worst = std::max(worst, (numeric - analytic).cwiseAbs().maxCoeff() /
                                    (1 + analytic.cwiseAbs().maxCoeff()));
      };
      for (int i = 0; i < 3; ++i) {
        Eigen::Vector3d step = Eigen::Vector3d::Zero();
        step[i] = 1e-6;
        compare((camera.Project(p + step) - camera.Project(p - step)) / 2e-6, J_point.col(i));
      }
      for (int i = 0; i < camera.NumParams(); i += (i < 4 ? 1 : 7)) {
        const double step = 1e-6 * std::max(1.0, std::abs(params[i]));
        CameraModel plus = camera, minus = camera;
        Eigen::VectorXd shifted = params;
        shifted[i] += step;
        plus.SetParams(shifted);
        shifted[i] -= 2 * step;
        minus.SetParams(shifted);
        compare((plus.Project(p) - minus.Project(p)) / (2 * step), J_params.col(i));
      }
    }
    EXPECT_LT(worst, 1e-6) << camera.splined.nx;
  }
}

TEST(SplinedCameraTest, UnprojectThenProjectReturnsThePixelEverywhereInTheImage) {
  for (const CameraModel& camera : TestCameras()) {
    double worst_px = 0;
    for (const Eigen::Vector2d& pixel : PixelGrid(camera, 8)) {
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(pixel);
      ASSERT_TRUE(ray) << pixel.transpose();
      worst_px = std::max(worst_px, (camera.Project(*ray) - pixel).norm());
    }
    // Newton stops one step past 1e-10 px.
    EXPECT_LT(worst_px, 1e-8) << camera.splined.nx;
  }
}

TEST(SplinedCameraTest, UnprojectAgreesWithMrcalUnproject) {
  for (const CameraModel& camera : TestCameras()) {
    const mrcal_lensmodel_t lensmodel = MrcalLensModel(camera);
    const Eigen::VectorXd intrinsics = camera.Params();
    double worst_rad = 0;
    for (const Eigen::Vector2d& pixel : PixelGrid(camera, 61)) {
      const mrcal_point2_t q{{pixel.x(), pixel.y()}};
      mrcal_point3_t v{};
      ASSERT_TRUE(mrcal_unproject(&v, &q, 1, &lensmodel, intrinsics.data()));
      const Eigen::Vector3d theirs = Eigen::Vector3d(v.x, v.y, v.z).normalized();
      const Eigen::Vector3d ours = camera.Unproject(pixel)->normalized();
      worst_rad = std::max(worst_rad, std::acos(std::min(1.0, ours.dot(theirs))));
    }
    // mrcal's own solver stops near 1e-8 px; 1e-6 rad is ~1e-3 px at f = 500.
    EXPECT_LT(worst_rad, 1e-6) << camera.splined.nx;
  }
}

TEST(SplinedCameraTest, ScalingChangesOnlyTheCore) {
  const CameraModel camera = SplinedTestCamera();
  const CameraModel half = camera.Scaled(0.5);
  EXPECT_EQ(half.distortion, camera.distortion);
  EXPECT_EQ(half.splined, camera.splined);
  EXPECT_EQ(half.Check(), "");
  double worst_px = 0;
  for (const Eigen::Vector2d& pixel : PixelGrid(camera, 20)) {
    const Eigen::Vector3d p = *camera.Unproject(pixel);
    // Pixel edges scale: (q + 0.5) / 2 - 0.5.
    worst_px = std::max(worst_px, (half.Project(p) - ((pixel.array() + 0.5) * 0.5 - 0.5).matrix()).norm());
  }
  EXPECT_LT(worst_px, 1e-8);
}

TEST(SplinedCameraTest, CheckNamesTheField) {
  const CameraModel good = SplinedTestCamera();
  const auto check = [&](auto change) {
    CameraModel camera = good;
    change(camera);
    return camera.Check();
  };
  EXPECT_EQ(check([](CameraModel& c) { c.splined.order = 4; }),
            "splined.order: must be 2 or 3, got 4");
  EXPECT_EQ(check([](CameraModel& c) { c.splined.nx = 3; }),
            "splined.nx: must be in [4, 64], got 3");
  EXPECT_EQ(check([](CameraModel& c) { c.splined.ny = 65; }),
            "splined.ny: must be in [4, 64], got 65");
  EXPECT_EQ(check([](CameraModel& c) { c.splined.fov_x_deg = 0; }),
            "splined.fov_x_deg: must be in [1, 179] degrees, got 0");
  EXPECT_EQ(check([](CameraModel& c) { c.splined.fov_x_deg = 180; }),
            "splined.fov_x_deg: must be in [1, 179] degrees, got 180");
  EXPECT_EQ(check([](CameraModel& c) { c.distortion.pop_back(); }),
            "distortion: splined with nx = 16, ny = 13 needs 2 nx ny = 416 control values, got "
            "415");
  EXPECT_EQ(check([](CameraModel& c) { c.distortion[7] = std::numeric_limits<double>::quiet_NaN(); }),
            "distortion[7]: must be finite, got nan");
  EXPECT_EQ(check([](CameraModel& c) { c.fx = 0; }), "fx: must be in [1, 1e6] px, got 0");
}

TEST(SplinedCameraTest, EqualityComparesTheConfig) {
  const CameraModel a = SplinedTestCamera();
  CameraModel b = a;
  EXPECT_TRUE(a == b);
  b.splined.fov_x_deg = 71;
  EXPECT_FALSE(a == b);
  b = a;
  b.distortion[100] += 1e-12;
  EXPECT_FALSE(a == b);
  // The config of a non-splined camera is not part of it.
  CameraModel p = CameraModel::Pinhole(640, 480, 500, 500), q = p;
  q.splined.nx = 9;
  EXPECT_TRUE(p == q);
}

}  // namespace
}  // namespace hw::core
