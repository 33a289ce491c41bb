#include "reconstruct/trajectory_eval.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace hw::reconstruct {
namespace {

using core::Rigid3d;
using core::Trajectory;
using ::testing::HasSubstr;

constexpr double kPi = std::numbers::pi;

Rigid3d RandomRigid(std::mt19937& rng, double max_translation_m) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix<double, 6, 1> xi;
  for (int k = 0; k < 3; ++k) xi(k) = u(rng) * 1.5;  // up to ~150° rotations
  for (int k = 3; k < 6; ++k) xi(k) = u(rng) * max_translation_m;
  return Rigid3d::Exp(xi);
}

Rigid3d RotZ(double angle_rad, const Eigen::Vector3d& t = Eigen::Vector3d::Zero()) {
  return Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ())), t);
}

Rigid3d Translation(double x, double y, double z) {
  return Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, z));
}

// A smooth hand-held-like trajectory: a loop with a slow climb, the camera turning with it.
Rigid3d SmoothPose(double t_s) {
  const double a = 0.8 * t_s;
  const Eigen::Quaterniond q =
      Eigen::AngleAxisd(a, Eigen::Vector3d::UnitY()) *
      Eigen::AngleAxisd(0.2 * std::sin(1.3 * t_s), Eigen::Vector3d::UnitX());
  return Rigid3d(q, Eigen::Vector3d(0.5 * std::cos(a), 0.3 * std::sin(a), 0.1 * t_s));
}

// Poses of SmoothPose at start_s + k / rate_hz, k = 0 .. count - 1.
Trajectory SmoothTrajectory(double start_s, double rate_hz, int count) {
  Trajectory trajectory;
  for (int k = 0; k < count; ++k) {
    const double t = k / rate_hz;
    trajectory.Add(start_s + t, SmoothPose(t));
  }
  return trajectory;
}

// Every pose of `trajectory` mapped into another world frame: other_from_world * pose.
Trajectory Transformed(const Trajectory& trajectory, const Rigid3d& other_from_world) {
  Trajectory out;
  for (const core::TimedPose& p : trajectory.poses()) {
    out.Add(p.timestamp_s, other_from_world * p.world_from_sensor);
  }
  return out;
}

void ExpectSameTransform(const Rigid3d& actual, const Rigid3d& expected, double tolerance) {
  const core::PoseError e = core::ComparePoses(actual, expected);
  EXPECT_LT(e.rotation_rad, tolerance);
  EXPECT_LT(e.translation_m, tolerance);
}

TEST(AlignPoints, RecoversAKnownTransformExactlyWhateverThePointOrder) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Rigid3d target_from_source = RandomRigid(rng, 5.0);
    std::vector<Eigen::Vector3d> source, target;
    for (int i = 0; i < 3 + trial; ++i) {  // from the minimum of 3 points up
      source.emplace_back(u(rng), u(rng), u(rng));
      target.push_back(target_from_source * source.back());
    }
    ExpectSameTransform(AlignPoints(source, target), target_from_source, 1e-9);
    // The same correspondences in another order: the same transform.
    std::vector<size_t> order(source.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    std::vector<Eigen::Vector3d> source_shuffled, target_shuffled;
    for (const size_t i : order) {
      source_shuffled.push_back(source[i]);
      target_shuffled.push_back(target[i]);
    }
    ExpectSameTransform(AlignPoints(source_shuffled, target_shuffled), AlignPoints(source, target),
                        1e-12);
  }
}

TEST(AlignPoints, CoplanarPointsGiveARotationNotAReflection) {
  // For planar points the cross-covariance has rank 2 and U V^T is a reflection for about
  // half the transforms: without Umeyama's sign fix these would come out mirrored.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Rigid3d target_from_source = RandomRigid(rng, 2.0);
    std::vector<Eigen::Vector3d> source, target;
    for (int i = 0; i < 6; ++i) {
      source.emplace_back(u(rng), u(rng), 0.0);
      target.push_back(target_from_source * source.back());
    }
    const Rigid3d aligned = AlignPoints(source, target);
    EXPECT_NEAR(aligned.rotation.toRotationMatrix().determinant(), 1.0, 1e-12);
    ExpectSameTransform(aligned, target_from_source, 1e-9);
  }
}

TEST(ErrorStats, MatchNumpyDefinitions) {
  // numpy: mean 2.5, median (2+3)/2, std (population) sqrt(1.25), rmse sqrt(30/4).
  const ErrorStats s = ComputeErrorStats({4.0, 1.0, 3.0, 2.0});
  EXPECT_EQ(s.count, 4);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_DOUBLE_EQ(ComputeErrorStats({5.0, 1.0, 3.0}).median, 3.0);
  const ErrorStats empty = ComputeErrorStats({});
  EXPECT_EQ(empty.count, 0);
  EXPECT_EQ(empty.rmse, 0.0);
}

TEST(EvaluateTrajectory, RigidlyMovedCopyHasZeroErrorAndRecoversTheTransform) {
  const Trajectory groundtruth = SmoothTrajectory(1305031102.175304, 30.0, 150);
  std::mt19937 rng(3);
  const Rigid3d groundtruth_from_estimate = RandomRigid(rng, 10.0);
  const Trajectory estimated = Transformed(groundtruth, groundtruth_from_estimate.Inverse());
  const TrajectoryEval eval = EvaluateTrajectory(estimated, groundtruth, {});
  EXPECT_EQ(eval.estimated_poses, 150);
  EXPECT_EQ(eval.groundtruth_poses, 150);
  EXPECT_EQ(eval.associated_pairs, 150);
  ExpectSameTransform(eval.groundtruth_from_estimate, groundtruth_from_estimate, 1e-9);
  EXPECT_EQ(eval.ate_m.count, 150);
  EXPECT_LT(eval.ate_m.max, 1e-9);
  EXPECT_LT(eval.ate_m.rmse, 1e-9);
  // Relative poses do not see the world frame: RPE is zero as well. 150 poses at 30 Hz over
  // 4.97 s: poses 0..119 have a partner 1 s (30 poses) later.
  EXPECT_EQ(eval.rpe_m.count, 120);
  EXPECT_LT(eval.rpe_m.max, 1e-9);
  EXPECT_LT(eval.rpe_deg.max, 1e-7);
}

TEST(EvaluateTrajectory, IsotropicPositionNoiseGivesTheExpectedRmse) {
  // Estimated positions = true positions + N(0, sigma² I3), rotations exact, same frame. The
  // alignment fits 6 parameters to 3n residuals, so E[sum of squares] = sigma² (3n - 6)
  // (linear least squares; the 5 mm noise is small against the ~1 m extent) and
  // rmse ≈ sigma sqrt(3 - 6/n). The sum of squares is chi-square with k = 3n - 6 degrees of
  // freedom, so rmse has relative standard deviation sqrt(1 / (2k)) = 0.9% at n = 2000;
  // the tolerance is 4 of those.
  const int n = 2000;
  const double sigma_m = 0.005;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, sigma_m);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  Trajectory groundtruth, estimated;
  for (int k = 0; k < n; ++k) {
    const double t = 10.0 + k * 0.01;
    const Eigen::Quaterniond rotation = RandomRigid(rng, 0.0).rotation;
    const Eigen::Vector3d position(u(rng), u(rng), u(rng));
    groundtruth.Add(t, Rigid3d(rotation, position));
    estimated.Add(
        t, Rigid3d(rotation, position + Eigen::Vector3d(noise(rng), noise(rng), noise(rng))));
  }
  const TrajectoryEval eval = EvaluateTrajectory(estimated, groundtruth, {});
  EXPECT_EQ(eval.associated_pairs, n);
  const double expected_rmse = sigma_m * std::sqrt(3.0 - 6.0 / n);
  const double relative_sd = std::sqrt(1.0 / (2.0 * (3.0 * n - 6.0)));
  EXPECT_NEAR(eval.ate_m.rmse, expected_rmse, 4 * relative_sd * expected_rmse);
  // The mean of a chi(3) distribution is 2 sqrt(2/pi) sigma: same relative tolerance (its
  // relative spread per sample is smaller than the squared error's).
  EXPECT_NEAR(eval.ate_m.mean, 2 * std::sqrt(2 / kPi) * sigma_m,
              4 * relative_sd * 2 * std::sqrt(2 / kPi) * sigma_m);
  // The fitted transform is the identity up to the noise averaged over n points: its
  // translation (the centroid is ~0) has per-axis sd sigma / sqrt(n), its rotation per-axis
  // sd sigma / (sqrt(n) r) with r = 0.41 m the rms distance of the points from an axis
  // through the centroid (uniform in a 1 m cube: sqrt(2 / 12)). A norm of 3 such components
  // exceeds 5 sqrt(3) sd with probability < 1e-5.
  const double position_sd_m = sigma_m / std::sqrt(n);
  EXPECT_LT(eval.groundtruth_from_estimate.TranslationNorm(), 5 * std::sqrt(3) * position_sd_m);
  EXPECT_LT(eval.groundtruth_from_estimate.RotationAngle(),
            5 * std::sqrt(3) * position_sd_m / std::sqrt(2.0 / 12));
}

TEST(AssociatePoses, PairsOffsetJitteredTimesAndSkipsMissingPoses) {
  // Ground truth at 30 Hz on a TUM-like epoch clock (1.3e9 s: 2.4e-7 s resolution), with
  // every 11th pose (k % 11 == 5) missing. The estimate is late by 4 ms ± 3 ms of jitter,
  // every 7th pose missing. |dt| <= 7 ms < 20 ms for the right partner, the next-nearest
  // true pose is >= 26 ms away: a pose whose partner is missing must stay unpaired.
  const double start_s = 1305031102.0;
  const int count = 121;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> jitter(-0.003, 0.003);
  Trajectory groundtruth, estimated;
  std::vector<int> est_k;  // the frame number of each estimated pose
  for (int k = 0; k < count; ++k) {
    const double t = k / 30.0;
    if (k % 11 != 5) groundtruth.Add(start_s + t, SmoothPose(t));
    if (k % 7 != 3) {
      estimated.Add(start_s + t + 0.004 + jitter(rng), SmoothPose(t));
      est_k.push_back(k);
    }
  }
  // Two estimated poses long after the ground truth ends: never paired.
  estimated.Add(start_s + 10, SmoothPose(10));
  estimated.Add(start_s + 11, SmoothPose(11));
  est_k.push_back(-1);
  est_k.push_back(-1);

  const std::vector<PosePair> pairs = AssociatePoses(estimated, groundtruth, 0.02);
  std::set<int> paired_k;
  for (const PosePair& p : pairs) {
    const int k = est_k[p.estimated_index];
    ASSERT_GE(k, 0);
    // The true pose of the same frame.
    EXPECT_NEAR(groundtruth.poses()[p.groundtruth_index].timestamp_s, start_s + k / 30.0, 1e-6);
    paired_k.insert(k);
  }
  std::set<int> expected_k;
  for (int k = 0; k < count; ++k) {
    if (k % 11 != 5 && k % 7 != 3) expected_k.insert(k);
  }
  EXPECT_EQ(paired_k, expected_k);
  EXPECT_EQ(pairs.size(), expected_k.size());
  for (size_t i = 1; i < pairs.size(); ++i) {
    EXPECT_LT(pairs[i - 1].estimated_index, pairs[i].estimated_index);
  }

  // RPE pairs: frames k and k + 30, both associated (a missing partner is not replaced by its
  // neighbour 33 ms away: the tolerance is max(20 ms, half the 33 ms spacing)).
  int expected_rpe_pairs = 0;
  for (const int k : expected_k) expected_rpe_pairs += expected_k.count(k + 30) ? 1 : 0;
  const TrajectoryEval eval = EvaluateTrajectory(estimated, groundtruth, {});
  EXPECT_EQ(eval.associated_pairs, static_cast<int>(expected_k.size()));
  EXPECT_EQ(eval.rpe_m.count, expected_rpe_pairs);
  EXPECT_LT(eval.ate_m.max, 1e-9);  // same poses, only the clocks differ
}

TEST(AssociatePoses, GreedyBySmallestDifferenceLikeAssociatePy) {
  // Binary-exact times. Estimated 0.25 and 0.375 both want true 0.5 (|dt| 0.25 and 0.125):
  // the smaller difference wins it, 0.25 then takes true 0 (|dt| 0.25, within the limit
  // inclusive). A nearest-neighbour search would pair both with 0.5.
  Trajectory groundtruth, estimated;
  groundtruth.Add(0.0, Rigid3d());
  groundtruth.Add(0.5, Rigid3d());
  estimated.Add(0.25, Rigid3d());
  estimated.Add(0.375, Rigid3d());
  std::vector<PosePair> pairs = AssociatePoses(estimated, groundtruth, 0.25);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0].estimated_index, 0u);
  EXPECT_EQ(pairs[0].groundtruth_index, 0u);
  EXPECT_EQ(pairs[1].estimated_index, 1u);
  EXPECT_EQ(pairs[1].groundtruth_index, 1u);
  // Just below the limit: 0.25 stays unpaired.
  pairs = AssociatePoses(estimated, groundtruth, 0.2);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].estimated_index, 1u);

  // A tie (0.125 from both 0 and 0.25) goes to the earlier true pose, as the script's sort
  // of (diff, groundtruth stamp, estimated stamp) tuples does.
  Trajectory tie_gt, tie_est;
  tie_gt.Add(0.0, Rigid3d());
  tie_gt.Add(0.25, Rigid3d());
  tie_est.Add(0.125, Rigid3d());
  pairs = AssociatePoses(tie_est, tie_gt, 0.2);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].groundtruth_index, 0u);
}

// associate.py literally: every pair within the limit, sorted by (|dt|, groundtruth stamp,
// estimated stamp), taken greedily.
std::vector<PosePair> AssociateAllPairs(const Trajectory& estimated, const Trajectory& groundtruth,
                                        double max_time_difference_s) {
  struct Candidate {
    double dt_s;
    size_t gt, est;
  };
  std::vector<Candidate> candidates;
  for (size_t i = 0; i < estimated.size(); ++i) {
    for (size_t j = 0; j < groundtruth.size(); ++j) {
      const double dt_s =
          std::abs(groundtruth.poses()[j].timestamp_s - estimated.poses()[i].timestamp_s);
      if (dt_s <= max_time_difference_s) candidates.push_back({dt_s, j, i});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.dt_s, a.gt, a.est) < std::tie(b.dt_s, b.gt, b.est);
  });
  std::vector<char> est_used(estimated.size(), 0), gt_used(groundtruth.size(), 0);
  std::vector<PosePair> pairs;
  for (const Candidate& c : candidates) {
    if (est_used[c.est] || gt_used[c.gt]) continue;
    est_used[c.est] = gt_used[c.gt] = 1;
    pairs.push_back({c.est, c.gt});
  }
  std::sort(pairs.begin(), pairs.end(), [](const PosePair& a, const PosePair& b) {
    return a.estimated_index < b.estimated_index;
  });
  return pairs;
}

TEST(AssociatePoses, SameAsAllPairsGreedyOnRandomClocks) {
  // Irregular clocks, rates from sparse to dense, limits from below to far above the frame
  // spacing (where one pose has many candidates and the greedy order matters), times on a
  // 1/64 s grid in half the trials so that exact ties occur.
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int pairs_seen = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const bool on_grid = trial % 2 == 0;
    const auto random_clock = [&](int count, double mean_gap_s) {
      Trajectory trajectory;
      double t = 1000.0 + u(rng);
      for (int k = 0; k < count; ++k) {
        double gap = mean_gap_s * 2 * u(rng);
        if (on_grid) gap = std::max(1.0, std::round(gap * 64)) / 64;
        if (on_grid && k == 0) t = std::round(t * 64) / 64;
        t += std::max(gap, 1e-4);
        trajectory.Add(t, Rigid3d());
      }
      return trajectory;
    };
    const Trajectory groundtruth = random_clock(1 + trial % 60, 0.01 + 0.1 * u(rng));
    const Trajectory estimated = random_clock(1 + (trial * 7) % 60, 0.01 + 0.1 * u(rng));
    const double max_dt_s = on_grid ? std::round(1 + 20 * u(rng)) / 64 : 0.3 * u(rng) + 1e-3;
    const std::vector<PosePair> expected = AssociateAllPairs(estimated, groundtruth, max_dt_s);
    const std::vector<PosePair> actual = AssociatePoses(estimated, groundtruth, max_dt_s);
    ASSERT_EQ(actual.size(), expected.size()) << "trial " << trial;
    for (size_t k = 0; k < actual.size(); ++k) {
      EXPECT_EQ(actual[k].estimated_index, expected[k].estimated_index) << "trial " << trial;
      EXPECT_EQ(actual[k].groundtruth_index, expected[k].groundtruth_index) << "trial " << trial;
    }
    pairs_seen += static_cast<int>(actual.size());
  }
  EXPECT_GT(pairs_seen, 1000);  // the trials do associate
}

TEST(EvaluateTrajectory, ConstantRateDriftGivesTheAnalyticRpe) {
  // The estimate drifts in the world frame at a constant rate: est(t) = D(t) gt(t) with
  // D(t) = [Rz(w t) | v t]. For poses i, j (Δ = t_j - t_i):
  //   D(t_i)^-1 D(t_j) = [Rz(w Δ) | Rz(-w t_i) v Δ] =: X,
  //   E = (gt_i^-1 gt_j)^-1 gt_i^-1 X gt_j = gt_j^-1 X gt_j,
  // so the rotation error is exactly w Δ and the translation error is
  //   |R_x p_j + t_x - p_j| = |(Rz(w Δ) - I) p_j + Rz(-w t_i) v Δ|   (p_j: true position).
  // With w = 0 that is |v| Δ for every pair.
  const Eigen::Vector3d v_m_per_s(0.003, -0.004, 0.012);  // |v| = 13 mm/s
  for (const double w_rad_per_s : {0.0, 0.02}) {
    SCOPED_TRACE(w_rad_per_s);
    const Trajectory groundtruth = SmoothTrajectory(0.0, 30.0, 91);  // 3 s
    Trajectory estimated;
    for (const core::TimedPose& p : groundtruth.poses()) {
      const double t = p.timestamp_s;
      estimated.Add(t, RotZ(w_rad_per_s * t, v_m_per_s * t) * p.world_from_sensor);
    }
    const TrajectoryEval eval = EvaluateTrajectory(estimated, groundtruth, {});
    ASSERT_EQ(eval.rpe_m.count, 61);  // poses 0..60 have a partner 30 poses (1 s) later
    std::vector<double> expected_m;
    for (int i = 0; i + 30 <= 90; ++i) {
      const double t_i = groundtruth.poses()[i].timestamp_s;
      const double delta = groundtruth.poses()[i + 30].timestamp_s - t_i;
      const Eigen::Vector3d& p_j = groundtruth.poses()[i + 30].world_from_sensor.translation;
      const Eigen::Matrix3d rz_delta = RotZ(w_rad_per_s * delta).rotation.toRotationMatrix();
      const Eigen::Matrix3d rz_back = RotZ(-w_rad_per_s * t_i).rotation.toRotationMatrix();
      expected_m.push_back(
          ((rz_delta - Eigen::Matrix3d::Identity()) * p_j + rz_back * v_m_per_s * delta).norm());
    }
    const ErrorStats expected = ComputeErrorStats(expected_m);
    EXPECT_NEAR(eval.rpe_m.rmse, expected.rmse, 1e-12);
    EXPECT_NEAR(eval.rpe_m.min, expected.min, 1e-12);
    EXPECT_NEAR(eval.rpe_m.max, expected.max, 1e-12);
    if (w_rad_per_s == 0.0) {
      EXPECT_NEAR(eval.rpe_m.min, 0.013, 1e-12);
      EXPECT_NEAR(eval.rpe_m.max, 0.013, 1e-12);
    }
    const double expected_deg = w_rad_per_s * 180.0 / kPi;  // Δ = 1 s
    // Angles from quaternions near the identity: acos-free (atan2), good to ~1e-8 degrees.
    EXPECT_NEAR(eval.rpe_deg.min, expected_deg, 1e-7);
    EXPECT_NEAR(eval.rpe_deg.max, expected_deg, 1e-7);
  }
}

TEST(EvaluateTrajectory, MatchesTheTumBenchmarkDefinitionOnAHandComputedExample) {
  // ATE as evaluate_ate.py computes it, worked by hand. True positions: an octahedron with
  // half-axes 2, 1, 0.5 (centroid 0). The estimate is the same octahedron scaled by 1.1 and
  // then moved by a rigid transform M (est = M^-1 * 1.1 p). Undoing M, the cross-covariance
  // is 1.1 diag(8, 2, 0.5): symmetric positive definite, so Horn's rotation is the identity
  // and the best rigid fit is exactly M; each residual is 0.1 |p|:
  //   errors 0.2, 0.2, 0.1, 0.1, 0.05, 0.05 m
  //   rmse = sqrt((2·0.04 + 2·0.01 + 2·0.0025) / 6) = sqrt(0.0175) = 0.1322876 m
  //   mean = 0.7 / 6 = 0.1166667, median = (0.1 + 0.1) / 2 = 0.1 (numpy.median),
  //   std (numpy, population) = sqrt(0.0175 - 0.1166667²) = 0.0623610, min 0.05, max 0.2.
  // Timestamps: the estimate's are 10 ms late and associate with max_difference 0.02 s.
  const std::vector<Eigen::Vector3d> octahedron = {{2, 0, 0},  {-2, 0, 0},  {0, 1, 0},
                                                   {0, -1, 0}, {0, 0, 0.5}, {0, 0, -0.5}};
  const Rigid3d m = Rigid3d(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5), Eigen::Vector3d(3, -1, 2));
  Trajectory groundtruth, estimated;
  for (size_t k = 0; k < octahedron.size(); ++k) {
    groundtruth.Add(static_cast<double>(k),
                    Translation(octahedron[k].x(), octahedron[k].y(), octahedron[k].z()));
    estimated.Add(k + 0.01,
                  m.Inverse() * Translation(1.1 * octahedron[k].x(), 1.1 * octahedron[k].y(),
                                            1.1 * octahedron[k].z()));
  }
  TrajectoryEvalOptions options;
  options.max_time_difference_s = 0.02;
  const TrajectoryEval ate = EvaluateTrajectory(estimated, groundtruth, options);
  EXPECT_EQ(ate.associated_pairs, 6);
  ExpectSameTransform(ate.groundtruth_from_estimate, m, 1e-12);
  EXPECT_NEAR(ate.ate_m.rmse, std::sqrt(0.0175), 1e-12);
  EXPECT_NEAR(ate.ate_m.mean, 0.7 / 6, 1e-12);
  EXPECT_NEAR(ate.ate_m.median, 0.1, 1e-12);
  EXPECT_NEAR(ate.ate_m.std, std::sqrt(0.0175 - (0.7 / 6) * (0.7 / 6)), 1e-12);
  EXPECT_NEAR(ate.ate_m.min, 0.05, 1e-12);
  EXPECT_NEAR(ate.ate_m.max, 0.2, 1e-12);

  // RPE over 1 s, by hand. Truth: identity at t = 0, moved 1 m along x at t = 1, then 1 m
  // along y at t = 2. Estimate: identity, then [Rz(90°) | (1, 0.1, 0)], then
  // [Rz(90°) | (0, 0.1, 0)].
  //  Pair 0→1: B = gt0^-1 gt1 = [I | (1,0,0)], A = est0^-1 est1 = [Rz90 | (1,0.1,0)];
  //    E = B^-1 A = [Rz90 | (0, 0.1, 0)]: 0.1 m, 90°.
  //    (evaluate_rpe.py's A B^-1 = [Rz90 | (1,0.1,0) - Rz90 (1,0,0)] = [Rz90 | (1,-0.9,0)]:
  //    1.345 m, 90° — the script's form charges the rotation error times the 1 m travelled.)
  //  Pair 1→2: B = [I | (0,1,0)], A = [Rz90^-1 Rz90 | Rz(-90°) ((0,0.1,0) - (1,0.1,0))]
  //    = [I | Rz(-90°) (-1,0,0)] = [I | (0,1,0)] = B: E = I, 0 m, 0° (both forms).
  //  rpe_m: 0.1, 0 → rmse sqrt(0.01 / 2) = 0.0707107, mean 0.05, max 0.1.
  //  rpe_deg: 90, 0 → rmse sqrt(8100 / 2) = 63.63961, mean 45.
  Trajectory gt_rpe, est_rpe;
  gt_rpe.Add(0, Rigid3d());
  gt_rpe.Add(1, Translation(1, 0, 0));
  gt_rpe.Add(2, Translation(1, 1, 0));
  est_rpe.Add(0, Rigid3d());
  est_rpe.Add(1, RotZ(kPi / 2, Eigen::Vector3d(1, 0.1, 0)));
  est_rpe.Add(2, RotZ(kPi / 2, Eigen::Vector3d(0, 0.1, 0)));
  const TrajectoryEval rpe = EvaluateTrajectory(est_rpe, gt_rpe, options);
  ASSERT_EQ(rpe.rpe_m.count, 2);
  EXPECT_NEAR(rpe.rpe_m.max, 0.1, 1e-12);
  EXPECT_NEAR(rpe.rpe_m.min, 0.0, 1e-12);
  EXPECT_NEAR(rpe.rpe_m.rmse, std::sqrt(0.005), 1e-12);
  EXPECT_NEAR(rpe.rpe_deg.max, 90.0, 1e-9);
  EXPECT_NEAR(rpe.rpe_deg.min, 0.0, 1e-6);
  EXPECT_NEAR(rpe.rpe_deg.mean, 45.0, 1e-6);
}

TEST(EvaluateTrajectory, ShortTrajectoryHasNoRpeButAnAte) {
  const Trajectory groundtruth = SmoothTrajectory(0.0, 30.0, 20);  // 0.63 s < 1 s
  const TrajectoryEval eval = EvaluateTrajectory(groundtruth, groundtruth, {});
  EXPECT_EQ(eval.ate_m.count, 20);
  EXPECT_EQ(eval.rpe_m.count, 0);
  EXPECT_EQ(eval.rpe_deg.count, 0);
  TrajectoryEvalOptions options;
  options.rpe_delta_s = 0.1;  // 3 poses at 30 Hz
  EXPECT_EQ(EvaluateTrajectory(groundtruth, groundtruth, options).rpe_m.count, 17);
}

// The std::invalid_argument message of EvaluateTrajectory, or "" when it does not throw.
std::string EvaluationError(const Trajectory& estimated, const Trajectory& groundtruth) {
  try {
    EvaluateTrajectory(estimated, groundtruth, {});
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(EvaluateTrajectory, TooFewPairsOrDegeneratePositionsThrow) {
  const Trajectory groundtruth = SmoothTrajectory(100.0, 30.0, 30);
  // Disjoint clocks: nothing associates.
  EXPECT_THAT(EvaluationError(SmoothTrajectory(0.0, 30.0, 30), groundtruth),
              HasSubstr("only 0 pose pair(s) associate within 0.02 s"));
  EXPECT_THAT(EvaluationError(SmoothTrajectory(0.0, 30.0, 30), groundtruth),
              HasSubstr("same clock"));
  // Two pairs.
  EXPECT_THAT(EvaluationError(SmoothTrajectory(100.0, 30.0, 2), groundtruth),
              HasSubstr("only 2 pose pair(s)"));
  EXPECT_THAT(EvaluationError(Trajectory(), groundtruth), HasSubstr("estimated: no poses"));
  EXPECT_THAT(EvaluationError(groundtruth, Trajectory()), HasSubstr("ground truth: no poses"));
  // Three pairs suffice.
  EXPECT_EQ(EvaluationError(SmoothTrajectory(100.0, 30.0, 3), groundtruth), "");

  // Positions on a line (rotations varying): the rotation about the line is undetermined.
  Trajectory line, point;
  for (int k = 0; k < 10; ++k) {
    line.Add(k * 0.1, RotZ(0.1 * k, Eigen::Vector3d(0.3 * k, 0.1 * k, -0.2 * k)));
    point.Add(k * 0.1, RotZ(0.1 * k, Eigen::Vector3d(1, 2, 3)));
  }
  EXPECT_THAT(EvaluationError(line, line), HasSubstr("collinear"));
  EXPECT_THAT(EvaluationError(point, point), HasSubstr("collinear or coincide"));
  // A true trajectory on a line fixes no rotation either, whatever the estimate.
  EXPECT_THAT(EvaluationError(SmoothTrajectory(0.0, 10.0, 10), line), HasSubstr("collinear"));
}

TEST(TrajectoryEvalOptions, CheckNamesTheFieldAndValue) {
  TrajectoryEvalOptions options;
  EXPECT_EQ(options.Check(), "");
  options.max_time_difference_s = 0;
  EXPECT_EQ(options.Check(), "max_time_difference_s: must be > 0 s, got 0");
  options.max_time_difference_s = std::nan("");
  EXPECT_THAT(options.Check(), HasSubstr("max_time_difference_s"));
  options = TrajectoryEvalOptions();
  options.rpe_delta_s = -1;
  EXPECT_EQ(options.Check(), "rpe_delta_s: must be > 0 s, got -1");
  options.rpe_delta_s = std::numeric_limits<double>::infinity();
  EXPECT_THAT(options.Check(), HasSubstr("rpe_delta_s"));
}

}  // namespace
}  // namespace hw::reconstruct
