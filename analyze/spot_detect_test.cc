#include "analyze/spot_detect.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include <gtest/gtest.h>

#include "analyze/spot_resolution.h"

namespace hw::analyze {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A rectangle z = 0 of size_x_m × size_y_m centred on the origin, triangulated on a grid
// of `step_m` with alternating diagonals, carrying temperature(x, y) and, when finite, a
// uniform temperature_footprint_m.
ThermalMesh Rectangle(double size_x_m, double size_y_m, double step_m,
                      const std::function<double(double, double)>& temperature,
                      double footprint_m = std::nan("")) {
  const int nx = static_cast<int>(std::lround(size_x_m / step_m));
  const int ny = static_cast<int>(std::lround(size_y_m / step_m));
  core::PlyMesh ply;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> t;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const double x = -0.5 * size_x_m + i * step_m, y = -0.5 * size_y_m + j * step_m;
      points.emplace_back(x, y, 0);
      t.push_back(temperature(x, y));
    }
  }
  ply.SetPositions(points, core::PlyType::kFloat64);
  ply.AddProperty("temperature_c", core::PlyType::kFloat64, t);
  if (std::isfinite(footprint_m)) {
    ply.AddProperty("temperature_footprint_m", core::PlyType::kFloat64, std::vector<double>(t.size(), footprint_m));
  }
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i, b = a + 1, c = a + nx + 2, d = a + nx + 1;
      if ((i + j) % 2 == 0) {
        ply.faces.emplace_back(a, b, c);
        ply.faces.emplace_back(a, c, d);
      } else {
        ply.faces.emplace_back(a, b, d);
        ply.faces.emplace_back(b, c, d);
      }
    }
  }
  return MakeThermalMesh(ply, "plane.ply");
}

// A square plane z = 0 of side `size_m` (Rectangle).
ThermalMesh Plane(double size_m, double step_m, const std::function<double(double, double)>& temperature) {
  return Rectangle(size_m, size_m, step_m, temperature);
}

// The fixtures' plateau profile (fixtures/scene.h): T = threshold on the boundary of the
// region (signed distance d), rising to peak inside and decaying to background outside.
double Plateau(double d, double background_c, double peak_c, double falloff_m) {
  const double threshold = 0.5 * (background_c + peak_c);
  const double a = (threshold - background_c) / (peak_c - background_c);
  const double g = d <= 0 ? 1 - (1 - a) * std::exp(d / falloff_m) : a * std::exp(-d / falloff_m);
  return background_c + (peak_c - background_c) * g;
}

TEST(SpotDetectTest, DiscOnAPlaneHasItsClosedForms) {
  const double radius = 0.1;
  const ThermalMesh mesh = Plane(1.6, 0.005, [&](double x, double y) {
    return Plateau(std::hypot(x - 0.1, y + 0.05) - radius, 20, 60, 0.01);
  });
  const SpotDetection d = DetectSpots(mesh, SpotOptions());
  ASSERT_EQ(d.spots.size(), 1u);
  const Spot& s = d.spots[0];
  EXPECT_EQ(s.id, "H1");
  EXPECT_TRUE(s.hot);
  EXPECT_EQ(s.reference, "surrounding");
  // The ring starts 4 tail lengths (4 cm) beyond the edge: the tail there is 20·e^-4 =
  // 0.37 K and the median sits ~2 cm further (width 10 cm): < 0.1 K.
  EXPECT_NEAR(s.reference_c, 20, 0.1);
  EXPECT_NEAR(s.peak_c, Plateau(-radius, 20, 60, 0.01), 1e-9);  // the deepest vertex (centre)
  // The level is half-way between reference and the robust peak: within 0.1 K of 40, i.e.
  // the boundary moves < 0.1 K / (20 K / 1 cm) = 0.05 mm, 0.1 % of the area. Chords of a 5 mm
  // mesh on a 10 cm circle lose < (5 mm)² / (8·10 cm)·2πr/πr² ... < 0.5 %.
  EXPECT_NEAR(s.area_m2, kPi * radius * radius, 0.01 * kPi * radius * radius);
  EXPECT_NEAR(s.length_m, 2 * radius, 0.002);
  EXPECT_NEAR(s.width_m, 2 * radius, 0.002);
  EXPECT_NEAR(s.centroid_in_world.x(), 0.1, 1e-3);
  EXPECT_NEAR(s.centroid_in_world.y(), -0.05, 1e-3);
  EXPECT_LE(std::abs(s.area_m2 - kPi * radius * radius), 2 * s.area_sigma_m2);
  EXPECT_EQ(s.severity, "major");  // ΔT ≈ 40 K > 15 K
  EXPECT_EQ(s.unrolling, "plane");
}

// e^(-|x| / λ), the profile of heat spreading from a buried line, blurred by a Gaussian of
// std s (closed form: an exponentially modified Gaussian on each side).
double BlurredExponential(double x, double lambda, double s) {
  const double a = s * s / lambda, r = s * std::sqrt(2.0);
  return 0.5 * std::exp(s * s / (2 * lambda * lambda)) *
         (std::exp(-x / lambda) * std::erfc((a - x) / r) + std::exp(x / lambda) * std::erfc((a + x) / r));
}

// A strip 0.307 m long (plateau along y, sharp ends) whose cross-section is `across`: 20 °C
// plus 10 K at the profile's 1.
ThermalMesh Strip(const std::function<double(double)>& across, double footprint_m) {
  return Rectangle(0.3, 0.5, 0.002, [&](double x, double y) {
    const double along = std::abs(y) <= 0.15 ? 1.0 : std::exp(-(std::abs(y) - 0.15) / 0.005);
    return 20 + 10 * across(x) * along;
  }, footprint_m);
}

// The thermal image blurs a peaked spot wider (a buried cable seen at 3-5 pixels across):
// the half-ΔT width grows by ~1.75 σ_b, which the mesh's own noise terms know nothing of.
// With temperature_footprint_m the uncertainty spans it; without, it does not.
TEST(SpotDetectTest, BlurOfAPeakedSpotIsCoveredByTheResolutionTerm) {
  const double width = 0.024, lambda = 0.5 * width / std::log(2.0);  // FWHM 24 mm
  const double blur = 0.004;                                        // σ_b on the surface
  const double footprint = blur / std::sqrt(1.0 / 12 + 0.25);       // optics_psf_px 0.5
  const auto profile = [&](double x) { return BlurredExponential(x, lambda, blur); };
  const SpotDetection with = DetectSpots(Strip(profile, footprint), SpotOptions());
  const SpotDetection without = DetectSpots(Strip(profile, std::nan("")), SpotOptions());
  ASSERT_EQ(with.spots.size(), 1u);
  ASSERT_EQ(without.spots.size(), 1u);
  const Spot& s = with.spots[0];
  EXPECT_NEAR(s.footprint_m, footprint, 1e-9);
  EXPECT_NEAR(s.blur_sigma_m, blur, 1e-9);
  EXPECT_NEAR(s.width_px, s.width_m / footprint, 1e-9);
  EXPECT_TRUE(s.resolved);  // ≈ 4.5 px
  // Widened by 6-7.5 mm (1.5-1.9 σ_b: the closed form gives 7.0 mm; the mesh's 2 mm steps).
  EXPECT_GT(s.width_m - width, 1.5 * blur);
  EXPECT_LT(s.width_m - width, 1.9 * blur);
  EXPECT_NEAR(without.spots[0].width_m, s.width_m, 1e-12);  // the field changes no figure
  EXPECT_LE(s.width_m - width, 2 * s.width_sigma_m);
  EXPECT_GT(s.width_m - width, 2 * without.spots[0].width_sigma_m);
  const double true_area = width * (0.3 + 2 * 0.005 * std::log(2.0));
  EXPECT_LE(s.area_m2 - true_area, 2 * s.area_sigma_m2);
  EXPECT_GT(s.area_m2 - true_area, 2 * without.spots[0].area_sigma_m2);
  EXPECT_TRUE(std::isnan(without.spots[0].footprint_m));
  EXPECT_TRUE(without.spots[0].resolved);
  // The blur lowers the peak too: 10 K reads e^(s²/2)·erfc(s/√2) = 0.839 of it (s = σ_b/λ =
  // 0.23), 8.39 K. The bound (from the measured width less the largest widening) spans the
  // 1.61 K, and is not loose by more than a third for this, the most peaked profile; two
  // sigmas cover it, the mesh's own noise terms (0: an exact field) do not.
  EXPECT_NEAR(s.delta_k, 10 * BlurredExponential(0, lambda, blur), 0.01);
  const double delta_error = 10 - s.delta_k;
  EXPECT_GE(s.delta_blur_bound_k, delta_error - 0.02);
  EXPECT_LT(s.delta_blur_bound_k, 1.33 * delta_error);
  EXPECT_LE(delta_error, 2 * s.delta_sigma_k + 0.02);
  EXPECT_GT(delta_error, 2 * without.spots[0].delta_sigma_k);
  EXPECT_TRUE(std::isnan(without.spots[0].delta_blur_bound_k));
}

// The point-source form: a disc whose radial profile is exponential, blurred in both
// directions, loses more of its peak than a line (closed form at s = 0.2: 1 − s·√(π/2)·
// e^(s²/2)·erfc(s/√2) = 0.783 against the line's 0.857), and a blur far below the width
// loses nothing.
TEST(SpotDetectTest, PeakDropBoundOfLinesAndPoints) {
  const double width = 0.05, blur = 0.2 * (width / (2 * std::log(2.0))) / (1 + 0.2 * kMaxBlurWideningSigmas / (2 * std::log(2.0)));
  // width − 1.8 σ_b is the true width the bound assumes: λ = that / (2 ln 2) = σ_b / 0.2.
  const double true_lambda = (width - kMaxBlurWideningSigmas * blur) / (2 * std::log(2.0));
  ASSERT_NEAR(blur / true_lambda, 0.2, 1e-9);
  EXPECT_NEAR(PeakDropBound(width, blur, true), 1 - std::exp(0.02) * std::erfc(0.2 / std::sqrt(2.0)), 1e-12);
  EXPECT_NEAR(PeakDropBound(width, blur, false),
              0.2 * std::sqrt(kPi / 2) * std::exp(0.02) * std::erfc(0.2 / std::sqrt(2.0)), 1e-12);
  EXPECT_GT(PeakDropBound(width, blur, false), PeakDropBound(width, blur, true));
  EXPECT_LT(PeakDropBound(1.0, 1e-4, true), 1e-3);
  EXPECT_EQ(PeakDropBound(0.05, std::nan(""), true), 0.0);
  EXPECT_EQ(PeakDropBound(0.0, 0.01, true), 0.0);
  // Narrower than the blur: taken as the blur's width (finite, < 1).
  EXPECT_LT(PeakDropBound(0.001, 0.01, false), 1.0);
}

// A straight step's half-ΔT line does not move under blur: the same footprint leaves a
// 24 mm box strip's width within half a mesh step and only bounds it (one-sided, ≤ 0.9 σ_b
// as one sigma).
TEST(SpotDetectTest, BlurLeavesAStepEdgedSpotInPlace) {
  const double half = 0.012, blur = 0.004, footprint = blur / std::sqrt(1.0 / 12 + 0.25);
  const auto box = [&](double x) {
    return 0.5 * (std::erf((x + half) / (blur * std::sqrt(2.0))) - std::erf((x - half) / (blur * std::sqrt(2.0))));
  };
  const SpotDetection d = DetectSpots(Strip(box, footprint), SpotOptions());
  ASSERT_EQ(d.spots.size(), 1u);
  EXPECT_NEAR(d.spots[0].width_m, 2 * half, 0.001);
  EXPECT_LT(d.spots[0].width_sigma_m, 0.5 * kMaxBlurWideningSigmas * blur + 0.001);
  // Its peak is erf(12 / (4 √2)) = 0.997 of 10 K; the bound assumes the most peaked profile
  // and so only bounds it (one-sided, not an estimate).
  EXPECT_NEAR(d.spots[0].delta_k, 10 * std::erf(half / (blur * std::sqrt(2.0))), 0.01);
  EXPECT_GT(d.spots[0].delta_blur_bound_k, 10 - d.spots[0].delta_k);
}

// Fewer thermal pixels across than min_resolved_px: flagged (analyze warns), not dropped.
TEST(SpotDetectTest, ASpotNarrowerThanThreePixelsIsUnderResolved) {
  const double lambda = 0.012 / std::log(2.0);
  const ThermalMesh mesh = Strip([&](double x) { return BlurredExponential(x, lambda, 0.004); }, 0.012);
  const SpotDetection d = DetectSpots(mesh, SpotOptions());
  ASSERT_EQ(d.spots.size(), 1u);
  EXPECT_LT(d.spots[0].width_px, 3);
  EXPECT_FALSE(d.spots[0].resolved);
  SpotOptions lenient;
  lenient.min_resolved_px = 0;
  EXPECT_TRUE(DetectSpots(mesh, lenient).spots.at(0).resolved);
}

// Two hot joints on one slightly warm busbar (1.5 K above the wall: a candidate, not a
// spot): one connected component of candidate vertices holding two peaks. Each is a spot.
TEST(SpotDetectTest, TwoSpotsOnOneWarmStripAreBothFound) {
  const ThermalMesh mesh = Rectangle(1.6, 0.8, 0.005, [&](double x, double y) {
    const double bar = std::abs(y) < 0.03 && std::abs(x) < 0.7 ? 1.5 : 0.0;
    const double joint1 = Plateau(std::hypot(x + 0.5, y) - 0.03, 20, 50, 0.005) - 20;
    const double joint2 = Plateau(std::hypot(x - 0.5, y) - 0.03, 20, 45, 0.005) - 20;
    return 20 + std::max({bar, joint1, joint2});
  });
  SpotOptions ambient;
  ambient.reference = SpotOptions::Reference::kAmbient;
  ambient.ambient_c = 20;
  for (const SpotOptions& options : {SpotOptions(), ambient}) {
    const SpotDetection d = DetectSpots(mesh, options);
    ASSERT_EQ(d.spots.size(), 2u);
    EXPECT_NEAR(d.spots[0].centroid_in_world.x(), -0.5, 0.002);
    EXPECT_NEAR(d.spots[1].centroid_in_world.x(), 0.5, 0.002);
    EXPECT_NEAR(d.spots[1].peak_c, 45, 0.5);
    for (const Spot& s : d.spots) EXPECT_NEAR(s.area_m2, kPi * 0.03 * 0.03, 0.05 * kPi * 0.03 * 0.03);
  }
}

TEST(SpotDetectTest, HotAndColdSpotsAreOrderedAndNamed) {
  const ThermalMesh mesh = Plane(2.0, 0.01, [&](double x, double y) {
    const double hot1 = Plateau(std::hypot(x + 0.5, y) - 0.08, 20, 30, 0.01) - 20;
    const double hot2 = Plateau(std::hypot(x - 0.5, y) - 0.08, 20, 50, 0.01) - 20;
    // A cold rectangle 0.3 × 0.1 m: signed distance of a box.
    const double qx = std::abs(x) - 0.15, qy = std::abs(y - 0.6) - 0.05;
    const double box = std::hypot(std::max(qx, 0.0), std::max(qy, 0.0)) + std::min(std::max(qx, qy), 0.0);
    const double cold = Plateau(box, 20, 14, 0.01) - 20;
    return 20 + hot1 + hot2 + cold;
  });
  const SpotDetection d = DetectSpots(mesh, SpotOptions());
  ASSERT_EQ(d.spots.size(), 3u);
  EXPECT_EQ(d.spots[0].id, "H1");
  EXPECT_NEAR(d.spots[0].peak_c, 50, 0.5);  // the stronger hot spot first
  EXPECT_EQ(d.spots[1].id, "H2");
  EXPECT_NEAR(d.spots[1].centroid_in_world.x(), -0.5, 1e-3);
  EXPECT_EQ(d.spots[2].id, "C1");
  EXPECT_FALSE(d.spots[2].hot);
  EXPECT_LT(d.spots[2].delta_k, -5);
  EXPECT_NEAR(d.spots[2].area_m2, 0.03, 0.03 * 0.01);  // a rectangle on grid lines: exact up to the level
  EXPECT_NEAR(d.spots[2].length_m, 0.3, 0.002);
  EXPECT_NEAR(d.spots[2].width_m, 0.1, 0.002);
  EXPECT_EQ(d.spots[1].severity, "probable");  // ΔT ≈ 10 K
  EXPECT_EQ(d.spots[0].severity, "major");
}

TEST(SpotDetectTest, NoiseIsCoveredByTheReportedUncertainty) {
  // 0.5 K of vertex noise on a 5 mm mesh: the reported one-sigma area uncertainty must cover
  // the error in about 95 % of trials at 2σ. Over 20 seeds allow 3 misses (binomial tail).
  int covered = 0, delta_covered = 0, trials = 20;
  double delta_bias = 0;
  for (int seed = 0; seed < trials; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed));
    std::normal_distribution<double> noise(0, 0.5);
    const double radius = 0.06;
    const ThermalMesh mesh = Plane(0.8, 0.005, [&](double x, double y) {
      return Plateau(std::hypot(x, y) - radius, 20, 30, 0.008) + noise(rng);
    });
    const SpotDetection d = DetectSpots(mesh, SpotOptions());
    ASSERT_GE(d.spots.size(), 1u);
    const Spot& s = d.spots[0];
    const double error = s.area_m2 - kPi * radius * radius;
    covered += std::abs(error) <= 2 * s.area_sigma_m2;
    EXPECT_LT(std::abs(error) / (kPi * radius * radius), 0.1);
    // ΔT: the hottest of ~450 noisy plateau vertices reads ~3σ high (+1.5 K over the true
    // 10 K): the maximum's bias is in its sigma.
    delta_covered += std::abs(s.delta_k - 10) <= 2 * s.delta_sigma_k;
    delta_bias += s.delta_k - 10;
  }
  EXPECT_GE(covered, trials - 3);
  EXPECT_GE(delta_covered, trials - 3);
  EXPECT_GT(delta_bias / trials, 0.5);  // the bias is real (a test that could not fail otherwise)
}

TEST(SpotDetectTest, AWholeWarmSurfaceIsNotASpot) {
  // Half of the plane 8 K warmer: wider than max_area_m2 — a surface at another
  // temperature, rejected with its reason.
  SpotOptions options;
  options.max_area_m2 = 0.5;
  const ThermalMesh mesh = Plane(2.0, 0.02, [&](double x, double) { return x > 0 ? 28.0 : 20.0; });
  const SpotDetection d = DetectSpots(mesh, options);
  EXPECT_TRUE(d.spots.empty());
  ASSERT_FALSE(d.rejected.empty());
  EXPECT_NE(d.rejected[0].reason.find("max_area_m2"), std::string::npos);
}

TEST(SpotDetectTest, AbsoluteAndAmbientModes) {
  const ThermalMesh mesh = Plane(1.0, 0.005, [&](double x, double y) {
    return Plateau(std::hypot(x, y) - 0.1, 20, 60, 0.01);
  });
  SpotOptions absolute;
  absolute.detect = SpotOptions::Detect::kAbsolute;
  absolute.hot_above_c = 50;
  absolute.find_cold = false;
  const SpotDetection a = DetectSpots(mesh, absolute);
  ASSERT_EQ(a.spots.size(), 1u);
  EXPECT_EQ(a.spots[0].reference, "surrounding");  // the limit bounds it; ΔT is over the surface
  EXPECT_DOUBLE_EQ(a.spots[0].level_c, 50);
  // T = 50 where 1 - 0.5·e^(d/1cm) = 0.75: d = 1 cm·ln 0.5 = −6.93 mm.
  const double r50 = 0.1 + 0.01 * std::log(0.5);
  EXPECT_NEAR(a.spots[0].area_m2, kPi * r50 * r50, 0.01 * kPi * r50 * r50);

  SpotOptions ambient;
  ambient.reference = SpotOptions::Reference::kAmbient;
  ambient.ambient_c = 10;  // level = 10 + (60 − 10)/2 = 35 °C, outside the true boundary
  const SpotDetection b = DetectSpots(mesh, ambient);
  ASSERT_EQ(b.spots.size(), 1u);
  EXPECT_EQ(b.spots[0].reference, "ambient");
  EXPECT_NEAR(b.spots[0].reference_c, 10, 1e-12);
  // T = 35 outside: 0.5·e^(−d/1cm)·40 = 15 → d = 1 cm·ln(20/15).
  const double r35 = 0.1 + 0.01 * std::log(20.0 / 15.0);
  EXPECT_NEAR(b.spots[0].area_m2, kPi * r35 * r35, 0.01 * kPi * r35 * r35);
}

TEST(SpotDetectTest, UnobservedSurfaceIsNeverASpot) {
  // A NaN hole in the middle of a uniform plane: no spot, no crash.
  const ThermalMesh mesh = Plane(1.0, 0.01, [&](double x, double y) {
    return std::hypot(x, y) < 0.1 ? std::nan("") : 20.0;
  });
  EXPECT_TRUE(DetectSpots(mesh, SpotOptions()).spots.empty());
}

TEST(SpotDetectTest, ALowEmissivityLabelIsNoColdSpotInSurfaceTemperature) {
  // A shiny label (ε 0.3) on a 30 °C surface in a 20 °C room reads ~7 K cold in apparent
  // temperature; reconstruct writes the corrected surface temperature as temperature_c.
  const ThermalMesh base = Plane(1.0, 0.01, [](double, double) { return 30.0; });
  core::PlyMesh ply;
  ply.SetPositions(base.points_in_world, core::PlyType::kFloat64);
  std::vector<double> surface(base.points_in_world.size(), 30.0), apparent(surface.size());
  for (size_t v = 0; v < surface.size(); ++v) {
    const Eigen::Vector3d& p = base.points_in_world[v];
    apparent[v] = std::abs(p.x()) < 0.1 && std::abs(p.y()) < 0.05 ? 23.0 : 29.6;
  }
  ply.AddProperty("temperature_c", core::PlyType::kFloat64, surface);
  ply.AddProperty("temperature_apparent_c", core::PlyType::kFloat64, apparent);
  ply.faces = base.faces;
  EXPECT_TRUE(DetectSpots(MakeThermalMesh(ply, "m.ply"), SpotOptions()).spots.empty());
  const SpotDetection apparent_spots = DetectSpots(MakeThermalMesh(ply, "m.ply", "temperature_apparent_c"), SpotOptions());
  ASSERT_EQ(apparent_spots.spots.size(), 1u);  // what an apparent-temperature analysis would report
  EXPECT_FALSE(apparent_spots.spots[0].hot);
  EXPECT_EQ(apparent_spots.field, "temperature_apparent_c");
}

TEST(SpotDetectTest, NonManifoldMeshesAreMeasured) {
  // Three sheets sharing one edge (a fin on a plate) and a vertex shared by two fans: the
  // graph and the clipping need no manifoldness; the spot on the plate is measured.
  ThermalMesh plate = Plane(1.0, 0.01, [](double x, double y) { return Plateau(std::hypot(x, y) - 0.1, 20, 40, 0.01); });
  core::PlyMesh ply;
  std::vector<Eigen::Vector3d> points = plate.points_in_world;
  std::vector<double> t = plate.temperature_c;
  std::vector<Eigen::Vector3i> faces = plate.faces;
  // A fin along the plate's edge y = -0.5 (x from -0.5 to -0.49): two extra triangles on it.
  const int a = 0, b = 1;  // the first grid edge
  points.emplace_back(-0.5, -0.5, 0.2);
  points.emplace_back(-0.49, -0.5, -0.2);
  t.push_back(20);
  t.push_back(20);
  faces.emplace_back(a, b, static_cast<int>(points.size()) - 2);
  faces.emplace_back(b, a, static_cast<int>(points.size()) - 1);
  ply.SetPositions(points, core::PlyType::kFloat64);
  ply.AddProperty("temperature_c", core::PlyType::kFloat64, t);
  ply.faces = faces;
  const SpotDetection d = DetectSpots(MakeThermalMesh(ply, "fin.ply"), SpotOptions());
  ASSERT_EQ(d.spots.size(), 1u);
  EXPECT_NEAR(d.spots[0].area_m2, kPi * 0.01, 0.02 * kPi * 0.01);
}

// A hot screw head (r 8 mm) on a 30 mm terminal strip 0.6 m long: the ring's two strips
// beside it are 18 % of the annulus a spot on an open surface has, but 15 times the head's
// area: surroundings enough (min_ring_area_ratio). Coverage alone would reject it.
TEST(SpotDetectTest, ASmallSpotOnANarrowFaceHasSurroundings) {
  const double radius = 0.008;
  const ThermalMesh mesh = Rectangle(0.6, 0.03, 0.001, [&](double x, double y) {
    return Plateau(std::hypot(x - 0.1, y) - radius, 28, 70, 0.002);
  });
  SpotOptions options;
  const SpotDetection d = DetectSpots(mesh, options);
  ASSERT_EQ(d.spots.size(), 1u);
  EXPECT_NEAR(d.spots[0].area_m2, kPi * radius * radius, 0.03 * kPi * radius * radius);
  EXPECT_NEAR(d.spots[0].reference_c, 28, 0.05);
  options.min_ring_area_ratio = 0;
  const SpotDetection coverage_alone = DetectSpots(mesh, options);
  EXPECT_TRUE(coverage_alone.spots.empty());
  ASSERT_FALSE(coverage_alone.rejected.empty());
  EXPECT_NE(coverage_alone.rejected[0].reason.find("no surrounding surface"), std::string::npos);
}

// A reconstruction rounds a crease: a warm cabinet side (x = 0, normal +x, 3 K above the
// wall) meets the wall behind it (y = 0, normal -y) through a 1 cm fillet, and the side's
// warmth, blurred, fills the fillet up to 2 mm short of the wall. The side is a whole part:
// no surroundings on its own surface. Paths leaving the region where the fillet has
// already turned 80° used to walk on round the crease and take the wall as surroundings;
// held to the region's mean normal within 2 cm of where they leave, they stop.
TEST(SpotDetectTest, AWholePartIsNotASpotWhenItsCreaseIsRounded) {
  const double h = 0.0025, radius = 0.01, depth = 0.2, wall = 0.8, height = 1.0;
  std::vector<Eigen::Vector2d> profile;  // (x, y), along the side face, the fillet, the wall
  std::vector<Eigen::Vector2d> normals;
  for (double y = -depth; y < -radius - 1e-9; y += h) profile.emplace_back(0, y), normals.emplace_back(1, 0);
  const int arc_steps = 8;
  for (int k = 0; k <= arc_steps; ++k) {
    const double a = 0.5 * kPi * k / arc_steps;  // 0: the side's normal, 90°: the wall's
    profile.emplace_back(radius - radius * std::cos(a), -radius + radius * std::sin(a));
    normals.emplace_back(std::cos(a), -std::sin(a));
  }
  for (double x = radius + h; x <= wall + 1e-9; x += h) profile.emplace_back(x, 0), normals.emplace_back(0, -1);
  std::vector<double> arc_length = {0};
  for (size_t i = 1; i < profile.size(); ++i) arc_length.push_back(arc_length.back() + (profile[i] - profile[i - 1]).norm());
  const double fillet_end = arc_length[profile.size() - static_cast<size_t>(std::lround((wall - radius) / h)) - 1];
  const double edge = fillet_end - 0.002;  // where the blurred step crosses its half-way level
  const int n = static_cast<int>(profile.size()), rows = static_cast<int>(std::lround(height / h)) + 1;
  std::vector<Eigen::Vector3d> points, point_normals;
  std::vector<double> t;
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < n; ++i) {
      points.emplace_back(profile[i].x(), profile[i].y(), j * h);
      point_normals.emplace_back(normals[i].x(), normals[i].y(), 0);
      t.push_back(21 + 3 * std::clamp(0.5 - (arc_length[i] - edge) / 0.004, 0.0, 1.0));
    }
  }
  core::PlyMesh ply;
  ply.SetPositions(points, core::PlyType::kFloat64);
  ply.SetNormals(point_normals, core::PlyType::kFloat64);
  ply.AddProperty("temperature_c", core::PlyType::kFloat64, t);
  for (int j = 0; j + 1 < rows; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
      ply.faces.emplace_back(a, d, c);  // normals: the side's +x, the wall's -y
      ply.faces.emplace_back(a, c, b);
    }
  }
  const ThermalMesh mesh = MakeThermalMesh(ply, "rounded.ply");
  SpotOptions options;
  const SpotDetection held = DetectSpots(mesh, options);
  EXPECT_TRUE(held.spots.empty());
  ASSERT_FALSE(held.rejected.empty());
  EXPECT_NE(held.rejected[0].reason.find("no surrounding surface"), std::string::npos) << held.rejected[0].reason;
  // Each path held to the normal of the vertex it left from: the wall becomes the side's
  // surroundings and the whole side a 3 K "spot".
  options.ring_normal_radius_m = 0;
  const SpotDetection own = DetectSpots(mesh, options);
  ASSERT_EQ(own.spots.size(), 1u);
  EXPECT_NEAR(own.spots[0].delta_k, 3, 0.1);
  EXPECT_GT(own.spots[0].area_m2, depth * height * 0.9);
}

// A mesh corrected for emissivity (temperature_emissivity): a 10 K spot on bare metal
// (ε 0.28, the surface round it painted) is not a measurement — not searched, its area
// reported; on paint, or without the field (fixture truth), or with the rule off: found.
TEST(SpotDetectTest, ASpotOnALowEmissivitySurfaceIsNotRated) {
  const ThermalMesh base = Plane(1.0, 0.01, [](double x, double y) {
    return Plateau(std::hypot(x, y) - 0.05, 20, 30, 0.005);  // ΔT 10 K, r 5 cm
  });
  auto with = [&](double spot_emissivity) {
    ThermalMesh mesh = base;
    mesh.emissivity.assign(mesh.points_in_world.size(), 0.93);
    for (size_t v = 0; v < mesh.points_in_world.size(); ++v) {
      if (mesh.points_in_world[v].norm() < 0.06) mesh.emissivity[v] = spot_emissivity;
    }
    return mesh;
  };
  const SpotDetection metal = DetectSpots(with(0.28), SpotOptions());
  EXPECT_TRUE(metal.spots.empty());
  // The metal disc (r 6 cm at 1 cm vertex spacing) is the surface not rated.
  EXPECT_NEAR(metal.unrated_area_m2, M_PI * 0.06 * 0.06, 0.0015);
  const SpotDetection paint = DetectSpots(with(0.9), SpotOptions());
  EXPECT_EQ(paint.spots.size(), 1u);
  EXPECT_EQ(paint.unrated_area_m2, 0);
  EXPECT_EQ(DetectSpots(base, SpotOptions()).spots.size(), 1u);
  SpotOptions off;
  off.min_emissivity = 0;
  EXPECT_EQ(DetectSpots(with(0.28), off).spots.size(), 1u);
  off.min_emissivity = 1.5;
  EXPECT_NE(off.Check().find("min_emissivity"), std::string::npos);
}

// The fields reconstruct adds: a spot is confirmed only when enough thermal frames saw it
// (min_views) and they agree about it (max_view_spread_ratio).
TEST(SpotDetectTest, ASpotTheViewsDoNotConfirmIsRejected) {
  const ThermalMesh base = Plane(1.0, 0.01, [](double x, double y) {
    return Plateau(std::hypot(x, y) - 0.05, 20, 30, 0.005);  // ΔT 10 K, r 5 cm
  });
  auto with = [&](double views, double spot_std_c) {
    ThermalMesh mesh = base;
    mesh.views.assign(mesh.points_in_world.size(), 40);
    mesh.std_c.assign(mesh.points_in_world.size(), 0.2);
    for (size_t v = 0; v < mesh.points_in_world.size(); ++v) {
      if (mesh.points_in_world[v].norm() < 0.06) {
        mesh.views[v] = views;
        mesh.std_c[v] = spot_std_c;
      }
    }
    return DetectSpots(mesh, SpotOptions());
  };
  auto rejected_for = [](const SpotDetection& d, const std::string& option) {
    for (const RejectedCandidate& r : d.rejected) {
      if (r.reason.find(option) != std::string::npos) return true;
    }
    return false;
  };
  // Seen 40 times, the views within 0.4 K of each other: found, the spread reported.
  const SpotDetection agreed = with(40, 0.4);
  ASSERT_EQ(agreed.spots.size(), 1u);
  EXPECT_NEAR(agreed.spots[0].mean_view_spread_c, 0.4, 1e-9);
  EXPECT_NEAR(agreed.spots[0].mean_views, 40, 1e-9);
  // The views 6 K apart about a 10 K spot (a reflection moving with the viewpoint): rejected.
  const SpotDetection disputed = with(40, 6);
  EXPECT_TRUE(disputed.spots.empty());
  EXPECT_TRUE(rejected_for(disputed, "max_view_spread_ratio"));
  // 4 K apart (0.4 of ΔT): still found; and with the rule off, the 6 K one is.
  EXPECT_EQ(with(40, 4).spots.size(), 1u);
  ThermalMesh mesh = base;
  mesh.std_c.assign(mesh.points_in_world.size(), 6);
  SpotOptions off;
  off.max_view_spread_ratio = 0;
  EXPECT_EQ(DetectSpots(mesh, off).spots.size(), 1u);
  // Seen twice: unconfirmed.
  const SpotDetection glimpsed = with(2, 0.4);
  EXPECT_TRUE(glimpsed.spots.empty());
  EXPECT_TRUE(rejected_for(glimpsed, "min_views"));
  // Seen 8 times where the plane round it was seen 40 (< 0.5 of them): a glimpse, rejected;
  // 24 times (0.6): found; with the rule off, 8 is.
  const SpotDetection few = with(8, 0.4);
  EXPECT_TRUE(few.spots.empty());
  EXPECT_TRUE(rejected_for(few, "min_views_ratio"));
  EXPECT_EQ(with(24, 0.4).spots.size(), 1u);
  SpotOptions no_ratio;
  no_ratio.min_views_ratio = 0;
  ThermalMesh seen_less = base;
  seen_less.views.assign(seen_less.points_in_world.size(), 40);
  for (size_t v = 0; v < seen_less.points_in_world.size(); ++v) {
    if (seen_less.points_in_world[v].norm() < 0.06) seen_less.views[v] = 8;
  }
  EXPECT_EQ(DetectSpots(seen_less, no_ratio).spots.size(), 1u);
}

TEST(SpotDetectTest, OptionsAndSeverityChecks) {
  SpotOptions o;
  EXPECT_EQ(o.Check(), "");
  o.reference = SpotOptions::Reference::kAmbient;
  EXPECT_NE(o.Check().find("ambient_c"), std::string::npos);
  o = SpotOptions();
  o.detect = SpotOptions::Detect::kAbsolute;
  o.hot_above_c = 10;
  o.cold_below_c = 30;
  EXPECT_NE(o.Check().find("inverted"), std::string::npos);
  o = SpotOptions();
  o.min_ring_area_ratio = -1;
  EXPECT_NE(o.Check().find("min_ring_area_ratio"), std::string::npos);
  o = SpotOptions();
  o.ring_normal_radius_m = -0.01;
  EXPECT_NE(o.Check().find("ring_normal_radius_m"), std::string::npos);
  o = SpotOptions();
  o.optics_psf_px = -1;
  EXPECT_NE(o.Check().find("optics_psf_px"), std::string::npos);
  o = SpotOptions();
  o.min_resolved_px = std::nan("");
  EXPECT_NE(o.Check().find("min_resolved_px"), std::string::npos);
  o = SpotOptions();
  o.max_view_spread_ratio = -0.5;
  EXPECT_NE(o.Check().find("max_view_spread_ratio"), std::string::npos);
  o = SpotOptions();
  o.min_views_ratio = 1.5;
  EXPECT_NE(o.Check().find("min_views_ratio"), std::string::npos);
  o = SpotOptions();
  o.severity = {{5, "b", ""}, {1, "a", ""}};
  EXPECT_NE(o.Check().find("severity[1].min_delta_k"), std::string::npos);
  const std::vector<SeverityBand> neta = NetaSeverityTable();
  EXPECT_EQ(SeverityFor(neta, 0.5), nullptr);
  EXPECT_EQ(SeverityFor(neta, 3.9)->name, "possible");
  EXPECT_EQ(SeverityFor(neta, -10)->name, "probable");
  EXPECT_EQ(SeverityFor(neta, 16)->name, "major");
}

}  // namespace
}  // namespace hw::analyze
