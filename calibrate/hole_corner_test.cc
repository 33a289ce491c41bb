// VisibleHoleCorner against a brute-force ray test of which points of the front plane see
// through both openings of a hole in a thick plate.

#include "calibrate/hole_corner.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace hw::calibrate {
namespace {

// The hole [x0, x0 + s] × [y0, y0 + s], plate z in [0, t]. A point (u, v) of the front plane
// shows the background when it is inside the front opening and the camera's ray through it
// is inside the back opening at z = t.
bool SeesThrough(double u, double v, double x0, double y0, double s, double t, const double c[3]) {
  if (u < x0 || u > x0 + s || v < y0 || v > y0 + s) return false;
  const double f = (t - c[2]) / -c[2];  // ray from c through (u, v, 0) reaches z = t
  const double bu = c[0] + (u - c[0]) * f, bv = c[1] + (v - c[1]) * f;
  return bu >= x0 && bu <= x0 + s && bv >= y0 && bv <= y0 + s;
}

TEST(VisibleHoleCorner, MatchesTheApertureFoundByRays) {
  const double x0 = 0.1, y0 = -0.05, s = 0.04;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> lateral(-0.8, 0.8), distance(0.4, 1.5), thickness(0.0005, 0.01);
  const double step = 2e-5;  // grid of the brute force, m
  int tilted = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const double c[3] = {lateral(rng), lateral(rng), -distance(rng)};
    const double t = thickness(rng);
    // The aperture's extent by rays.
    double lo_x = 1e9, hi_x = -1e9, lo_y = 1e9, hi_y = -1e9;
    for (double u = x0; u <= x0 + s; u += step) {
      for (double v = y0; v <= y0 + s; v += 8 * step) {
        if (SeesThrough(u, v, x0, y0, s, t, c)) lo_x = std::min(lo_x, u), hi_x = std::max(hi_x, u);
      }
    }
    for (double v = y0; v <= y0 + s; v += step) {
      for (double u = x0; u <= x0 + s; u += 8 * step) {
        if (SeesThrough(u, v, x0, y0, s, t, c)) lo_y = std::min(lo_y, v), hi_y = std::max(hi_y, v);
      }
    }
    ASSERT_LT(lo_x, hi_x) << "trial " << trial;
    // Corners TL, TR, BR, BL with their outward directions.
    const double corners[4][2] = {{x0, y0}, {x0 + s, y0}, {x0 + s, y0 + s}, {x0, y0 + s}};
    const double outward[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int k = 0; k < 4; ++k) {
      double visible[2];
      VisibleHoleCorner(corners[k], outward[k], t, c, visible);
      const double expect_x = outward[k][0] > 0 ? hi_x : lo_x, expect_y = outward[k][1] > 0 ? hi_y : lo_y;
      EXPECT_NEAR(visible[0], expect_x, 1.5 * step) << "trial " << trial << " corner " << k;
      EXPECT_NEAR(visible[1], expect_y, 1.5 * step) << "trial " << trial << " corner " << k;
      tilted += std::abs(visible[0] - corners[k][0]) > 10 * step;
    }
  }
  EXPECT_GT(tilted, 40);  // the cameras were off-axis enough for the walls to show
}

TEST(VisibleHoleCorner, ThinPlateAndHeadOnViewKeepTheCorner) {
  const double corner[2] = {0.2, 0.1}, outward[2] = {1, -1};
  const double oblique[3] = {-0.5, 0.4, -0.8};
  double visible[2];
  VisibleHoleCorner(corner, outward, 0.0, oblique, visible);
  EXPECT_DOUBLE_EQ(visible[0], 0.2);
  EXPECT_DOUBLE_EQ(visible[1], 0.1);
  // A camera beyond the corner on both sides looks into the hole past it: the front edges.
  const double beyond[3] = {0.5, -0.3, -1.0};
  VisibleHoleCorner(corner, outward, 0.003, beyond, visible);
  EXPECT_EQ(visible[0], 0.2);
  EXPECT_EQ(visible[1], 0.1);
}

// Moving the camera through the plane of a wall switches the visible edge without a jump:
// Ceres sees a continuous residual.
TEST(VisibleHoleCorner, IsContinuousWhereTheVisibleEdgeSwitches) {
  const double corner[2] = {0.2, 0.1}, outward[2] = {1, 1};
  const double t = 0.005;
  for (double dx : {-1e-6, 1e-6}) {
    const double c[3] = {0.2 + dx, -0.3, -0.7};
    double visible[2];
    VisibleHoleCorner(corner, outward, t, c, visible);
    EXPECT_NEAR(visible[0], 0.2, 1e-8);
  }
  // Far off to the left the right wall shows: the corner moves in by t·(x − c_x)/(t − c_z).
  const double c[3] = {-0.3, 0.1, -0.7};
  double visible[2];
  VisibleHoleCorner(corner, outward, t, c, visible);
  EXPECT_NEAR(visible[0], 0.2 - t * 0.5 / 0.705, 1e-12);
  EXPECT_NEAR(visible[1], 0.1, 1e-12);  // in the plane y = 0.1 of the bottom wall
}

}  // namespace
}  // namespace hw::calibrate
