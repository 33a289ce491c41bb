#pragma once

// The calibration bench's diagnostic images, the pictures mrcal's tools show: the
// detections drawn on an image, the residual vector field, the residual histogram, and the
// projection uncertainty map. 8-bit BGR images (cv::Mat CV_8UC3), to be written as PNG.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "calibrate/detection.h"

namespace hw::calibrate {

// `image` (one channel, any depth: stretched between its 1st and 99th percentiles) with
// the detection drawn: every corner a small cross, its id beside it every `label_every`
// corners, the first corner of the target circled (it shows the orientation the detector
// chose), the view's verdict in the top-left corner. Upscaled ×2 below 640 px wide
// (thermal images).
cv::Mat DrawDetection(const cv::Mat& image, const Detection& detection, int label_every = 4);

// All views' residuals (observed − projected, px) as arrows from their corners, `scale`
// times longer, on a width × height canvas (× 2 below 640 px wide); outliers red, inliers
// coloured by view; a scale bar "1 px".
cv::Mat DrawResidualField(int width_px, int height_px, const std::vector<std::vector<Eigen::Vector2d>>& corners_px,
                          const std::vector<std::vector<Eigen::Vector2d>>& residuals_px,
                          const std::vector<std::vector<bool>>& outlier, double scale);

// Histogram of the inlier residual coordinates (x and y pooled, px) with the normal density
// of standard deviation `sigma_px` over it; 640 × 400.
cv::Mat DrawResidualHistogram(const std::vector<std::vector<Eigen::Vector2d>>& residuals_px,
                              const std::vector<std::vector<bool>>& outlier, double sigma_px);

// The projection uncertainty (px, 1σ) given on a grid_cols × grid_rows grid over a
// width × height image (row-major), colour-mapped (turbo, 0 to max_px) at the image's size
// (× 2 below 640 px), each cell's value printed, with a colour key.
cv::Mat DrawUncertaintyMap(int width_px, int height_px, const std::vector<double>& uncertainty_px, int grid_cols,
                           int grid_rows, double max_px, const std::string& title);

}  // namespace hw::calibrate
