#include "reconstruct/thermal_scene_correction.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <opencv2/core.hpp>

#include "core/option_check.h"

namespace hw::reconstruct {

std::string SceneCorrectionOptions::Check() const {
  using core::OptionFail;
  auto positive = [](double v) { return v > 0 && std::isfinite(v); };
  if (min_reference_views < 1) return OptionFail("min_reference_views", min_reference_views, ">= 1");
  if (!positive(max_reference_std_k)) return OptionFail("max_reference_std_k", max_reference_std_k, "finite and > 0 K");
  if (!positive(max_residual_k)) return OptionFail("max_residual_k", max_residual_k, "finite and > 0 K");
  if (max_pair_shift_px < 0 || max_pair_shift_px > 10000) return OptionFail("max_pair_shift_px", max_pair_shift_px, "in [0, 10000] px");
  if (!(event_window_s >= 0) || !std::isfinite(event_window_s)) return OptionFail("event_window_s", event_window_s, "finite and >= 0 s");
  if (min_reference_rays < 1) return OptionFail("min_reference_rays", min_reference_rays, ">= 1");
  if (!(pixel_rate > 0 && pixel_rate <= 1)) return OptionFail("pixel_rate", pixel_rate, "in (0, 1]");
  if (!positive(max_pixel_offset_k)) return OptionFail("max_pixel_offset_k", max_pixel_offset_k, "finite and > 0 K");
  return "";
}

SceneCorrection::SceneCorrection(const SceneCorrectionOptions& options, int width, int height)
    : options_(options), pixel_offset_k_(height, width, CV_32FC1, cv::Scalar(0)) {
  assert(options.Check().empty());
  assert(width > 0 && height > 0);
}

cv::Mat SceneCorrection::CorrectPixels(const cv::Mat& apparent_c) const {
  assert(apparent_c.type() == CV_32FC1 && apparent_c.size() == pixel_offset_k_.size());
  if (!options_.pixel_offset) return apparent_c;
  return apparent_c - pixel_offset_k_;
}

namespace {

// Median of v (reordered); v not empty.
float Median(std::vector<float>& v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  float m = v[mid];
  if (v.size() % 2 == 0) m = 0.5f * (m + *std::max_element(v.begin(), v.begin() + mid));
  return m;
}

}  // namespace

// The median of the residuals within max_residual_k of the median of all of them (a jump at a
// shutter event moves them all; a reflection moves a few far), and how many those are.
// Reorders `residuals`; 0 and 0 when empty.
std::pair<float, size_t> SceneCorrection::KeptMedian(std::vector<SceneResidual>& residuals) {
  if (residuals.empty()) return {0.0f, 0};
  scratch_.resize(residuals.size());
  for (size_t i = 0; i < residuals.size(); ++i) scratch_[i] = residuals[i].residual_k;
  const float centre = Median(scratch_);
  const float max_residual = static_cast<float>(options_.max_residual_k);
  auto is_near = [&](const SceneResidual& r) { return std::abs(r.residual_k - centre) <= max_residual; };
  const size_t kept = static_cast<size_t>(std::partition(residuals.begin(), residuals.end(), is_near) - residuals.begin());
  scratch_.resize(kept);
  for (size_t i = 0; i < kept; ++i) scratch_[i] = residuals[i].residual_k;
  return {kept > 0 ? Median(scratch_) : 0.0f, kept};
}

SceneCorrectionUpdate SceneCorrection::Update(std::vector<SceneResidual>& pairs,
                                              std::vector<SceneResidual>& residuals, bool after_event) {
  SceneCorrectionUpdate u;
  const size_t min_rays = static_cast<size_t>(options_.min_reference_rays);
  if (options_.frame_offset && after_event) {
    // The nearest pairs that suffice: the smallest shift within which min_rays lie.
    int radius = -1;
    if (pairs.size() >= min_rays) {
      auto by_shift = [](const SceneResidual& a, const SceneResidual& b) { return a.shift_px < b.shift_px; };
      std::nth_element(pairs.begin(), pairs.begin() + static_cast<std::ptrdiff_t>(min_rays - 1), pairs.end(), by_shift);
      radius = pairs[min_rays - 1].shift_px;
      pairs.erase(std::partition(pairs.begin(), pairs.end(), [&](const SceneResidual& p) { return p.shift_px <= radius; }),
                  pairs.end());
    }
    const auto [offset, kept] = KeptMedian(pairs);
    u.pair_rays = static_cast<int>(kept);
    if (kept >= min_rays) {
      frame_offset_k_ = offset;
      u.frame_estimated = true;
      u.pair_shift_px = radius;
    }
  }
  u.frame_offset_k = options_.frame_offset ? frame_offset_k_ : 0.0;
  if (!options_.pixel_offset) return u;
  // What each pixel's residual keeps beyond the residuals' own median (not the frame offset:
  // the regions' means carry the offsets of the views that made them, so that a common part
  // never leaks into the pixels).
  const auto [kept_median, kept] = KeptMedian(residuals);
  u.reference_rays = static_cast<int>(kept);
  const bool enough = kept >= min_rays;
  const float max_residual = static_cast<float>(options_.max_residual_k);
  if (enough) {
    const float rate = static_cast<float>(options_.pixel_rate);
    const float cap = static_cast<float>(options_.max_pixel_offset_k);
    float* b = pixel_offset_k_.ptr<float>();
    for (size_t i = 0; i < kept; ++i) {
      const float excess = residuals[i].residual_k - kept_median;
      if (std::abs(excess) > max_residual) continue;
      float& bp = b[residuals[i].pixel];
      bp = std::clamp(bp + rate * excess, -cap, cap);
    }
    // Re-centred: a common part of the pixel estimates is the frame offset's to carry.
    pixel_offset_k_ -= cv::mean(pixel_offset_k_)[0];
  }
  u.pixel_offset_rms_k = cv::norm(pixel_offset_k_, cv::NORM_L2) / std::sqrt(static_cast<double>(pixel_offset_k_.total()));
  return u;
}

}  // namespace hw::reconstruct
