// The whole intrinsics calibration (detector + solver) on the fixtures' thermal square-grid
// sessions, against their truth, over several seeds and rig units: the solved camera must
// project like the true one within the projection uncertainty it reports.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <gtest/gtest.h>

#include "calibrate/intrinsics_solver.h"
#include "calibrate/square_grid.h"
#include "core/scan.h"
#include "fixtures/calibration_sessions.h"
#include "tests/support.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;

struct TruthComparison {
  int points = 0, within_3_sigma = 0;
  double worst_ratio = 0;     // max |Δ| / σ over the grid
  double median_diff_px = 0;  // median |Δ|
};

// Solves the thermal camera of a small square-grid session (seed, rig unit) and compares, on
// the interior 9 × 9 points of an 11 × 11 grid over the image, where truth and solution
// project a point at 2 m seen by the true camera at that pixel.
TruthComparison SolveAndCompare(uint64_t seed) {
  auto options = fixtures::CalibrationSessionOptions::Preset(fixtures::CalibrationSessionKind::kThermalSquareGrid,
                                                             true, seed, seed);
  options.thermal_square_grid.views.num_views = 12;
  const fs::path dir = hw::test::TestFolder("session-" + std::to_string(seed));
  fixtures::SynthesizeCalibrationSession(options, dir);
  const core::Scan scan = core::Scan::Open(dir);
  const core::Target target = core::ReadTarget(dir / "target.yaml");
  const core::CameraModel truth = *core::ReadRig(dir / "truth" / "rig.yaml").thermal;
  std::vector<ViewObservation> views;
  for (int i = 0; i < scan.NumFrames(core::Stream::kThermal); ++i) {
    const Detection d = DetectSquareGrid(scan.LoadThermal(i), target);
    if (d.accepted) views.push_back({d.corner_ids, d.pixels});
  }
  EXPECT_GE(views.size(), 10u);
  const IntrinsicsResult solved = SolveIntrinsics(target, truth.width, truth.height, views);
  const int map_cols = 11, map_rows = 11;
  const std::vector<double> sigma = ProjectionUncertaintyMap(solved, map_cols, map_rows, 2.0);
  TruthComparison out;
  std::vector<double> diffs;
  for (int r = 1; r + 1 < map_rows; ++r) {
    for (int c = 1; c + 1 < map_cols; ++c) {
      const Eigen::Vector2d q(c * (truth.width - 1.0) / (map_cols - 1), r * (truth.height - 1.0) / (map_rows - 1));
      const std::optional<Eigen::Vector3d> ray = truth.Unproject(q);
      if (!ray) continue;
      const Eigen::Vector3d point = ray->normalized() * 2.0;
      const double diff = (solved.camera.Project(point) - q).norm();
      const double s = sigma[static_cast<size_t>(r * map_cols + c)];
      diffs.push_back(diff);
      ++out.points;
      out.within_3_sigma += diff <= 3 * s;
      out.worst_ratio = std::max(out.worst_ratio, diff / s);
    }
  }
  std::nth_element(diffs.begin(), diffs.begin() + static_cast<std::ptrdiff_t>(diffs.size() / 2), diffs.end());
  out.median_diff_px = diffs[diffs.size() / 2];
  std::printf("seed %llu: %zu views, rms %.3f px, sigma_obs %.3f px; |truth - solved| median %.3f px, %d of %d grid "
              "points within 3 sigma, worst %.2f sigma\n",
              static_cast<unsigned long long>(seed), views.size(), solved.rms_px, solved.observation_sigma_px,
              out.median_diff_px, out.within_3_sigma, out.points, out.worst_ratio);
  return out;
}

// Issue 12's target, NOT met yet, so run on demand (README, *Calibration bench*):
// build/calibrate/intrinsics_truth_test --gtest_also_run_disabled_tests. Measured: seed 1
// 75 of 81 points within 3σ (worst 3.2σ); seed 2 median 3.9 px off, worst 10.9σ (σ_obs
// 0.18 px: a bias the noise model does not know — the detector's corners sit ~0.2 px inside
// the holes); seed 3's 12 small views are refused as too fronto-parallel.
TEST(IntrinsicsTruthTest, DISABLED_ThermalSessionsProjectLikeTheTruthWithinTheReportedUncertainty) {
  for (uint64_t seed : {1u, 2u, 3u}) {
    const TruthComparison c = SolveAndCompare(seed);
    EXPECT_GE(c.within_3_sigma, c.points * 9 / 10) << "seed " << seed;
  }
}

}  // namespace
}  // namespace hw::calibrate
