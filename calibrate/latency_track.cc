// Blob tracks of the latency calibration (calibrate/latency.h): frames as linear contrast
// images, the median background, the foreground blobs and their tracks.
#include "calibrate/latency.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/radiometry.h"

namespace hw::calibrate {
namespace {

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

}  // namespace

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

}  // namespace hw::calibrate
