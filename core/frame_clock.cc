#include "core/frame_clock.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "core/median.h"
#include "core/option_check.h"
#include "core/strings.h"

namespace hw::core {

std::string StampRegularisationOptions::Check() const {
  if (!(std::isfinite(window_s) && window_s > 0)) return OptionFail("window_s", window_s, "> 0");
  if (!(max_jitter_fraction > 0 && max_jitter_fraction <= 0.5)) {
    return OptionFail("max_jitter_fraction", max_jitter_fraction, "in (0, 0.5]");
  }
  if (!(std::isfinite(outlier_sigmas) && outlier_sigmas > 0)) {
    return OptionFail("outlier_sigmas", outlier_sigmas, "> 0");
  }
  if (!(max_outlier_fraction >= 0 && max_outlier_fraction < 1)) {
    return OptionFail("max_outlier_fraction", max_outlier_fraction, "in [0, 1)");
  }
  if (min_frames < 3) return OptionFail("min_frames", min_frames, ">= 3");
  return "";
}

namespace {

// Index files store microseconds: a stream without jitter still scatters by that much.
constexpr double kStampResolutionS = 1e-6;

// A least-squares line t = t_mean + slope · (n − n_mean) through (slot, stamp) pairs, in
// coordinates relative to a reference frame (stamps of ~1e3–1e9 s would lose the µs in sums).
struct Line {
  int m = 0;                  // frames fitted
  double n_mean = 0, t_mean = 0, slope = 0, s_nn = 0;
  int64_t n_ref = 0;
  double t_ref = 0;
  double At(int64_t n) const { return t_ref + t_mean + slope * (static_cast<double>(n - n_ref) - n_mean); }
  // Fractional slot of time t.
  double SlotOf(double t) const { return static_cast<double>(n_ref) + n_mean + (t - t_ref - t_mean) / slope; }
  // Standard error of At(n) for stamps with jitter σ.
  double StdAt(int64_t n, double sigma) const {
    const double d = static_cast<double>(n - n_ref) - n_mean;
    return sigma * std::sqrt(1.0 / m + d * d / s_nn);
  }
};

// Fits the frames [lo, hi) that are not outliers; false when fewer than 3 or all on one slot.
bool FitLine(std::span<const double> stamps, const std::vector<int64_t>& slots, const std::vector<char>& outlier,
             size_t lo, size_t hi, size_t ref, Line* line) {
  Line l;
  l.n_ref = slots[ref];
  l.t_ref = stamps[ref];
  double sn = 0, st = 0;
  for (size_t j = lo; j < hi; ++j) {
    if (outlier[j]) continue;
    sn += static_cast<double>(slots[j] - l.n_ref);
    st += stamps[j] - l.t_ref;
    ++l.m;
  }
  if (l.m < 3) return false;
  l.n_mean = sn / l.m;
  l.t_mean = st / l.m;
  double snt = 0;
  for (size_t j = lo; j < hi; ++j) {
    if (outlier[j]) continue;
    const double dn = static_cast<double>(slots[j] - l.n_ref) - l.n_mean;
    l.s_nn += dn * dn;
    snt += dn * (stamps[j] - l.t_ref - l.t_mean);
  }
  if (!(l.s_nn > 0)) return false;
  l.slope = snt / l.s_nn;
  if (!(l.slope > 0)) return false;
  *line = l;
  return true;
}

std::string Ms(double s) { return StringPrintf("%.1f ms", s * 1e3); }
std::string Sec(double s) { return StringPrintf("%.6f", s); }

}  // namespace

StampFit RegulariseStamps(std::span<const double> stamps, const StampRegularisationOptions& options) {
  assert(options.Check().empty());
  const size_t n = stamps.size();
  for (size_t i = 0; i < n; ++i) {
    assert(std::isfinite(stamps[i]) && (i == 0 || stamps[i] > stamps[i - 1]));
  }
  StampFit fit;
  fit.times_s.assign(stamps.begin(), stamps.end());
  if (n < static_cast<size_t>(options.min_frames)) {
    fit.reason = std::to_string(n) + " frames, fewer than " + std::to_string(options.min_frames);
    return fit;
  }
  std::vector<double> steps(n - 1);
  for (size_t i = 1; i < n; ++i) steps[i - 1] = stamps[i] - stamps[i - 1];
  const double period0 = Median(steps);
  const double pause_s = options.window_s / 2;
  // Slots within this many of a frame's are fitted with it (at least two on each side).
  const int64_t half = std::max<int64_t>(2, std::llround(options.window_s / 2 / period0));

  // 1. Slots, forward. Each frame's slot is where the line through the segment's earlier
  // frames (within the window) puts its stamp. A frame that lands on or before its
  // predecessor's slot says the predecessor came late (arrival jitter is lateness): the
  // earlier frames are moved back one slot each until they fit, and flagged as outliers; a
  // run longer than `half` is not a late delivery: two frames really share a slot.
  std::vector<int64_t> slots(n, 0);
  std::vector<char> outlier(n, 0);
  std::vector<size_t> segment_begin(n, 0);  // first frame of each frame's segment
  fit.segments = 1;
  for (size_t i = 1; i < n; ++i) {
    const double dt = stamps[i] - stamps[i - 1];
    if (dt > pause_s) {  // a new segment; its slots only need to increase
      ++fit.segments;
      segment_begin[i] = i;
      slots[i] = slots[i - 1] + std::max<int64_t>(1, std::llround(dt / period0));
      continue;
    }
    segment_begin[i] = segment_begin[i - 1];
    size_t lo = i - 1;
    while (lo > segment_begin[i] && slots[i - 1] - slots[lo - 1] <= 2 * half) --lo;
    Line line;
    const double x = FitLine(stamps, slots, outlier, lo, i, i - 1, &line)
                         ? line.SlotOf(stamps[i])
                         : static_cast<double>(slots[i - 1]) + dt / period0;
    const int64_t slot = std::llround(x);
    slots[i] = slot;
    // At most `half` frames moved back: a longer run is not a late delivery.
    int64_t need = slot - 1;
    for (size_t j = i - 1, moved = 0; slots[j] > need; --j) {
      if (++moved > static_cast<size_t>(half)) {
        fit.reason = "frames at " + Sec(stamps[i - 1]) + " and " + Sec(stamps[i]) +
                     " s fall on one exposure slot (period " + Ms(period0) + "): not a regular stream";
        return fit;
      }
      slots[j] = need--;
      outlier[j] = 1;
      if (j == segment_begin[i]) break;  // a segment's slots need not start at its predecessor's
    }
  }

  // 2. Times: each frame's slot on the line through the inliers whose slots lie within half
  // of its own, in its segment; twice, the second time without the stamps the first fit put
  // beyond outlier_sigmas · σ.
  std::vector<double> fitted(n), residual(n), std_error(n, 0), slopes;
  std::vector<char> fitted_ok(n, 0);
  double sigma = 0;
  for (int pass = 0; pass < 2; ++pass) {
    slopes.clear();
    size_t lo = 0, hi = 0;
    for (size_t i = 0; i < n; ++i) {
      lo = std::max(lo, segment_begin[i]);
      while (slots[i] - slots[lo] > half) ++lo;
      hi = std::max(hi, i + 1);
      while (hi < n && segment_begin[hi] == segment_begin[i] && slots[hi] - slots[i] <= half) ++hi;
      Line line;
      fitted_ok[i] = FitLine(stamps, slots, outlier, lo, hi, i, &line);
      fitted[i] = fitted_ok[i] ? line.At(slots[i]) : stamps[i];
      residual[i] = stamps[i] - fitted[i];
      if (fitted_ok[i]) {
        slopes.push_back(line.slope);
        std_error[i] = line.StdAt(slots[i], 1);  // times σ below
      }
    }
    std::vector<double> absolute;
    for (size_t i = 0; i < n; ++i) {
      if (fitted_ok[i] && !outlier[i]) absolute.push_back(std::abs(residual[i]));
    }
    if (absolute.empty()) {
      fit.reason = "no segment of 3 or more frames within " + Sec(pause_s) + " s of each other";
      return fit;
    }
    sigma = 1.4826 * Median(absolute);
    const double limit = options.outlier_sigmas * std::max(sigma, kStampResolutionS);
    if (pass == 0) {
      for (size_t i = 0; i < n; ++i) {
        if (fitted_ok[i] && std::abs(residual[i]) > limit) outlier[i] = 1;
      }
    }
  }

  fit.period_s = Median(slopes);
  fit.jitter_s = sigma;
  for (size_t i = 0; i < n; ++i) fit.outliers += outlier[i];
  if (sigma > options.max_jitter_fraction * fit.period_s) {
    fit.reason = "jitter " + Ms(sigma) + StringPrintf(" exceeds %g", options.max_jitter_fraction) + " of the period " +
                 Ms(fit.period_s) + ": not a regular stream";
    return fit;
  }
  if (fit.outliers > options.max_outlier_fraction * static_cast<double>(n)) {
    fit.reason = std::to_string(fit.outliers) + " of " + std::to_string(n) +
                 " stamps far from a regular grid: not a regular stream";
    return fit;
  }
  for (size_t i = 1; i < n; ++i) {
    if (!(fitted[i] > fitted[i - 1])) {
      fit.reason = "fitted times not increasing at " + Sec(stamps[i]) + " s";
      return fit;
    }
  }
  std::vector<double> errors;
  int64_t empty_slots = 0;
  for (size_t i = 1; i < n; ++i) {
    if (segment_begin[i] == segment_begin[i - 1]) empty_slots += slots[i] - slots[i - 1] - 1;
  }
  // More empty slots than frames: the grid is finer than the stream (the median interval of
  // a stream delivering frames in pairs), not its clock.
  if (empty_slots > static_cast<int64_t>(n)) {
    fit.reason = std::to_string(empty_slots) + " empty slots for " + std::to_string(n) + " frames at period " +
                 Ms(fit.period_s) + ": not a regular stream";
    return fit;
  }
  fit.empty_slots = empty_slots;
  for (size_t i = 0; i < n; ++i) {
    fit.max_shift_s = std::max(fit.max_shift_s, std::abs(residual[i]));
    if (fitted_ok[i]) errors.push_back(std_error[i] * sigma);
    else ++fit.unfitted;
  }
  fit.time_std_s = errors.empty() ? 0 : Median(errors);
  fit.times_s = std::move(fitted);
  fit.applied = true;
  return fit;
}

}  // namespace hw::core
