#pragma once

// Sub-pixel sides of a square seen in an image (a square_grid hole, square_grid.h) from
// intensity profiles across its sides. Not for an aprilgrid tag's black square: its border
// is an eighth of the tag, 2-3 px on 20 px tags, and the slopes of a blurred narrow bar push
// each other apart (on the small aprilgrid session the steepest points moved the corners
// 0.34 px outwards, RMS 0.47 px, against libapriltag's own 0.31 / 0.36 px).

#include <array>

#include <opencv2/core.hpp>

namespace hw::calibrate {

// Where on a profile across a square's side the edge is placed.
enum class EdgeLocator {
  // The steepest point (derivative-of-Gaussian peak): the step itself. Levels beside it (a
  // background heated near a mask's plate, seen through the hole with a parallax that
  // changes with the view) move it only by their own slope, the mid-level by their height
  // (a 30 % pedestal falling off over 2 px: 0.15 px against 0.26 px, edge_profiles_test;
  // on the fixtures' masks 0.05 against 0.09 px, square_grid_test). Where a hole's side wall shows it lands between the
  // wall's two steps. For solvers that estimate the apparent shape (the intrinsics'
  // target-shape model, mrcal_problem.h).
  kSteepest,
  // The crossing of the mid-level between the profile's ends (5 px each side on large
  // squares): the outline between the background and what is not background, a hole's walls
  // counted as plate when their level is nearer the plate's. For solvers that model that
  // outline geometrically (the target extrinsics' visible hole corners, hole_corner.h).
  kMidLevel,
};

struct EdgeProfileOptions {
  EdgeLocator edge = EdgeLocator::kSteepest;
  // kSteepest: scale of the derivative-of-Gaussian, pixels (SquareGridOptions::Check:
  // [0.3, 3]). Above the half pixel over which bilinear sampling's slope is constant, below
  // the 2 px between a hole's edge and its neighbours' on the smallest holes detected;
  // 0.8 px measured best of 0.8 / 1.0 / 1.5 on the small and full thermal sessions
  // (README). Larger suits noisier images.
  double edge_sigma_px = 0.8;
};

// Intersection of the lines (p1, direction d1) and (p2, d2); false when parallel.
bool IntersectLines(const cv::Point2d& p1, const cv::Point2d& d1, const cv::Point2d& p2, const cv::Point2d& d2,
                    cv::Point2d* out);

// Bilinear sample of a CV_32F image at (x, y), pixels (centre of the top-left pixel at 0, 0),
// clamped to the border.
double SampleBilinear(const cv::Mat& f, double x, double y);

// Refines `corners` (a convex quad, consecutive corners joined by the sides; pixels) of a
// square around `centre` in `f` (CV_32F, intensities scaled so that the square's contrast is
// of order 1: a profile needs 0.05 between its ends). Along each side, profiles across it
// from 20 % to 80 % of its length every 0.5 px, ±30 % of its length (2–5 px) each way,
// sampled every 0.1 px; an edge point per profile as options.edge says (kSteepest: of the
// slope's peaks of the ends' sign and at least half the strongest, the one nearest the current side,
// sub-sample by a parabola; kMidLevel: the mid-level crossing nearest the current side); a
// line through a side's edge points (Huber), intersected with its neighbours' lines.
// Returns false and leaves `corners` as they were when a side has fewer than 3 edge points,
// two sides are parallel or a corner would move more than max(2 px, 30 % of its distance
// from the centre).
bool RefineSquareCorners(const cv::Mat& f, const EdgeProfileOptions& options, const cv::Point2d& centre,
                         std::array<cv::Point2d, 4>& corners);

}  // namespace hw::calibrate
