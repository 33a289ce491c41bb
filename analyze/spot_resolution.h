#pragma once

// The thermal image's resolution over a spot, and what its blur does to the spot's extent.

#include "analyze/spot.h"
#include "analyze/spot_detect.h"

namespace hw::analyze {

// Largest widening of a spot's half-ΔT width by a Gaussian blur of std σ_b, in units of σ_b
// (both sides together), for blurs up to a quarter of the width: a profile with a kink at
// its peak widens linearly in σ_b — the exponential profile of heat spreading from a buried
// line or point by 1.7-1.8 σ_b — a smooth peak (Gaussian, Lorentzian) by less, quadratically,
// and a straight step's half-ΔT line does not move at all.
inline constexpr double kMaxBlurWideningSigmas = 1.8;

// Fills spot->footprint_m, blur_sigma_m, width_px and resolved from footprint_m (the
// area-weighted mean size of a thermal pixel on the surface over the spot's region, metres;
// NaN or <= 0 when unknown: then the fields are NaN, resolved is true and nothing else
// changes), spot->width_m and the options (optics_psf_px, min_resolved_px). The blur only
// ever widens, by 0 (step) to kMaxBlurWideningSigmas·σ_b (peaked profile) in all; half of
// that bound is added as one sigma, in quadrature, to width_sigma_m and length_sigma_m, and
// perimeter_m times half of the per-side bound to area_sigma_m2 (the whole boundary moves
// out together), so that two sigmas span it.
// Also the blur's bound on ΔT (spot->delta_blur_bound_k, half of it added to
// delta_sigma_k as one sigma): see PeakDropBound.
void ApplyResolution(double footprint_m, double perimeter_m, const SpotOptions& options, Spot* spot);

// Largest fraction by which a Gaussian blur of std blur_sigma_m lowers the peak of a spot
// whose blurred half-ΔT width is width_m (m), in [0, 1): the profile taken as the most
// peaked one, exponential e^(−d/λ) (heat spreading from a buried line or point), its true
// width the measured one less the largest widening (kMaxBlurWideningSigmas·σ_b) but not below
// σ_b (a narrower profile is not resolved at all), λ = true width / (2 ln 2). A line source
// (`line`: a spot at least twice as long as wide) is blurred across only: peak factor
// e^(s²/2)·erfc(s/√2), s = σ_b/λ; a point source in both directions: 1 − s·√(π/2)·e^(s²/2)·
// erfc(s/√2). Returns 0 for a non-positive or non-finite input.
double PeakDropBound(double width_m, double blur_sigma_m, bool line);

}  // namespace hw::analyze
