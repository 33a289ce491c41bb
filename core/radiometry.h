#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

// Thermal radiometry: Planck band radiance of a thermal camera's spectral band and the
// emissivity / reflected-temperature model that turns the apparent temperature a camera
// reports (emissivity 1) into surface temperature, and back.
//
// Model (no atmosphere at handheld ranges), all radiances integrated over the band:
//   L(T_apparent) = emissivity * L(T_surface) + (1 - emissivity) * L(T_reflected)
// Temperatures cross the API in degrees Celsius where the name ends in _c, kelvin in _k.

namespace hw::core {

// CODATA 2018 exact SI constants.
inline constexpr double kPlanckJs = 6.62607015e-34;      // h, J·s
inline constexpr double kSpeedOfLightMps = 299792458.0;  // c, m/s
inline constexpr double kBoltzmannJpk = 1.380649e-23;    // k, J/K
// First and second radiation constants for radiance: c1 = 2 h c^2 (W·m^2/sr),
// c2 = h c / k (m·K).
inline constexpr double kRadianceC1 = 2.0 * kPlanckJs * kSpeedOfLightMps * kSpeedOfLightMps;
inline constexpr double kRadianceC2 = kPlanckJs * kSpeedOfLightMps / kBoltzmannJpk;

inline constexpr double kKelvinOffset = 273.15;  // T_k = T_c + kKelvinOffset
constexpr double CelsiusToKelvin(double temperature_c) { return temperature_c + kKelvinOffset; }
constexpr double KelvinToCelsius(double temperature_k) { return temperature_k - kKelvinOffset; }

// Planck spectral radiance at one wavelength (µm) and temperature (K), in W/(m^2·sr·µm).
// 0 at 0 K; NaN for negative or NaN temperature.
double SpectralRadiance(double wavelength_um, double temperature_k);

// "" if [lambda_lo_um, lambda_hi_um] is a usable spectral band (finite, 0 < lo < hi),
// else a message naming the bad value, for parsers to wrap in InputError.
std::string CheckSpectralBand(double lambda_lo_um, double lambda_hi_um);

// Planck radiance integrated over a spectral band, its temperature derivative and its
// inverse. Exact to ~1e-15 relative (closed-form series, no quadrature; a band of
// relative width w loses a factor ~1/w to cancellation). Immutable after construction,
// so one instance can be shared by threads. Cost per call (one core, -O2):
// see radiometry_test.cc timing output (~70 ns Radiance, ~90 ns Temperature, ~240 ns
// SurfaceFromApparent).
class BandRadiance {
 public:
  // Band edges in µm; asserts CheckSpectralBand(...) == "" (validate inputs first).
  BandRadiance(double lambda_lo_um, double lambda_hi_um);

  double lambda_lo_um() const { return lambda_lo_um_; }
  double lambda_hi_um() const { return lambda_hi_um_; }

  // Band radiance in W/(m^2·sr) of a black body at temperature_k (K). 0 at 0 K,
  // +inf at +inf, NaN for negative or NaN temperature. Overflows to +inf above ~1e75 K.
  double Radiance(double temperature_k) const;
  // dL/dT in W/(m^2·sr·K). NaN for negative or NaN temperature, 0 at 0 K.
  double Derivative(double temperature_k) const;
  // Both at once (shares the work), for Newton iterations and uncertainty propagation.
  void RadianceAndDerivative(double temperature_k, double* radiance,
                             double* derivative) const;
  // Inverse of Radiance: the black-body temperature (K) with this band radiance
  // (W/(m^2·sr)). NaN for radiance <= 0 or NaN; +inf for +inf. Newton on ln L versus
  // 1/T (nearly linear) from a tabulated start good to ~6e-10, so one step; exact to
  // ~1e-15 relative. Also NaN outside the range that doubles can represent: radiances
  // below that of ~1.5 K (~1e-300 in 7.5-14 µm) or above that of ~1e60 K.
  double Temperature(double radiance) const;

 private:
  // ln L at node temperatures (geometric in T), for Temperature()'s starting point.
  struct Node {
    double log_radiance;         // ln(W/(m^2·sr))
    double inverse_temperature;  // 1/K
    double slope;                // d(1/T) / d(ln L), 1/K
  };
  double StartInverseTemperature(double log_radiance) const;

  double lambda_lo_um_;
  double lambda_hi_um_;
  std::vector<Node> nodes_;  // increasing log_radiance
};

// BandRadiance's Radiance and Temperature from a table, for per-pixel work (thermal fusion
// converts every ray three times): cubic Hermite interpolation of the band radiance between
// nodes every step_k kelvin over [min_k, max_k] (values and slopes from BandRadiance),
// inverted by Newton's method on the same cubic; radiometry_test prints the cost of each
// against the series. Error: the Hermite remainder, h^4 max|d4L/dT4| / 384, about
// (n h / T)^4 / 384 relative with n = c2 / (lambda T) the radiance's local power of T: at
// the default 0.5 K steps from 150 K, below 1e-9 relative in 7.5-14 µm (2e-9 K), 1e-7 in
// 3-5 µm (2e-7 K), checked against BandRadiance by radiometry_test; short-wave bands at low
// temperatures (n > 30) lose more (0.9-1.7 µm at 150 K: 3e-6 relative, 1e-5 K). Outside [min_k, max_k],
// and for NaN, negative, zero or infinite inputs, it returns what BandRadiance returns.
// Immutable: threads may share one.
class BandRadianceTable {
 public:
  // Asserts 0 < min_k < max_k and 0 < step_k <= max_k - min_k.
  explicit BandRadianceTable(const BandRadiance& band, double min_k = 150, double max_k = 1200,
                             double step_k = 0.5);

  const BandRadiance& band() const { return band_; }
  double Radiance(double temperature_k) const;  // W/(m^2·sr)
  double Temperature(double radiance) const;    // K

 private:
  BandRadiance band_;
  double min_k_, step_k_, inverse_step_k_;
  std::vector<double> radiance_;  // L at node i, T = min_k + i · step_k (increasing)
  std::vector<double> slope_;     // step_k · dL/dT there
};

// Apparent temperature (°C) a camera with this band reports for a surface at surface_c
// (°C) of the given emissivity, in (0, 1] (asserted), reflecting a surrounding at
// reflected_c (°C, the reflected apparent temperature). NaN if any input is NaN or below
// absolute zero.
double ApparentFromSurface(const BandRadiance& band, double surface_c, double emissivity,
                           double reflected_c);

// Inverse of ApparentFromSurface: surface temperature (°C) from the apparent temperature
// (°C). Returns NaN when the implied surface radiance (L(apparent) - (1 - e) L(reflected)) / e
// is <= 0: the reading is colder than the reflection alone can explain (happens with a low
// emissivity and a hot reflection), so no surface temperature fits; also NaN for NaN inputs.
double SurfaceFromApparent(const BandRadiance& band, double apparent_c, double emissivity,
                           double reflected_c);

// SurfaceFromApparent through the table (the same formula, the table's conversions).
double SurfaceFromApparent(const BandRadianceTable& table, double apparent_c, double emissivity,
                           double reflected_c);

// Surface temperature and its partial derivatives, for propagating uncertainties, e.g.
// sigma_surface = |d_apparent| * NETD for the camera noise, |d_emissivity| * sigma_e for the
// emissivity. All fields NaN where SurfaceFromApparent is NaN.
struct SurfaceTemperature {
  double surface_c = 0;
  double d_apparent = 0;    // dT_surface / dT_apparent, K/K (>= 1 for emissivity < 1)
  double d_reflected = 0;   // dT_surface / dT_reflected, K/K (<= 0)
  double d_emissivity = 0;  // dT_surface / d emissivity, K per unit emissivity
};
SurfaceTemperature SurfaceFromApparentWithDerivatives(const BandRadiance& band,
                                                      double apparent_c, double emissivity,
                                                      double reflected_c);

// dT_surface / dT_apparent alone (K/K): turns a NETD into a surface-temperature sigma.
// NaN where SurfaceFromApparent is NaN.
double SurfacePerApparent(const BandRadiance& band, double apparent_c, double emissivity,
                          double reflected_c);

// ---------------------------------------------------------------------------------------
// Directional emissivity: how a surface's emissivity varies with the angle θ between the
// viewing ray and the surface normal (Kirchhoff: ε(θ) = 1 - R(θ) for an opaque surface).
// The shared physics of the synthetic scenes (fixtures/) and of the correction of thermal
// observations (reconstruct/).

// How emissivity varies with the viewing angle. Explicit per surface rather than a threshold
// on ε_n: a dull oxidised metal and a thin dark film can share ε_n yet behave oppositely.
enum class EmissivityLaw {
  kDielectric,  // paint, plastic, tape, glass, masonry: flat, then falls to 0 at grazing
  kMetal,       // bare metal: rises towards grazing (peak near 80–88°), 0 at 90°
};
// "dielectric" | "metal" (the spelling of the emissivity file).
std::string EmissivityLawName(EmissivityLaw law);
// Inverse of EmissivityLawName (exact, lower case); nullopt for anything else.
std::optional<EmissivityLaw> ParseEmissivityLaw(std::string_view name);

// Complex refractive index n + ik of an absorbing medium (seen from air, index 1).
struct ComplexIndex {
  double n = 1;
  double k = 0;
};

// Unpolarised Fresnel reflectance (mean of s and p) of a smooth interface from air into a
// medium of index n + ik at incidence cos θ (|cos θ| clamped to [0, 1]), in the real closed
// form of Born & Wolf §14.2 (no complex arithmetic): ((n-1)² + k²)/((n+1)² + k²) at normal
// incidence, 1 at grazing incidence (undefined, NaN, for the index-matched n = 1, k = 0 there).
double FresnelReflectance(const ComplexIndex& index, double cos_theta);

// Metals in 8–14 µm have k/n ≈ 3–5 (Drude regime above the collision rate; Ordal et al.,
// Appl. Opt. 22, 1983). A real surface's ε_n (oxide, roughness) is higher than the polished
// metal's, so we keep the ratio and scale |n + ik| to reproduce the stated ε_n: the
// documented assumption that turns one number into optical constants. The low end, 3,
// lets ε_n reach MaxMetalNormalEmissivity(), enough for dull galvanised steel (0.28) and a
// bare steel boss (0.3).
inline constexpr double kMetalExtinctionRatio = 3.0;  // k / n
// Highest ε_n = 4n/((n+1)² + k²) over n at k = 3n: 2/(1 + √(1 + 3²)) ≈ 0.4805.
double MaxMetalNormalEmissivity();
// The n + ik with k = kMetalExtinctionRatio·n whose normal emissivity 1 - R(0) is
// normal_emissivity (the larger, metallic root of the quadratic). Asserts
// 0 < normal_emissivity <= MaxMetalNormalEmissivity().
ComplexIndex MetalIndexForNormalEmissivity(double normal_emissivity);
// Directional emissivity of a bare metal: 1 - FresnelReflectance(MetalIndexForNormal-
// Emissivity(ε_n), cos θ). Equals ε_n at normal incidence, rises towards grazing (the
// p-polarised pseudo-Brewster peak, around 85° and over 2·ε_n for ε_n = 0.1) and drops to 0
// at 90°. The peak is a polished metal's: it shrinks as ε_n grows (+4 % near 60° at
// ε_n = 0.3), and from ε_n ≈ 0.33 (n < 1) the curve falls from the normal on.
double MetalDirectionalEmissivity(double normal_emissivity, double cos_theta);

// The real index n of a smooth non-absorbing dielectric with normal emissivity ε_n:
// ε_n = 1 - ((n-1)/(n+1))², so n = (1 + √(1-ε_n))/(1 - √(1-ε_n)) (1.58 for ε_n = 0.95).
// Asserts 0 < normal_emissivity <= 1 (n = 1 at ε_n = 1).
double DielectricIndexForNormalEmissivity(double normal_emissivity);

// Directional emissivity a correction assumes (physics, not fixtures' "truth" law):
//  kDielectric: 1 - FresnelReflectance({DielectricIndexForNormalEmissivity(ε_n), 0}, cos θ):
//    within 0.01 of ε_n up to 40°, 0 at 90°; falls monotonically for ε_n >= 0.8 (n <= 2.6,
//    paint, plastic, glass, masonry); for lower ε_n the p-polarised Brewster peak lifts it
//    above ε_n before it falls (+2 % at 70° for ε_n = 0.6, +70 % at 85° for ε_n = 0.3).
//    ε_n = 1 (a black body, n = 1) is 1 at every angle.
//  kMetal: MetalDirectionalEmissivity (k = kMetalExtinctionRatio·n). A "metal" with
//    ε_n > MaxMetalNormalEmissivity() has no optical constants of that ratio: such a
//    surface is oxidised or coated, which emits like a dielectric, so it gets kDielectric.
// cos_theta: |cos θ| clamped to [0, 1]. normal_emissivity in (0, 1] (asserted).
// ~30 ns per call (see radiometry_test.cc timing output): cheap enough per thermal ray.
double DirectionalEmissivity(EmissivityLaw law, double normal_emissivity, double cos_theta);

}  // namespace hw::core
