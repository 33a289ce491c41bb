#include "calibrate/latency.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <random>

#include <Eigen/Dense>

#include "core/error.h"
#include "core/option_check.h"
#include "core/strings.h"

namespace hw::calibrate {
namespace {

using core::OptionFail;
using core::StringPrintf;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------
// Signals

// Interval k = [t_k, t_{k+1}] of a signal is usable when both samples are valid and it is
// not a gap.
bool IntervalValid(const LatencySignal& s, size_t k, double gap_factor) {
  return k + 1 < s.time_s.size() && std::isfinite(s.value[k]) && std::isfinite(s.value[k + 1]) &&
         s.time_s[k + 1] - s.time_s[k] <= gap_factor * s.period_s;
}

// Index k of the usable interval holding t_s, or -1.
int Locate(const LatencySignal& s, double t_s, double gap_factor) {
  const auto it = std::upper_bound(s.time_s.begin(), s.time_s.end(), t_s);
  if (it == s.time_s.begin()) return -1;
  size_t k = static_cast<size_t>(it - s.time_s.begin()) - 1;
  if (k + 1 == s.time_s.size()) {
    if (t_s != s.time_s.back() || k == 0) return -1;
    --k;  // the last sample itself: the interval ending there
  }
  return IntervalValid(s, k, gap_factor) ? static_cast<int>(k) : -1;
}

double LinearAt(const LatencySignal& s, int k, double t_s) {
  const size_t i = static_cast<size_t>(k);
  const double f = (t_s - s.time_s[i]) / (s.time_s[i + 1] - s.time_s[i]);
  return (1 - f) * s.value[i] + f * s.value[i + 1];
}

// Slope at sample i for the cubic Hermite: central difference over the neighbouring valid
// intervals, one-sided at a segment's end.
double Slope(const LatencySignal& s, size_t i, double gap_factor) {
  const bool left = i > 0 && IntervalValid(s, i - 1, gap_factor);
  const bool right = IntervalValid(s, i, gap_factor);
  if (left && right) return (s.value[i + 1] - s.value[i - 1]) / (s.time_s[i + 1] - s.time_s[i - 1]);
  if (right) return (s.value[i + 1] - s.value[i]) / (s.time_s[i + 1] - s.time_s[i]);
  if (left) return (s.value[i] - s.value[i - 1]) / (s.time_s[i] - s.time_s[i - 1]);
  return 0;
}

double CubicAt(const LatencySignal& s, int k, double t_s, double gap_factor) {
  const size_t i = static_cast<size_t>(k);
  const double h = s.time_s[i + 1] - s.time_s[i];
  const double u = (t_s - s.time_s[i]) / h;
  const double u2 = u * u, u3 = u2 * u;
  return (2 * u3 - 3 * u2 + 1) * s.value[i] + (u3 - 2 * u2 + u) * h * Slope(s, i, gap_factor) +
         (-2 * u3 + 3 * u2) * s.value[i + 1] + (u3 - u2) * h * Slope(s, i + 1, gap_factor);
}

// Segment id of every interval: usable intervals in one run share an id, others -1.
std::vector<int> Segments(const LatencySignal& s, double gap_factor) {
  std::vector<int> id(s.time_s.size(), -1);
  int current = -1;
  bool in_run = false;
  for (size_t k = 0; k + 1 < s.time_s.size(); ++k) {
    if (IntervalValid(s, k, gap_factor)) {
      if (!in_run) ++current;
      in_run = true;
      id[k] = current;
    } else {
      in_run = false;
    }
  }
  return id;
}

// Brent's minimisation of f on [a, b] to tolerance tol (parabolic steps, golden fallback).
template <typename F>
double BrentMinimise(const F& f, double a, double b, double tol) {
  constexpr double kGolden = 0.3819660112501051;
  double x = a + kGolden * (b - a), w = x, v = x;
  double fx = f(x), fw = fx, fv = fx;
  double d = 0, e = 0;
  for (int iter = 0; iter < 100; ++iter) {
    const double m = 0.5 * (a + b);
    const double tol1 = tol + 1e-12 * std::abs(x), tol2 = 2 * tol1;
    if (std::abs(x - m) <= tol2 - 0.5 * (b - a)) break;
    bool golden = true;
    if (std::abs(e) > tol1) {
      double r = (x - w) * (fx - fv), q = (x - v) * (fx - fw), p = (x - v) * q - (x - w) * r;
      q = 2 * (q - r);
      if (q > 0) p = -p;
      q = std::abs(q);
      if (std::abs(p) < std::abs(0.5 * q * e) && p > q * (a - x) && p < q * (b - x)) {
        e = d;
        d = p / q;
        const double u = x + d;
        if (u - a < tol2 || b - u < tol2) d = x < m ? tol1 : -tol1;
        golden = false;
      }
    }
    if (golden) {
      e = (x < m ? b : a) - x;
      d = kGolden * e;
    }
    const double u = std::abs(d) >= tol1 ? x + d : x + (d > 0 ? tol1 : -tol1);
    const double fu = f(u);
    if (fu <= fx) {
      (u < x ? b : a) = x;
      v = w, fv = fw, w = x, fw = fx, x = u, fx = fu;
    } else {
      (u < x ? a : b) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw, w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  return x;
}

// Affine least squares y ≈ g x + o over the (weighted by multiplicity) pairs; RSS.
struct AffineFit {
  double g = 0, o = 0, rss = kNaN;
};
AffineFit FitAffine(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0;
  for (size_t i = 0; i < x.size(); ++i) sx += x[i], sy += y[i];
  const double mx = sx / n, my = sy / n;
  double sxx = 0, sxy = 0, syy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
    syy += (y[i] - my) * (y[i] - my);
  }
  AffineFit fit;
  if (!(sxx > 0)) return fit;
  fit.g = sxy / sxx;
  fit.o = my - fit.g * mx;
  fit.rss = std::max(0.0, syy - sxy * sxy / sxx);
  return fit;
}

// Polynomial least squares y ≈ Σ_k c_k x^k, k = 0..degree (the cameras' position maps:
// affine, plus the curvature that lens-model and perspective errors leave); RSS.
struct PolyFit {
  Eigen::VectorXd c;
  double rss = kNaN;
  double Value(double x) const {
    double v = 0;
    for (Eigen::Index k = c.size() - 1; k >= 0; --k) v = v * x + c(k);
    return v;
  }
  double Slope(double x) const {
    double v = 0;
    for (Eigen::Index k = c.size() - 1; k >= 1; --k) v = v * x + static_cast<double>(k) * c(k);
    return v;
  }
};
PolyFit FitPoly(const std::vector<double>& x, const std::vector<double>& y, int degree) {
  const int m = degree + 1;
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd aty = Eigen::VectorXd::Zero(m);
  Eigen::VectorXd row(m);
  for (size_t i = 0; i < x.size(); ++i) {
    double p = 1;
    for (int k = 0; k < m; ++k) row(k) = p, p *= x[i];
    ata.selfadjointView<Eigen::Lower>().rankUpdate(row);
    aty += row * y[i];
  }
  ata = ata.selfadjointView<Eigen::Lower>();
  PolyFit fit;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(ata);
  if (ldlt.info() != Eigen::Success) return fit;
  fit.c = ldlt.solve(aty);
  double rss = 0;
  for (size_t i = 0; i < x.size(); ++i) rss += std::pow(y[i] - fit.Value(x[i]), 2);
  fit.rss = rss;
  return fit;
}

}  // namespace

std::string LatencyOptions::Check() const {
  if (!(max_offset_s > 0 && max_offset_s <= 10)) return OptionFail("max_offset_s", max_offset_s, "in (0, 10] s");
  if (!(coarse_step_s > 0 && coarse_step_s <= 0.05)) return OptionFail("coarse_step_s", coarse_step_s, "in (0, 0.05] s");
  if (!(coarse_step_s <= max_offset_s / 4)) return OptionFail("coarse_step_s", coarse_step_s, "at most max_offset_s / 4");
  if (background_frames < 5 || background_frames > 10000) {
    return OptionFail("background_frames", background_frames, "in [5, 10000]");
  }
  if (!(threshold_sigmas >= 2 && threshold_sigmas <= 100)) {
    return OptionFail("threshold_sigmas", threshold_sigmas, "in [2, 100]");
  }
  if (min_blob_px < 1 || min_blob_px > 1000000) return OptionFail("min_blob_px", min_blob_px, "in [1, 1e6] px");
  if (dilate_px < 0 || dilate_px > 20) return OptionFail("dilate_px", dilate_px, "in [0, 20] px");
  if (!(min_valid_fraction > 0 && min_valid_fraction <= 1)) {
    return OptionFail("min_valid_fraction", min_valid_fraction, "in (0, 1]");
  }
  if (!(min_motion_px > 0 && min_motion_px <= 1e4)) return OptionFail("min_motion_px", min_motion_px, "in (0, 1e4] px");
  if (!(min_correlation > 0 && min_correlation < 1)) return OptionFail("min_correlation", min_correlation, "in (0, 1)");
  if (!(ambiguity_ratio > 0 && ambiguity_ratio < 1)) return OptionFail("ambiguity_ratio", ambiguity_ratio, "in (0, 1)");
  if (!(gap_factor > 1 && gap_factor <= 100)) return OptionFail("gap_factor", gap_factor, "in (1, 100]");
  if (map_degree < 1 || map_degree > 3) return OptionFail("map_degree", map_degree, "in [1, 3]");
  if (bootstrap_samples < 0 || bootstrap_samples > 100000) {
    return OptionFail("bootstrap_samples", bootstrap_samples, "in [0, 100000]");
  }
  return "";
}

std::optional<double> SampleSignal(const LatencySignal& signal, double t_s, double gap_factor) {
  const int k = Locate(signal, t_s, gap_factor);
  if (k < 0) return std::nullopt;
  return CubicAt(signal, k, t_s, gap_factor);
}

PairOffset EstimatePairOffset(const LatencySignal& a, const LatencySignal& b, const LatencyOptions& options,
                              const std::filesystem::path& path_for_errors) {
  assert(options.Check().empty());
  PairOffset out;
  out.reference = a.name;
  out.other = b.name;
  const double gap = options.gap_factor;
  std::vector<size_t> valid;
  for (size_t i = 0; i < a.value.size(); ++i) {
    if (std::isfinite(a.value[i])) valid.push_back(i);
  }
  const size_t min_overlap = std::max<size_t>(10, valid.size() / 4);
  const std::string pair = b.name + " against " + a.name;

  // Coarse: Pearson correlation of a(t) and b(t − offset), b linear on its own stamps.
  const int steps = static_cast<int>(std::floor(options.max_offset_s / options.coarse_step_s + 1e-9));
  std::vector<double> x, y;
  for (int j = -steps; j <= steps; ++j) {
    const double offset = j * options.coarse_step_s;
    x.clear(), y.clear();
    for (size_t i : valid) {
      const double u = a.time_s[i] - offset;
      const int k = Locate(b, u, gap);
      if (k < 0) continue;
      x.push_back(LinearAt(b, k, u));
      y.push_back(a.value[i]);
    }
    double r = kNaN;
    if (x.size() >= min_overlap) {
      const AffineFit f = FitAffine(x, y);
      double syy = 0, my = 0;
      for (double v : y) my += v;
      my /= static_cast<double>(y.size());
      for (double v : y) syy += (v - my) * (v - my);
      if (syy > 0 && std::isfinite(f.rss)) r = std::copysign(std::sqrt(std::max(0.0, 1 - f.rss / syy)), f.g);
    }
    out.curve_offset_s.push_back(offset);
    out.curve_correlation.push_back(r);
  }
  const std::vector<double>& c = out.curve_correlation;
  size_t peak = c.size();
  for (size_t j = 0; j < c.size(); ++j) {
    if (std::isfinite(c[j]) && (peak == c.size() || c[j] > c[peak])) peak = j;
  }
  if (peak == c.size()) {
    throw core::InputError(path_for_errors, StringPrintf("%s: the streams overlap in time by fewer than %zu valid samples "
                                                         "at every offset within ±%g s",
                                                         pair.c_str(), min_overlap, options.max_offset_s));
  }
  out.coarse_offset_s = out.curve_offset_s[peak];
  out.peak_correlation = c[peak];
  if (out.peak_correlation < options.min_correlation) {
    throw core::InputError(path_for_errors, StringPrintf("%s: the blob tracks do not match (best correlation %.2f < %.2f "
                                                         "at %+.3f s): is one moving object seen by both cameras?",
                                                         pair.c_str(), out.peak_correlation, options.min_correlation,
                                                         out.coarse_offset_s));
  }
  if (peak == 0 || peak + 1 == c.size()) {
    throw core::InputError(path_for_errors, StringPrintf("%s: the correlation peaks at the edge of the search range "
                                                         "(%+.3f s): the offset may be larger than --max-offset %g s",
                                                         pair.c_str(), out.coarse_offset_s, options.max_offset_s));
  }
  // Second peak: any other local maximum (or a rising window edge) standing out of the dip
  // that separates it from the main peak by at least 0.02, where that dip falls below the
  // ambiguity level (ambiguity_ratio × the peak). A bump whose dip stays above it is a ripple
  // of the main lobe (sampling at frame times ripples the curve at the frame period: 0.971
  // and 0.956 20 ms apart on a short session), not a second offset the motion allows.
  out.second_peak_correlation = -1;
  double second_at = 0;
  for (size_t j = 0; j < c.size(); ++j) {
    if (j == peak || !std::isfinite(c[j])) continue;
    const bool left_ok = j == 0 || !std::isfinite(c[j - 1]) || c[j] >= c[j - 1];
    const bool right_ok = j + 1 == c.size() || !std::isfinite(c[j + 1]) || c[j] >= c[j + 1];
    if (!left_ok || !right_ok) continue;
    double dip = c[j];
    for (size_t m = std::min(j, peak); m <= std::max(j, peak); ++m) {
      if (std::isfinite(c[m])) dip = std::min(dip, c[m]);
    }
    if (c[j] - dip >= 0.02 && dip < options.ambiguity_ratio * out.peak_correlation &&
        c[j] > out.second_peak_correlation) out.second_peak_correlation = c[j], second_at = out.curve_offset_s[j];
  }
  if (out.second_peak_correlation >= options.ambiguity_ratio * out.peak_correlation) {
    throw core::InputError(path_for_errors, StringPrintf("%s: the offset is ambiguous: correlation %.3f at %+.3f s and %.3f "
                                                         "at %+.3f s (a periodic motion repeats within ±%g s: wave the "
                                                         "object irregularly, or narrow --max-offset)",
                                                         pair.c_str(), out.peak_correlation, out.coarse_offset_s,
                                                         out.second_peak_correlation, second_at, options.max_offset_s));
  }

  // Fine: the affine-fit residual, b by cubic Hermite, over a bracket of ±3 grid steps; the
  // samples are those whose b stays inside one gap-free segment over the whole bracket.
  const double lo = out.coarse_offset_s - 3 * options.coarse_step_s, hi = out.coarse_offset_s + 3 * options.coarse_step_s;
  const std::vector<int> segment = Segments(b, gap);
  std::vector<size_t> used;
  for (size_t i : valid) {
    const int k_lo = Locate(b, a.time_s[i] - hi, gap), k_hi = Locate(b, a.time_s[i] - lo, gap);
    if (k_lo >= 0 && k_hi >= 0 && segment[static_cast<size_t>(k_lo)] == segment[static_cast<size_t>(k_hi)]) used.push_back(i);
  }
  if (used.size() < min_overlap) {
    throw core::InputError(path_for_errors, StringPrintf("%s: only %zu samples overlap at the offset %+.3f s", pair.c_str(),
                                                         used.size(), out.coarse_offset_s));
  }
  auto b_at = [&](double u) { return CubicAt(b, Locate(b, u, gap), u, gap); };
  auto rss = [&](const std::vector<size_t>& indices, double offset) {
    std::vector<double> xs, ys;
    xs.reserve(indices.size()), ys.reserve(indices.size());
    for (size_t i : indices) {
      xs.push_back(b_at(a.time_s[i] - offset));
      ys.push_back(a.value[i]);
    }
    return FitPoly(xs, ys, options.map_degree).rss;
  };
  constexpr double kTolS = 1e-6;
  out.offset_s = BrentMinimise([&](double o) { return rss(used, o); }, lo, hi, kTolS);

  // Gauss-Newton covariance of (offset, g, o), residual autocorrelation, N_eff.
  const size_t n = used.size();
  std::vector<double> xs(n), ys(n), dxs(n);
  constexpr double kH = 1e-4;  // s, central difference of b
  for (size_t j = 0; j < n; ++j) {
    const double u = a.time_s[used[j]] - out.offset_s;
    xs[j] = b_at(u);
    ys[j] = a.value[used[j]];
    const int k1 = Locate(b, u + kH, gap), k0 = Locate(b, u - kH, gap);
    dxs[j] = k1 >= 0 && k0 >= 0 ? (CubicAt(b, k1, u + kH, gap) - CubicAt(b, k0, u - kH, gap)) / (2 * kH) : 0;
  }
  const PolyFit fit = FitPoly(xs, ys, options.map_degree);
  const int params = options.map_degree + 2;  // offset and the polynomial
  out.gain = fit.Slope(0);
  out.bias = fit.Value(0);
  out.map_coefficients.assign(fit.c.data(), fit.c.data() + fit.c.size());
  out.samples = static_cast<int>(n);
  std::vector<double> r(n);
  Eigen::MatrixXd jtj = Eigen::MatrixXd::Zero(params, params);
  Eigen::VectorXd jac(params);
  for (size_t j = 0; j < n; ++j) {
    r[j] = ys[j] - fit.Value(xs[j]);
    // r = y − P(b(t − offset)): ∂r/∂offset = P'(b)·b'(u), ∂r/∂c_k = −b(u)^k.
    jac(0) = fit.Slope(xs[j]) * dxs[j];
    double p = 1;
    for (int k = 1; k < params; ++k) jac(k) = -p, p *= xs[j];
    jtj += jac * jac.transpose();
  }
  const double sigma2 = fit.rss / std::max<double>(1, static_cast<double>(n) - params);
  out.residual_rms = std::sqrt(fit.rss / static_cast<double>(n));
  double rho_sum = 0;
  for (size_t lag = 1; lag < n / 4; ++lag) {
    double num = 0;
    for (size_t j = 0; j + lag < n; ++j) num += r[j] * r[j + lag];
    const double rho = fit.rss > 0 ? num / fit.rss : 0;
    if (rho <= 0) break;  // initial positive sequence (Geyer)
    rho_sum += rho;
  }
  out.effective_samples = static_cast<double>(n) / (1 + 2 * rho_sum);
  const Eigen::MatrixXd cov = sigma2 * jtj.inverse();
  out.sigma_fit_s = std::sqrt(std::max(0.0, cov(0, 0)) * static_cast<double>(n) / out.effective_samples);

  // Moving-block bootstrap over the reference samples: blocks longer than the residuals'
  // correlation so that each keeps its correlated errors together.
  if (options.bootstrap_samples > 0) {
    const double correlation_length = static_cast<double>(n) / out.effective_samples;
    const size_t block = std::clamp<size_t>(static_cast<size_t>(std::ceil(std::max(std::cbrt(static_cast<double>(n)),
                                                                                     2 * correlation_length))),
                                            1, std::max<size_t>(1, n / 3));
    out.bootstrap_block = static_cast<int>(block);
    std::mt19937_64 rng(options.bootstrap_seed);
    std::uniform_int_distribution<size_t> start(0, n - block);
    std::vector<size_t> indices;
    double sum = 0, sum2 = 0;
    for (int rep = 0; rep < options.bootstrap_samples; ++rep) {
      indices.clear();
      while (indices.size() < n) {
        const size_t s = start(rng);
        for (size_t j = s; j < s + block && indices.size() < n; ++j) indices.push_back(used[j]);
      }
      const double o = BrentMinimise([&](double off) { return rss(indices, off); }, lo, hi, kTolS);
      sum += o, sum2 += o * o;
    }
    const double m = sum / options.bootstrap_samples;
    out.sigma_bootstrap_s = std::sqrt(std::max(0.0, sum2 / options.bootstrap_samples - m * m));
  }
  out.sigma_s = std::max(out.sigma_fit_s, out.sigma_bootstrap_s);
  return out;
}

LatencyResult EstimateLatency(const core::Scan& scan, const LatencyOptions& options, const LatencyProgressFn& progress) {
  assert(options.Check().empty());
  const auto start = std::chrono::steady_clock::now();
  const core::Rig& rig = scan.rig();
  for (core::Stream s : {core::Stream::kRgb, core::Stream::kThermal}) {
    const bool camera = s == core::Stream::kRgb ? rig.rgb.has_value() : rig.thermal.has_value();
    if (!camera || scan.NumFrames(s) == 0) {
      const std::string name = core::StreamName(s);
      throw core::InputError(scan.folder(), "no " + name + " stream (" + name + ".txt with frames and cameras." + name +
                                                " in the rig): latency calibration needs depth, rgb and thermal");
    }
  }
  int total = 0;
  for (core::Stream s : core::kAllStreams) total += scan.NumFrames(s) + std::min(scan.NumFrames(s), options.background_frames);
  LatencyResult result;
  int base = 0;
  for (core::Stream s : core::kAllStreams) {
    BlobTrack& track = s == core::Stream::kDepth ? result.depth_track : s == core::Stream::kRgb ? result.rgb_track : result.thermal_track;
    track = TrackBlob(scan, s, options, progress, base, total);
    base += scan.NumFrames(s) + std::min(scan.NumFrames(s), options.background_frames);
  }
  for (const BlobTrack* t : {&result.depth_track, &result.rgb_track, &result.thermal_track}) {
    const std::string name = core::StreamName(t->stream);
    const int found = t->frames - t->missing;
    if (found < options.min_valid_fraction * t->frames || found < 10) {
      throw core::InputError(scan.folder(),
                             StringPrintf("no moving blob in enough %s frames: found in %d of %d (need %.0f%% and at least "
                                          "10); is something moving in front of a still background?",
                                          name.c_str(), found, t->frames, 100 * options.min_valid_fraction));
    }
    if (t->motion_px < options.min_motion_px) {
      throw core::InputError(scan.folder(), StringPrintf("the blob barely moves in %s: %.2f px RMS along its motion "
                                                         "axis (need >= %g px); wave the object wider",
                                                         name.c_str(), t->motion_px, options.min_motion_px));
    }
  }
  result.motion_axis = PrincipalAxis(result.depth_track.direction).first;
  auto signal_of = [&](const BlobTrack& t) {
    LatencySignal s;
    s.name = core::StreamName(t.stream);
    s.time_s = t.time_s;
    s.period_s = core::MedianPeriod(t.time_s);
    double sum = 0, sum2 = 0;
    int n = 0;
    for (const Eigen::Vector2d& d : t.direction) {
      const double v = d.allFinite() ? result.motion_axis.dot(d) : kNaN;
      s.value.push_back(v);
      if (std::isfinite(v)) sum += v, sum2 += v * v, ++n;
    }
    const double mean = sum / n, sd = std::sqrt(std::max(1e-300, sum2 / n - mean * mean));
    for (double& v : s.value) v = (v - mean) / sd;
    return s;
  };
  result.depth_signal = signal_of(result.depth_track);
  result.rgb_signal = signal_of(result.rgb_track);
  result.thermal_signal = signal_of(result.thermal_track);
  result.rgb = EstimatePairOffset(result.depth_signal, result.rgb_signal, options, scan.folder());
  result.thermal = EstimatePairOffset(result.depth_signal, result.thermal_signal, options, scan.folder());
  result.thermal_rgb = EstimatePairOffset(result.rgb_signal, result.thermal_signal, options, scan.folder());
  result.closure_s = result.thermal_rgb.offset_s - (result.thermal.offset_s - result.rgb.offset_s);
  result.closure_sigma_s = std::sqrt(result.rgb.sigma_s * result.rgb.sigma_s + result.thermal.sigma_s * result.thermal.sigma_s +
                                     result.thermal_rgb.sigma_s * result.thermal_rgb.sigma_s);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace hw::calibrate
