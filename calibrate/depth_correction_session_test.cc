// The depth calibration on the fixtures' depth-wall sessions (a hand-held wall recording with
// floor, furniture, a window and a person, the full structured-light sensor model), against
// the sensor's true disparity distortion.

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "calibrate/depth_correction_fit.h"
#include "core/scan.h"
#include "fixtures/cached_test_data.h"
#include "fixtures/calibration_sessions.h"
#include "fixtures/depth_sensor.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;

struct FieldError {
  double truth_rms_per_m = 0;  // the true field without its affine part, over the pixels
  double error_rms_per_m = 0;  // estimate − that, over the pixels
  double normalised_rms = 0;   // error / the estimate's σ (bilinear in the node σ), RMS
};

// Compares over the image's pixels (every 4th): the estimate against the sensor's true field
// (a 65 × 49 grid of it: 1/16 of a 17 × 13 grid's interpolation error, so "continuous"),
// both without their affine part over the pixels (which planes cannot show).
FieldError CompareWithTruth(const DepthCorrectionResult& r, const fixtures::DepthSensorOptions& sensor,
                            const core::CameraModel& camera) {
  const core::DepthCorrection truth = fixtures::TrueDepthCorrection(sensor, camera, 65, 49);
  core::DepthCorrection sigma = r.correction;
  sigma.offset_per_m = r.sigma_per_m;
  std::vector<Eigen::Vector3d> g;
  std::vector<double> estimate, true_value, node_sigma;
  for (int v = 2; v < camera.height; v += 4) {
    for (int u = 2; u < camera.width; u += 4) {
      const Eigen::Vector3d ray = *camera.Unproject({double(u), double(v)});
      g.emplace_back(1, ray.x(), ray.y());
      estimate.push_back(r.correction.OffsetAt(ray.x(), ray.y()));
      true_value.push_back(truth.OffsetAt(ray.x(), ray.y()));
      node_sigma.push_back(sigma.OffsetAt(ray.x(), ray.y()));
    }
  }
  const auto remove_affine = [&](std::vector<double>& values) {
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < values.size(); ++i) {
      a += g[i] * g[i].transpose();
      b += g[i] * values[i];
    }
    const Eigen::Vector3d c = a.ldlt().solve(b);
    for (size_t i = 0; i < values.size(); ++i) values[i] -= c.dot(g[i]);
  };
  remove_affine(estimate);
  remove_affine(true_value);
  FieldError e;
  double sum_truth = 0, sum_error = 0, sum_z = 0;
  for (size_t i = 0; i < estimate.size(); ++i) {
    sum_truth += true_value[i] * true_value[i];
    sum_error += std::pow(estimate[i] - true_value[i], 2);
    sum_z += std::pow((estimate[i] - true_value[i]) / node_sigma[i], 2);
  }
  const double n = static_cast<double>(estimate.size());
  e.truth_rms_per_m = std::sqrt(sum_truth / n);
  e.error_rms_per_m = std::sqrt(sum_error / n);
  e.normalised_rms = std::sqrt(sum_z / n);
  return e;
}

TEST(DepthCorrectionSession, RemovesMostOfTheSensorsFieldDespiteClutter) {
  // Two seeds: different paths, people and noise (one device: device_seed is the sensor's).
  for (const uint64_t seed : {1, 2}) {
    const fixtures::CalibrationSessionOptions options =
        fixtures::CalibrationSessionOptions::Preset(fixtures::CalibrationSessionKind::kDepthWall, true, seed, seed);
    const fs::path folder = fixtures::test::CachedSession("depth-wall-small-" + std::to_string(seed), options, "depth.txt");
    core::ScanOptions scan_options;
    scan_options.rig_path = folder / "truth" / "rig.yaml";  // the true depth camera
    const core::Scan scan = core::Scan::Open(folder, scan_options);
    DepthCorrectionOptions fit;
    const DepthCorrectionResult r = CalibrateDepthCorrection(scan, scan.rig().depth, fit);
    const FieldError e = CompareWithTruth(r, options.common().depth, scan.rig().depth);
    std::printf("seed %d: %d of %zu frames, %.2f-%.2f m, residual %.2f -> %.2f mm; field %.2f mm at 3 m, "
                "error %.2f mm (%.0f %%), normalised %.2f, max sigma %.2f mm, coverage %.2f\n",
                int(seed), r.frames_used, r.frames.size(), r.distance_min_m, r.distance_max_m, r.rms_before_mm,
                r.rms_after_mm, 9e3 * e.truth_rms_per_m, 9e3 * e.error_rms_per_m,
                100 * e.error_rms_per_m / e.truth_rms_per_m, e.normalised_rms, r.max_sigma_mm_at_3m, r.coverage);
    // Every still sees mostly wall (the person and furniture take at most a third of one).
    EXPECT_EQ(r.frames_used, static_cast<int>(r.frames.size()));
    EXPECT_LT(r.rms_after_mm, 0.8 * r.rms_before_mm);
    // Measured 7 % of the field left on seeds 1 and 2 (24 stills at 320 × 240; the 17 × 13
    // grid's own interpolation error is ~5 % of this pattern): 15 % leaves room for other
    // seeds' paths, not for a fit that missed the bowl or the pattern (≥ 50 %).
    EXPECT_LT(e.error_rms_per_m, 0.15 * e.truth_rms_per_m);
    // The reported σ covers the error (0.80 measured): neither optimistic (> 1.5) nor so
    // inflated that it says nothing (< 0.4).
    EXPECT_GT(e.normalised_rms, 0.4);
    EXPECT_LT(e.normalised_rms, 1.5);
  }
}

}  // namespace
}  // namespace hw::calibrate
