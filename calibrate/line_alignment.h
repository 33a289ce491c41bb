#pragma once

// The 2D–3D line alignment of the targetless extrinsics (calibrate/extrinsics_targetless.h):
// depth_from_thermal such that the depth frames' 3D segments project onto the thermal
// images' 2D segments, over many frames, ICP-like:
//
//   repeat (outer iterations):
//     associate: each 3D segment, put in the thermal frame by the current estimate and
//       projected (pinhole K of the rectified thermal image), with the 2D segment of its
//       frame nearest to it among those within the gates: direction within gate_deg,
//       both ends of the overlap within the distance gate (gate_mrad × f, shrinking from
//       initial_gate_mrad to final_gate_mrad), overlap at least min_overlap of the 2D
//       segment. Each 2D segment keeps its best 3D segment only.
//     solve (Ceres): two residuals per match — the signed distances (px) of the 3D points
//       projecting onto the two ends of the overlap to the 2D segment's line — over the
//       rotation (unit quaternion, Ceres's EigenQuaternionManifold, whose update
//       Exp(δ) · q is a rotation applied on the LEFT, in the depth frame) and translation of
//       depth_from_thermal, with a Huber loss whose scale is loss_sigmas × the robust σ
//       (MAD) of the previous iteration's residuals; with estimate_edge_offset, also one
//       offset (depth px) of every occlusion line across itself (Segment3d::
//       edge_shift_per_px), marginalised out of the covariance.
//   until the update is below 1e-3° and 1e-3 mm or max_iterations.
//
// Covariance, in ExtrinsicsEstimate's parameterisation [ω; δt]: the sandwich
// H⁻¹ (Σ_c g_c g_cᵀ) H⁻¹ (H = Σ w JᵀJ, g_c = Σ_{i∈c} w Jᵀ r over cluster c) with the
// clusters groups of cluster_frames consecutive frames, so that errors shared by the
// residuals of one line and by consecutive frames of one edge (the same edge's depth noise
// and thermal blur) count once per cluster, not once per residual; and never below the
// classic s² H⁻¹ × 2 (two residuals per match share the match's line); then multiplied by
// sigma_inflation² for the systematic errors no residual statistic shows (see there).
//
// Degeneracy: when the information H has a direction with a σ above max_sigma_deg /
// max_sigma_mm (e.g. all lines parallel: the translation along them is unobservable), the
// result is a failure naming that direction, not a number.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "calibrate/extrinsics.h"
#include "calibrate/lines_2d.h"
#include "calibrate/lines_3d.h"
#include "core/camera.h"
#include "core/transform.h"

namespace hw::calibrate {

// One thermal frame's lines: the 3D segments in the depth frame AT THE THERMAL FRAME'S TIME
// (metres) and the 2D segments of the rectified thermal image (pixels).
struct LineFrame {
  int thermal_index = -1;       // frame of the thermal stream (for diagnostics)
  std::vector<Segment3d> lines_3d;
  std::vector<Segment2d> lines_2d;
};

struct LineAlignmentOptions {
  int max_iterations = 12;          // outer (associate + solve) iterations, [1, 100]
  double initial_gate_mrad = 30;    // first distance gate, mrad of view (px / f), > 0
  double final_gate_mrad = 6;       // last distance gate, mrad, (0, initial_gate_mrad]
  double gate_deg = 4;              // direction gate, deg, (0, 45]
  double min_overlap = 0.5;         // overlap of a match, fraction of the 2D segment, (0, 1]
  double loss_sigmas = 2.0;         // Huber scale, robust σ of the residuals, > 0
  // Estimate, with the pose, one offset (depth pixels) of every occlusion line across
  // itself towards the background: how far the sensor's depth edges sit from the true
  // outlines (structured light fattens the foreground; no fixed value fits every sensor).
  // Only when occlusion lines give at least 2 min_matches residuals.
  bool estimate_edge_offset = true;
  int cluster_frames = 10;          // frames per cluster of the covariance, >= 1
  // Factor on the σ of the result, >= 1: the sandwich covariance sees only what the
  // residuals show, not the edges' systematic errors shared by every frame seeing them
  // (bolometer lag and blur of thermal edges, depth edge quantisation, a line's plane fit).
  // MEASURED on the fixtures' small extrinsics-targetless sessions (seeds 1–3): the error was
  // 1.0–7.3 sandwich σ, so 3 makes it ≤ 2.5 σ; revisit when the solver models those errors.
  double sigma_inflation = 3.0;
  int min_matches = 20;             // fewer matches: failure, >= 6
  // Larger σ (from the residuals, before sigma_inflation) of a rotation / translation
  // direction: degenerate. deg, mm, > 0.
  double max_sigma_deg = 1.0;
  double max_sigma_mm = 20.0;
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// One match of the last association.
struct LineMatch {
  int frame = 0;     // index into the frames vector
  int line_3d = 0;   // index into frames[frame].lines_3d
  int line_2d = 0;   // index into frames[frame].lines_2d
  double weight = 1; // robust weight of the last solve, [0, 1]
};

struct LineAlignmentResult {
  // Empty on success; else why no estimate could be made (too few matches, the unobservable
  // direction), and estimate holds the last iterate without a covariance.
  std::string failure;
  ExtrinsicsEstimate estimate;  // camera "thermal", residual_unit "px"
  std::vector<LineMatch> matches;
  double inlier_fraction = 0;       // matches with |r| within the Huber scale
  std::vector<double> cost_per_iteration;  // final Ceres cost (½ Σ ρ(r²)) of each outer iteration
  std::vector<int> matches_per_iteration;
  double robust_sigma_px = 0;       // MAD σ of the final residuals
  double edge_offset_px = 0;        // estimated occlusion edge offset, depth px (0: not estimated)
  double edge_offset_sigma_px = 0;  // its 1σ, depth px (0: not estimated)
  Matrix6d information = Matrix6d::Zero();  // H in [ω; δt]
};

// Aligns; `camera` is the rectified pinhole thermal camera the 2D segments are in.
// Asserts options.Check() is empty.
LineAlignmentResult AlignLines(const std::vector<LineFrame>& frames, const core::CameraModel& camera,
                               const core::Rigid3d& initial_depth_from_thermal,
                               const LineAlignmentOptions& options);

// The projection of a 3D segment (depth frame) into the thermal pinhole camera, clipped to
// z >= 0.05 m; false when nothing is in front.
bool ProjectSegment(const Segment3d& line, const core::Rigid3d& depth_from_thermal,
                    const core::CameraModel& camera, Eigen::Vector2d* a_px, Eigen::Vector2d* b_px);

}  // namespace hw::calibrate
