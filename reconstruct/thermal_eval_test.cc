#include "reconstruct/thermal_eval.h"

#include <chrono>
#include <iostream>
#include <cmath>
#include <map>
#include <utility>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/ply.h"
#include "fixtures/scenes.h"
#include "fixtures/synth_scan.h"
#include "tests/support.h"

namespace hw::reconstruct {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;
using Eigen::Vector3i;

// nx × ny vertices at (x0 + i·step, y0 + j·step, z), index j·nx + i; two triangles per
// cell, except the cell whose lower corner is `hole` (when given).
struct GridMesh {
  std::vector<Vector3d> vertices;
  std::vector<Vector3i> faces;
};
GridMesh MakeGrid(int nx, int ny, double x0, double y0, double step, double z,
                  std::pair<int, int> hole = {-1, -1}) {
  GridMesh g;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) g.vertices.emplace_back(x0 + i * step, y0 + j * step, z);
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      if (std::make_pair(i, j) == hole) continue;
      const int a = j * nx + i;
      g.faces.emplace_back(a, a + 1, a + nx + 1);
      g.faces.emplace_back(a, a + nx + 1, a + nx);
    }
  return g;
}

std::vector<Vector3f> ToFloat(const std::vector<Vector3d>& v) {
  std::vector<Vector3f> out;
  for (const Vector3d& p : v) out.push_back(p.cast<float>());
  return out;
}

// A 1 m square plane z = 0 centred on the origin, vertices every `step`, temperature t(x, y).
template <class Field>
TemperatureTruth PlaneTruth(double step, Field t) {
  const int n = static_cast<int>(std::lround(1.0 / step)) + 1;
  const GridMesh g = MakeGrid(n, n, -0.5, -0.5, step, 0);
  TemperatureTruth truth;
  truth.vertices = g.vertices;
  truth.faces = g.faces;
  for (const Vector3d& p : g.vertices) truth.temperature_c.push_back(t(p.x(), p.y()));
  return truth;
}

double Linear(double x, double y) { return 20 + 5 * x + 2 * y; }  // K/m: |gradient| = √29

TEST(TemperatureErrorOptions, CheckNamesTheField) {
  TemperatureErrorOptions o;
  EXPECT_EQ(o.Check(), "");
  o.edge_exclusion_m = 0;
  EXPECT_EQ(o.Check(), "");
  o.edge_exclusion_m = -0.001;
  EXPECT_NE(o.Check().find("edge_exclusion_m"), std::string::npos);
  o = {};
  o.max_distance_m = 0;
  EXPECT_NE(o.Check().find("max_distance_m"), std::string::npos);
  o = {};
  o.uniform_radius_m = NAN;
  EXPECT_NE(o.Check().find("uniform_radius_m"), std::string::npos);
  o = {};
  o.uniform_range_k = 0;
  EXPECT_NE(o.Check().find("uniform_range_k"), std::string::npos);
  o = {};
  o.num_threads = -1;
  EXPECT_NE(o.Check().find("num_threads"), std::string::npos);
  for (const double bad : {-0.5, 10.5, double{NAN}}) {
    o = {};
    o.resolved_footprints = bad;
    EXPECT_NE(o.Check().find("resolved_footprints"), std::string::npos) << bad;
  }
  o.resolved_footprints = 0;
  EXPECT_EQ(o.Check(), "");
}

TEST(TemperatureErrors, StatsAndInterpolatedPercentile) {
  TemperatureComparison c;
  c.truth_c = {0, 0, 0, 0, 0, NAN, 0};
  c.uniform = {1, 1, 0, 0, 0, 1, 0};
  const TemperatureErrorStats s = TemperatureErrors(c, {1, -2, 3, 4, 5, 7, NAN});
  EXPECT_EQ(s.vertices, 7);
  EXPECT_EQ(s.observed, 6);
  EXPECT_EQ(s.compared, 5);
  EXPECT_EQ(s.compared_uniform, 2);
  // |errors| 1 2 3 4 5: rank 0.95·4 = 3.8 → 4 + 0.8·(5 − 4).
  EXPECT_NEAR(s.p95_abs_k, 4.8, 1e-12);
  EXPECT_NEAR(s.mean_k, 11.0 / 5, 1e-12);
  EXPECT_NEAR(s.rmse_k, std::sqrt(55.0 / 5), 1e-12);
  EXPECT_EQ(s.max_abs_k, 5);
  // Uniform: errors 1, −2; rank 0.95 → 1 + 0.95.
  EXPECT_NEAR(s.p95_abs_uniform_k, 1.95, 1e-12);
  EXPECT_NEAR(s.mean_uniform_k, -0.5, 1e-12);
  EXPECT_NEAR(s.rmse_uniform_k, std::sqrt(2.5), 1e-12);
  // Nothing observed: counts 0, stats NaN.
  const TemperatureErrorStats none = TemperatureErrors(c, std::vector<double>(7, NAN));
  EXPECT_EQ(none.compared, 0);
  EXPECT_TRUE(std::isnan(none.rmse_k) && std::isnan(none.p95_abs_k) && std::isnan(none.mean_uniform_k));
}

TEST(TemperatureErrors, AffineFitTakesOutACameraGainAndOffset) {
  // A camera reading 2 % high in slope and 1.5 K high: estimate = 1.02 · truth + 1.5, plus a
  // ±0.1 K alternating error the fit must leave.
  TemperatureComparison c;
  std::vector<double> estimate;
  for (int i = 0; i < 100; ++i) {
    c.truth_c.push_back(20 + 0.3 * i);
    c.uniform.push_back(i % 10 != 3);  // some outside the uniform subset
    estimate.push_back(1.02 * c.truth_c.back() + 1.5 + ((i % 2) ? 0.1 : -0.1) + (i % 10 == 3 ? 50 : 0));
  }
  const TemperatureErrorStats s = TemperatureErrors(c, estimate);
  EXPECT_NEAR(s.mean_uniform_k, 0.02 * (20 + 0.3 * 49.5) + 1.5, 0.05);
  EXPECT_NEAR(s.affine_gain, 1.02, 2e-3);
  EXPECT_NEAR(s.affine_offset_k, 1.5, 0.03);
  EXPECT_NEAR(s.rmse_affine_k, 0.1 / 1.02, 5e-3);
  // The excluded vertices are all odd (+0.1): the fit sees a few more −0.1 than +0.1, which
  // shifts its offset by ~0.01 K.
  EXPECT_LT(s.p95_abs_affine_k, 0.12);
}

// The same camera (gain 1.02, offset +1.5 K, ±0.1 K) and 4 % of the vertices 30–80 K off
// (reflections on metal, misplaced edges): the fit keeps the camera's gain and offset — the
// regression of the truth on the estimate gave 0.37 here (a camera gain of 2.7) — and the
// error after it counts the outliers at their full size.
TEST(TemperatureErrors, AffineFitIsNotTiltedByOutliers) {
  TemperatureComparison c;
  std::vector<double> estimate;
  double outlier_sum2 = 0;
  for (int i = 0; i < 200; ++i) {
    c.truth_c.push_back(20 + 0.15 * i);
    c.uniform.push_back(1);
    const double outlier = i % 25 == 7 ? 30.0 + 5 * (i % 11) : 0.0;
    estimate.push_back(1.02 * c.truth_c.back() + 1.5 + ((i % 2) ? 0.1 : -0.1) + outlier);
    outlier_sum2 += std::pow(outlier / 1.02, 2);
  }
  const TemperatureErrorStats s = TemperatureErrors(c, estimate);
  EXPECT_NEAR(s.affine_gain, 1.02, 2e-3);
  EXPECT_NEAR(s.affine_offset_k, 1.5, 0.05);
  EXPECT_NEAR(s.rmse_affine_k, std::sqrt((outlier_sum2 + 192 * std::pow(0.1 / 1.02, 2)) / 200), 0.05);
  EXPECT_NEAR(s.p95_abs_affine_k, 0.1 / 1.02, 0.01);  // the 95th percentile: the ±0.1 K vertices
}

// A fusion that loses half the contrast (a misregistered model smears hot onto cool): the
// fitted gain stops at 0.9, so the map takes out at most a camera's gain and the loss stays
// in the error (the unclamped fit would call it a gain of 0.5 and report no error).
TEST(TemperatureErrors, AffineFitDoesNotTakeOutAFusionsLossOfContrast) {
  TemperatureComparison c;
  std::vector<double> estimate;
  for (int i = 0; i < 100; ++i) {
    c.truth_c.push_back(20 + 0.4 * i);  // 20 … 59.6 °C
    c.uniform.push_back(1);
    estimate.push_back(0.5 * c.truth_c.back() + 20);
  }
  const TemperatureErrorStats s = TemperatureErrors(c, estimate);
  EXPECT_DOUBLE_EQ(s.affine_gain, 0.9);
  // (0.5 t + 20 − o) / 0.9 − t with o the least-squares offset at gain 0.9: a line of slope
  // −4/9 through zero at the mean truth (39.8 °C): RMSE 4/9 · σ_t, σ_t = 0.4 · √((100² − 1)/12).
  EXPECT_NEAR(s.rmse_affine_k, 4.0 / 9 * 0.4 * std::sqrt((100.0 * 100 - 1) / 12), 1e-6);
}

// Nine uniform vertices of qualities 0.1 … 0.9 in shuffled order, one outside the uniform
// subset and one without a quality (neither counted), the estimate's error 1 K in the
// lowest third, 2 K in the middle one, 3 K in the best, one vertex unobserved: classes
// 0.1–0.3, 0.4–0.6, 0.7–0.9 (each three vertices, the unobserved one in its range but not
// compared), RMSE exactly 1, 2, 3 K; after a gain/offset map the residuals it leaves. Tied
// qualities at a border go to the lower class.
TEST(TemperatureErrors, ByViewQualityTerciles) {
  TemperatureComparison c;
  const std::vector<double> q = {0.5, 0.1, 0.9, 0.3, 0.7, 0.2, 0.8, 0.4, 0.6, 0.05, NAN};
  c.truth_c.assign(q.size(), 20.0);
  c.uniform = {1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 1};
  std::vector<double> estimate;
  for (double quality : q) estimate.push_back(20.0 + (quality <= 0.3 ? 1 : quality <= 0.6 ? 2 : 3));
  estimate[2] = NAN;  // quality 0.9 unobserved
  TemperatureErrorStats stats;  // no affine map: NaN after it
  const std::array<ViewQualityClass, 3> classes = TemperatureErrorsByViewQuality(c, stats, estimate, q);
  const double from[] = {0.1, 0.4, 0.7}, to[] = {0.3, 0.6, 0.9};
  const int compared[] = {3, 3, 2};
  for (int k = 0; k < 3; ++k) {
    EXPECT_DOUBLE_EQ(classes[k].quality_from, from[k]) << k;
    EXPECT_DOUBLE_EQ(classes[k].quality_to, to[k]) << k;
    EXPECT_EQ(classes[k].compared, compared[k]) << k;
    EXPECT_NEAR(classes[k].rmse_k, k + 1.0, 1e-12) << k;
    EXPECT_TRUE(std::isnan(classes[k].rmse_affine_k)) << k;
  }
  // A camera gain of 1 and offset of +2 K taken out: residuals −1, 0, +1 K.
  stats.affine_gain = 1;
  stats.affine_offset_k = 2;
  const std::array<ViewQualityClass, 3> mapped = TemperatureErrorsByViewQuality(c, stats, estimate, q);
  EXPECT_NEAR(mapped[0].rmse_affine_k, 1, 1e-12);
  EXPECT_NEAR(mapped[1].rmse_affine_k, 0, 1e-12);
  EXPECT_NEAR(mapped[2].rmse_affine_k, 1, 1e-12);
  // Ties: six vertices of quality 0.5 and three of 0.9 — the first two classes' borders
  // both fall on 0.5, so all six are in the lowest class and the middle one is empty.
  const std::vector<double> tied = {0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.9, 0.9, 0.9, 0.05, NAN};
  const std::array<ViewQualityClass, 3> t = TemperatureErrorsByViewQuality(c, stats, estimate, tied);
  EXPECT_EQ(t[0].compared, 5);  // the unobserved vertex (index 2) is in it, not compared
  EXPECT_DOUBLE_EQ(t[0].quality_to, 0.5);
  EXPECT_EQ(t[1].compared, 0);
  EXPECT_TRUE(std::isnan(t[1].rmse_k) && std::isnan(t[1].quality_from));
  EXPECT_EQ(t[2].compared, 3);
  EXPECT_DOUBLE_EQ(t[2].quality_from, 0.9);
  // No quality anywhere: three empty classes.
  const std::array<ViewQualityClass, 3> none =
      TemperatureErrorsByViewQuality(c, stats, estimate, std::vector<double>(q.size(), NAN));
  for (const ViewQualityClass& e : none) EXPECT_EQ(e.compared, 0);
}

TEST(CompareTemperatures, LinearFieldOffsetPlaneExactStats) {
  // Truth: 5 cm triangles (linear interpolation reproduces a linear field exactly). Model:
  // 21 × 21 vertices 1 mm above it; estimate = truth − 2 K on every fifth vertex, + 0.5 K
  // on the others.
  const TemperatureTruth truth = PlaneTruth(0.05, Linear);
  const GridMesh model = MakeGrid(21, 21, -0.1, -0.1, 0.01, 0.001);
  const std::vector<Vector3f> positions = ToFloat(model.vertices);
  std::vector<double> estimate;
  for (size_t i = 0; i < positions.size(); ++i) {
    estimate.push_back(Linear(positions[i].x(), positions[i].y()) + (i % 5 == 0 ? -2.0 : 0.5));
  }
  TemperatureErrorOptions options;
  options.edge_exclusion_m = 0;
  const TemperatureComparison c = CompareTemperatures(positions, model.faces, estimate, truth, options);
  for (size_t i = 0; i < positions.size(); ++i) {
    EXPECT_NEAR(c.truth_c[i], Linear(positions[i].x(), positions[i].y()), 1e-9) << i;
    EXPECT_EQ(c.uniform[i], 1) << i;  // range within 1 cm: 2·0.01·√29 = 0.108 K
  }
  // 441 vertices, 89 of them (0, 5, ..., 440) at −2 K, 352 at +0.5 K.
  const TemperatureErrorStats& s = c.stats;
  EXPECT_EQ(s.vertices, 441);
  EXPECT_EQ(s.observed, 441);
  EXPECT_EQ(s.compared, 441);
  EXPECT_EQ(s.compared_uniform, 441);
  EXPECT_NEAR(s.mean_k, (352 * 0.5 - 89 * 2.0) / 441, 1e-9);
  EXPECT_NEAR(s.rmse_k, std::sqrt((352 * 0.25 + 89 * 4.0) / 441), 1e-9);
  EXPECT_NEAR(s.p95_abs_k, 2, 1e-9);  // rank 0.95·440 = 418 >= 352: among the 2 K errors
  EXPECT_NEAR(s.max_abs_k, 2, 1e-9);
  EXPECT_NEAR(s.rmse_uniform_k, s.rmse_k, 1e-12);
  EXPECT_NEAR(s.p95_abs_uniform_k, s.p95_abs_k, 1e-12);
  EXPECT_NEAR(s.mean_uniform_k, s.mean_k, 1e-12);

  // Another estimate over the same comparison: the truth itself, no error.
  std::vector<double> exact;
  for (const Vector3f& p : positions) exact.push_back(Linear(p.x(), p.y()));
  const TemperatureErrorStats e = TemperatureErrors(c, exact);
  EXPECT_EQ(e.compared, 441);
  EXPECT_LT(e.max_abs_k, 1e-9);
}

TEST(CompareTemperatures, UniformRangeIsTheFieldsRangeInTheBallNotTheTriangles) {
  // On 5 cm triangles a triangle's vertices span up to 0.35 K of the linear field, but
  // within r of a point the field spans 2·r·√29 K: the uniform flag follows the latter.
  const TemperatureTruth truth = PlaneTruth(0.05, Linear);
  const GridMesh model = MakeGrid(21, 21, -0.1, -0.1, 0.01, 0.001);
  const std::vector<Vector3f> positions = ToFloat(model.vertices);
  const std::vector<double> estimate(positions.size(), 20);
  for (const double r : {0.01, 0.02}) {
    const double range_k = 2 * r * std::sqrt(29.0);
    for (const double factor : {0.98, 1.02}) {
      TemperatureErrorOptions options;
      options.uniform_radius_m = r;
      options.uniform_range_k = factor * range_k;
      const TemperatureComparison c = CompareTemperatures(positions, model.faces, estimate, truth, options);
      int uniform = 0;
      for (const uint8_t u : c.uniform) uniform += u;
      EXPECT_EQ(uniform, factor > 1 ? c.stats.compared : 0) << "r " << r << " factor " << factor;
      EXPECT_GT(c.stats.compared, 0);
    }
  }
}

TEST(CompareTemperatures, VerticesBeyondMaxDistanceAreNotCompared) {
  const TemperatureTruth truth = PlaneTruth(0.05, Linear);
  // Points only (no faces, so no boundary): heights 1, 9, 11 and 50 mm; one 5 mm beyond the
  // plane's edge x = 0.5 and 1 mm above (5.1 mm from the edge); one unobserved.
  const std::vector<Vector3f> positions = {{0, 0, 0.001f},  {0.1f, 0.1f, 0.009f}, {0, 0, 0.011f},
                                           {0.2f, 0, 0.05f}, {0.505f, 0, 0.001f},  {0.3f, 0.3f, -0.004f}};
  std::vector<double> estimate;
  for (const Vector3f& p : positions) estimate.push_back(Linear(std::min(0.5f, p.x()), p.y()) + 1);
  estimate[5] = NAN;
  const TemperatureComparison c = CompareTemperatures(positions, {}, estimate, truth, {});
  EXPECT_NEAR(c.truth_c[0], 20, 1e-9);
  EXPECT_NEAR(c.truth_c[1], Linear(0.1f, 0.1f), 1e-9);
  EXPECT_TRUE(std::isnan(c.truth_c[2]));
  EXPECT_TRUE(std::isnan(c.truth_c[3]));
  EXPECT_NEAR(c.truth_c[4], Linear(0.5, 0), 1e-9);  // at the edge
  EXPECT_NEAR(c.truth_c[5], Linear(0.3f, 0.3f), 1e-9);  // compared if observed
  EXPECT_EQ(c.stats.vertices, 6);
  EXPECT_EQ(c.stats.observed, 5);
  EXPECT_EQ(c.stats.compared, 3);
  EXPECT_NEAR(c.stats.rmse_k, 1, 1e-9);
  EXPECT_NEAR(c.stats.mean_k, 1, 1e-9);
}

TEST(CompareTemperatures, VerticesNearHolesAndSilhouettesAreExcluded) {
  // 21 × 21 model vertices 1 cm apart, one cell (10, 10) left out. Within 1.5 cm of a boundary
  // vertex are its 8 neighbours (√2 cm) but not the next (2 cm): the outer two rings and the
  // 4 × 4 vertices 9..12 around the hole go, 17² − 16 = 273 stay.
  const TemperatureTruth truth = PlaneTruth(0.05, Linear);
  const GridMesh model = MakeGrid(21, 21, -0.1, -0.1, 0.01, 0.001, {10, 10});
  const std::vector<Vector3f> positions = ToFloat(model.vertices);
  // Misregistered edge pixels: +5 K on the 16 vertices around the hole.
  std::vector<double> estimate;
  const auto near_hole = [](int i, int j) { return i >= 9 && i <= 12 && j >= 9 && j <= 12; };
  for (int j = 0; j < 21; ++j)
    for (int i = 0; i < 21; ++i) {
      const Vector3f& p = positions[j * 21 + i];
      estimate.push_back(Linear(p.x(), p.y()) + (near_hole(i, j) ? 5 : 0));
    }
  TemperatureErrorOptions options;
  options.edge_exclusion_m = 0.015;
  const TemperatureComparison c = CompareTemperatures(positions, model.faces, estimate, truth, options);
  for (int j = 0; j < 21; ++j)
    for (int i = 0; i < 21; ++i) {
      const bool expected = i >= 2 && i <= 18 && j >= 2 && j <= 18 && !near_hole(i, j);
      EXPECT_EQ(std::isfinite(c.truth_c[j * 21 + i]), expected) << i << " " << j;
    }
  EXPECT_EQ(c.stats.compared, 273);
  EXPECT_LT(c.stats.max_abs_k, 1e-9);

  // Without the exclusion every vertex counts, and so do the hole's 16 errors.
  options.edge_exclusion_m = 0;
  const TemperatureComparison all = CompareTemperatures(positions, model.faces, estimate, truth, options);
  EXPECT_EQ(all.stats.compared, 441);
  EXPECT_NEAR(all.stats.rmse_k, 5 * std::sqrt(16.0 / 441), 1e-9);
}

TEST(CompareTemperatures, HotDiscBorderIsOutsideTheUniformSubset) {
  // Truth: 1 cm triangles, the linear field plus 30 K on the vertices within 15 cm of the
  // centre (a step smeared over one triangle). Model: 5 mm grid, 1 mm above.
  constexpr double kRadius = 0.15;
  const TemperatureTruth truth = PlaneTruth(0.01, [](double x, double y) {
    return Linear(x, y) + (std::hypot(x, y) <= kRadius ? 30 : 0);
  });
  const GridMesh model = MakeGrid(121, 121, -0.3, -0.3, 0.005, 0.001);
  const std::vector<Vector3f> positions = ToFloat(model.vertices);
  TemperatureErrorOptions options;
  options.edge_exclusion_m = 0;
  const TemperatureComparison first =
      CompareTemperatures(positions, model.faces, std::vector<double>(positions.size(), 20), truth, options);
  // Estimate: the truth, 3 K off within 5 mm of the disc's border.
  std::vector<double> estimate;
  int border = 0, far = 0, uniform = 0;
  for (size_t i = 0; i < positions.size(); ++i) {
    const double d = std::abs(std::hypot(double{positions[i].x()}, double{positions[i].y()}) - kRadius);
    ASSERT_TRUE(std::isfinite(first.truth_c[i]));
    estimate.push_back(first.truth_c[i] + (d < 0.005 ? 3 : 0));
    uniform += first.uniform[i];
    if (d < 0.005) {
      ++border;
      EXPECT_EQ(first.uniform[i], 0) << "border vertex " << i;
    } else if (d > 0.04) {
      // The smeared step lies within √2 cm of the border, the ball within 1 cm of the
      // vertex: 4 cm away only the linear field's 0.1 K remains.
      ++far;
      EXPECT_EQ(first.uniform[i], 1) << "far-field vertex " << i;
    }
  }
  ASSERT_GT(border, 100);
  ASSERT_GT(far, 10000);
  // The same on one thread as on three.
  options.num_threads = 1;
  const TemperatureComparison one =
      CompareTemperatures(positions, model.faces, std::vector<double>(positions.size(), 20), truth, options);
  options.num_threads = 3;
  const TemperatureComparison three =
      CompareTemperatures(positions, model.faces, std::vector<double>(positions.size(), 20), truth, options);
  for (size_t i = 0; i < positions.size(); ++i) {
    ASSERT_EQ(one.truth_c[i], three.truth_c[i]) << i;
    ASSERT_EQ(one.uniform[i], three.uniform[i]) << i;
  }
  const TemperatureErrorStats s = TemperatureErrors(first, estimate);
  const double n = static_cast<double>(positions.size());
  EXPECT_EQ(s.compared, static_cast<int>(positions.size()));
  EXPECT_EQ(s.compared_uniform, uniform);
  EXPECT_NEAR(s.rmse_k, 3 * std::sqrt(border / n), 1e-9);
  EXPECT_NEAR(s.mean_k, 3 * border / n, 1e-9);
  // The border's errors are reported, but not in the uniform subset.
  EXPECT_LT(s.rmse_uniform_k, 1e-9);
  EXPECT_LT(s.p95_abs_uniform_k, 1e-9);
}

// A ledge: the plane z = 0 with the linear field, and 2 cm in front of it a 30 °C plate over
// x >= 0 (the slot between a mounting plate and a cabinet wall, seen from afar). Model
// vertices on the plane at x = −d, 1 mm above it: the plate's edge is √(d² + 2²) cm from
// their closest truth point, never within the uniform subset's 1 cm, but within the
// resolved subset's ball of 2 footprints where d < √(R² − 0.02²) (R = 2 · footprint): at a
// 15 mm footprint (a 320-pixel, 56° camera at 4.4 m) R = 3 cm, d < 22.4 mm.
TEST(CompareTemperatures, ResolvedSubsetDropsWhatAPixelMixesAcrossAStep) {
  TemperatureTruth truth = PlaneTruth(0.05, Linear);
  const GridMesh plate = MakeGrid(11, 21, 0, -0.5, 0.05, 0.02);
  const int offset = static_cast<int>(truth.vertices.size());
  for (const Vector3d& v : plate.vertices) {
    truth.vertices.push_back(v);
    truth.temperature_c.push_back(30);
  }
  for (const Vector3i& f : plate.faces) truth.faces.push_back(f + Vector3i::Constant(offset));
  std::vector<Vector3f> positions;
  std::vector<double> d_m;
  for (int j = -4; j <= 4; ++j) {
    for (int i = 1; i <= 90; ++i) {
      d_m.push_back(0.005 * i);
      positions.emplace_back(static_cast<float>(-d_m.back()), static_cast<float>(0.05 * j), 0.001f);
    }
  }
  const size_t n = positions.size();
  const double edge_d_m = std::sqrt(0.03 * 0.03 - 0.02 * 0.02);
  // The estimate: exact, but 3 K warm where a 15 mm pixel mixes the plate in.
  std::vector<double> estimate;
  int mixed = 0;
  for (size_t i = 0; i < n; ++i) {
    estimate.push_back(Linear(positions[i].x(), positions[i].y()) + (d_m[i] < edge_d_m ? 3 : 0));
    mixed += d_m[i] < edge_d_m;
  }
  ASSERT_EQ(mixed, 36);  // d = 5, 10, 15, 20 mm on 9 rows
  TemperatureErrorOptions options;
  options.edge_exclusion_m = 0;
  // No footprints: no resolved subset.
  const TemperatureComparison none = CompareTemperatures(positions, {}, estimate, truth, options);
  EXPECT_TRUE(none.resolved.empty());
  EXPECT_EQ(none.stats.compared_resolved, 0);
  EXPECT_TRUE(std::isnan(none.stats.rmse_resolved_affine_k));

  for (const int threads : {1, 3}) {
    options.num_threads = threads;
    const TemperatureComparison c =
        CompareTemperatures(positions, {}, estimate, truth, options, std::vector<double>(n, 0.015));
    ASSERT_EQ(c.resolved.size(), n);
    for (size_t i = 0; i < n; ++i) {
      ASSERT_EQ(c.uniform[i], 1) << "d " << d_m[i];  // the plate is >= 2 cm away
      EXPECT_EQ(c.resolved[i], d_m[i] < edge_d_m ? 0 : 1) << "d " << d_m[i] << " threads " << threads;
    }
    // The camera map is fitted on the uniform subset, where the 3 K are trimmed (beyond
    // max(5 σ, 1 K)): gain 1, offset 0; the uniform subset keeps their error, the resolved
    // one has none.
    const TemperatureErrorStats& s = c.stats;
    EXPECT_NEAR(s.affine_gain, 1, 1e-9);
    EXPECT_NEAR(s.affine_offset_k, 0, 1e-9);
    EXPECT_NEAR(s.rmse_affine_k, 3 * std::sqrt(static_cast<double>(mixed) / n), 1e-9);
    EXPECT_EQ(s.compared_resolved, static_cast<int>(n) - mixed);
    EXPECT_LT(s.rmse_resolved_affine_k, 1e-9);
    EXPECT_LT(s.p95_abs_resolved_affine_k, 1e-9);
  }
  // A footprint of 4 mm (R = max(1 cm, 8 mm)): every uniform vertex is resolved; unobserved
  // (NaN) is not; one of 6 cm (R 12 cm) is wider than kMaxResolvedRadiusM: not resolved.
  std::vector<double> footprints(n, 0.004);
  footprints[0] = NAN;
  footprints[n - 1] = 0.06;
  const TemperatureComparison fine = CompareTemperatures(positions, {}, estimate, truth, options, footprints);
  for (size_t i = 0; i < n; ++i) EXPECT_EQ(fine.resolved[i], (i == 0 || i == n - 1) ? 0 : 1) << i;
  // resolved_footprints 0: the resolved subset is the uniform one.
  options.resolved_footprints = 0;
  const TemperatureComparison off =
      CompareTemperatures(positions, {}, estimate, truth, options, std::vector<double>(n, 0.015));
  for (size_t i = 0; i < n; ++i) EXPECT_EQ(off.resolved[i], off.uniform[i]) << i;
}

TEST(ReadTemperatureTruth, ReadsTheFieldsAndNamesTheFileWhenOneIsMissing) {
  core::PlyMesh mesh;
  mesh.SetPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  mesh.AddProperty("temperature_c", core::PlyType::kFloat32, {20, 30.5, 40});
  mesh.AddProperty("emissivity", core::PlyType::kFloat32, {0.5, 0.75, 0.95});
  mesh.faces = {{0, 1, 2}};
  const auto folder = test::TestFolder();
  core::WritePly(folder / "scene.ply", mesh);
  const TemperatureTruth truth = ReadTemperatureTruth(folder / "scene.ply");
  ASSERT_EQ(truth.vertices.size(), 3u);
  EXPECT_EQ(truth.vertices[1], Vector3d(1, 0, 0));
  EXPECT_EQ(truth.faces, mesh.faces);
  EXPECT_EQ(truth.temperature_c, (std::vector<double>{20, 30.5, 40}));
  ASSERT_EQ(truth.emissivity.size(), 3u);
  EXPECT_NEAR(truth.emissivity[2], 0.95, 1e-7);  // float on disk

  const auto expect_error = [&](const core::PlyMesh& bad, const std::string& name, const std::string& what) {
    core::WritePly(folder / name, bad);
    try {
      ReadTemperatureTruth(folder / name);
      ADD_FAILURE() << name << " was read";
    } catch (const core::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  core::PlyMesh no_faces = mesh;
  no_faces.faces.clear();
  expect_error(no_faces, "points.ply", "no faces");
  core::PlyMesh no_temperature = mesh;
  no_temperature.RemoveProperty("temperature_c");
  expect_error(no_temperature, "geometry.ply", "temperature_c");
  core::PlyMesh nan_temperature = mesh;
  nan_temperature.SetProperty("temperature_c", core::PlyType::kFloat32, {20, NAN, 40});
  expect_error(nan_temperature, "nan.ply", "vertex 1");
}

// The boundary vertices of a mesh (edges of one face), computed here independently.
std::vector<Vector3d> BoundaryOf(const TemperatureTruth& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (const Vector3i& f : mesh.faces)
    for (int k = 0; k < 3; ++k) ++edges[std::minmax(f[k], f[(k + 1) % 3])];
  std::vector<bool> on(mesh.vertices.size(), false);
  for (const auto& [e, count] : edges)
    if (count == 1) on[e.first] = on[e.second] = true;
  std::vector<Vector3d> out;
  for (size_t i = 0; i < on.size(); ++i)
    if (on[i]) out.push_back(mesh.vertices[i]);
  return out;
}

TEST(CompareTemperatures, FixtureTruthAgainstItselfHasNoError) {
  // The truth mesh of the test scans (equipment-small, SynthScanOptions::Small), through a
  // PLY file as scans store it, compared with its own vertices and temperatures.
  const fixtures::SynthScanOptions scan = fixtures::SynthScanOptions::Small("equipment-small");
  const fixtures::Scene scene = fixtures::MakeScene(scan.scene, scan.scene_options);
  const auto path = test::TestFolder() / "scene.ply";
  core::WritePly(path, scene.Tessellate(fixtures::TruthMeshOptions(scan)));
  const TemperatureTruth truth = ReadTemperatureTruth(path);
  ASSERT_EQ(truth.emissivity.size(), truth.vertices.size());
  const std::vector<Vector3f> positions = ToFloat(truth.vertices);  // exact: float on disk
  const auto started = std::chrono::steady_clock::now();
  const TemperatureComparison c =
      CompareTemperatures(positions, truth.faces, truth.temperature_c, truth, {});
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const int n = static_cast<int>(truth.vertices.size());
  EXPECT_EQ(c.stats.vertices, n);
  EXPECT_EQ(c.stats.observed, n);
  // A vertex's closest truth point is itself (or a copy with the same temperature).
  EXPECT_LT(c.stats.max_abs_k, 1e-9);
  // Compared: exactly the vertices at least 1 cm from every boundary vertex (surface rims,
  // junctions between surfaces, duplicated vertices along emissivity patches and seams).
  const std::vector<Vector3d> boundary = BoundaryOf(truth);
  int far_from_boundary = 0;
  for (int i = 0; i < n; ++i) {
    double nearest = INFINITY;
    for (const Vector3d& b : boundary) nearest = std::min(nearest, (b - truth.vertices[i]).norm());
    const bool far = nearest >= 0.01;
    far_from_boundary += far;
    EXPECT_EQ(std::isfinite(c.truth_c[i]), far) << i;
  }
  EXPECT_EQ(c.stats.compared, far_from_boundary);
  EXPECT_GT(c.stats.compared, n / 4);
  // The uniform flag against bounds on the truth's range within 1 cm of a vertex (every 40th):
  // at least that of the truth vertices within 1 cm, at most that of those within 1 cm plus
  // the longest edge (the vertices of every triangle the ball meets).
  double longest_edge_m = 0;
  for (const Vector3i& f : truth.faces)
    for (int k = 0; k < 3; ++k)
      longest_edge_m = std::max(longest_edge_m, (truth.vertices[f[k]] - truth.vertices[f[(k + 1) % 3]]).norm());
  const TemperatureErrorOptions defaults;
  int surely_uniform = 0, surely_not = 0;
  for (int i = 0; i < n; i += 40) {
    if (!std::isfinite(c.truth_c[i])) continue;
    double lo_in = INFINITY, hi_in = -INFINITY, lo_out = INFINITY, hi_out = -INFINITY;
    for (int k = 0; k < n; ++k) {
      const double d = (truth.vertices[k] - truth.vertices[i]).norm();
      const double t = truth.temperature_c[k];
      if (d <= defaults.uniform_radius_m) {
        lo_in = std::min(lo_in, t);
        hi_in = std::max(hi_in, t);
      }
      if (d <= defaults.uniform_radius_m + longest_edge_m) {
        lo_out = std::min(lo_out, t);
        hi_out = std::max(hi_out, t);
      }
    }
    if (hi_in - lo_in > defaults.uniform_range_k) {
      ++surely_not;
      EXPECT_EQ(c.uniform[i], 0) << i;
    } else if (hi_out - lo_out <= defaults.uniform_range_k) {
      ++surely_uniform;
      EXPECT_EQ(c.uniform[i], 1) << i;
    }
  }
  EXPECT_GT(surely_not, 20);
  EXPECT_GT(surely_uniform, 20);
  EXPECT_GT(c.stats.compared_uniform, 0);
  EXPECT_LT(c.stats.compared_uniform, c.stats.compared);
  std::cout << n << " truth vertices, " << boundary.size() << " on boundaries, " << c.stats.compared
            << " compared, " << c.stats.compared_uniform << " uniform; CompareTemperatures " << seconds
            << " s\n";
}

}  // namespace
}  // namespace hw::reconstruct
