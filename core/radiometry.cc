#include "core/radiometry.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>

namespace hw::core {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = std::numbers::pi;
constexpr double kMetresPerMicrometre = 1e-6;

// The band integral in the dimensionless variable x = c2 / (lambda T):
//   L = c1 (T / c2)^4 * integral_{c2/(lambda_hi T)}^{c2/(lambda_lo T)} x^3 / (e^x - 1) dx.
// Two exact series cover it: for small x the Bernoulli expansion of the integral from 0,
// for large x the exponential series of the integral to infinity. Both reach full double
// precision in <= 20 terms when they switch at x = 2.
constexpr double kSeriesSwitchX = 2.0;
// integral_0^inf x^3 / (e^x - 1) dx = pi^4 / 15.
constexpr double kFullIntegral = kPi * kPi * kPi * kPi / 15.0;

// Coefficients c_j of P(x) = x^3 (1/3 - x/8 + sum_j c_j x^(2j)), the integral from 0 to
// x, from x^3 / (e^x - 1) = sum_k B_k x^(k+2) / k!:
//   c_j = B_2j / ((2j)! (2j + 3)),  B_2j / (2j)! = (-1)^(j+1) 2 zeta(2j) / (2 pi)^(2j).
// The terms shrink like (x / 2 pi)^(2j): at x = 2, 18 terms leave < 1e-18.
constexpr int kBernoulliTerms = 18;

double Zeta(int s) {
  // Direct sum (smallest terms first) plus an Euler-Maclaurin tail: error < 1e-20.
  const int n_max = 1000;
  const double n = n_max;
  double sum = std::pow(n, -s + 1) / (s - 1) - 0.5 * std::pow(n, -s) +
               s * std::pow(n, -s - 1) / 12.0;
  for (int k = n_max; k >= 1; --k) sum += std::pow(static_cast<double>(k), -s);
  return sum;
}

const std::array<double, kBernoulliTerms>& BernoulliCoefficients() {
  static const std::array<double, kBernoulliTerms> coefficients = [] {
    std::array<double, kBernoulliTerms> c{};
    for (int j = 1; j <= kBernoulliTerms; ++j) {
      const double zeta = (j == 1) ? kPi * kPi / 6.0 : Zeta(2 * j);
      const double sign = (j % 2 == 1) ? 1.0 : -1.0;
      c[j - 1] = sign * 2.0 * zeta / std::pow(2.0 * kPi, 2 * j) / (2.0 * j + 3.0);
    }
    return c;
  }();
  return coefficients;
}

// integral_0^x t^3 / (e^t - 1) dt, for 0 <= x <= kSeriesSwitchX.
double IntegralFromZero(double x) {
  const auto& c = BernoulliCoefficients();
  const double x2 = x * x;
  double s = c[kBernoulliTerms - 1];
  for (int j = kBernoulliTerms - 2; j >= 0; --j) s = s * x2 + c[j];
  return x * x2 * (1.0 / 3.0 - x / 8.0 + x2 * s);
}

// integral_x^inf t^3 / (e^t - 1) dt = sum_n e^(-n x) (x^3/n + 3x^2/n^2 + 6x/n^3 + 6/n^4),
// for x >= kSeriesSwitchX.
double IntegralToInfinity(double x) {
  const double e = std::exp(-x);
  if (e == 0) return 0;
  const double x2 = x * x;
  const double x3 = x2 * x;
  double sum = 0;
  double en = e;  // e^(-n x)
  for (int n = 1; n < 64; ++n) {
    const double inv = 1.0 / n;
    sum += en * inv * (x3 + inv * (3.0 * x2 + inv * (6.0 * x + inv * 6.0)));
    en *= e;
    if (en < 1e-18 * e) break;
  }
  return sum;
}

// integral_a^b t^3 / (e^t - 1) dt for 0 <= a <= b, avoiding the subtraction of two
// nearly equal full-range integrals.
double BandIntegral(double a, double b) {
  if (b <= kSeriesSwitchX) return IntegralFromZero(b) - IntegralFromZero(a);
  if (a >= kSeriesSwitchX) return IntegralToInfinity(a) - IntegralToInfinity(b);
  return (kFullIntegral - IntegralFromZero(a)) - IntegralToInfinity(b);
}

// x^4 / (e^x - 1), 0 for x = inf; x^3 -> 0 at x = 0.
double X4OverExpm1(double x) {
  if (x == 0) return 0;
  const double d = std::expm1(x);
  if (std::isinf(d)) return 0;
  const double x2 = x * x;
  return x2 * x2 / d;
}

// Temperature() starting table: nodes geometric in T over this range (K). Outside it
// Newton still converges, in a few more steps.
constexpr double kTableMinK = 20.0;
constexpr double kTableMaxK = 6000.0;
constexpr int kTableNodes = 256;  // start within ~6e-10 relative: one Newton step
// Newton in u = 1/T stops after a step smaller than this fraction of u: ln L is nearly
// linear in u (exactly so in the Wien limit; -ln u + const in the Rayleigh-Jeans limit,
// where the next error is 0.5 (step/u)^2 u), so the error left is below 1e-17 u.
constexpr double kNewtonStepTolerance = 3e-9;
constexpr int kNewtonMaxSteps = 100;

}  // namespace

double SpectralRadiance(double wavelength_um, double temperature_k) {
  if (!(temperature_k >= 0)) return kNaN;
  if (temperature_k == 0) return 0;
  const double lambda_m = wavelength_um * kMetresPerMicrometre;
  const double x = kRadianceC2 / (lambda_m * temperature_k);
  const double l5 = std::pow(lambda_m, 5);
  // W/(m^2 sr m) -> W/(m^2 sr um)
  return kRadianceC1 / (l5 * std::expm1(x)) * kMetresPerMicrometre;
}

std::string CheckSpectralBand(double lambda_lo_um, double lambda_hi_um) {
  std::ostringstream message;
  if (!std::isfinite(lambda_lo_um) || !(lambda_lo_um > 0)) {
    message << "lower band edge must be a finite number > 0 µm, got " << lambda_lo_um;
  } else if (!std::isfinite(lambda_hi_um) || !(lambda_hi_um > lambda_lo_um)) {
    message << "upper band edge must be finite and > the lower edge " << lambda_lo_um
            << " µm, got " << lambda_hi_um;
  }
  return message.str();
}

BandRadiance::BandRadiance(double lambda_lo_um, double lambda_hi_um)
    : lambda_lo_um_(lambda_lo_um), lambda_hi_um_(lambda_hi_um) {
  assert(CheckSpectralBand(lambda_lo_um, lambda_hi_um).empty());
  // Start the table where the radiance is comfortably representable (x_lo <= 600).
  const double min_k = std::max(
      kTableMinK, kRadianceC2 / (lambda_hi_um_ * kMetresPerMicrometre * 600.0));
  const double max_k = std::max(kTableMaxK, 4.0 * min_k);
  const double ratio = std::pow(max_k / min_k, 1.0 / (kTableNodes - 1));
  nodes_.reserve(kTableNodes);
  double t = min_k;
  for (int i = 0; i < kTableNodes; ++i, t *= ratio) {
    double radiance, derivative;
    RadianceAndDerivative(t, &radiance, &derivative);
    assert(radiance > 0 && derivative > 0);
    // d(ln L)/du = -T^2 L'/L with u = 1/T.
    nodes_.push_back(Node{std::log(radiance), 1.0 / t, -radiance / (t * t * derivative)});
  }
}

void BandRadiance::RadianceAndDerivative(double temperature_k, double* radiance,
                                         double* derivative) const {
  if (!(temperature_k >= 0)) {
    *radiance = *derivative = kNaN;
    return;
  }
  if (temperature_k == 0) {
    *radiance = *derivative = 0;
    return;
  }
  if (std::isinf(temperature_k)) {
    *radiance = *derivative = kInf;
    return;
  }
  const double a = kRadianceC2 / (lambda_hi_um_ * kMetresPerMicrometre * temperature_k);
  const double b = kRadianceC2 / (lambda_lo_um_ * kMetresPerMicrometre * temperature_k);
  const double s = temperature_k / kRadianceC2;
  const double scale = kRadianceC1 * (s * s) * (s * s);  // c1 (T / c2)^4
  *radiance = scale * BandIntegral(a, b);
  // d/dT of scale * integral_a(T)^b(T): 4 L / T plus the moving limits, da/dT = -a/T.
  *derivative =
      (4.0 * *radiance + scale * (X4OverExpm1(a) - X4OverExpm1(b))) / temperature_k;
}

double BandRadiance::Radiance(double temperature_k) const {
  double radiance, derivative;
  RadianceAndDerivative(temperature_k, &radiance, &derivative);
  return radiance;
}

double BandRadiance::Derivative(double temperature_k) const {
  double radiance, derivative;
  RadianceAndDerivative(temperature_k, &radiance, &derivative);
  return derivative;
}

double BandRadiance::StartInverseTemperature(double log_radiance) const {
  const Node& first = nodes_.front();
  const Node& last = nodes_.back();
  // Colder than the table: Wien regime, ln L linear in 1/T.
  if (log_radiance <= first.log_radiance) {
    return first.inverse_temperature + first.slope * (log_radiance - first.log_radiance);
  }
  // Hotter: towards Rayleigh-Jeans, L proportional to T.
  if (log_radiance >= last.log_radiance) {
    return last.inverse_temperature * std::exp(-(log_radiance - last.log_radiance));
  }
  // Cubic Hermite interpolation of u(ln L) between the bracketing nodes.
  const auto upper = std::upper_bound(
      nodes_.begin(), nodes_.end(), log_radiance,
      [](double y, const Node& node) { return y < node.log_radiance; });
  const Node& n1 = *upper;
  const Node& n0 = *(upper - 1);
  const double h = n1.log_radiance - n0.log_radiance;
  const double t = (log_radiance - n0.log_radiance) / h;
  const double t2 = t * t;
  const double t3 = t2 * t;
  return (2 * t3 - 3 * t2 + 1) * n0.inverse_temperature + (t3 - 2 * t2 + t) * h * n0.slope +
         (-2 * t3 + 3 * t2) * n1.inverse_temperature + (t3 - t2) * h * n1.slope;
}

double BandRadiance::Temperature(double radiance) const {
  if (!(radiance > 0)) return kNaN;
  if (std::isinf(radiance)) return kInf;
  const double target = std::log(radiance);
  double u = StartInverseTemperature(target);
  if (!(u > 0)) u = nodes_.back().inverse_temperature;
  for (int step = 0; step < kNewtonMaxSteps; ++step) {
    const double t = 1.0 / u;
    double l, dl_dt;
    RadianceAndDerivative(t, &l, &dl_dt);
    if (!(l > 0) || !std::isfinite(l)) {
      // Underflow (far too cold a guess) or overflow: move towards the other side.
      u = (l > 0) ? 2.0 * u : 0.5 * u;
      continue;
    }
    const double g = std::log(l) - target;
    const double dg_du = -t * t * dl_dt / l;
    const double du = -g / dg_du;
    // Newton's step, kept within a factor 4 so a poor start cannot leave u > 0.
    const double u_next = std::clamp(u + du, 0.25 * u, 4.0 * u);
    if (std::abs(du) <= kNewtonStepTolerance * u) return 1.0 / u_next;
    u = u_next;
  }
  return kNaN;  // not reached for radiances of temperatures in ~[1 K, 1e30 K]
}

BandRadianceTable::BandRadianceTable(const BandRadiance& band, double min_k, double max_k, double step_k)
    : band_(band), min_k_(min_k), step_k_(step_k), inverse_step_k_(1.0 / step_k) {
  assert(min_k > 0 && max_k > min_k && step_k > 0 && step_k <= max_k - min_k);
  const int nodes = static_cast<int>(std::ceil((max_k - min_k) / step_k)) + 1;
  radiance_.resize(nodes);
  slope_.resize(nodes);
  for (int i = 0; i < nodes; ++i) {
    double derivative;
    band_.RadianceAndDerivative(min_k + i * step_k, &radiance_[i], &derivative);
    slope_[i] = step_k * derivative;
  }
}

double BandRadianceTable::Radiance(double temperature_k) const {
  const double x = (temperature_k - min_k_) * inverse_step_k_;
  // NaN fails the test too.
  if (!(x >= 0 && x < static_cast<double>(radiance_.size() - 1))) return band_.Radiance(temperature_k);
  const size_t i = static_cast<size_t>(x);
  const double s = x - static_cast<double>(i), r = 1 - s;
  // Hermite basis: (1 + 2s)(1 - s)^2, s(1 - s)^2, s^2(3 - 2s), s^2(s - 1).
  return (1 + 2 * s) * r * r * radiance_[i] + s * r * r * slope_[i] + s * s * (3 - 2 * s) * radiance_[i + 1] -
         s * s * r * slope_[i + 1];
}

double BandRadianceTable::Temperature(double radiance) const {
  if (!(radiance >= radiance_.front() && radiance < radiance_.back())) return band_.Temperature(radiance);
  const size_t i = static_cast<size_t>(std::upper_bound(radiance_.begin(), radiance_.end(), radiance) -
                                       radiance_.begin()) - 1;
  const double l0 = radiance_[i], l1 = radiance_[i + 1], m0 = slope_[i], m1 = slope_[i + 1];
  // The cubic is within ~1e-5 of its chord over one node interval: from the chord's root
  // Newton's method converges in two steps; four bound it.
  double s = (radiance - l0) / (l1 - l0);
  for (int step = 0; step < 4; ++step) {
    const double r = 1 - s;
    const double value = (1 + 2 * s) * r * r * l0 + s * r * r * m0 + s * s * (3 - 2 * s) * l1 - s * s * r * m1;
    const double derivative = 6 * s * r * (l1 - l0) + r * (1 - 3 * s) * m0 + s * (3 * s - 2) * m1;
    const double ds = (radiance - value) / derivative;
    s = std::clamp(s + ds, 0.0, 1.0);
    if (std::abs(ds) <= 1e-14) break;
  }
  return min_k_ + (static_cast<double>(i) + s) * step_k_;
}

namespace {

// SurfaceFromApparent through either conversion (BandRadiance or its table).
template <class Conversion>
double SurfaceFromApparentWith(const Conversion& band, double apparent_c, double emissivity, double reflected_c) {
  assert(emissivity > 0 && emissivity <= 1);
  if (emissivity == 1) return apparent_c + 0 * reflected_c;
  const double radiance = (band.Radiance(CelsiusToKelvin(apparent_c)) -
                           (1 - emissivity) * band.Radiance(CelsiusToKelvin(reflected_c))) /
                          emissivity;
  return KelvinToCelsius(band.Temperature(radiance));  // NaN for radiance <= 0
}

}  // namespace

double SurfaceFromApparent(const BandRadianceTable& table, double apparent_c, double emissivity,
                           double reflected_c) {
  return SurfaceFromApparentWith(table, apparent_c, emissivity, reflected_c);
}

double ApparentFromSurface(const BandRadiance& band, double surface_c, double emissivity,
                           double reflected_c) {
  assert(emissivity > 0 && emissivity <= 1);
  if (emissivity == 1) return surface_c + 0 * reflected_c;  // exact identity; NaN propagates
  const double radiance = emissivity * band.Radiance(CelsiusToKelvin(surface_c)) +
                          (1 - emissivity) * band.Radiance(CelsiusToKelvin(reflected_c));
  return KelvinToCelsius(band.Temperature(radiance));
}

double SurfaceFromApparent(const BandRadiance& band, double apparent_c, double emissivity,
                           double reflected_c) {
  return SurfaceFromApparentWith(band, apparent_c, emissivity, reflected_c);
}

SurfaceTemperature SurfaceFromApparentWithDerivatives(const BandRadiance& band,
                                                      double apparent_c, double emissivity,
                                                      double reflected_c) {
  assert(emissivity > 0 && emissivity <= 1);
  double l_apparent, d_apparent, l_reflected, d_reflected;
  band.RadianceAndDerivative(CelsiusToKelvin(apparent_c), &l_apparent, &d_apparent);
  band.RadianceAndDerivative(CelsiusToKelvin(reflected_c), &l_reflected, &d_reflected);
  const double l_surface = (l_apparent - (1 - emissivity) * l_reflected) / emissivity;
  SurfaceTemperature result;
  const double surface_k =
      emissivity == 1 ? CelsiusToKelvin(apparent_c) + 0 * reflected_c
                      : band.Temperature(l_surface);
  if (std::isnan(surface_k)) {
    result.surface_c = result.d_apparent = result.d_reflected = result.d_emissivity = kNaN;
    return result;
  }
  const double d_surface = band.Derivative(surface_k);
  result.surface_c = KelvinToCelsius(surface_k);
  // L_s = (L_a - (1 - e) L_r) / e  =>  dL_s = dL_a / e - (1 - e) / e dL_r - (L_s - L_r) / e de.
  result.d_apparent = d_apparent / (emissivity * d_surface);
  result.d_reflected = -(1 - emissivity) * d_reflected / (emissivity * d_surface);
  result.d_emissivity = -(l_surface - l_reflected) / (emissivity * d_surface);
  return result;
}

double SurfacePerApparent(const BandRadiance& band, double apparent_c, double emissivity,
                          double reflected_c) {
  return SurfaceFromApparentWithDerivatives(band, apparent_c, emissivity, reflected_c)
      .d_apparent;
}

// ---------------------------------------------------------------------------------------
// Directional emissivity

std::string EmissivityLawName(EmissivityLaw law) {
  switch (law) {
    case EmissivityLaw::kDielectric: return "dielectric";
    case EmissivityLaw::kMetal: return "metal";
  }
  assert(false && "unknown EmissivityLaw");
  return "";
}

std::optional<EmissivityLaw> ParseEmissivityLaw(std::string_view name) {
  if (name == "dielectric") return EmissivityLaw::kDielectric;
  if (name == "metal") return EmissivityLaw::kMetal;
  return std::nullopt;
}

double FresnelReflectance(const ComplexIndex& index, double cos_theta) {
  const double c = std::clamp(std::abs(cos_theta), 0.0, 1.0);
  const double sin2 = 1.0 - c * c;
  const double n = index.n, k = index.k;
  // a + ib = sqrt((n + ik)² - sin²θ) (= N·cos θ_t). Take whichever of a², b² has no
  // cancellation from the square-root form and the other from a·b = n·k.
  const double p = n * n - k * k - sin2;
  const double q = std::hypot(p, 2 * n * k);
  double a = 0, b = 0;
  if (p >= 0) {
    a = std::sqrt(0.5 * (q + p));
    b = a > 0 ? n * k / a : 0;
  } else {
    b = std::sqrt(0.5 * (q - p));
    a = n * k / b;
  }
  const double rs = ((a - c) * (a - c) + b * b) / ((a + c) * (a + c) + b * b);
  // Born & Wolf's Rp/Rs = ((a - sinθ tanθ)² + b²)/((a + sinθ tanθ)² + b²), multiplied
  // through by cos²θ so that grazing incidence (cos θ = 0, ratio 1) is not 0/0.
  const double lo = a * c - sin2, hi = a * c + sin2, bc = b * c;
  const double ratio = (lo * lo + bc * bc) / (hi * hi + bc * bc);
  return 0.5 * (rs + rs * ratio);
}

double MaxMetalNormalEmissivity() {
  const double r = kMetalExtinctionRatio;
  return 2.0 / (1.0 + std::sqrt(1.0 + r * r));
}

ComplexIndex MetalIndexForNormalEmissivity(double normal_emissivity) {
  const double e = normal_emissivity, r2 = kMetalExtinctionRatio * kMetalExtinctionRatio;
  assert(e > 0 && e <= MaxMetalNormalEmissivity() * (1 + 1e-12) && "metal emissivity");
  // ε_n = 4n / ((n + 1)² + r²n²)  ⇔  ε(1 + r²)·n² - (4 - 2ε)·n + ε = 0. Both terms of the
  // larger root add (no cancellation); the smaller root is a weakly absorbing dielectric.
  const double A = e * (1 + r2), B = 4 - 2 * e;
  const double disc = std::max(0.0, B * B - 4 * A * e);
  const double n = (B + std::sqrt(disc)) / (2 * A);
  return {n, kMetalExtinctionRatio * n};
}

double MetalDirectionalEmissivity(double normal_emissivity, double cos_theta) {
  return 1.0 - FresnelReflectance(MetalIndexForNormalEmissivity(normal_emissivity), cos_theta);
}

double DielectricIndexForNormalEmissivity(double normal_emissivity) {
  assert(normal_emissivity > 0 && normal_emissivity <= 1 && "dielectric emissivity");
  const double r = std::sqrt(1.0 - normal_emissivity);  // |(n - 1)/(n + 1)|
  return (1.0 + r) / (1.0 - r);
}

double DirectionalEmissivity(EmissivityLaw law, double normal_emissivity, double cos_theta) {
  assert(normal_emissivity > 0 && normal_emissivity <= 1 && "emissivity");
  if (law == EmissivityLaw::kMetal && normal_emissivity <= MaxMetalNormalEmissivity()) {
    return MetalDirectionalEmissivity(normal_emissivity, cos_theta);
  }
  // n = 1 reflects nothing at any angle but is 0/0 in the closed form at grazing incidence.
  if (normal_emissivity == 1) return 1.0;
  return 1.0 - FresnelReflectance({DielectricIndexForNormalEmissivity(normal_emissivity), 0.0},
                                  cos_theta);
}

}  // namespace hw::core
