#include "reconstruct/camera_rays.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "core/splined_test_support.h"
#include "reconstruct/tsdf_test_support.h"

namespace hw::reconstruct {
namespace {

// The undistorted radius r of a purely radial lens r (1 + k1 r²) = r_distorted on the
// physical branch (r below the fold, where d/dr = 1 + 3 k1 r² vanishes): bisection, not the
// Newton of CameraModel::Undistort. k1 < 0 and r_distorted below the fold's value.
double UndistortRadial(double k1, double r_distorted) {
  double lo = 0, hi = std::sqrt(-1 / (3 * k1));
  for (int i = 0; i < 100; ++i) {
    const double mid = (lo + hi) / 2;
    (mid * (1 + k1 * mid * mid) < r_distorted ? lo : hi) = mid;
  }
  return (lo + hi) / 2;
}

// Every valid pixel: the lens model maps its ray back onto its centre, and the covering
// pinhole's image holds its undistorted projection (in double, as a reader would check it;
// covering_pixel in float, as the raycast uses it).
void ExpectRaysProjectToTheirPixels(const CameraRays& rays) {
  const core::CameraModel& camera = rays.camera();
  const PinholeCamera& covering = rays.covering_pinhole();
  EXPECT_EQ(covering.fx, static_cast<float>(camera.fx));
  EXPECT_EQ(covering.fy, static_cast<float>(camera.fy));
  double worst_px = 0;
  for (int y = 0; y < rays.height(); ++y) {
    for (int x = 0; x < rays.width(); ++x) {
      if (!rays.valid(x, y)) {
        EXPECT_TRUE(std::isnan(rays.xy(x, y).x()) && std::isnan(rays.distortion_px(x, y)));
        continue;
      }
      const Eigen::Vector2f xy = rays.xy(x, y);
      const Eigen::Vector2d pixel = camera.Project(Eigen::Vector3d(xy.x(), xy.y(), 1));
      worst_px = std::max(worst_px, (pixel - Eigen::Vector2d(x, y)).norm());
      const double u = double(covering.fx) * double(xy.x()) + double(covering.cx);
      const double v = double(covering.fy) * double(xy.y()) + double(covering.cy);
      EXPECT_TRUE(u >= -0.5 && u < covering.width - 0.5 && v >= -0.5 && v < covering.height - 0.5)
          << x << " " << y << ": " << u << " " << v;
      const Eigen::Vector2f uv = rays.covering_pixel(x, y);
      EXPECT_TRUE(uv.x() >= -0.5f && uv.x() < covering.width - 0.5f && uv.y() >= -0.5f &&
                  uv.y() < covering.height - 0.5f);
      // The distortion as the contract defines it, from the float ray: the float rounding
      // of xy (1e-7 relative, < 1e-4 px) and the 1e-10 px of Undistort apart, the same.
      const Eigen::Vector2d ray = xy.cast<double>();
      const double moved =
          (Eigen::Vector2d(x, y) - Eigen::Vector2d(camera.fx * ray.x() + camera.cx, camera.fy * ray.y() + camera.cy))
              .norm();
      EXPECT_NEAR(rays.distortion_px(x, y), moved, 1e-3) << x << " " << y;
    }
  }
  // Undistort converges to 1e-10 px; the float ray (1e-7 relative of |xy| < 1.5, through f
  // 300 and a lens Jacobian below 1) adds < 1e-4 px.
  EXPECT_LT(worst_px, 1e-3);
  ::testing::Test::RecordProperty("worst_reprojection_px", std::to_string(worst_px));
}

// The design thermal lens: every pixel is inside its invertible range (d r_d / d r_u =
// 1 − 0.9 r² + 0.6 r⁴ − 0.14 r⁶ > 0.5 up to r = 1.3, while the corners are at r ≈ 0.8).
TEST(CameraRays, ThermalLensRaysProjectToTheirPixels) {
  const CameraRays rays(test::ThermalCamera());
  ASSERT_EQ(rays.width(), 320);
  ASSERT_EQ(rays.height(), 240);
  int valid = 0;
  for (int y = 0; y < rays.height(); ++y) {
    for (int x = 0; x < rays.width(); ++x) valid += rays.valid(x, y);
  }
  EXPECT_EQ(valid, 320 * 240);
  ExpectRaysProjectToTheirPixels(rays);

  // Barrel distortion pushes the undistorted projections outwards: the covering pinhole is
  // grown on every side, by at most the extent needed plus the 1 px margin and the pixel
  // rounding (< 3 px).
  const PinholeCamera& covering = rays.covering_pinhole();
  float u_lo = 1e9f, u_hi = -1e9f, v_lo = 1e9f, v_hi = -1e9f;
  for (int y = 0; y < rays.height(); ++y) {
    for (int x = 0; x < rays.width(); ++x) {
      const Eigen::Vector2f uv = rays.covering_pixel(x, y);
      u_lo = std::min(u_lo, uv.x());
      u_hi = std::max(u_hi, uv.x());
      v_lo = std::min(v_lo, uv.y());
      v_hi = std::max(v_hi, uv.y());
    }
  }
  EXPECT_GT(covering.width, 320 + 40);  // ≈ 35 px on each side at mid-height
  EXPECT_GT(covering.height, 240 + 20);
  EXPECT_LT(u_lo, 2.5f);
  EXPECT_LT(v_lo, 2.5f);
  EXPECT_GT(u_hi, covering.width - 3.5f);
  EXPECT_GT(v_hi, covering.height - 3.5f);
  // Whole-pixel shifts of the principal point.
  const double shift_x = double(covering.cx) - 161.2, shift_y = double(covering.cy) - 118.4;
  EXPECT_NEAR(shift_x, std::round(shift_x), 1e-4);
  EXPECT_NEAR(shift_y, std::round(shift_y), 1e-4);

  // The distortion grows from the centre to the corners: along each diagonal, and the
  // largest of the image is at a corner. At the principal point it is 0 (the pixel nearest
  // it is 0.36 px away: |Δ| ≈ 0.3 · 0.36³ / 300² px, nothing).
  EXPECT_LT(rays.distortion_px(161, 118), 1e-4);
  for (const auto& [corner_x, corner_y] : {std::pair{0, 0}, {319, 0}, {0, 239}, {319, 239}}) {
    float previous = -1;
    for (int i = 0; i <= 100; ++i) {
      const int x = static_cast<int>(std::lround(161 + (corner_x - 161) * i / 100.0));
      const int y = static_cast<int>(std::lround(118 + (corner_y - 118) * i / 100.0));
      EXPECT_GE(rays.distortion_px(x, y), previous) << x << " " << y;
      previous = rays.distortion_px(x, y);
    }
  }
  float largest = 0;
  int largest_x = -1, largest_y = -1;
  for (int y = 0; y < rays.height(); ++y) {
    for (int x = 0; x < rays.width(); ++x) {
      if (rays.distortion_px(x, y) > largest) {
        largest = rays.distortion_px(x, y);
        largest_x = x;
        largest_y = y;
      }
    }
  }
  EXPECT_TRUE((largest_x == 0 || largest_x == 319) && (largest_y == 0 || largest_y == 239))
      << largest_x << " " << largest_y;
  EXPECT_GT(largest, 20.0f);
  RecordProperty("corner_distortion_px", std::to_string(largest));
}

// A purely radial lens, k1 = −0.3, on a short focal length: r_d = r (1 − 0.3 r²) peaks at
// r = 1/√0.9 = 1.054, r_d = 0.7027; the corners (r_d = 199.6 / 220 = 0.907) and the ends
// of the middle row (0.725) have no preimage at all. Every pixel inside the fold has its
// ray, and distortion_px is f · (r − r_d) with r found by bisection.
TEST(CameraRays, StrongBarrelHasNoRayPastTheFold) {
  core::CameraModel camera;
  camera.width = 320;
  camera.height = 240;
  camera.type = core::CameraModelType::kOpenCV;
  camera.fx = camera.fy = 220;
  camera.cx = 159.5;
  camera.cy = 119.5;
  camera.distortion = {-0.3, 0, 0, 0};
  const CameraRays rays(camera);
  const double r_fold = 1 / std::sqrt(0.9), rd_fold = r_fold * (1 - 0.3 * r_fold * r_fold);
  int valid = 0, invalid = 0;
  for (int y = 0; y < rays.height(); ++y) {
    for (int x = 0; x < rays.width(); ++x) {
      const double r_d = std::hypot(x - camera.cx, y - camera.cy) / camera.fx;
      if (r_d > rd_fold) {
        EXPECT_FALSE(rays.valid(x, y)) << x << " " << y;
        ++invalid;
        continue;
      }
      // Up to 0.69 the map's slope is still > 0.2 (1 − 0.9 r², r = 0.93): a well-posed
      // inverse. Between 0.69 and the fold the certification may give up (it errs safe).
      if (r_d > 0.69) continue;
      ASSERT_TRUE(rays.valid(x, y)) << x << " " << y;
      ++valid;
      const double expected_px = camera.fx * (UndistortRadial(-0.3, r_d) - r_d);
      EXPECT_NEAR(rays.distortion_px(x, y), expected_px, 1e-3) << x << " " << y;
    }
  }
  EXPECT_GT(invalid, 1000);
  EXPECT_GT(valid, 60000);
  ExpectRaysProjectToTheirPixels(rays);
}

// Without distortion: the model's own pinhole covers the image, nothing moves.
TEST(CameraRays, PinholeModelIsItsOwnCovering) {
  core::CameraModel pinhole = core::CameraModel::Pinhole(160, 120, 120, 121);
  pinhole.cx = 81.3;  // off-centre, so that the covering must keep it
  core::CameraModel zero_opencv = pinhole;
  zero_opencv.type = core::CameraModelType::kOpenCV;
  zero_opencv.distortion = {0, 0, 0, 0, 0};
  for (const core::CameraModel& camera : {pinhole, zero_opencv}) {
    const CameraRays rays(camera);
    const PinholeCamera expected = PinholeCamera::Of(camera);
    const PinholeCamera& covering = rays.covering_pinhole();
    EXPECT_EQ(covering.width, expected.width);
    EXPECT_EQ(covering.height, expected.height);
    EXPECT_EQ(covering.cx, expected.cx);
    EXPECT_EQ(covering.cy, expected.cy);
    for (int y = 0; y < rays.height(); ++y) {
      for (int x = 0; x < rays.width(); ++x) {
        ASSERT_TRUE(rays.valid(x, y));
        EXPECT_EQ(rays.distortion_px(x, y), 0.0f);
      }
    }
    ExpectRaysProjectToTheirPixels(rays);
  }
}

// mrcal's splined model (a 320 x 240 lens, 16 x 13 knots over 80 degrees): every pixel has
// its ray, and a spline whose controls are all 0 is still not distortion-free (it is the
// stereographic projection, not a pinhole).
TEST(CameraRays, SplinedLensRaysProjectToTheirPixels) {
  const CameraRays rays(core::test::SplinedTestCamera(320, 240, 250));
  for (int y = 0; y < rays.height(); ++y) {
    for (int x = 0; x < rays.width(); ++x) ASSERT_TRUE(rays.valid(x, y)) << x << " " << y;
  }
  ExpectRaysProjectToTheirPixels(rays);
  core::CameraModel stereographic = core::test::SplinedTestCamera(320, 240, 250);
  std::fill(stereographic.distortion.begin(), stereographic.distortion.end(), 0.0);
  const CameraRays flat(stereographic);
  ExpectRaysProjectToTheirPixels(flat);
  // At the image corner (r ~ 0.8, 38 degrees) the stereographic projection is 2 tan(theta/2)
  // = 0.69 against tan(theta) = 0.8: ~25 px at f = 250.
  EXPECT_GT(flat.distortion_px(0, 0), 10.0f);
}

TEST(CameraRays, DefaultHasNoPixels) {
  const CameraRays rays;
  EXPECT_EQ(rays.width(), 0);
  EXPECT_EQ(rays.height(), 0);
}

}  // namespace
}  // namespace hw::reconstruct
