#pragma once

// Targetless thermal↔depth extrinsics (issue 13), after Moghadam, Bosse & Zlot, "Line-based
// extrinsic calibration of range and image sensors" (ICRA 2013): straight 3D edges of the
// depth frames (plane folds and occlusion boundaries, calibrate/lines_3d.h) must project onto
// straight 2D edges of the thermal images (calibrate/lines_2d.h); depth_from_thermal is
// found by robust 2D–3D line alignment over many frames (calibrate/line_alignment.h).
//
// Frames: every `frame_step`-th thermal frame is paired with the depth frame nearest in time
// on the depth clock (t_depth_clock = t_thermal + rig thermal time_offset_s). With a
// world_from_depth trajectory (e.g. `heatwave reconstruct`'s trajectory.txt), the depth
// frame's 3D lines are moved to the depth camera's pose at the thermal frame's time:
//   depth(t_thermal)_from_depth(t_depth) = world_from_depth(t_thermal)⁻¹ · world_from_depth(t_depth);
// without one, only pairs closer than max_pair_dt_s are used as they are (the motion in
// between is an error the robust solve must absorb; it biases the result on a fast path).
//
// The rig of the scan supplies the depth and thermal intrinsics, the thermal time offset
// and the starting depth_from_thermal; calibrate intrinsics and latency first.

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "calibrate/extrinsics.h"
#include "calibrate/line_alignment.h"
#include "calibrate/lines_2d.h"
#include "calibrate/lines_3d.h"
#include "core/scan.h"
#include "core/trajectory.h"

namespace hw::calibrate {

struct TargetlessOptions {
  DepthLineOptions depth_lines;
  ImageLineOptions image_lines;
  LineAlignmentOptions alignment;
  bool use_fold_lines = true;       // use the planes' intersection lines
  bool use_occlusion_lines = true;  // use the occlusion boundaries (foreground side)
  int frame_step = 1;              // use every n-th thermal frame, >= 1
  int max_frames = 400;            // at most this many thermal frames, evenly spread, >= 1
  double max_pair_dt_s = 0.010;    // without trajectory: largest |t_depth − t_thermal|, s, > 0
  double max_trajectory_gap_s = 0.2;  // trajectory poses further apart are a gap, s, > 0
  int num_threads = 0;             // line extraction threads, >= 0; 0: hardware concurrency
  // "" when valid, else a message naming the field (with its sub-struct), value and constraint.
  std::string Check() const;
};

// Per used thermal frame.
struct TargetlessFrameStats {
  int thermal_index = 0;
  int depth_index = 0;
  double dt_s = 0;       // t_depth − t_thermal, depth clock, s
  int lines_3d = 0;
  int lines_2d = 0;
  int matches = 0;       // in the final association
};

struct TargetlessResult {
  ExtrinsicsEstimate estimate;  // camera "thermal", residual_unit "px" (rectified thermal image)
  std::vector<TargetlessFrameStats> frames;
  int matches = 0;
  double inlier_fraction = 0;
  double robust_sigma_px = 0;
  double edge_offset_px = 0;        // estimated occlusion edge offset (LineAlignmentOptions), depth px
  double edge_offset_sigma_px = 0;
  std::vector<double> cost_per_iteration;
  std::vector<int> matches_per_iteration;
  bool used_trajectory = false;
  core::Rigid3d initial_depth_from_thermal;  // the rig's, the starting point
  // For DrawTargetlessDiagnostic: the lines of every used frame (rectified image).
  std::vector<LineFrame> line_frames;
  core::CameraModel rectified_thermal;
};

using TargetlessProgressFn = std::function<void(int done, int total)>;

// Estimates depth_from_thermal. Throws core::InputError naming the scan folder when the scan
// has no thermal camera or frames, no thermal frame pairs with a depth frame (or lies on the
// trajectory), or the lines do not determine the pose: too few matches, or a direction of
// the pose unobservable (all lines parallel...) — never a made-up number. Frame decoding
// errors propagate (InputError naming the file). Asserts options.Check() is empty.
TargetlessResult EstimateTargetlessExtrinsics(const core::Scan& scan,
                                              const std::optional<core::Trajectory>& world_from_depth,
                                              const TargetlessOptions& options,
                                              const TargetlessProgressFn& progress = nullptr);

// A diagnostic image of used frame `frame` (index into result.frames): the rectified thermal
// image (grey), its 2D segments (yellow), the 3D lines projected with the starting estimate
// (red) and the final one (green); matched 2D segments thicker. CV_8UC3 BGR, scaled up by
// `zoom` (>= 1).
cv::Mat DrawTargetlessDiagnostic(const core::Scan& scan, const TargetlessResult& result, int frame,
                                 const TargetlessOptions& options, int zoom = 3);

}  // namespace hw::calibrate
