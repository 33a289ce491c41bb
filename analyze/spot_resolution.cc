#include "analyze/spot_resolution.h"

#include <cmath>
#include <limits>

namespace hw::analyze {

void ApplyResolution(double footprint_m, double perimeter_m, const SpotOptions& options, Spot* spot) {
  if (!(footprint_m > 0) || !std::isfinite(footprint_m)) {
    spot->footprint_m = spot->blur_sigma_m = spot->width_px = std::numeric_limits<double>::quiet_NaN();
    spot->resolved = true;
    return;
  }
  spot->footprint_m = footprint_m;
  // The pixel's box (uniform over one pixel: σ 1/√12) convolved with the optics' Gaussian.
  spot->blur_sigma_m = footprint_m * std::sqrt(1.0 / 12.0 + options.optics_psf_px * options.optics_psf_px);
  spot->width_px = spot->width_m / footprint_m;
  spot->resolved = !(spot->width_px < options.min_resolved_px);
  const double widening_sigma_m = 0.5 * kMaxBlurWideningSigmas * spot->blur_sigma_m;  // both sides
  spot->width_sigma_m = std::hypot(spot->width_sigma_m, widening_sigma_m);
  spot->length_sigma_m = std::hypot(spot->length_sigma_m, widening_sigma_m);
  spot->area_sigma_m2 = std::hypot(spot->area_sigma_m2, perimeter_m * 0.5 * widening_sigma_m);
}

}  // namespace hw::analyze
