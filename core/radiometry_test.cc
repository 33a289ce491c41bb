#include "core/radiometry.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

namespace hw::core {
namespace {

using ::testing::HasSubstr;
using LD = long double;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- Independent reference: Planck's law integrated numerically in long double. ----

constexpr LD kH = 6.62607015e-34L;
constexpr LD kC = 299792458.0L;
constexpr LD kK = 1.380649e-23L;
constexpr LD kC1 = 2 * kH * kC * kC;
constexpr LD kC2 = kH * kC / kK;
constexpr LD kPiL = 3.141592653589793238462643383279502884L;

// Planck spectral radiance B(lambda, T), W/(m^2 sr m), and dB/dT.
LD Planck(LD lambda_m, LD t) {
  return kC1 / (std::pow(lambda_m, 5) * std::expm1(kC2 / (lambda_m * t)));
}
LD PlanckDt(LD lambda_m, LD t) {
  const LD x = kC2 / (lambda_m * t);
  const LD em1 = std::expm1(x);
  return kC1 / std::pow(lambda_m, 5) * (em1 + 1) / (em1 * em1) * x / t;
}

// Gauss-Legendre nodes/weights on [-1, 1] by Newton on P_n, in long double.
std::vector<std::pair<LD, LD>> GaussLegendre(int n) {
  std::vector<std::pair<LD, LD>> rule;
  for (int i = 1; i <= n; ++i) {
    LD x = std::cos(kPiL * (i - 0.25L) / (n + 0.5L));
    LD dp = 0;
    for (int iter = 0; iter < 100; ++iter) {
      LD p0 = 1, p1 = x;
      for (int k = 2; k <= n; ++k) {
        const LD p2 = ((2 * k - 1) * x * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      dp = n * (x * p1 - p0) / (x * x - 1);
      const LD dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-19L) break;
    }
    rule.emplace_back(x, 2 / ((1 - x * x) * dp * dp));
  }
  return rule;
}

// Composite 20-point Gauss-Legendre over [lo, hi] micrometres with `panels` equal panels,
// of f(lambda_m): the integrand is smooth and varies by at most e^10 per panel here, so
// this is exact to long-double rounding.
template <typename F>
LD IntegrateBand(LD lo_um, LD hi_um, int panels, F f) {
  static const std::vector<std::pair<LD, LD>> rule = GaussLegendre(20);
  const LD lo = lo_um * 1e-6L, hi = hi_um * 1e-6L;
  const LD width = (hi - lo) / panels;
  LD sum = 0;
  for (int p = 0; p < panels; ++p) {
    const LD a = lo + p * width;
    for (const auto& [x, w] : rule) sum += w * f(a + 0.5L * width * (x + 1));
  }
  return sum * 0.5L * width;
}

LD ReferenceRadiance(LD lo_um, LD hi_um, LD t) {
  return IntegrateBand(lo_um, hi_um, 40, [t](LD l) { return Planck(l, t); });
}
LD ReferenceDerivative(LD lo_um, LD hi_um, LD t) {
  return IntegrateBand(lo_um, hi_um, 40, [t](LD l) { return PlanckDt(l, t); });
}

struct Band {
  double lo_um, hi_um;
};
// The rig's band, a common LWIR band, MWIR, and SWIR (deep Wien regime).
const std::vector<Band> kBands = {{7.5, 14.0}, {8.0, 14.0}, {3.0, 5.0}, {0.9, 1.7}};
// -40 .. 1000 °C; for 7.5-14 µm these put both ends of the band on either side of the
// series switch and straddling it, so every branch of the band integral is exercised.
const std::vector<double> kTemperaturesC = {-40, -20, 0, 20, 37, 100, 250, 400, 600, 800, 1000};

TEST(RadiometryTest, ConstantsAreCodata2018) {
  EXPECT_NEAR(kRadianceC1, 1.191042972e-16, 1e-25);  // CODATA c1L
  EXPECT_NEAR(kRadianceC2, 1.438776877e-2, 1e-11);   // CODATA c2
  EXPECT_EQ(CelsiusToKelvin(20.0), 293.15);
  EXPECT_EQ(KelvinToCelsius(273.15), 0.0);
}

TEST(RadiometryTest, BandRadianceMatchesNumericalIntegration) {
  double worst = 0;
  for (const Band& band : kBands) {
    const BandRadiance radiance(band.lo_um, band.hi_um);
    for (const double t_c : kTemperaturesC) {
      const double t_k = CelsiusToKelvin(t_c);
      const LD reference = ReferenceRadiance(band.lo_um, band.hi_um, t_k);
      const double relative = static_cast<double>(
          std::abs((radiance.Radiance(t_k) - reference) / reference));
      worst = std::max(worst, relative);
      EXPECT_LT(relative, 1e-13) << band.lo_um << "-" << band.hi_um << " µm at " << t_c;
    }
  }
  std::printf("band radiance vs Gauss-Legendre: max relative error %.3g\n", worst);
}

TEST(RadiometryTest, KnownValue) {
  // 8-14 µm at 300 K: 54.93346138 W/(m^2 sr) (composite Simpson, 20000 panels, in Python),
  // 37.6% of sigma T^4 / pi.
  const BandRadiance band(8, 14);
  EXPECT_NEAR(band.Radiance(300), 54.93346138, 1e-8);
}

TEST(RadiometryTest, StefanBoltzmann) {
  const LD sigma = 2 * std::pow(kPiL, 5) * std::pow(kK, 4) / (15 * std::pow(kH, 3) * kC * kC);
  EXPECT_NEAR(static_cast<double>(sigma), 5.670374419e-8, 1e-17);
  // 0.1..1000 µm holds all but ~(x_lo^3/3) / (pi^4/15) of the radiance, x_lo = c2/(1000 µm T):
  // < 1e-6 from 600 K up.
  const BandRadiance wide(0.1, 1000);
  for (const double t_k : {600.0, 800.0, 1000.0, 1273.15}) {
    const double total = static_cast<double>(sigma) * std::pow(t_k, 4) / std::numbers::pi;
    EXPECT_NEAR(wide.Radiance(t_k) / total, 1.0, 1e-6) << t_k;
  }
  // A band wide enough to hold everything to 1e-15 checks the whole integral exactly.
  const BandRadiance all(1e-3, 1e9);
  for (const double t_k : {1.0, 10.0, 77.0, 300.0, 1000.0, 5000.0}) {
    const double total = static_cast<double>(sigma) * std::pow(t_k, 4) / std::numbers::pi;
    EXPECT_NEAR(all.Radiance(t_k) / total, 1.0, 1e-14) << t_k;
  }
}

TEST(RadiometryTest, DerivativeMatchesIntegralAndFiniteDifferences) {
  double worst_integral = 0, worst_fd = 0;
  for (const Band& band : kBands) {
    const BandRadiance radiance(band.lo_um, band.hi_um);
    for (const double t_c : kTemperaturesC) {
      const double t = CelsiusToKelvin(t_c);
      const double d = radiance.Derivative(t);
      const LD reference = ReferenceDerivative(band.lo_um, band.hi_um, t);
      const double rel_integral = static_cast<double>(std::abs((d - reference) / reference));
      // 5-point central difference, h = 1e-4 T: truncation ~ (h/T)^4 x^5 / 30 < 1e-10,
      // rounding ~ 1e-16 / 1e-4 = 1e-12.
      const double h = 1e-4 * t;
      const double fd = (-radiance.Radiance(t + 2 * h) + 8 * radiance.Radiance(t + h) -
                         8 * radiance.Radiance(t - h) + radiance.Radiance(t - 2 * h)) /
                        (12 * h);
      const double rel_fd = std::abs((d - fd) / d);
      worst_integral = std::max(worst_integral, rel_integral);
      worst_fd = std::max(worst_fd, rel_fd);
      EXPECT_LT(rel_integral, 1e-13) << band.lo_um << " " << t_c;
      EXPECT_LT(rel_fd, 1e-9) << band.lo_um << " " << t_c;
      double l2, d2;
      radiance.RadianceAndDerivative(t, &l2, &d2);
      EXPECT_EQ(l2, radiance.Radiance(t));
      EXPECT_EQ(d2, d);
    }
  }
  std::printf("dL/dT: max relative error %.3g vs integral, %.3g vs finite differences\n",
              worst_integral, worst_fd);
}

TEST(RadiometryTest, TemperatureInvertsRadiance) {
  double worst = 0;
  for (const Band& band : kBands) {
    const BandRadiance radiance(band.lo_um, band.hi_um);
    // Fine sweep over the working range plus far outside the starting table.
    std::vector<double> temperatures;
    for (double t = 150; t < 2500; t *= 1.013) temperatures.push_back(t);
    for (const double t : {60.0, 1e4, 1e5}) temperatures.push_back(t);
    if (band.lo_um > 5) temperatures.push_back(5.0);  // L ~ 1e-50 W/(m^2 sr) in LWIR
    for (const double t : temperatures) {
      const double back = radiance.Temperature(radiance.Radiance(t));
      worst = std::max(worst, std::abs(back - t) / t);
      ASSERT_NEAR(back, t, 1e-13 * t) << band.lo_um << "-" << band.hi_um << " at " << t;
    }
  }
  std::printf("Temperature(Radiance(T)): max relative error %.3g\n", worst);
  // Absolute: 1e-9 K over -40..1000 °C in the rig's band.
  const BandRadiance rig(7.5, 14);
  for (const double t_c : kTemperaturesC) {
    const double t = CelsiusToKelvin(t_c);
    EXPECT_NEAR(rig.Temperature(rig.Radiance(t)), t, 1e-9);
  }
}

TEST(RadiometryTest, TemperatureOfReferenceRadiance) {
  // Against the independent integral: the inverse is right, not only self-consistent.
  const BandRadiance band(7.5, 14);
  for (const double t_c : {-40.0, 20.0, 500.0}) {
    const double t = CelsiusToKelvin(t_c);
    const double l = static_cast<double>(ReferenceRadiance(7.5, 14, t));
    EXPECT_NEAR(band.Temperature(l), t, 1e-11);
  }
}

TEST(RadiometryTest, EdgeValues) {
  const BandRadiance band(7.5, 14);
  EXPECT_EQ(band.Radiance(0), 0.0);
  EXPECT_EQ(band.Derivative(0), 0.0);
  EXPECT_TRUE(std::isnan(band.Radiance(-1)));
  EXPECT_TRUE(std::isnan(band.Radiance(std::nan(""))));
  EXPECT_TRUE(std::isnan(band.Derivative(-1)));
  EXPECT_TRUE(std::isinf(band.Radiance(INFINITY)));
  EXPECT_TRUE(std::isnan(band.Temperature(0)));
  EXPECT_TRUE(std::isnan(band.Temperature(-3)));
  EXPECT_TRUE(std::isnan(band.Temperature(std::nan(""))));
  EXPECT_TRUE(std::isinf(band.Temperature(INFINITY)));
  EXPECT_EQ(band.lambda_lo_um(), 7.5);
  EXPECT_EQ(band.lambda_hi_um(), 14.0);
  // Monotone and positive over a fine sweep (no seams at the series switch, x = 2).
  double previous = 0;
  for (double t = 2; t < 3000; t *= 1.001) {
    const double l = band.Radiance(t);
    ASSERT_GT(l, previous) << t;
    ASSERT_GT(band.Derivative(t), 0) << t;
    previous = l;
  }
}

TEST(RadiometryTest, SpectralRadiance) {
  for (const double lambda_um : {1.0, 4.0, 10.0, 100.0}) {
    for (const double t : {250.0, 300.0, 1500.0}) {
      const LD reference = Planck(lambda_um * 1e-6L, t) * 1e-6L;  // per µm
      EXPECT_NEAR(SpectralRadiance(lambda_um, t) / static_cast<double>(reference), 1.0, 1e-14);
    }
  }
  // Wien's displacement law: the peak is at 2897.771955 µm K / T.
  const double t = 300;
  const double peak_um = 2897.771955 / t;
  EXPECT_GT(SpectralRadiance(peak_um, t), SpectralRadiance(peak_um * 1.001, t));
  EXPECT_GT(SpectralRadiance(peak_um, t), SpectralRadiance(peak_um / 1.001, t));
  EXPECT_EQ(SpectralRadiance(10, 0), 0.0);
  EXPECT_TRUE(std::isnan(SpectralRadiance(10, -1)));
}

TEST(RadiometryTest, CheckSpectralBand) {
  EXPECT_EQ(CheckSpectralBand(7.5, 14), "");
  EXPECT_THAT(CheckSpectralBand(0, 14), HasSubstr("lower band edge must be a finite number > 0"));
  EXPECT_THAT(CheckSpectralBand(-1, 14), HasSubstr("got -1"));
  EXPECT_THAT(CheckSpectralBand(std::nan(""), 14), HasSubstr("lower band edge"));
  EXPECT_THAT(CheckSpectralBand(14, 7.5), HasSubstr("upper band edge must be finite and > "
                                                    "the lower edge 14 µm, got 7.5"));
  EXPECT_THAT(CheckSpectralBand(7.5, 7.5), HasSubstr("upper band edge"));
  EXPECT_THAT(CheckSpectralBand(7.5, INFINITY), HasSubstr("upper band edge"));
}

TEST(RadiometryTest, ApparentSurfaceRoundTrip) {
  double worst = 0, worst_vs_bound = 0;
  for (const Band& b : kBands) {
    const BandRadiance band(b.lo_um, b.hi_um);
    for (double e = 0.1; e <= 1.0 + 1e-12; e += 0.1) {
      const double emissivity = std::min(e, 1.0);
      for (double reflected_c = -20; reflected_c <= 60; reflected_c += 10) {
        for (const double surface_c : kTemperaturesC) {
          const double apparent_c = ApparentFromSurface(band, surface_c, emissivity, reflected_c);
          const double back = SurfaceFromApparent(band, apparent_c, emissivity, reflected_c);
          const double error = std::abs(back - surface_c);
          // The inversion amplifies the ~1e-15 relative rounding of the apparent temperature
          // by its condition number dT_s/dT_a (up to ~4e5 in SWIR with e = 0.1: the surface
          // then contributes a millionth of the signal). Within 10x of that bound, and
          // within 1e-9 K outright in the thermal bands (d < 300 there).
          const double d = SurfacePerApparent(band, apparent_c, emissivity, reflected_c);
          const double bound = 1e-12 + 1e-14 * d * CelsiusToKelvin(apparent_c);
          worst = std::max(worst, error);
          worst_vs_bound = std::max(worst_vs_bound, error / bound);
          ASSERT_LE(error, bound) << b.lo_um << " e=" << emissivity << " refl=" << reflected_c
                                  << " surface=" << surface_c;
          if (b.lo_um >= 3) {
            ASSERT_LE(error, 1e-9) << b.lo_um << " e=" << emissivity << " refl=" << reflected_c;
          }
        }
      }
    }
  }
  std::printf("SurfaceFromApparent(ApparentFromSurface(T)): max error %.3g K, %.3g of bound\n",
              worst, worst_vs_bound);
}

TEST(RadiometryTest, ApparentMatchesIndependentModel) {
  // e L(T_s) + (1 - e) L(T_r) with the reference integral, inverted by bisection.
  const double e = 0.7, surface_c = 80, reflected_c = 15;
  const LD target = e * ReferenceRadiance(7.5, 14, CelsiusToKelvin(surface_c)) +
                    (1 - e) * ReferenceRadiance(7.5, 14, CelsiusToKelvin(reflected_c));
  LD lo = 200, hi = 400;
  for (int i = 0; i < 80; ++i) {
    const LD mid = 0.5L * (lo + hi);
    (ReferenceRadiance(7.5, 14, mid) < target ? lo : hi) = mid;
  }
  const BandRadiance band(7.5, 14);
  EXPECT_NEAR(ApparentFromSurface(band, surface_c, e, reflected_c),
              static_cast<double>(lo) - 273.15, 1e-10);
}

TEST(RadiometryTest, PhysicalBehaviour) {
  const BandRadiance band(7.5, 14);
  // Emissivity 1: apparent is the surface temperature, exactly.
  for (const double t_c : kTemperaturesC) {
    EXPECT_EQ(ApparentFromSurface(band, t_c, 1.0, 55.0), t_c);
    EXPECT_EQ(SurfaceFromApparent(band, t_c, 1.0, -10.0), t_c);
  }
  // Colder surroundings: a grey surface looks colder than it is, but warmer than them;
  // the lower the emissivity, the colder it looks.
  double previous = 100;
  for (const double e : {0.95, 0.8, 0.5, 0.2}) {
    const double apparent = ApparentFromSurface(band, 100, e, 20);
    EXPECT_LT(apparent, previous) << e;
    EXPECT_GT(apparent, 20);
    previous = apparent;
  }
  // Hotter surroundings: it looks warmer. Equal temperatures: no change.
  EXPECT_GT(ApparentFromSurface(band, 20, 0.5, 100), 20);
  EXPECT_NEAR(ApparentFromSurface(band, 37, 0.3, 37), 37, 1e-10);
  // Apparent temperature is never colder than the coldest of surface and reflection.
  EXPECT_GT(ApparentFromSurface(band, -40, 0.9, -20), -40);
}

TEST(RadiometryTest, NoSurfaceTemperatureFitsTooColdAReading) {
  // e = 0.1, reflection at 60 °C: the reflection alone gives more than 0 °C apparent, so a
  // 0 °C reading implies a negative surface radiance.
  const BandRadiance band(7.5, 14);
  EXPECT_TRUE(std::isnan(SurfaceFromApparent(band, 0, 0.1, 60)));
  const SurfaceTemperature s = SurfaceFromApparentWithDerivatives(band, 0, 0.1, 60);
  EXPECT_TRUE(std::isnan(s.surface_c));
  EXPECT_TRUE(std::isnan(s.d_apparent));
  EXPECT_TRUE(std::isnan(s.d_reflected));
  EXPECT_TRUE(std::isnan(s.d_emissivity));
  EXPECT_TRUE(std::isnan(SurfacePerApparent(band, 0, 0.1, 60)));
  // The boundary: the apparent temperature of a 0 K surface, i.e. of the reflection alone.
  const double floor_c = ApparentFromSurface(band, -kKelvinOffset, 0.1, 60);
  EXPECT_GT(floor_c, 0);
  EXPECT_FALSE(std::isnan(SurfaceFromApparent(band, floor_c + 0.5, 0.1, 60)));
  EXPECT_TRUE(std::isnan(SurfaceFromApparent(band, floor_c - 0.5, 0.1, 60)));
  // NaN inputs propagate.
  EXPECT_TRUE(std::isnan(SurfaceFromApparent(band, std::nan(""), 0.9, 20)));
  EXPECT_TRUE(std::isnan(SurfaceFromApparent(band, 20, 0.9, std::nan(""))));
  EXPECT_TRUE(std::isnan(SurfaceFromApparent(band, 20, 1.0, std::nan(""))));
  EXPECT_TRUE(std::isnan(ApparentFromSurface(band, std::nan(""), 0.9, 20)));
  EXPECT_TRUE(std::isnan(ApparentFromSurface(band, -300, 0.9, 20)));  // below absolute zero
}

TEST(RadiometryTest, SurfaceDerivativesMatchFiniteDifferences) {
  const BandRadiance band(7.5, 14);
  for (const double e : {0.3, 0.7, 0.95, 1.0}) {
    for (const double apparent_c : {25.0, 60.0, 300.0}) {
      const double reflected_c = 20;
      const SurfaceTemperature s =
          SurfaceFromApparentWithDerivatives(band, apparent_c, e, reflected_c);
      EXPECT_NEAR(s.surface_c, SurfaceFromApparent(band, apparent_c, e, reflected_c), 1e-12);
      const double h = 1e-3;  // K, and unit emissivity
      auto f = [&](double a, double em, double r) { return SurfaceFromApparent(band, a, em, r); };
      const double d_apparent =
          (f(apparent_c + h, e, reflected_c) - f(apparent_c - h, e, reflected_c)) / (2 * h);
      const double d_reflected =
          (f(apparent_c, e, reflected_c + h) - f(apparent_c, e, reflected_c - h)) / (2 * h);
      // Central difference in emissivity; at e = 1 only the one-sided one exists.
      const double d_emissivity =
          e < 1 ? (f(apparent_c, e + 1e-5, reflected_c) - f(apparent_c, e - 1e-5, reflected_c)) /
                      2e-5
                : (f(apparent_c, e, reflected_c) - f(apparent_c, e - 1e-6, reflected_c)) / 1e-6;
      EXPECT_NEAR(s.d_apparent, d_apparent, 1e-6 * std::abs(d_apparent));
      EXPECT_NEAR(s.d_reflected, d_reflected, 1e-6 * std::abs(d_apparent));
      EXPECT_NEAR(s.d_emissivity, d_emissivity, 1e-4 * std::abs(d_emissivity));
      EXPECT_EQ(SurfacePerApparent(band, apparent_c, e, reflected_c), s.d_apparent);
      EXPECT_GE(s.d_apparent, 1.0 - 1e-15);
      EXPECT_LE(s.d_reflected, 0.0);
    }
  }
  EXPECT_EQ(SurfacePerApparent(band, 30, 1.0, 20), 1.0);
}

TEST(RadiometryTest, EmissivityOutsideRangeIsABug) {
  const BandRadiance band(7.5, 14);
  EXPECT_DEBUG_DEATH(ApparentFromSurface(band, 20, 0.0, 20), "emissivity");
  EXPECT_DEBUG_DEATH(SurfaceFromApparent(band, 20, 1.5, 20), "emissivity");
}

// ---- Directional emissivity ----

constexpr double kDeg = std::numbers::pi / 180;

// Independent reference: Fresnel amplitude coefficients with complex arithmetic, Snell's
// law N·sin θ_t = sin θ, and the root of cos θ_t that decays into the medium (Im(N cos θ_t)
// >= 0); unpolarised R = (|r_s|² + |r_p|²) / 2.
double ComplexFresnelReflectance(double n, double k, double theta_rad) {
  using C = std::complex<double>;
  const C index(n, k);
  const double c = std::cos(theta_rad), s = std::sin(theta_rad);
  C n_cos_t = std::sqrt(index * index - s * s);
  if (n_cos_t.imag() < 0) n_cos_t = -n_cos_t;
  const C cos_t = n_cos_t / index;
  const C rs = (c - n_cos_t) / (c + n_cos_t);
  const C rp = (index * c - cos_t) / (index * c + cos_t);
  return 0.5 * (std::norm(rs) + std::norm(rp));
}

TEST(RadiometryTest, FresnelReflectanceMatchesTheComplexForm) {
  // Metals of the scenes, gold-like, a lossless and a weakly absorbing dielectric (b = 0
  // branch), and the dielectric of a painted surface.
  const std::vector<ComplexIndex> indices = {
      MetalIndexForNormalEmissivity(0.07), MetalIndexForNormalEmissivity(0.3), {25.3, 89.8},
      {1.5, 0.0}, {2.4, 0.05}, {DielectricIndexForNormalEmissivity(0.95), 0.0}};
  for (const ComplexIndex& index : indices) {
    // Normal incidence: the textbook ((n-1)² + k²)/((n+1)² + k²).
    const double n = index.n, k = index.k;
    EXPECT_NEAR(FresnelReflectance(index, 1.0),
                ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k), 1e-14);
    for (const double deg : {10.0, 30.0, 45.0, 60.0, 75.0, 80.0, 85.0, 88.0, 89.0, 89.9}) {
      const double r = FresnelReflectance(index, std::cos(deg * kDeg));
      // Round-off of either form is ~1e-15 relative; 1e-12 leaves room for the grazing
      // angles where cos θ_t is computed from a difference.
      EXPECT_NEAR(r, ComplexFresnelReflectance(n, k, deg * kDeg), 1e-12) << n << "+" << k << "i "
                                                                         << deg;
      EXPECT_GE(r, 0);  // energy: absorptance 1 - R in [0, 1]
      EXPECT_LE(r, 1);
    }
    EXPECT_EQ(FresnelReflectance(index, 0.0), 1.0);  // grazing: total reflection
  }
  // Hecht, Optics, §4.6: crown glass n = 1.5 at 45° reflects R_s = 0.0920, R_p = 0.0085.
  EXPECT_NEAR(FresnelReflectance({1.5, 0}, std::cos(45 * kDeg)), 0.5 * (0.0920 + 0.0085), 1e-4);
}

TEST(RadiometryTest, MetalEmissivityRisesTowardsGrazingAngles) {
  EXPECT_NEAR(MaxMetalNormalEmissivity(), 2 / (1 + std::sqrt(10.0)), 1e-15);
  for (const double e_n : {0.07, 0.1, 0.2, 0.28, 0.3}) {
    const ComplexIndex index = MetalIndexForNormalEmissivity(e_n);
    EXPECT_NEAR(index.k / index.n, kMetalExtinctionRatio, 1e-15);
    EXPECT_GT(index.n, 1);  // the metallic root
    EXPECT_NEAR(MetalDirectionalEmissivity(e_n, 1.0), e_n, 1e-12);
    EXPECT_EQ(MetalDirectionalEmissivity(e_n, 0.0), 0.0);
    EXPECT_GT(MetalDirectionalEmissivity(e_n, std::cos(60 * kDeg)), e_n);
  }
  // Bare copper and aluminium (ε_n 0.07, 0.1): the p-polarised peak lies at 80–88°, where
  // the emissivity is over twice ε_n, and the curve rises monotonically up to it.
  for (const double e_n : {0.07, 0.1}) {
    EXPECT_GT(MetalDirectionalEmissivity(e_n, std::cos(80 * kDeg)), 1.5 * e_n);
    std::vector<double> curve;
    for (int tenth = 0; tenth <= 900; ++tenth) {
      curve.push_back(
          DirectionalEmissivity(EmissivityLaw::kMetal, e_n, std::cos(tenth * 0.1 * kDeg)));
    }
    const auto top = std::max_element(curve.begin(), curve.end());
    const double peak = *top, peak_deg = 0.1 * static_cast<double>(top - curve.begin());
    EXPECT_TRUE(std::is_sorted(curve.begin(), top + 1)) << e_n;
    EXPECT_GE(peak_deg, 80);
    EXPECT_LE(peak_deg, 88);
    EXPECT_GT(peak, 2 * e_n);
  }
}

TEST(RadiometryTest, DirectionalEmissivityIsTheNormalEmissivityAtNormalIncidence) {
  for (const double e_n : {0.02, 0.1, 0.3, 0.48}) {
    EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kMetal, e_n, 1.0), e_n, 1e-12) << e_n;
  }
  for (const double e_n : {0.02, 0.3, 0.6, 0.9, 0.95, 0.99, 1.0}) {
    EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, e_n, 1.0), e_n, 1e-12) << e_n;
    EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, e_n, -1.0), e_n, 1e-12) << e_n;
  }
  // Paint, ε_n = 0.95: n = (1 + √0.05)/(1 - √0.05).
  EXPECT_NEAR(DielectricIndexForNormalEmissivity(0.95),
              (1 + std::sqrt(0.05)) / (1 - std::sqrt(0.05)), 1e-14);
  EXPECT_EQ(DielectricIndexForNormalEmissivity(1.0), 1.0);
}

TEST(RadiometryTest, DielectricEmissivityFallsToZeroAtGrazingIncidence) {
  for (const double e_n : {0.3, 0.6, 0.8, 0.9, 0.95, 0.99}) {
    // Flat near the normal: within 0.01 of ε_n up to 40° (0.0062 at worst, ε_n = 0.95).
    for (double deg = 0; deg <= 40; deg += 1) {
      EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, e_n, std::cos(deg * kDeg)),
                  e_n, 0.01)
          << e_n << " " << deg;
    }
    EXPECT_EQ(DirectionalEmissivity(EmissivityLaw::kDielectric, e_n, 0.0), 0.0) << e_n;
  }
  // Monotonic for the usual paints, plastics and glass (n <= 2.6).
  for (const double e_n : {0.8, 0.9, 0.95, 0.99, 0.9999}) {
    double previous = 1;
    for (int tenth = 0; tenth <= 900; ++tenth) {
      const double e =
          DirectionalEmissivity(EmissivityLaw::kDielectric, e_n, std::cos(tenth * 0.1 * kDeg));
      EXPECT_LE(e, previous) << e_n << " " << tenth * 0.1;
      previous = e;
    }
  }
  // Paint at 60° and 80° (ε_n = 0.95): 0.899 and 0.601 from the Fresnel equations with
  // n = 1.576 (hand computation with the complex form above).
  EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, 0.95, std::cos(60 * kDeg)),
              1 - ComplexFresnelReflectance(1.5760143110525877, 0, 60 * kDeg), 1e-12);
  EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, 0.95, std::cos(60 * kDeg)), 0.8985,
              1e-4);
  EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, 0.95, std::cos(80 * kDeg)), 0.6011,
              1e-4);
  // Lower ε_n: the Brewster peak lifts the curve above ε_n first (0.612 at 70° for 0.6,
  // 0.515 at 85° for 0.3, from the complex form).
  EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, 0.6, std::cos(70 * kDeg)), 0.6119,
              1e-4);
  EXPECT_NEAR(DirectionalEmissivity(EmissivityLaw::kDielectric, 0.3, std::cos(85 * kDeg)), 0.5153,
              1e-4);
  // A black body emits the same at every angle.
  for (const double c : {1.0, 0.5, 0.01, 0.0}) {
    EXPECT_EQ(DirectionalEmissivity(EmissivityLaw::kDielectric, 1.0, c), 1.0);
  }
}

// Dunkle's closed form of the hemispherical emissivity of a smooth dielectric of index n
// (R. V. Dunkle, 1963; reproduced in Siegel & Howell, "Thermal Radiation Heat Transfer",
// and Modest, "Radiative Heat Transfer", ch. 3): 0.908 for glass, n = 1.5, against ε_n 0.96.
double DunkleHemisphericalEmissivity(double n) {
  const double n2 = n * n, n4 = n2 * n2;
  return 0.5 - (3 * n + 1) * (n - 1) / (6 * (n + 1) * (n + 1)) -
         n2 * (n2 - 1) * (n2 - 1) / std::pow(n2 + 1, 3) * std::log((n - 1) / (n + 1)) +
         2 * n2 * n * (n2 + 2 * n - 1) / ((n2 + 1) * (n4 - 1)) -
         8 * n4 * (n4 + 1) / ((n2 + 1) * (n4 - 1) * (n4 - 1)) * std::log(n);
}

TEST(RadiometryTest, DielectricHemisphericalEmissivityMatchesDunkle) {
  EXPECT_NEAR(DunkleHemisphericalEmissivity(1.5), 0.908, 5e-4);  // the published value
  // ε_h = 2 ∫_0^1 ε(μ) μ dμ, μ = cos θ, by 40-panel 20-point Gauss-Legendre (the integrand
  // is smooth in μ for n > 1: error far below the 1e-9 tolerance).
  const std::vector<std::pair<LD, LD>> rule = GaussLegendre(20);
  for (const double e_n : {0.5, 0.8, 0.9, 0.96, 0.99}) {
    const int panels = 40;
    double sum = 0;
    for (int p = 0; p < panels; ++p) {
      for (const auto& [x, w] : rule) {
        const double mu = (p + 0.5 * (static_cast<double>(x) + 1)) / panels;
        sum += static_cast<double>(w) * 0.5 / panels * 2 * mu *
               DirectionalEmissivity(EmissivityLaw::kDielectric, e_n, mu);
      }
    }
    EXPECT_NEAR(sum, DunkleHemisphericalEmissivity(DielectricIndexForNormalEmissivity(e_n)), 1e-9)
        << e_n;
  }
}

TEST(RadiometryTest, MetalLawAboveTheMetalRangeIsDielectric) {
  for (const double c : {1.0, 0.7, 0.3, 0.05, 0.0}) {
    EXPECT_EQ(DirectionalEmissivity(EmissivityLaw::kMetal, 0.1, c),
              MetalDirectionalEmissivity(0.1, c));
    EXPECT_EQ(DirectionalEmissivity(EmissivityLaw::kMetal, 0.9, c),
              DirectionalEmissivity(EmissivityLaw::kDielectric, 0.9, c));
  }
}

TEST(RadiometryTest, EmissivityLawNames) {
  for (const EmissivityLaw law : {EmissivityLaw::kDielectric, EmissivityLaw::kMetal}) {
    EXPECT_EQ(ParseEmissivityLaw(EmissivityLawName(law)), law);
  }
  EXPECT_EQ(EmissivityLawName(EmissivityLaw::kMetal), "metal");
  EXPECT_EQ(EmissivityLawName(EmissivityLaw::kDielectric), "dielectric");
  EXPECT_EQ(ParseEmissivityLaw("Metal"), std::nullopt);
  EXPECT_EQ(ParseEmissivityLaw(""), std::nullopt);
  EXPECT_EQ(ParseEmissivityLaw("metals"), std::nullopt);
}

TEST(RadiometryTest, DirectionalEmissivityOutsideRangeIsABug) {
  EXPECT_DEBUG_DEATH(DirectionalEmissivity(EmissivityLaw::kDielectric, 0.0, 1.0), "emissivity");
  EXPECT_DEBUG_DEATH(DirectionalEmissivity(EmissivityLaw::kMetal, 1.2, 1.0), "emissivity");
}

TEST(RadiometryTest, TableMatchesTheSeries) {
  // Random temperatures over the table's range (and its nodes, where the interpolation is
  // exact up to rounding) against BandRadiance: the bounds radiometry.h states.
  std::mt19937 rng(7);
  for (const Band& b : kBands) {
    const BandRadiance band(b.lo_um, b.hi_um);
    const BandRadianceTable table(band);
    const bool short_wave = b.hi_um < 3;  // n = c2 / (λT) up to ~100: looser, as documented
    const double max_kelvin = short_wave ? 1e-4 : 1e-6;
    double worst_relative = 0, worst_kelvin = 0;
    std::uniform_real_distribution<double> temperature_k(150, 1200);
    for (int k = 0; k < 20000; ++k) {
      const double t = k < 100 ? 150 + 0.5 * k : temperature_k(rng);
      const double exact = band.Radiance(t);
      worst_relative = std::max(worst_relative, std::abs(table.Radiance(t) / exact - 1));
      worst_kelvin = std::max(worst_kelvin, std::abs(table.Temperature(exact) - t));
    }
    SCOPED_TRACE(testing::Message() << b.lo_um << "-" << b.hi_um << " µm");
    if (!short_wave) {
      EXPECT_LT(worst_relative, b.lo_um >= 7 ? 1e-9 : 1e-7);  // LWIR; MWIR (n up to 32)
    }
    EXPECT_LT(worst_kelvin, max_kelvin);
    std::printf("table %.1f-%.1f µm: worst radiance %.1e relative, temperature %.1e K\n", b.lo_um, b.hi_um,
                worst_relative, worst_kelvin);
  }
}

TEST(RadiometryTest, TableFallsBackToTheSeriesOutsideItsRange) {
  const BandRadiance band(7.5, 14);
  const BandRadianceTable table(band, 200, 400, 1);
  for (const double t : {1.0, 100.0, 199.999, 400.0, 401.0, 5000.0, 0.0}) {
    EXPECT_EQ(table.Radiance(t), band.Radiance(t)) << t;
    const double l = band.Radiance(t);
    if (l > 0) {
      EXPECT_EQ(table.Temperature(l), band.Temperature(l)) << t;
    }
  }
  EXPECT_TRUE(std::isnan(table.Radiance(-1)));
  EXPECT_TRUE(std::isnan(table.Radiance(kNaN)));
  EXPECT_EQ(table.Radiance(kInf), kInf);
  EXPECT_TRUE(std::isnan(table.Temperature(0)));
  EXPECT_TRUE(std::isnan(table.Temperature(-1)));
  EXPECT_TRUE(std::isnan(table.Temperature(kNaN)));
  EXPECT_EQ(table.Temperature(kInf), kInf);
  // The last node's range: 400 K is past the last interval, still the series' value; just
  // below it, the cubic's.
  EXPECT_NEAR(table.Temperature(band.Radiance(399.9999)), 399.9999, 1e-6);
}

TEST(RadiometryTest, SurfaceFromApparentThroughTheTableMatchesTheSeries) {
  const BandRadiance band(7.5, 14);
  const BandRadianceTable table(band);
  for (const double emissivity : {0.05, 0.3, 0.7, 0.95, 1.0}) {
    for (const double reflected_c : {-20.0, 20.0, 60.0}) {
      for (const double apparent_c : {-30.0, 0.0, 19.0, 25.0, 80.0, 300.0}) {
        const double exact = SurfaceFromApparent(band, apparent_c, emissivity, reflected_c);
        const double tabled = SurfaceFromApparent(table, apparent_c, emissivity, reflected_c);
        if (std::isnan(exact)) {  // colder than the reflection alone
          EXPECT_TRUE(std::isnan(tabled)) << emissivity << " " << reflected_c << " " << apparent_c;
          continue;
        }
        // The radiance error (< 1e-9 relative) divided by the emissivity: 1e-6 K / ε at most.
        EXPECT_NEAR(tabled, exact, 2e-5) << emissivity << " " << reflected_c << " " << apparent_c;
      }
    }
  }
  EXPECT_TRUE(std::isnan(SurfaceFromApparent(table, kNaN, 0.9, 20)));
}

TEST(RadiometryTest, Timing) {
  // Prints the cost per call; no assertion (machine-dependent).
  const BandRadiance band(7.5, 14);
  const int n = 50000;
  double sink = 0;
  auto time_ns = [&](auto&& f) {
    const auto start = std::chrono::steady_clock::now();
    for (int i = 0; i < n; ++i) sink += f(i);
    return std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start)
               .count() /
           n;
  };
  const double radiance_ns = time_ns([&](int i) { return band.Radiance(233.15 + 0.005 * i); });
  const double l0 = band.Radiance(233.15), l1 = band.Radiance(1273.15);
  const double temperature_ns =
      time_ns([&](int i) { return band.Temperature(l0 + (l1 - l0) * i / n); });
  const double surface_ns =
      time_ns([&](int i) { return SurfaceFromApparent(band, 20 + 0.001 * i, 0.95, 20); });
  const double dielectric_ns = time_ns([&](int i) {
    return DirectionalEmissivity(EmissivityLaw::kDielectric, 0.95, 1.0 - i / double(n));
  });
  const double metal_ns = time_ns([&](int i) {
    return DirectionalEmissivity(EmissivityLaw::kMetal, 0.1, 1.0 - i / double(n));
  });
  const BandRadianceTable table(band);
  const double table_radiance_ns = time_ns([&](int i) { return table.Radiance(233.15 + 0.005 * i); });
  const double table_temperature_ns = time_ns([&](int i) { return table.Temperature(l0 + (l1 - l0) * i / n); });
  const double table_surface_ns =
      time_ns([&](int i) { return SurfaceFromApparent(table, 20 + 0.001 * i, 0.95, 20); });
  std::printf("per call: Radiance %.0f ns, Temperature %.0f ns, SurfaceFromApparent %.0f ns, "
              "DirectionalEmissivity dielectric %.0f ns, metal %.0f ns; through the table: Radiance %.0f ns, "
              "Temperature %.0f ns, SurfaceFromApparent %.0f ns (checksum %g)\n",
              radiance_ns, temperature_ns, surface_ns, dielectric_ns, metal_ns, table_radiance_ns,
              table_temperature_ns, table_surface_ns, sink);
  EXPECT_TRUE(std::isfinite(sink));
}

}  // namespace
}  // namespace hw::core
