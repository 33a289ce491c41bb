#include "calibrate/latency.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <random>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/option_check.h"
#include "core/radiometry.h"
#include "core/strings.h"

namespace hw::calibrate {
namespace {

using core::OptionFail;
using core::StringPrintf;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------
// Frames as linear contrast images

// Converts a stream's frames to one-channel CV_32F images linear in the light a pixel
// integrates (NaN: no measurement), so that a blurred blob's weighted centroid is the
// centroid of its sharp positions over the exposure.
class FrameConverter {
 public:
  FrameConverter(const core::Scan& scan, core::Stream stream) : scan_(scan), stream_(stream) {
    for (int v = 0; v < 256; ++v) {
      const double s = v / 255.0;
      srgb_to_linear_[static_cast<size_t>(v)] =
          static_cast<float>(s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4));
    }
    if (stream == core::Stream::kThermal) {
      const auto& band = scan.rig().thermal_settings->spectral_band_um;
      band_ = std::make_unique<core::BandRadiance>(band[0], band[1]);
      // Band radiance tabulated every 0.05 K over the range of any indoor or process scene.
      for (int k = 0; k < kTableSize; ++k) {
        radiance_table_.push_back(band_->Radiance(core::CelsiusToKelvin(kTableMinC + k * kTableStepC)));
      }
    }
  }

  cv::Mat Load(int i) const {
    cv::Mat out;
    if (stream_ == core::Stream::kDepth) {
      out = scan_.LoadDepth(i);
      out.setTo(std::numeric_limits<float>::quiet_NaN(), out <= 0);
    } else if (stream_ == core::Stream::kRgb) {
      const cv::Mat rgb = scan_.LoadRgb(i);
      out.create(rgb.size(), CV_32F);
      for (int y = 0; y < rgb.rows; ++y) {
        const cv::Vec3b* in = rgb.ptr<cv::Vec3b>(y);
        float* o = out.ptr<float>(y);
        for (int x = 0; x < rgb.cols; ++x) {  // Rec. 709 luma of linear RGB
          o[x] = 0.2126f * srgb_to_linear_[in[x][0]] + 0.7152f * srgb_to_linear_[in[x][1]] +
                 0.0722f * srgb_to_linear_[in[x][2]];
        }
      }
    } else {
      out = scan_.LoadThermal(i);
      for (int y = 0; y < out.rows; ++y) {
        float* p = out.ptr<float>(y);
        for (int x = 0; x < out.cols; ++x) p[x] = static_cast<float>(Radiance(p[x]));
      }
    }
    return out;
  }

 private:
  static constexpr double kTableMinC = -60, kTableStepC = 0.05;
  static constexpr int kTableSize = 32001;  // to 1540 °C

  double Radiance(double apparent_c) const {
    const double u = (apparent_c - kTableMinC) / kTableStepC;
    if (!(u >= 0 && u < kTableSize - 1)) return band_->Radiance(core::CelsiusToKelvin(apparent_c));
    const int k = static_cast<int>(u);
    const double f = u - k;
    return (1 - f) * radiance_table_[static_cast<size_t>(k)] + f * radiance_table_[static_cast<size_t>(k) + 1];
  }

  const core::Scan& scan_;
  core::Stream stream_;
  std::array<float, 256> srgb_to_linear_{};
  std::unique_ptr<core::BandRadiance> band_;
  std::vector<double> radiance_table_;
};

// Per-pixel median over `frames` of the valid (finite) values; NaN where fewer than half
// of them are valid (a pixel mostly without measurement has no background).
cv::Mat MedianBackground(const std::vector<cv::Mat>& frames) {
  const int rows = frames.front().rows, cols = frames.front().cols;
  const size_t k = frames.size();
  cv::Mat background(rows, cols, CV_32F);
  std::vector<float> values(k);
  for (int y = 0; y < rows; ++y) {
    for (int x = 0; x < cols; ++x) {
      size_t n = 0;
      for (const cv::Mat& f : frames) {
        const float v = f.at<float>(y, x);
        if (std::isfinite(v)) values[n++] = v;
      }
      float median = std::numeric_limits<float>::quiet_NaN();
      if (2 * n >= k && n > 0) {
        std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(n / 2), values.begin() + static_cast<std::ptrdiff_t>(n));
        median = values[n / 2];
      }
      background.at<float>(y, x) = median;
    }
  }
  return background;
}

// A connected foreground component of one frame, with its contrast-weighted centroid.
struct Candidate {
  Eigen::Vector2d centroid_px;
  double area_px = 0;
};

// The candidate blobs of one frame (largest first, at most 4) and the frame's noise σ.
struct FrameBlobs {
  std::vector<Candidate> candidates;
  double noise = kNaN;
};

FrameBlobs FindBlobs(const cv::Mat& frame, const cv::Mat& background, const LatencyOptions& options,
                     double noise_floor) {
  FrameBlobs out;
  cv::Mat diff = frame - background;  // NaN where either is
  // Robust noise: MAD of the difference over a pixel subsample (the blob is a minority).
  std::vector<float> sample;
  sample.reserve(static_cast<size_t>(diff.total() / 3 + 1));
  for (int y = 0; y < diff.rows; y += 2) {
    const float* d = diff.ptr<float>(y);
    for (int x = y % 4 / 2; x < diff.cols; x += 2) {
      if (std::isfinite(d[x])) sample.push_back(d[x]);
    }
  }
  if (sample.size() < 16) return out;
  auto median_of = [](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return static_cast<double>(v[v.size() / 2]);
  };
  const double centre = median_of(sample);
  for (float& v : sample) v = std::abs(v - static_cast<float>(centre));
  out.noise = 1.4826 * median_of(sample);
  const double threshold = options.threshold_sigmas * std::max(out.noise, noise_floor);

  cv::Mat mask(diff.size(), CV_8U);
  for (int y = 0; y < diff.rows; ++y) {
    const float* d = diff.ptr<float>(y);
    uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < diff.cols; ++x) m[x] = std::isfinite(d[x]) && std::abs(static_cast<double>(d[x]) - centre) > threshold ? 255 : 0;
  }
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  std::vector<int> order;
  for (int c = 1; c < n; ++c) {
    const int x = stats.at<int>(c, cv::CC_STAT_LEFT), y = stats.at<int>(c, cv::CC_STAT_TOP);
    const int w = stats.at<int>(c, cv::CC_STAT_WIDTH), h = stats.at<int>(c, cv::CC_STAT_HEIGHT);
    // A blob cut by the image border has a truncated centroid: not a measurement.
    if (x == 0 || y == 0 || x + w == diff.cols || y + h == diff.rows) continue;
    if (stats.at<int>(c, cv::CC_STAT_AREA) < options.min_blob_px) continue;
    order.push_back(c);
  }
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return stats.at<int>(a, cv::CC_STAT_AREA) > stats.at<int>(b, cv::CC_STAT_AREA); });
  if (order.size() > 4) order.resize(4);
  const int r = options.dilate_px;
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1));
  for (int c : order) {
    const cv::Rect box = cv::Rect(stats.at<int>(c, cv::CC_STAT_LEFT) - r, stats.at<int>(c, cv::CC_STAT_TOP) - r,
                                  stats.at<int>(c, cv::CC_STAT_WIDTH) + 2 * r, stats.at<int>(c, cv::CC_STAT_HEIGHT) + 2 * r) &
                         cv::Rect(0, 0, diff.cols, diff.rows);
    cv::Mat own = labels(box) == c, region;
    cv::dilate(own, region, kernel);
    // Polarity of the blob (hot / cold, dark / light, near / far), then the signed contrast
    // as weight: noise around the blob averages out instead of biasing the centroid.
    double sum = 0;
    for (int y = 0; y < box.height; ++y) {
      for (int x = 0; x < box.width; ++x) {
        if (own.at<uint8_t>(y, x)) sum += static_cast<double>(diff.at<float>(box.y + y, box.x + x)) - centre;
      }
    }
    const double polarity = sum >= 0 ? 1 : -1;
    double w_sum = 0, wx = 0, wy = 0;
    for (int y = 0; y < box.height; ++y) {
      for (int x = 0; x < box.width; ++x) {
        const float d = diff.at<float>(box.y + y, box.x + x);
        if (!region.at<uint8_t>(y, x) || !std::isfinite(d)) continue;
        const double w = polarity * (static_cast<double>(d) - centre);
        w_sum += w;
        wx += w * (box.x + x);
        wy += w * (box.y + y);
      }
    }
    if (!(w_sum > 0)) continue;
    out.candidates.push_back({Eigen::Vector2d(wx / w_sum, wy / w_sum), static_cast<double>(stats.at<int>(c, cv::CC_STAT_AREA))});
  }
  return out;
}

// The contrast below which a difference is never foreground, whatever the measured noise
// (a noise-free synthetic or heavily quantised stream): 5 mm, 0.002 linear luma, 0.02 K.
double NoiseFloor(const core::Scan& scan, core::Stream stream) {
  if (stream == core::Stream::kDepth) return 0.005;
  if (stream == core::Stream::kRgb) return 0.002;
  const auto& band = scan.rig().thermal_settings->spectral_band_um;
  return 0.02 * core::BandRadiance(band[0], band[1]).Derivative(core::CelsiusToKelvin(25));
}

// Principal axis (unit) and RMS spread along it of the finite points.
std::pair<Eigen::Vector2d, double> PrincipalAxis(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  int n = 0;
  for (const auto& p : points) {
    if (p.allFinite()) mean += p, ++n;
  }
  if (n < 2) return {Eigen::Vector2d::UnitX(), 0};
  mean /= n;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : points) {
    if (p.allFinite()) cov += (p - mean) * (p - mean).transpose();
  }
  cov /= n;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  Eigen::Vector2d axis = eig.eigenvectors().col(1);
  // One sign for every camera of the rig (they look the same way): the dominant
  // component positive.
  if ((std::abs(axis.x()) >= std::abs(axis.y()) ? axis.x() : axis.y()) < 0) axis = -axis;
  return {axis, std::sqrt(std::max(0.0, eig.eigenvalues()(1)))};
}

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

BlobTrack TrackBlob(const core::Scan& scan, core::Stream stream, const LatencyOptions& options,
                    const LatencyProgressFn& progress, int progress_base, int progress_total) {
  assert(options.Check().empty());
  const int n = scan.NumFrames(stream);
  assert(n > 0);
  const FrameConverter converter(scan, stream);
  std::mutex mutex;
  int done = 0;
  auto advance = [&] {
    if (!progress) return;
    const std::lock_guard<std::mutex> lock(mutex);
    progress(progress_base + ++done, progress_total);
  };

  // Frames listed but without a file (Scan warns about them) are missing frames.
  std::vector<int> present;
  for (int i = 0; i < n; ++i) {
    if (scan.FrameExists(stream, i)) present.push_back(i);
  }
  if (present.empty()) {
    throw core::InputError(scan.folder(), "no frame file of the " + core::StreamName(stream) + " stream exists");
  }
  // Background: the median of evenly spaced frames.
  const int m = static_cast<int>(present.size());
  const int k = std::min(m, options.background_frames);
  std::vector<cv::Mat> sample(static_cast<size_t>(k));
  cv::parallel_for_(cv::Range(0, k), [&](const cv::Range& range) {
    for (int j = range.start; j < range.end; ++j) {
      const int p = k == 1 ? 0 : static_cast<int>(std::lround(static_cast<double>(j) * (m - 1) / (k - 1)));
      sample[static_cast<size_t>(j)] = converter.Load(present[static_cast<size_t>(p)]);
      advance();
    }
  });
  const cv::Mat background = MedianBackground(sample);
  sample.clear();

  // Candidates per frame (in parallel), then the track (in order).
  const double floor = NoiseFloor(scan, stream);
  std::vector<FrameBlobs> blobs(static_cast<size_t>(n));
  cv::parallel_for_(cv::Range(0, n), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      if (scan.FrameExists(stream, i)) blobs[static_cast<size_t>(i)] = FindBlobs(converter.Load(i), background, options, floor);
      advance();
    }
  });

  BlobTrack track;
  track.stream = stream;
  track.frames = n;
  track.time_s = scan.Timestamps(stream);
  const Eigen::Vector2d missing(kNaN, kNaN);
  track.centroid_px.assign(static_cast<size_t>(n), missing);
  track.direction.assign(static_cast<size_t>(n), missing);
  track.area_px.assign(static_cast<size_t>(n), 0);
  std::vector<double> noises;
  std::optional<Eigen::Vector2d> previous;
  for (size_t i = 0; i < blobs.size(); ++i) {
    if (std::isfinite(blobs[i].noise)) noises.push_back(blobs[i].noise);
    const std::vector<Candidate>& c = blobs[i].candidates;
    if (c.empty()) continue;
    // The largest blob, unless one nearly as large continues the track.
    size_t best = 0;
    if (previous) {
      double nearest = (c[0].centroid_px - *previous).norm();
      for (size_t j = 1; j < c.size(); ++j) {
        const double d = (c[j].centroid_px - *previous).norm();
        if (c[j].area_px >= 0.3 * c[0].area_px && d < nearest) best = j, nearest = d;
      }
    }
    track.centroid_px[i] = c[best].centroid_px;
    track.area_px[i] = c[best].area_px;
    previous = c[best].centroid_px;
  }
  // A blob far from the track's typical size is something else (a hand, a passer-by, the
  // object half out of view): missing.
  std::vector<double> areas;
  for (double a : track.area_px) {
    if (a > 0) areas.push_back(a);
  }
  if (!areas.empty()) {
    std::nth_element(areas.begin(), areas.begin() + static_cast<std::ptrdiff_t>(areas.size() / 2), areas.end());
    const double median_area = areas[areas.size() / 2];
    for (size_t i = 0; i < track.area_px.size(); ++i) {
      if (track.area_px[i] > 0 && (track.area_px[i] > 3 * median_area || track.area_px[i] < median_area / 3)) {
        track.area_px[i] = 0;
        track.centroid_px[i] = missing;
      }
    }
  }
  if (!noises.empty()) {
    std::nth_element(noises.begin(), noises.begin() + static_cast<std::ptrdiff_t>(noises.size() / 2), noises.end());
    track.noise = noises[noises.size() / 2];
  }

  // Directions in the depth camera's orientation: every stream's motion on one axis.
  const core::Rig& rig = scan.rig();
  const core::CameraModel& camera = stream == core::Stream::kDepth ? rig.depth
                                    : stream == core::Stream::kRgb ? *rig.rgb
                                                                   : *rig.thermal;
  const Eigen::Quaterniond depth_from_camera = stream == core::Stream::kDepth ? Eigen::Quaterniond::Identity()
                                               : stream == core::Stream::kRgb ? rig.depth_from_rgb.rotation
                                                                              : rig.depth_from_thermal.rotation;
  for (size_t i = 0; i < track.centroid_px.size(); ++i) {
    if (!track.centroid_px[i].allFinite()) {
      ++track.missing;
      continue;
    }
    const std::optional<Eigen::Vector3d> ray = camera.Unproject(track.centroid_px[i]);
    if (!ray) {
      ++track.missing;
      track.centroid_px[i] = missing;
      continue;
    }
    const Eigen::Vector3d r = depth_from_camera * *ray;
    track.direction[i] = r.head<2>() / r.z();
  }
  track.motion_px = PrincipalAxis(track.centroid_px).second;
  return track;
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
  // that separates it from the main peak by at least 0.02.
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
    if (c[j] - dip >= 0.02 && c[j] > out.second_peak_correlation) out.second_peak_correlation = c[j], second_at = out.curve_offset_s[j];
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
