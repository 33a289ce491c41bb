#pragma once

// A calibration target found in one image — the common currency of the detectors
// (square_grid, chessboard, aprilgrid) and the solvers.

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hw::calibrate {

struct Detection {
  std::string view;            // the image's file or frame name, for messages
  int width_px = 0;            // image size, pixels
  int height_px = 0;
  // The corners found: ids index core::TargetCorners(target); pixels are in heatwave's
  // (OpenCV's) convention, the centre of the top-left pixel at (0, 0). Same sizes.
  std::vector<int> corner_ids;
  std::vector<Eigen::Vector2d> pixels;
  // RMS distance, pixels, of the corners to the best homography from the target plane:
  // lens distortion makes it nonzero on a good detection; a wrong corner order makes it
  // large. NaN before it is computed.
  double homography_rms_px = std::numeric_limits<double>::quiet_NaN();
  bool accepted = false;
  std::string reason;  // why the view was rejected ("" when accepted)
};

}  // namespace hw::calibrate
