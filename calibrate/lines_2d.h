#pragma once

// 2D line segments of thermal images, for the targetless thermal↔depth extrinsics
// (calibrate/extrinsics_targetless.h).
//
// A straight 3D edge images as a curve through a distorting lens, so segments are detected
// in the image RECTIFIED to a pinhole camera with the model's fx fy cx cy (Rectifier): a
// straight edge is then a straight segment and its projection needs K only. The apparent
// temperatures (core::Scan::LoadThermal) are mapped to 8 bits between robust percentiles
// of the frame (no fixed temperature span: a scene of 20–22 °C and one of 10–60 °C both
// fill the range) by contrast-limited histogram equalisation (faint wall-to-wall edges
// next to a radiator stay visible; noise is amplified at most max_gain times), then OpenCV's LSD (Grompone von Gioi et al., an a-contrario detector:
// no gradient threshold to tune) finds the segments; segments shorter than a fraction of
// the image diagonal and those touching pixels the rectification has no source for are
// dropped.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/camera.h"

namespace hw::calibrate {

// A 2D segment, pixels of the rectified image.
struct Segment2d {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  double Length() const { return (b - a).norm(); }
};

// Resampling of a camera's images to the pinhole camera with its fx fy cx cy and size.
class Rectifier {
 public:
  explicit Rectifier(const core::CameraModel& camera);
  // The rectified pinhole camera.
  const core::CameraModel& pinhole() const { return pinhole_; }
  // Bilinear resampling of a single-channel image of the camera (borders replicated).
  cv::Mat Apply(const cv::Mat& image) const;
  // CV_8U: 255 where the rectified pixel has a source inside the original image.
  const cv::Mat& valid() const { return valid_; }

 private:
  core::CameraModel pinhole_;
  cv::Mat map_x_, map_y_, valid_;
};

struct ImageLineOptions {
  double low_percentile = 1;    // temperature mapped to 0, percentile of the frame, [0, 50)
  double high_percentile = 99;  // mapped to 255, percentile, (low_percentile, 100]
  // Contrast-limited equalisation between the percentiles: the mapping's slope is at most
  // max_gain × the linear stretch's (1: the linear stretch), >= 1.
  double max_gain = 4;
  double min_span_c = 0.5;      // a frame spanning less (°C) is stretched over this span, > 0
  double lsd_scale = 1.0;       // LSD's image scale, (0, 1]: 1 keeps the full resolution
  double lsd_sigma_scale = 0.6; // LSD's Gaussian σ = sigma_scale / scale, > 0
  double min_length_fraction = 0.06;  // shortest segment, fraction of the image diagonal, (0, 1)
  int border_px = 2;            // drop segments within this of an invalid pixel, px, >= 0
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// The 8-bit contrast-limited equalisation of an apparent-temperature image (CV_32FC1 °C) between its percentiles
// (pixels where `valid` is 0 are ignored; `valid` may be empty).
cv::Mat StretchThermal(const cv::Mat& apparent_c, const cv::Mat& valid, const ImageLineOptions& options);

// The segments of an 8-bit image (CV_8UC1); `valid` as above. Asserts options.Check().
std::vector<Segment2d> DetectImageLines(const cv::Mat& image_8u, const cv::Mat& valid,
                                        const ImageLineOptions& options);

}  // namespace hw::calibrate
