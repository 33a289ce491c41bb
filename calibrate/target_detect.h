#pragma once

// Detectors of the printed calibration targets (chessboard, aprilgrid) and the check every
// detector's result goes through (CheckDetection). Corner ids, the TARGET frame and the
// boards' orientation are those of core::TargetCorners (figures in
// fixtures/calibration_targets.h); pixels are in OpenCV's convention (the centre of the
// top-left pixel at (0, 0)).

#include <string>

#include <opencv2/core.hpp>

#include "calibrate/detection.h"
#include "core/rig.h"

namespace hw::calibrate {

struct BoardDetectOptions {
  // Chessboard only: accept a board partly out of view or hidden. Its corners are numbered
  // from the board edges that show (an edge shows when beyond the outer ring of squares
  // the white margin shows): a partial board needs a visible edge along each axis along
  // which it is incomplete, else it is rejected (its ids would be a guess).
  bool partial = true;
  // Largest RMS residual, pixels, of the corners to the best target-plane homography,
  // (0, 50]: lens distortion leaves ~0.1-1 px on a good view; a wrong order leaves squares.
  double max_homography_rms_px = 2.0;
  std::string Check() const;  // "" or "field: must be ..., got ..."
};

// Fewest corners a detector accepts (or all of a smaller target): a homography has 8
// degrees of freedom, so with fewer corners its residual checks little.
inline constexpr int kMinDetectedCorners = 8;

// The chessboard `target` (type chessboard, target.Check() == "") in `image` (8-bit grey,
// 8-bit 3-channel taken as RGB, or 16-bit / float of any channel count, normalised min-max
// to 8 bits first; a corner's saddle point does not move under a monotonic tone curve, so
// no linearisation), with cv::findChessboardCornersSB (NORMALIZE_IMAGE, EXHAUSTIVE,
// ACCURACY; with options.partial a failed full-board search is followed by one with
// CALIB_CB_LARGER from 3x3 corners to find the largest visible part), its corners refined
// with cv::cornerSubPix (window adapted to the square size; on the fixtures' sessions
// 0.066 px RMS against 0.104 px for findChessboardCornersSB alone). Cost: ~0.1 s per
// 320x240 image, 0.2-0.6 s per 640x480 one (ACCURACY upsamples).
// Orientation: the corner order OpenCV returns is normalised to core::TargetCorners: the
// grid is made right-handed as seen from the front (mirrored orders are flipped), then of
// the rotations that fit the board (0°, 180°; 90°, 270° on square boards) those are kept
// whose square colours match the print (square (i, j) black when i + j is even, the
// top-left square black) and whose placement agrees with the visible board edges. When
// more than one remains — the full board with rows + cols even is symmetric under 180°
// (e.g. the 5x7 board), a square one also under 90° — the one closest to upright wins:
// the board's +x axis (along its rows) closest to the image's +x axis. A board held upside
// down is therefore numbered from its (then) top-left corner, consistently over a session
// as long as it is not rolled by more than 90° from upright.
// Returns the detection after CheckDetection(target, options.max_homography_rms_px,
// min(kMinDetectedCorners, all corners)); accepted == false with a reason when no board is
// found, a partial board cannot be numbered or the check fails. width_px / height_px and
// view = view_name are always set. Asserts options.Check() and target.Check() are "" and
// the type is chessboard.
Detection DetectChessboard(const cv::Mat& image, const core::Target& target,
                           const BoardDetectOptions& options = {}, const std::string& view_name = "");

// The aprilgrid `target` (family tag36h11) in `image`, with libapriltag (no decimation,
// edge refinement on). The detection runs in LINEAR light: an 8-bit image (grey, or
// 3-channel taken as RGB) is taken as sRGB-encoded (what cameras store) and decoded first
// — on the encoded image libapriltag's thresholded quads shrink towards the black squares
// of blurred tags: on the full intrinsics-aprilgrid session (640x480) the corners move
// 0.46 px inwards along the tag diagonals in sRGB light, 0.19 px outwards in linear light
// (RMS 0.52 against 0.23 px; target_detect_test.cc); 16-bit and float images are taken
// as linear and normalised min-max to 8 bits. Corners: ids 4·tag_id + k, k in
// libapriltag's order (core::TargetCorners), moved from libapriltag's pixel convention
// (centres at +0.5, AprilRobotics/apriltag#121) to OpenCV's. Tags whose id is outside the
// grid are ignored; a tag id seen twice is dropped (either may be a misread). Then
// CheckDetection as DetectChessboard. Asserts as DetectChessboard, with type aprilgrid
// and family tag36h11.
Detection DetectAprilGrid(const cv::Mat& image, const core::Target& target,
                          const BoardDetectOptions& options = {}, const std::string& view_name = "");

// The check every detector's result goes through: at least `min_corners` corners (and 4),
// pixels and ids of equal size, ids in [0, |TargetCorners(target)|) and unique, and the RMS
// residual (pixels) of the corners to the homography target plane → image fitted to all of
// them (cv::findHomography, least squares, no RANSAC) at most `max_rms_px`. Fills
// detection.homography_rms_px (NaN when it cannot be computed), accepted and reason (""
// when accepted; otherwise names the failed test and its numbers, e.g. "homography RMS
// 12.3 px > 2 px: ..."). Asserts target.Check() == "".
void CheckDetection(const core::Target& target, double max_rms_px, int min_corners,
                    Detection& detection);

}  // namespace hw::calibrate
