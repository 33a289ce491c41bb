#include "reconstruct/trajectory_eval.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <queue>
#include <stdexcept>
#include <tuple>

#include "core/strings.h"

namespace hw::reconstruct {

namespace {

// The rotation about the line through collinear positions is undetermined: the cross-
// covariance then has rank 1. Its second singular value relative to the first is ~1e-16 for
// exactly collinear points in double; a real trajectory along a rail with 1 mm noise over
// 1 m still gives ~1e-3, so 1e-10 only rejects what is degenerate to rounding.
constexpr double kDegenerateSingularValueRatio = 1e-10;

struct Alignment {
  core::Rigid3d target_from_source;
  Eigen::Vector3d singular_values;  // of the cross-covariance, decreasing
};

Alignment Align(const std::vector<Eigen::Vector3d>& source,
                const std::vector<Eigen::Vector3d>& target) {
  assert(source.size() == target.size() && source.size() >= 3);
  const double n = static_cast<double>(source.size());
  Eigen::Vector3d source_mean = Eigen::Vector3d::Zero(), target_mean = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < source.size(); ++i) {
    source_mean += source[i];
    target_mean += target[i];
  }
  source_mean /= n;
  target_mean /= n;
  // Cross-covariance sum (target_i - mean)(source_i - mean)^T; R = U S V^T maximises
  // trace(R^T W) (Umeyama 1991, eq. 39-40), S flips the last axis when U V^T would be a
  // reflection.
  Eigen::Matrix3d w = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < source.size(); ++i) {
    w += (target[i] - target_mean) * (source[i] - source_mean).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(w, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) s(2) = -1;
  const Eigen::Matrix3d rotation = svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
  Alignment result;
  result.target_from_source =
      core::Rigid3d(Eigen::Quaterniond(rotation), target_mean - rotation * source_mean);
  result.singular_values = svd.singularValues();
  return result;
}

std::string Span(const core::Trajectory& trajectory) {
  if (trajectory.empty()) return "no poses";
  return core::StringPrintf("%zu poses over [%.6f, %.6f] s", trajectory.size(),
                            trajectory.StartTime(), trajectory.EndTime());
}

// The associated pair whose estimated time is closest to t (the earlier one on a tie).
size_t ClosestIndex(const std::vector<double>& times_s, double t) {
  assert(!times_s.empty());
  const auto after = std::lower_bound(times_s.begin(), times_s.end(), t);
  if (after == times_s.begin()) return 0;
  if (after == times_s.end()) return times_s.size() - 1;
  const size_t j = static_cast<size_t>(after - times_s.begin());
  return (t - times_s[j - 1] <= times_s[j] - t) ? j - 1 : j;
}

}  // namespace

std::string TrajectoryEvalOptions::Check() const {
  if (!(std::isfinite(max_time_difference_s) && max_time_difference_s > 0)) {
    return "max_time_difference_s: must be > 0 s, got " +
           core::StringPrintf("%g", max_time_difference_s);
  }
  if (!(std::isfinite(rpe_delta_s) && rpe_delta_s > 0)) {
    return "rpe_delta_s: must be > 0 s, got " + core::StringPrintf("%g", rpe_delta_s);
  }
  return "";
}

ErrorStats ComputeErrorStats(std::vector<double> errors) {
  ErrorStats stats;
  if (errors.empty()) return stats;
  std::sort(errors.begin(), errors.end());
  const size_t n = errors.size();
  double sum = 0, sum_squares = 0;
  for (const double e : errors) {
    sum += e;
    sum_squares += e * e;
  }
  stats.count = static_cast<int>(n);
  stats.mean = sum / static_cast<double>(n);
  stats.rmse = std::sqrt(sum_squares / static_cast<double>(n));
  // Two-pass variance: sum_squares/n - mean² cancels catastrophically for near-equal errors.
  double sum_deviations = 0;
  for (const double e : errors) sum_deviations += (e - stats.mean) * (e - stats.mean);
  stats.std = std::sqrt(sum_deviations / static_cast<double>(n));
  stats.median = n % 2 == 1 ? errors[n / 2] : 0.5 * (errors[n / 2 - 1] + errors[n / 2]);
  stats.min = errors.front();
  stats.max = errors.back();
  return stats;
}

std::vector<PosePair> AssociatePoses(const core::Trajectory& estimated,
                                     const core::Trajectory& groundtruth,
                                     double max_time_difference_s) {
  assert(max_time_difference_s > 0);
  const std::vector<core::TimedPose>& est = estimated.poses();
  const std::vector<core::TimedPose>& gt = groundtruth.poses();
  // associate.py sorts all candidate pairs by (|dt|, groundtruth stamp, estimated stamp) and
  // takes them in turn: memory in proportion to the candidates, i.e. to max_time_difference_s
  // (10 min at 30 Hz with a 10 s limit: 1e7). The same greedy choice, lazily: each unpaired
  // estimated pose keeps one entry in a heap, its nearest not-yet-known-taken true pose
  // (two pointers walking outwards: increasing |dt|, the earlier pose on a tie). The smallest
  // entry whose true pose is still free is the smallest free candidate overall; an entry whose
  // true pose was taken meanwhile moves on to that pose's next candidate.
  std::vector<double> gt_times_s(gt.size());
  for (size_t j = 0; j < gt.size(); ++j) gt_times_s[j] = gt[j].timestamp_s;
  struct Cursor {
    std::ptrdiff_t left, right;  // next candidates below / at or above the estimated time
  };
  std::vector<Cursor> cursors(est.size());
  struct Entry {
    double dt_s;
    size_t gt, est;
    // std::priority_queue pops the largest: invert for the smallest (dt, gt, est).
    bool operator<(const Entry& o) const {
      return std::tie(dt_s, gt, est) > std::tie(o.dt_s, o.gt, o.est);
    }
  };
  std::vector<char> gt_used(gt.size(), 0);
  // The next candidate of estimated pose i (advancing its cursor), false when none is left.
  const auto next_candidate = [&](size_t i, Entry& entry) {
    Cursor& c = cursors[i];
    const double t = est[i].timestamp_s;
    const auto n = static_cast<std::ptrdiff_t>(gt.size());
    while (c.left >= 0 && gt_used[static_cast<size_t>(c.left)]) --c.left;
    while (c.right < n && gt_used[static_cast<size_t>(c.right)]) ++c.right;
    const double left_dt_s = c.left >= 0 ? t - gt_times_s[static_cast<size_t>(c.left)]
                                         : std::numeric_limits<double>::infinity();
    const double right_dt_s = c.right < n ? gt_times_s[static_cast<size_t>(c.right)] - t
                                          : std::numeric_limits<double>::infinity();
    const bool take_left = left_dt_s <= right_dt_s;
    const double dt_s = take_left ? left_dt_s : right_dt_s;
    if (!(dt_s <= max_time_difference_s)) return false;
    entry = {dt_s, static_cast<size_t>(take_left ? c.left-- : c.right++), i};
    return true;
  };
  std::priority_queue<Entry> heap;
  for (size_t i = 0; i < est.size(); ++i) {
    const auto right = std::lower_bound(gt_times_s.begin(), gt_times_s.end(), est[i].timestamp_s);
    cursors[i].right = right - gt_times_s.begin();
    cursors[i].left = cursors[i].right - 1;
    Entry entry;
    if (next_candidate(i, entry)) heap.push(entry);
  }
  std::vector<PosePair> pairs;
  while (!heap.empty()) {
    const Entry top = heap.top();
    heap.pop();
    if (gt_used[top.gt]) {
      Entry entry;
      if (next_candidate(top.est, entry)) heap.push(entry);
      continue;
    }
    gt_used[top.gt] = 1;
    pairs.push_back({top.est, top.gt});
  }
  std::sort(pairs.begin(), pairs.end(), [](const PosePair& a, const PosePair& b) {
    return a.estimated_index < b.estimated_index;
  });
  return pairs;
}

core::Rigid3d AlignPoints(const std::vector<Eigen::Vector3d>& source,
                          const std::vector<Eigen::Vector3d>& target) {
  return Align(source, target).target_from_source;
}

TrajectoryEval EvaluateTrajectory(const core::Trajectory& estimated,
                                  const core::Trajectory& groundtruth,
                                  const TrajectoryEvalOptions& options) {
  assert(options.Check().empty());
  TrajectoryEval result;
  result.estimated_poses = static_cast<int>(estimated.size());
  result.groundtruth_poses = static_cast<int>(groundtruth.size());
  const std::vector<PosePair> pairs =
      AssociatePoses(estimated, groundtruth, options.max_time_difference_s);
  result.associated_pairs = static_cast<int>(pairs.size());
  if (pairs.size() < 3) {
    throw std::invalid_argument(core::StringPrintf(
        "only %zu pose pair(s) associate within %g s (estimated: %s; ground truth: %s); "
        "at least 3 are needed: are both trajectories on the same clock?",
        pairs.size(), options.max_time_difference_s, Span(estimated).c_str(),
        Span(groundtruth).c_str()));
  }

  // ATE (evaluate_ate.py): align the estimated positions onto the true ones.
  const std::vector<core::TimedPose>& est = estimated.poses();
  const std::vector<core::TimedPose>& gt = groundtruth.poses();
  std::vector<Eigen::Vector3d> est_positions, gt_positions;
  est_positions.reserve(pairs.size());
  gt_positions.reserve(pairs.size());
  for (const PosePair& p : pairs) {
    est_positions.push_back(est[p.estimated_index].world_from_sensor.translation);
    gt_positions.push_back(gt[p.groundtruth_index].world_from_sensor.translation);
  }
  const Alignment alignment = Align(est_positions, gt_positions);
  const Eigen::Vector3d& sv = alignment.singular_values;
  if (!(sv(0) > 0) || sv(1) <= kDegenerateSingularValueRatio * sv(0)) {
    throw std::invalid_argument(core::StringPrintf(
        "the positions of the %zu associated poses are collinear or coincide: they do not "
        "determine the alignment's rotation",
        pairs.size()));
  }
  result.groundtruth_from_estimate = alignment.target_from_source;
  std::vector<double> ate_m(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    ate_m[k] = (gt_positions[k] - result.groundtruth_from_estimate * est_positions[k]).norm();
  }
  result.ate_m = ComputeErrorStats(std::move(ate_m));

  // RPE over rpe_delta_s between associated pairs (by estimated time).
  std::vector<double> times_s(pairs.size()), spacings_s;
  for (size_t k = 0; k < pairs.size(); ++k) times_s[k] = est[pairs[k].estimated_index].timestamp_s;
  spacings_s.reserve(pairs.size() - 1);
  for (size_t k = 1; k < pairs.size(); ++k) spacings_s.push_back(times_s[k] - times_s[k - 1]);
  const double tolerance_s =
      std::max(options.max_time_difference_s, 0.5 * ComputeErrorStats(spacings_s).median);
  std::vector<double> rpe_m, rpe_deg;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const double target_s = times_s[i] + options.rpe_delta_s;
    const size_t j = ClosestIndex(times_s, target_s);
    if (j <= i || std::abs(times_s[j] - target_s) > tolerance_s) continue;
    const core::Rigid3d& gt_i = gt[pairs[i].groundtruth_index].world_from_sensor;
    const core::Rigid3d& gt_j = gt[pairs[j].groundtruth_index].world_from_sensor;
    const core::Rigid3d& est_i = est[pairs[i].estimated_index].world_from_sensor;
    const core::Rigid3d& est_j = est[pairs[j].estimated_index].world_from_sensor;
    const core::Rigid3d error = (gt_i.Inverse() * gt_j).Inverse() * (est_i.Inverse() * est_j);
    rpe_m.push_back(error.TranslationNorm());
    rpe_deg.push_back(error.RotationAngle() * 180.0 / std::numbers::pi);
  }
  result.rpe_m = ComputeErrorStats(std::move(rpe_m));
  result.rpe_deg = ComputeErrorStats(std::move(rpe_deg));
  return result;
}

}  // namespace hw::reconstruct
