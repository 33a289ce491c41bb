#pragma once

// Trajectory accuracy as the TUM RGB-D benchmark measures it (Sturm et al. 2012):
// absolute trajectory error after a rigid alignment and relative pose error over a time
// interval, poses associated by timestamp.

#include <cstddef>
#include <string>
#include <vector>

#include "core/trajectory.h"
#include "core/transform.h"

namespace hw::reconstruct {

struct TrajectoryEvalOptions {
  // Poses of the two trajectories are paired when their timestamps differ by at most this
  // (s), greedily by smallest difference, each pose used once (TUM's associate.py). > 0.
  double max_time_difference_s = 0.02;
  // RPE: pose pairs delta_s apart (s), > 0. Pair i is matched with the associated pair j
  // whose estimated timestamp is closest to t_i + rpe_delta_s, provided it lies within
  // max(max_time_difference_s, half the median spacing of the associated pairs) of it: a
  // regularly sampled trajectory always finds its partner, a gap (lost tracking, the end
  // of the trajectory) gives no pair rather than one over a much shorter interval.
  double rpe_delta_s = 1.0;

  std::string Check() const;
};

// Statistics of a set of errors as TUM's scripts print them: std is the population
// standard deviation (numpy's default), median the mean of the two middle values for an
// even count. All zero when count == 0.
struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;
  int count = 0;
};

// The statistics of `errors` (any order; taken by value to sort a copy).
ErrorStats ComputeErrorStats(std::vector<double> errors);

// One associated pose pair: indices into estimated.poses() and groundtruth.poses().
struct PosePair {
  size_t estimated_index = 0;
  size_t groundtruth_index = 0;
};

// TUM's associate.py on two sorted trajectories: every (estimated, groundtruth) pose pair
// whose timestamps differ by at most max_time_difference_s (s) is a candidate; candidates
// are taken greedily by smallest |dt| (ties: earlier groundtruth, then earlier estimated
// time, as the script's tuple sort), each pose used at most once. Returned in increasing
// estimated time. Timestamps are compared as given (both on the same clock). The limit is
// inclusive (the script's is strict: they differ only for a |dt| exactly at the limit).
// Memory O(poses) whatever the limit (a lazy heap, not the script's list of all candidates).
std::vector<PosePair> AssociatePoses(const core::Trajectory& estimated,
                                     const core::Trajectory& groundtruth,
                                     double max_time_difference_s);

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
// associate or their positions do not determine a rotation (all collinear). Asserts
// options.Check() is empty.
//
// ATE: |groundtruth_i.t - groundtruth_from_estimate * estimated_i.t| over the associated
// pairs (evaluate_ate.py). RPE (Sturm et al. 2012, eq. 1): for pairs i, j ~rpe_delta_s
// apart, E = (gt_i^-1 gt_j)^-1 (est_i^-1 est_j); rpe_m is |translation(E)|, rpe_deg its
// rotation angle. No pairs rpe_delta_s apart (a trajectory shorter than that) leaves the
// RPE stats at count 0. This is the paper's definition; TUM's evaluate_rpe.py computes
// (est_i^-1 est_j)(gt_i^-1 gt_j)^-1 instead: the same angle, but a translation that also
// holds the relative rotation error times the distance travelled (|t_A - R_A R_B^T t_B|
// rather than |t_A - t_B| for A = est_i^-1 est_j, B = gt_i^-1 gt_j), so the two agree
// exactly only when the relative rotations do. The paper's form is kept because its
// translation is purely the difference of the two relative translations.
TrajectoryEval EvaluateTrajectory(const core::Trajectory& estimated,
                                  const core::Trajectory& groundtruth,
                                  const TrajectoryEvalOptions& options);

// Umeyama's closed form: the rigid transform target_from_source (no scale) minimising the
// sum of squared distances |target_i − T source_i|². Asserts equal sizes >= 3. For
// collinear points the rotation about their line is arbitrary (one of the minimisers).
core::Rigid3d AlignPoints(const std::vector<Eigen::Vector3d>& source,
                          const std::vector<Eigen::Vector3d>& target);

}  // namespace hw::reconstruct
