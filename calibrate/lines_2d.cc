#include "calibrate/lines_2d.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/option_check.h"

namespace hw::calibrate {

Rectifier::Rectifier(const core::CameraModel& camera) {
  pinhole_ = core::CameraModel::Pinhole(camera.width, camera.height, camera.fx, camera.fy);
  pinhole_.cx = camera.cx;
  pinhole_.cy = camera.cy;
  map_x_.create(camera.height, camera.width, CV_32FC1);
  map_y_.create(camera.height, camera.width, CV_32FC1);
  valid_ = cv::Mat::zeros(camera.height, camera.width, CV_8UC1);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      const Eigen::Vector2d src = camera.Project(ray);
      map_x_.at<float>(v, u) = static_cast<float>(src.x());
      map_y_.at<float>(v, u) = static_cast<float>(src.y());
      if (src.allFinite() && camera.IsInImage(src)) valid_.at<uint8_t>(v, u) = 255;
    }
  }
}

cv::Mat Rectifier::Apply(const cv::Mat& image) const {
  cv::Mat out;
  cv::remap(image, out, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

std::string ImageLineOptions::Check() const {
  using core::OptionFail;
  if (!(low_percentile >= 0 && low_percentile < 50)) return OptionFail("low_percentile", low_percentile, "in [0, 50)");
  if (!(high_percentile > low_percentile && high_percentile <= 100)) {
    return OptionFail("high_percentile", high_percentile, "in (low_percentile, 100]");
  }
  if (!(max_gain >= 1)) return OptionFail("max_gain", max_gain, ">= 1");
  if (!(min_span_c > 0)) return OptionFail("min_span_c", min_span_c, "> 0 °C");
  if (!(lsd_scale > 0 && lsd_scale <= 1)) return OptionFail("lsd_scale", lsd_scale, "in (0, 1]");
  if (!(lsd_sigma_scale > 0)) return OptionFail("lsd_sigma_scale", lsd_sigma_scale, "> 0");
  if (!(min_length_fraction > 0 && min_length_fraction < 1)) {
    return OptionFail("min_length_fraction", min_length_fraction, "in (0, 1)");
  }
  if (border_px < 0) return OptionFail("border_px", border_px, ">= 0 px");
  return "";
}

cv::Mat StretchThermal(const cv::Mat& apparent_c, const cv::Mat& valid, const ImageLineOptions& options) {
  assert(apparent_c.type() == CV_32FC1);
  std::vector<float> values;
  values.reserve(apparent_c.total());
  for (int v = 0; v < apparent_c.rows; ++v) {
    for (int u = 0; u < apparent_c.cols; ++u) {
      if (!valid.empty() && !valid.at<uint8_t>(v, u)) continue;
      values.push_back(apparent_c.at<float>(v, u));
    }
  }
  cv::Mat out = cv::Mat::zeros(apparent_c.size(), CV_8UC1);
  if (values.empty()) return out;
  auto percentile = [&](double p) {
    const size_t k = std::min(values.size() - 1, static_cast<size_t>(p / 100.0 * (values.size() - 1) + 0.5));
    std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
    return static_cast<double>(values[k]);
  };
  double lo = percentile(options.low_percentile);
  double hi = percentile(options.high_percentile);
  if (hi - lo < options.min_span_c) {
    const double mid = 0.5 * (lo + hi);
    lo = mid - 0.5 * options.min_span_c;
    hi = mid + 0.5 * options.min_span_c;
  }
  // Contrast-limited equalisation over [lo, hi] (global CLAHE): the mapping's slope follows
  // the histogram, so the temperature levels covering much of the image (a room's walls)
  // get the contrast a radiator would take in a linear stretch, but never more than
  // max_gain × the linear slope, so that a uniform region's noise is not blown up.
  constexpr int kBins = 256;
  std::vector<double> histogram(kBins, 0.0);
  for (const float x : values) {
    histogram[std::clamp(static_cast<int>((static_cast<double>(x) - lo) / (hi - lo) * kBins), 0, kBins - 1)] += 1;
  }
  const double limit = options.max_gain * static_cast<double>(values.size()) / kBins;
  double excess = 0;
  for (double& h : histogram) excess += std::max(0.0, h - limit), h = std::min(h, limit);
  std::vector<double> lut(kBins + 1, 0.0);
  double cumulative = 0;
  for (int b = 0; b < kBins; ++b) {
    cumulative += histogram[b] + excess / kBins;
    lut[b + 1] = 255.0 * cumulative / static_cast<double>(values.size());
  }
  for (int v = 0; v < apparent_c.rows; ++v) {
    for (int u = 0; u < apparent_c.cols; ++u) {
      // Piecewise linear between bin edges.
      const double x = std::clamp((static_cast<double>(apparent_c.at<float>(v, u)) - lo) / (hi - lo) * kBins, 0.0, static_cast<double>(kBins) - 1e-9);
      const int b = static_cast<int>(x);
      const double f = x - b;
      out.at<uint8_t>(v, u) = cv::saturate_cast<uint8_t>((1 - f) * lut[b] + f * lut[b + 1]);
    }
  }
  return out;
}

std::vector<Segment2d> DetectImageLines(const cv::Mat& image_8u, const cv::Mat& valid,
                                        const ImageLineOptions& options) {
  assert(options.Check().empty());
  assert(image_8u.type() == CV_8UC1);
  const cv::Ptr<cv::LineSegmentDetector> lsd =
      cv::createLineSegmentDetector(cv::LSD_REFINE_STD, options.lsd_scale, options.lsd_sigma_scale);
  std::vector<cv::Vec4f> lines;
  lsd->detect(image_8u, lines);
  cv::Mat invalid_near;
  if (!valid.empty() && options.border_px > 0) {
    cv::Mat invalid;
    cv::bitwise_not(valid, invalid);
    cv::dilate(invalid, invalid_near, cv::Mat::ones(2 * options.border_px + 1, 2 * options.border_px + 1, CV_8UC1));
  }
  const double min_len = options.min_length_fraction * std::hypot(image_8u.cols, image_8u.rows);
  std::vector<Segment2d> segments;
  for (const cv::Vec4f& l : lines) {
    Segment2d s;
    s.a = Eigen::Vector2d(l[0], l[1]);
    s.b = Eigen::Vector2d(l[2], l[3]);
    if (s.Length() < min_len) continue;
    bool ok = true;
    if (!invalid_near.empty()) {
      for (int k = 0; k <= 10 && ok; ++k) {
        const Eigen::Vector2d p = s.a + (s.b - s.a) * (k / 10.0);
        const int u = std::clamp(static_cast<int>(std::lround(p.x())), 0, image_8u.cols - 1);
        const int v = std::clamp(static_cast<int>(std::lround(p.y())), 0, image_8u.rows - 1);
        ok = !invalid_near.at<uint8_t>(v, u);
      }
    }
    if (ok) segments.push_back(s);
  }
  return segments;
}

}  // namespace hw::calibrate
