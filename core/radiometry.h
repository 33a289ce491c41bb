#pragma once

#include <string>
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

}  // namespace hw::core
