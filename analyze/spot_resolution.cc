#include "analyze/spot_resolution.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hw::analyze {

double PeakDropBound(double width_m, double blur_sigma_m, bool line) {
  if (!(width_m > 0) || !(blur_sigma_m > 0) || !std::isfinite(width_m) || !std::isfinite(blur_sigma_m)) return 0;
  const double true_width_m = std::max(width_m - kMaxBlurWideningSigmas * blur_sigma_m, blur_sigma_m);
  const double s = blur_sigma_m / (true_width_m / (2 * std::log(2.0)));
  const double tail = std::exp(0.5 * s * s) * std::erfc(s / std::sqrt(2.0));
  const double peak = line ? tail : 1 - s * std::sqrt(0.5 * 3.14159265358979323846) * tail;
  return std::clamp(1 - peak, 0.0, 0.99);
}

void ApplyResolution(double footprint_m, double perimeter_m, const SpotOptions& options, Spot* spot) {
  if (!(footprint_m > 0) || !std::isfinite(footprint_m)) {
    spot->delta_blur_bound_k = std::numeric_limits<double>::quiet_NaN();
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
  // The measured |ΔT| is (1 − drop) of the true one at most drop below it.
  const double drop = PeakDropBound(spot->width_m, spot->blur_sigma_m, spot->length_m >= 2 * spot->width_m);
  spot->delta_blur_bound_k = std::abs(spot->delta_k) * drop / (1 - drop);
  spot->delta_sigma_k = std::hypot(spot->delta_sigma_k, 0.5 * spot->delta_blur_bound_k);
}

}  // namespace hw::analyze
