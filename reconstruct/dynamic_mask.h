#pragma once

// Depth that moved in front of the model: people walking by, a hand, a door swinging. After a
// frame is tracked, a depth pixel whose point lies nearer than the model's surface along the
// model view's ray (by more than a margin) stands in space the model saw empty: the surface
// behind it was seen through that space by the frames fused before. A sparse TSDF keeps no
// free space away from surfaces, so integrating such a point would start a new surface at
// once (its blocks are fresh), and the next frames would track against the person instead of
// the room (measured: a 31 °C passer crossing a 4 s `equipment` scan dragged the tracked
// pose 2.6 m along with them, every frame reported tracked). Masked pixels are not
// integrated; surfaces nobody saw before (no model surface behind) are integrated as usual.
//
// What it does not do: remove a person already fused (they entered over unseen space, or
// stood still in the first frames); and a static object first seen in front of surface seen
// before, but never itself, stays masked while the surface behind it is in the model view
// (an object that was in view when the surface behind it was is in the model already).

#include "core/transform.h"
#include "reconstruct/camera_maps.h"

#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace hw::reconstruct {

struct DynamicMaskOptions {
  // A pixel is masked when its depth along the model view's ray is short of the model's by
  // more than max(margin_m, margin_fraction · depth): above the depth noise, a structured-
  // light sensor's uncalibrated distortion (2–6 cm at 2–3.5 m on the fixtures, 1–3 % of range
  // on real units) and the model's silhouettes a pixel off. m, >= 0; 0 with fraction 0: off.
  double margin_m = 0.1;
  double margin_fraction = 0.05;  // of the pixel's depth, [0, 1)

  bool enabled() const { return margin_m > 0 || margin_fraction > 0; }
  std::string Check() const;  // names the field, value and constraint
};

// Sets to 0 (no measurement) the pixels of depth_m (CV_32FC1 metres, camera `camera` at
// world_from_depth) that lie in front of `model` (a raycast, world-frame points, seen by
// model_camera at world_from_model) as above — in front of the nearest model surface of the
// 3×3 model pixels around the point's projection, so that a silhouette's rim a pixel off is
// not taken for a person — and returns how many. Pixels whose point falls outside the model
// view (or on its border), behind its camera, or next to a model pixel without a surface are
// kept.
// num_threads: row bands (0: hardware concurrency). Asserts sizes and types.
int MaskInFrontOfModel(cv::Mat& depth_m, const PinholeCamera& camera, const core::Rigid3d& world_from_depth,
                       const PointMap& model, const PinholeCamera& model_camera,
                       const core::Rigid3d& world_from_model, const DynamicMaskOptions& options,
                       int num_threads = 0);

// The points of `model` (a raycast seen from world_from_model; world frame) that the depth
// frame saw through: projected into depth_m (camera at world_from_depth), every pixel within
// one of the projection measured a surface farther than the point by more than
// max(margin_m, margin_fraction · that depth). Something fused there has left (the model view
// still shows a person who walked on): TsdfVolume::CarveFreeSpace fades it. Points near a
// silhouette of the depth frame (a neighbour nearer, or without a measurement) are not
// returned, so that rims of thin objects a pixel off are not carved. num_threads as above.
std::vector<Eigen::Vector3f> ModelSeenThrough(const cv::Mat& depth_m, const PinholeCamera& camera,
                                              const core::Rigid3d& world_from_depth, const PointMap& model,
                                              const DynamicMaskOptions& options, int num_threads = 0);

// How much a depth frame at a pose contradicts a model view: its pixels standing in front of
// the model's surface (MaskInFrontOfModel) and the model's points it sees through
// (ModelSeenThrough), each over what could be compared. At the right pose in a static scene
// both are near 0 (edges, noise beyond the margins); at a wrong pose that ICP still converged
// on (a relocalisation one part over along a row of alike parts, a wall slid along) the live
// depth crosses space the model saw empty — measured: 0–2 % at tracked poses on the 160×120
// test scans, under 0.01 % on a full-size sweep, 5–9 % at relocalisations 0.25 m off.
struct ModelConflict {
  int in_front = 0;       // depth pixels in front of the model's surface
  int depth_pixels = 0;   // depth pixels with a measurement
  int seen_through = 0;   // model points the depth saw through
  int model_points = 0;   // model points with a surface
  // in_front / depth_pixels + seen_through / model_points (0 when nothing to compare).
  double Fraction() const;
};
// Both counts for the depth frame (CV_32FC1 metres, `camera` at world_from_depth) against
// `model` (a raycast at world_from_model through model_camera), with the margins of
// `options` (off: all zero but the totals). Leaves depth_m unchanged. Asserts as above.
ModelConflict MeasureModelConflict(const cv::Mat& depth_m, const PinholeCamera& camera,
                                   const core::Rigid3d& world_from_depth, const PointMap& model,
                                   const PinholeCamera& model_camera, const core::Rigid3d& world_from_model,
                                   const DynamicMaskOptions& options, int num_threads = 0);

namespace internal {

// Whether std::lround(x) (halves away from zero) lies in [lo, hi), lo >= 0, and then it in
// `index`, without the libm call (two per depth pixel were a third of the mask's time).
// NaN and infinities are outside. Exact: for 0 <= x < 2²³, x − trunc(x) is exact.
inline bool RoundedIndex(float x, int lo, int hi, int& index) {
  const bool above_lo = lo == 0 ? x > -0.5f : x >= static_cast<float>(lo) - 0.5f;
  if (!(above_lo && x < static_cast<float>(hi) - 0.5f)) return false;
  const int i = static_cast<int>(x);  // towards zero: 0 for x in (−0.5, 0)
  index = x - static_cast<float>(i) >= 0.5f ? i + 1 : i;
  return true;
}

}  // namespace internal

}  // namespace hw::reconstruct
