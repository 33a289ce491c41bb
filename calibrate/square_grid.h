#pragma once

// Detector of the square_grid target (a heated mask: square holes cut in a plate in front
// of a background at another temperature, Vidas et al. 2012) in thermal images.
//
// Orientation (the grid is symmetric: 2-fold, or 4-fold when rows == cols, so the image
// alone cannot tell which hole is hole 0): the target frame's x axis is taken as the hole
// edge direction that points most to the image's right, y as the other edge direction,
// pointing down. Views must therefore hold the target within ±45° of upright (roll about the
// line of sight); a hand-held target is never upside down in calibration practice, and the
// fixtures' sessions roll it by at most 20° (fixtures/target_views.h, max_roll_deg). With
// rows != cols a view rolled by 90° is rejected (its hole spans do not fit the grid).
//
// Partial views: when the holes found do not span the whole grid (a hand or clamp over some
// of them), their place in the grid is the one whose predicted missing holes are not seen as
// plate (the plate's margin shows where the grid ends); a view where that stays ambiguous is
// rejected.

#include <string>

#include <opencv2/core.hpp>

#include "calibrate/detection.h"
#include "calibrate/edge_profiles.h"
#include "core/rig.h"

namespace hw::calibrate {

struct SquareGridOptions {
  // Sub-pixel refinement of the corners: lines fitted to edge points on intensity profiles
  // across each side of each hole instead of to the thresholded contour's pixels (shifted
  // half a pixel outwards). Measured in square_grid_test.cc and intrinsics_truth_test.cc
  // (README, *Calibration bench*).
  bool refine = true;
  // Where on a side's profile the edge is, and the scale of kSteepest (edge_profiles.h).
  EdgeLocator edge = EdgeLocator::kSteepest;
  double edge_sigma_px = 0.8;  // pixels, [0.3, 3]
  // A view whose corners fit the best homography from the target plane worse (RMS, pixels)
  // is rejected: a wrong order or a bad corner. (0, 50]. Lens distortion adds to it.
  double max_homography_rms_px = 2.0;
  // Smallest hole blob considered, pixels², [1, 1e6].
  double min_hole_area_px = 12;
  std::string Check() const;
};

// Finds the target's holes (either polarity: holes warmer or colder than the plate) in a
// single-channel image of any depth (CV_8U, CV_16U raw counts with their own range, CV_32F
// °C, ...): the image is contrast-normalised first (robust percentiles) and thresholded
// against its local mean (so low contrast, vignetting and blur are tolerated). Returns a
// Detection with the 4 corners of every hole placed in the grid (partial views accepted),
// ids per core::TargetCorners (hole-major, TL TR BR BL seen from the front), pixels in
// OpenCV's convention (centre of the top-left pixel at (0, 0)), the corners sorted by id.
// accepted = false with a reason when fewer than half the holes are found, their place in
// the grid is ambiguous or the homography check fails (once the holes are placed in the
// grid, a rejected view still returns their corners and homography_rms_px). Throws
// std::invalid_argument when `target` is not a valid square_grid, the image is empty or not
// single-channel, or options.Check() is not "".
Detection DetectSquareGrid(const cv::Mat& image, const core::Target& target,
                           const SquareGridOptions& options = {},
                           const std::string& view_name = "");

}  // namespace hw::calibrate
