#include "analyze/compare.h"

#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <gtest/gtest.h>

#include "analyze/test_scene.h"

namespace hw::analyze {
namespace {

using test::MakeVariant;
using test::Pose;
using test::RoomScene;
using test::Variant;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The default field of test::Variant: 20 + 0.4 z + 0.2 x, °C (gradient 0.45 K/m).
double Field(const Eigen::Vector3d& p) { return 20 + 0.4 * p.z() + 0.2 * p.x(); }

// A 0.3 m disc on the wall x = 0 around (0, 1.5, 1.2).
bool InDisc(const Eigen::Vector3d& p) {
  return std::abs(p.x()) < 1e-9 && (p - Eigen::Vector3d(0, 1.5, 1.2)).norm() < 0.3;
}

Alignment Known(const Eigen::Isometry3d& after_from_before) {
  Alignment a;
  a.after_from_before = after_from_before;
  return a;
}

struct Pair {
  ThermalMesh before, after;
  test::SceneMesh after_scene;
  Eigen::Isometry3d truth;
};

// BEFORE at 5 cm edges; AFTER at 4.5 cm, moved by 10° and 0.3 m, 5 K warmer in the disc.
Pair DiscPair() {
  Pair p;
  p.before = MakeVariant(RoomScene(0.05), Variant{});
  p.truth = Pose(10, {0.3, 0.5, 1}, {0.2, -0.2, 0.1});
  Variant v;
  v.transform = p.truth;
  v.temperature_c = [](const Eigen::Vector3d& x) { return Field(x) + (InDisc(x) ? 5.0 : 0.0); };
  p.after_scene = RoomScene(0.045);
  p.after = MakeVariant(p.after_scene, v);
  return p;
}

// BEFORE has no disc, so the difference is exactly the disc's 5 K where AFTER's vertex is in
// it and 0 elsewhere, up to the regional mean of the linear field: its neighbourhood's
// centroid sits at most ≈ r/2 = 2.5 cm off the point (one-sided at a corner), × 0.45 K/m
// ≈ 0.011 K. Tolerance 0.03 K.
TEST(CompareTest, DiscDifferenceRecovered) {
  const Pair p = DiscPair();
  const TemperatureDifference d = MapDifference(p.before, p.after, Known(p.truth), CompareOptions{});
  ASSERT_EQ(d.difference_k.size(), p.after_scene.points.size());
  double disc_area = 0, total = 0;
  for (int f = 0; f < p.after.NumFaces(); ++f) total += p.after.FaceArea(f);
  std::vector<double> area(p.after_scene.points.size(), 0.0);
  for (int f = 0; f < p.after.NumFaces(); ++f) {
    for (int k = 0; k < 3; ++k) area[static_cast<size_t>(p.after.faces[static_cast<size_t>(f)][k])] += p.after.FaceArea(f) / 3;
  }
  int in_disc = 0;
  for (size_t v = 0; v < p.after_scene.points.size(); ++v) {
    const bool inside = InDisc(p.after_scene.points[v]);
    ASSERT_TRUE(std::isfinite(d.difference_k[v])) << v;
    EXPECT_NEAR(d.difference_k[v], inside ? 5.0 : 0.0, 0.03) << v;
    in_disc += inside;
    if (inside) disc_area += area[v];
  }
  EXPECT_GT(in_disc, 100);  // π 0.3² / (0.045²/2)/2 ≈ 140 vertices
  EXPECT_EQ(d.compared_vertices, static_cast<int>(p.after_scene.points.size()));
  EXPECT_NEAR(d.compared_area_m2, total, 1e-9);
  EXPECT_NEAR(d.after_area_m2, total, 1e-9);
  EXPECT_NEAR(d.mean_k, 5 * disc_area / total, 0.03);
  EXPECT_NEAR(d.median_k, 0, 0.03);
  EXPECT_LT(d.p95_abs_k, 0.03);  // the disc is < 1 % of the area: beyond the 95th percentile
}

// Without a region BEFORE's value is interpolated at the closest point: exact for the linear
// field on the planes; on the cylinder the facets differ by their chord sag (≤ 1.5 mm) ×
// 0.45 K/m. Tolerance 1e-3 K.
TEST(CompareTest, NoRegionInterpolatesAtTheClosestPoint) {
  const Pair p = DiscPair();
  CompareOptions o;
  o.region_radius_m = 0;
  const TemperatureDifference d = MapDifference(p.before, p.after, Known(p.truth), o);
  for (size_t v = 0; v < p.after_scene.points.size(); ++v) {
    EXPECT_NEAR(d.before_c[v], Field(p.after_scene.points[v]), 1e-3) << v;
  }
}

// Where BEFORE has no surface (cut), no temperature (NaN) or AFTER has none, the result is
// NaN and those vertices leave the statistics.
TEST(CompareTest, NaNWhereUnobservedOrUncovered) {
  Variant b;
  b.keep_face = [](const Eigen::Vector3d& c) { return c.x() < 2.6; };
  // Unobserved above 2 m on the wall y = 0.
  b.temperature_c = [](const Eigen::Vector3d& x) { return x.y() < 1e-9 && x.z() > 2.0 ? kNaN : Field(x); };
  const ThermalMesh before = MakeVariant(RoomScene(0.05), b);
  Variant a;
  a.transform = Pose(10, {0.3, 0.5, 1}, {0.2, -0.2, 0.1});
  a.temperature_c = [](const Eigen::Vector3d& x) { return x.z() < 1e-9 && x.y() < 0.5 ? kNaN : Field(x); };
  const test::SceneMesh scene = RoomScene(0.045);
  const ThermalMesh after = MakeVariant(scene, a);
  const TemperatureDifference d = MapDifference(before, after, Known(a.transform), CompareOptions{});
  int compared = 0;
  for (size_t v = 0; v < scene.points.size(); ++v) {
    const Eigen::Vector3d& x = scene.points[v];
    const bool uncovered = x.x() > 2.6 + 0.06;                 // beyond the cut + max_distance
    const bool before_unobserved = x.y() < 1e-9 && x.z() > 2.0 + 0.06 && x.x() > 0.06;  // + region radius
    const bool after_unobserved = x.z() < 1e-9 && x.y() < 0.5;
    if (uncovered || before_unobserved) {
      EXPECT_TRUE(std::isnan(d.before_c[v])) << v;
    } else if (x.x() < 2.5 && !(x.y() < 1e-9 && x.z() > 1.95)) {
      EXPECT_NEAR(d.before_c[v], Field(x), 0.03) << v;
    }
    if (after_unobserved || uncovered || before_unobserved) {
      EXPECT_TRUE(std::isnan(d.difference_k[v])) << v;
    }
    compared += std::isfinite(d.difference_k[v]);
  }
  EXPECT_EQ(d.compared_vertices, compared);
  EXPECT_LT(d.compared_area_m2, 0.7 * d.after_area_m2);
  EXPECT_NEAR(d.mean_k, 0, 0.03);

  // A mesh without temperature: NaN everywhere, nothing compared.
  ThermalMesh plain = after;
  plain.temperature_c.clear();
  const TemperatureDifference none = MapDifference(before, plain, Known(a.transform), CompareOptions{});
  EXPECT_EQ(none.compared_vertices, 0);
  EXPECT_EQ(none.mean_k, 0);
  const TemperatureDifference none2 = MapDifference(plain, after, Known(a.transform), CompareOptions{});
  EXPECT_TRUE(std::isnan(none2.before_c[0]));
  EXPECT_EQ(none2.compared_area_m2, 0);
}

Spot MakeSpot(const std::string& id, bool hot, const Eigen::Vector3d& centroid, double area_m2, double sigma_m2,
              double peak_c) {
  Spot s;
  s.id = id;
  s.hot = hot;
  s.centroid_in_world = centroid;
  s.area_m2 = area_m2;
  s.area_sigma_m2 = sigma_m2;
  s.radius_m = std::sqrt(area_m2 / M_PI);
  s.peak_c = peak_c;
  s.reference_c = 20;
  s.delta_k = peak_c - 20;
  return s;
}

std::string Kinds(const SpotChange& c) {
  std::string s;
  for (const std::string& k : c.kinds) s += (s.empty() ? "" : ",") + k;
  return s;
}

TEST(CompareTest, MatchSpots) {
  const Eigen::Isometry3d T = Pose(10, {0.3, 0.5, 1}, {0.2, -0.2, 0.1});
  const Eigen::Vector3d p1(0, 1, 1), p2(1, 0, 1.5), p3(2, 2, 0), p4(3, 1, 0), p5(0, 2.5, 2);
  const std::vector<Spot> before{
      MakeSpot("H1", true, p1, 0.10, 0.005, 40),   // grows by 60 % (8.5 σ), +3 K
      MakeSpot("H2", true, p2, 0.10, 0.03, 35),    // +40 % but only 0.94 of 2σ: unchanged
      MakeSpot("C1", false, p3, 0.05, 0.005, 10),  // gone
      MakeSpot("H3", true, p4, 0.20, 0.005, 50),   // shrinks by half, −4 K
      MakeSpot("H4", true, p5, 0.05, 0.002, 30),   // where AFTER has a cold spot: no match
  };
  const std::vector<Spot> after{
      MakeSpot("H1", true, T * p4, 0.10, 0.005, 46),                                   // ← H3
      MakeSpot("H2", true, T * p1 + Eigen::Vector3d(0.02, 0, 0), 0.16, 0.005, 43),     // ← H1
      MakeSpot("H3", true, T * p2 + Eigen::Vector3d(0, 0.05, 0), 0.14, 0.03, 35.5),    // ← H2
      MakeSpot("H5", true, T * p2 + Eigen::Vector3d(0, 0.12, 0), 0.10, 0.005, 36),     // second near H2
      MakeSpot("C1", false, T * p5, 0.05, 0.002, 12),                                  // new, cold
      MakeSpot("H6", true, Eigen::Vector3d(5, 5, 5), 0.01, 0.001, 31),                 // new
  };
  const std::vector<SpotChange> c = MatchSpots(before, after, Known(T), CompareOptions{});
  ASSERT_EQ(c.size(), 8u);
  EXPECT_EQ(c[0].before_id, "H3");
  EXPECT_EQ(Kinds(c[0]), "shrank,cooled");  // half the area (20 σ), peak 50 → 46 °C
  EXPECT_EQ(c[1].before_id, "H1");
  EXPECT_EQ(Kinds(c[1]), "grew,heated");
  EXPECT_NEAR(c[1].distance_m, 0.02, 1e-9);
  EXPECT_EQ(c[1].area_before_m2, 0.10);
  EXPECT_EQ(c[1].area_after_m2, 0.16);
  EXPECT_EQ(c[1].peak_before_c, 40);
  EXPECT_EQ(c[1].peak_after_c, 43);
  EXPECT_EQ(c[1].delta_before_k, 20);
  EXPECT_EQ(c[1].delta_after_k, 23);
  EXPECT_EQ(c[2].before_id, "H2");
  EXPECT_EQ(Kinds(c[2]), "");  // within 2σ of the area, and +0.5 K
  EXPECT_EQ(c[3].after_id, "H5");
  EXPECT_EQ(Kinds(c[3]), "appeared");  // H2 went to the closer H3
  EXPECT_TRUE(std::isnan(c[3].distance_m));
  EXPECT_EQ(c[4].after_id, "C1");
  EXPECT_EQ(Kinds(c[4]), "appeared");  // H4 is hot
  EXPECT_EQ(Kinds(c[5]), "appeared");
  EXPECT_EQ(c[6].before_id, "C1");
  EXPECT_EQ(c[6].after_id, "");
  EXPECT_EQ(Kinds(c[6]), "vanished");
  EXPECT_TRUE(std::isnan(c[6].area_after_m2));
  EXPECT_EQ(c[7].before_id, "H4");
  EXPECT_EQ(Kinds(c[7]), "vanished");
}

// The reflection flags travel with the spots, and a change needs a second view when it
// stands on a flagged reading: any change with either flagged, an unchanged pair only when
// both scans' readings are flagged (one unflagged reading from another angle confirms it).
TEST(CompareTest, ChangesOnPossibleReflectionsNeedASecondView) {
  const Eigen::Isometry3d T = Pose(5, {0, 0, 1}, {0.1, 0, 0});
  const Eigen::Vector3d p1(0, 0, 1), p2(1, 0, 1), p3(2, 0, 1), p4(3, 0, 1);
  auto flagged = [](Spot s) {
    s.possible_reflection = true;
    return s;
  };
  const std::vector<Spot> before{
      flagged(MakeSpot("H1", true, p1, 0.01, 0.001, 30)),  // unchanged, flagged in BEFORE only
      flagged(MakeSpot("H2", true, p2, 0.01, 0.001, 30)),  // unchanged, flagged in both
      MakeSpot("H3", true, p3, 0.01, 0.001, 30),           // heated, flagged in AFTER only
      flagged(MakeSpot("H4", true, p4, 0.01, 0.001, 30)),  // vanished, was flagged
  };
  const std::vector<Spot> after{
      MakeSpot("H1", true, T * p1, 0.01, 0.001, 30),
      flagged(MakeSpot("H2", true, T * p2, 0.01, 0.001, 30)),
      flagged(MakeSpot("H3", true, T * p3, 0.01, 0.001, 35)),
      MakeSpot("H5", true, Eigen::Vector3d(5, 5, 5), 0.01, 0.001, 31),  // appeared, unflagged
  };
  const std::vector<SpotChange> c = MatchSpots(before, after, Known(T), CompareOptions{});
  ASSERT_EQ(c.size(), 5u);
  const std::vector<std::array<bool, 3>> expected = {
      {true, false, false}, {true, true, true}, {false, true, true}, {false, false, false}, {true, false, true}};
  for (size_t i = 0; i < c.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(c[i].before_possible_reflection, expected[i][0]);
    EXPECT_EQ(c[i].after_possible_reflection, expected[i][1]);
    EXPECT_EQ(NeedsSecondView(c[i]), expected[i][2]);
  }
  EXPECT_EQ(Kinds(c[0]), "");
  EXPECT_EQ(Kinds(c[2]), "heated");
  EXPECT_EQ(Kinds(c[4]), "vanished");
}

TEST(CompareTest, OptionsCheck) {
  EXPECT_EQ(CompareOptions{}.Check(), "");
  CompareOptions o;
  o.max_distance_m = 0;
  EXPECT_EQ(o.Check(), "max_distance_m: must be in (0, 100], got 0");
  o = {};
  o.region_radius_m = -1;
  EXPECT_NE(o.Check().find("region_radius_m"), std::string::npos);
  o = {};
  o.area_change_sigmas = kNaN;
  EXPECT_NE(o.Check().find("area_change_sigmas"), std::string::npos);
  o = {};
  o.peak_change_k = -1;
  EXPECT_NE(o.Check().find("peak_change_k"), std::string::npos);
  EXPECT_THROW(MatchSpots({}, {}, Alignment{}, o), std::invalid_argument);
}

}  // namespace
}  // namespace hw::analyze
