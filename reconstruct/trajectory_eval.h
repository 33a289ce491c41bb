#pragma once

// Trajectory accuracy as the TUM RGB-D benchmark measures it (Sturm et al. 2012):
// absolute trajectory error after a rigid alignment and relative pose error over a time
// interval, poses associated by timestamp.

#include <string>
#include <vector>

#include "core/trajectory.h"
#include "core/transform.h"

namespace hw::reconstruct {

struct TrajectoryEvalOptions {
  // Poses of the two trajectories are paired when their timestamps differ by at most this
  // (s), greedily by smallest difference, each pose used once (TUM's associate.py). > 0.
  double max_time_difference_s = 0.02;
  // RPE: pose pairs delta_s apart (s), > 0.
  double rpe_delta_s = 1.0;

  std::string Check() const;
};

struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;
  int count = 0;
};

struct TrajectoryEval {
  int estimated_poses = 0, groundtruth_poses = 0;
  int associated_pairs = 0;
  // groundtruth_from_estimate: the rigid transform (no scale) that best maps estimated
  // positions onto the associated true ones (Horn / Umeyama, least squares).
  core::Rigid3d groundtruth_from_estimate;
  ErrorStats ate_m;         // translational error after alignment, m
  ErrorStats rpe_m;         // relative translational error over rpe_delta_s, m
  ErrorStats rpe_deg;       // relative rotational error over rpe_delta_s, degrees
};

// Associates, aligns and measures. Throws std::invalid_argument when fewer than 3 pairs
// associate or their positions do not determine a rotation (all collinear).
TrajectoryEval EvaluateTrajectory(const core::Trajectory& estimated,
                                  const core::Trajectory& groundtruth,
                                  const TrajectoryEvalOptions& options);

// Umeyama's closed form: the rigid transform target_from_source (no scale) minimising the
// sum of squared distances |target_i − T source_i|². Asserts equal sizes >= 3.
core::Rigid3d AlignPoints(const std::vector<Eigen::Vector3d>& source,
                          const std::vector<Eigen::Vector3d>& target);

}  // namespace hw::reconstruct
