#include "reconstruct/thermal_update.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>

#include "reconstruct/option_check.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

namespace {

// The weighted median of a sequence given in ascending order by `next(value, weight)`
// (returns false at its end) of total weight `total` > 0: the value where the cumulative
// weight reaches total / 2, the mean of it and the next value when the half lands on the
// boundary between them (to a relative 1e-9: sums of equal float weights round).
template <class Next>
double WeightedMedianOfSorted(double total, Next&& next) {
  const double half = 0.5 * total;
  const double eps = 1e-9 * total;
  double cumulative = 0, value = 0, weight = 0;
  while (next(value, weight)) {
    cumulative += weight;
    if (cumulative >= half - eps) {
      double next_value = 0, next_weight = 0;
      if (cumulative <= half + eps && next(next_value, next_weight)) {
        return 0.5 * (value + next_value);
      }
      return value;
    }
  }
  return value;  // rounding left the sum short of half: the largest value
}

}  // namespace

std::string ThermalMethodName(ThermalMethod m) {
  switch (m) {
    case ThermalMethod::kLatest: return "latest";
    case ThermalMethod::kMean: return "mean";
    case ThermalMethod::kCappedMean: return "capped-mean";
    case ThermalMethod::kOnline: return "online";
    case ThermalMethod::kOffline: return "offline";
  }
  assert(false && "unknown ThermalMethod");
  return "";
}

std::optional<ThermalMethod> ParseThermalMethod(std::string_view name) {
  for (const ThermalMethod m : kThermalMethods) {
    if (name == ThermalMethodName(m)) return m;
  }
  return std::nullopt;
}

double OnlineUpdate(double recency_bias, double value_r, double confidence_r, double& value_a,
                    double& confidence_a) {
  assert(recency_bias >= 0 && recency_bias <= 1);
  assert(confidence_r >= 0 && confidence_r <= 1);
  if (confidence_a < 0) {
    value_a = value_r;
    confidence_a = confidence_r;
    return 1;
  }
  const double q = std::clamp(confidence_r - confidence_a + recency_bias, 0.0, 1.0);
  confidence_a = q * confidence_r + (1 - q) * confidence_a;
  value_a = q * value_r + (1 - q) * value_a;
  return q;
}

void CappedMeanUpdate(double max_weight, double value_r, double& value_a, double& weight_a) {
  assert(max_weight >= 1);
  assert(weight_a >= 0);
  // weight 0: value_a is unused (may be NaN); 0 · NaN would poison the mean.
  value_a = weight_a > 0 ? (weight_a * value_a + value_r) / (weight_a + 1) : value_r;
  weight_a = std::min(weight_a + 1, max_weight);
}

std::string OfflineOptions::Check() const {
  if (!InRange(outlier_sigmas, 1, 100)) {
    return Fail("outlier_sigmas", outlier_sigmas, "in [1, 100]");
  }
  if (!(min_sigma_k > 0) || !std::isfinite(min_sigma_k)) {
    return Fail("min_sigma_k", min_sigma_k, "> 0 K and finite");
  }
  return "";
}

OfflineEstimate RobustEstimate(std::span<Observation> obs, const OfflineOptions& o) {
  OfflineEstimate e;
  const size_t n = obs.size();
  if (n == 0) return e;
  double total = 0;
  for (const Observation& ob : obs) {
    assert(std::isfinite(ob.value_c));
    assert(ob.confidence > 0 && ob.confidence <= 1);
    total += static_cast<double>(ob.confidence);
  }
  std::sort(obs.begin(), obs.end(),
            [](const Observation& a, const Observation& b) { return a.value_c < b.value_c; });

  size_t i = 0;
  const double median = WeightedMedianOfSorted(total, [&](double& v, double& w) {
    if (i == n) return false;
    v = static_cast<double>(obs[i].value_c);
    w = static_cast<double>(obs[i].confidence);
    ++i;
    return true;
  });

  // |v − median| in ascending order without a second array: the deviations left of the
  // median grow going down, those right of it going up; merge the two runs.
  const auto below = [](const Observation& a, double m) {
    return static_cast<double>(a.value_c) < m;
  };
  const size_t split =
      static_cast<size_t>(std::lower_bound(obs.begin(), obs.end(), median, below) - obs.begin());
  size_t left = split, right = split;  // next: obs[left − 1] and obs[right]
  const double mad = WeightedMedianOfSorted(total, [&](double& d, double& w) {
    const bool has_left = left > 0, has_right = right < n;
    if (!has_left && !has_right) return false;
    const double d_left = has_left ? median - static_cast<double>(obs[left - 1].value_c) : 0;
    const double d_right = has_right ? static_cast<double>(obs[right].value_c) - median : 0;
    if (has_left && (!has_right || d_left <= d_right)) {
      d = d_left;
      w = static_cast<double>(obs[--left].confidence);
    } else {
      d = d_right;
      w = static_cast<double>(obs[right++].confidence);
    }
    return true;
  });

  // 1.4826 · MAD estimates σ of a Gaussian. The inliers are a contiguous run of the sorted
  // values; it holds at least half the weight (those within one MAD), so it is never empty.
  const double limit = o.outlier_sigmas * std::max(1.4826 * mad, o.min_sigma_k);
  size_t lo = 0, hi = n;
  while (lo < n && median - static_cast<double>(obs[lo].value_c) > limit) ++lo;
  while (hi > lo && static_cast<double>(obs[hi - 1].value_c) - median > limit) --hi;
  assert(hi > lo);

  double w_sum = 0, w2_sum = 0, wv_sum = 0;
  for (size_t k = lo; k < hi; ++k) {
    const double w = static_cast<double>(obs[k].confidence);
    w_sum += w;
    w2_sum += w * w;
    wv_sum += w * static_cast<double>(obs[k].value_c);
  }
  const double mean = wv_sum / w_sum;
  double wss = 0;  // second pass: no cancellation of Σ w v² − (Σ w v)² / Σ w
  for (size_t k = lo; k < hi; ++k) {
    const double dv = static_cast<double>(obs[k].value_c) - mean;
    wss += static_cast<double>(obs[k].confidence) * dv * dv;
  }
  const double effective = w_sum - w2_sum / w_sum;  // 0 for one view
  e.value_c = mean;
  e.views = static_cast<int>(hi - lo);
  e.rejected = static_cast<int>(n) - e.views;
  e.confidence = w_sum / e.views;
  e.std_c = e.views > 1 && effective > 0 ? std::sqrt(wss / effective) : 0;
  return e;
}

}  // namespace hw::reconstruct
