#pragma once

// How a surface region's temperature is updated from its thermal observations (value V_R,
// per-ray confidence C_R, reconstruct/thermal_confidence.h): the HeatWave paper's online
// rule, voxblox's capped running mean, and a robust offline estimate over all views.
// Pure functions of one region's state: the fusion applies them per voxel.

#include <limits>
#include <array>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace hw::reconstruct {

enum class ThermalMethod {
  kLatest,      // the last observation wins
  kMean,        // the plain running mean of all observations
  kCappedMean,  // voxblox's intensity integrator (CappedMeanUpdate)
  kOnline,      // the HeatWave paper's rule (OnlineUpdate)
  kOffline,     // the robust estimate over all views (RobustEstimate)
};
// Every method, in the order above (reports and comparisons list them so).
inline constexpr std::array<ThermalMethod, 5> kThermalMethods = {
    ThermalMethod::kLatest, ThermalMethod::kMean, ThermalMethod::kCappedMean, ThermalMethod::kOnline,
    ThermalMethod::kOffline};
// "latest", "mean", "capped-mean", "online", "offline".
std::string ThermalMethodName(ThermalMethod m);
// The method of one of those names; nullopt for any other.
std::optional<ThermalMethod> ParseThermalMethod(std::string_view name);

// The paper's online rule for one region and one observation (V_R, C_R): Q = clamp(C_R − C_A
// + b, 0, 1); C_A := Q·C_R + (1−Q)·C_A; V_A := Q·V_R + (1−Q)·V_A. A region not yet observed
// (C_A < 0 marks it; V_A unused) takes its first observation whole: V_A = V_R, C_A = C_R.
// Returns Q (1 for a first observation). Asserts b in [0, 1], C_R in [0, 1].
// A better view than the region's (C_R > C_A − b) replaces more of it; the recency bias b
// lets equally good later views in (b = 0: a view no better than the state is ignored).
double OnlineUpdate(double recency_bias, double value_r, double confidence_r, double& value_a,
                    double& confidence_a);

// voxblox's intensity integrator (voxblox/src/integrator/intensity_integrator.cc,
// IntensityIntegrator::addIntensityBearingVectors): V_A := (W·V_A + V_R) / (W + 1), then
// W := min(W + 1, max_weight). Until the weight reaches the cap it is the plain mean (for
// an integer cap: of the first max_weight + 1 observations); after it every update is
// V_A := (max_weight·V_A + V_R) / (max_weight + 1), an exponential moving average with
// α = 1 / (max_weight + 1) (voxblox's default cap is 100). weight_a 0 marks a region not
// yet observed (its value_a is then unused and overwritten). Asserts max_weight >= 1 and
// weight_a >= 0.
void CappedMeanUpdate(double max_weight, double value_r, double& value_a, double& weight_a);

// Robust offline estimate over all views of one region.
struct OfflineOptions {
  // An observation is an outlier when |v − m| > outlier_sigmas · s, m the confidence-weighted
  // median, s = max(1.4826 · weighted MAD, min_sigma_k).
  // 3: a Gaussian inlier is rejected with probability 0.27 %; reflections and mis-registered
  // edges (several K off) are far beyond.
  double outlier_sigmas = 3.0;  // [1, 100]
  // Floor of the per-view spread: with 2–3 views the MAD can be 0, and views of one region
  // disagree by more than the NETD (0.03–0.05 K): fixed-pattern and column noise (0.03–0.05 K
  // after an FFC, growing until the next), the offset drift between FFCs (0.1–0.3 K for
  // uncooled cores), a pixel's footprint changing with the view. 0.2 K keeps views that differ
  // by that kind of error, while reflections and misregistered edges (several K) stay far
  // beyond 3 · 0.2 K.
  double min_sigma_k = 0.2;  // K, > 0, finite
  std::string Check() const;
};

struct Observation {
  float value_c;     // temperature, °C, finite
  float confidence;  // C_R, in (0, 1]
};

struct OfflineEstimate {
  // Confidence-weighted mean of the inliers, °C.
  double value_c = std::numeric_limits<double>::quiet_NaN();
  double confidence = 0;  // mean confidence of the inliers
  // Confidence-weighted std of the inliers across views (0 for one): with reliability weights
  // w, sqrt(Σ w (v − mean)² / (V1 − V2 / V1)), V1 = Σ w, V2 = Σ w², which for equal weights
  // is the sample std (n − 1).
  double std_c = std::numeric_limits<double>::quiet_NaN();
  int views = 0;     // inliers
  int rejected = 0;  // outliers
};

// Over obs (any order; empty → views 0, NaN value). May reorder obs (sorts in place).
// The weighted median is the value where the cumulative confidence (values ascending)
// reaches half the total, the mean of the two middle values when it lands on a boundary
// between two (so equal confidences give the ordinary median). No allocation: O(n log n).
// Asserts the observations' ranges.
OfflineEstimate RobustEstimate(std::span<Observation> obs, const OfflineOptions& o);

}  // namespace hw::reconstruct
