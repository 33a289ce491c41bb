#include "reconstruct/thermal_scene_correction.h"

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include <gtest/gtest.h>

namespace hw::reconstruct {
namespace {

double Rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s / v.size());
}

TEST(SceneCorrectionTest, CheckNamesTheField) {
  EXPECT_EQ(SceneCorrectionOptions().Check(), "");
  SceneCorrectionOptions o;
  o.pixel_rate = 0;
  EXPECT_NE(o.Check().find("pixel_rate"), std::string::npos) << o.Check();
  o = SceneCorrectionOptions();
  o.min_reference_views = 0;
  EXPECT_NE(o.Check().find("min_reference_views"), std::string::npos);
  o = SceneCorrectionOptions();
  o.max_residual_k = std::nan("");
  EXPECT_NE(o.Check().find("max_residual_k"), std::string::npos);
  o = SceneCorrectionOptions();
  o.max_reference_std_k = -1;
  EXPECT_NE(o.Check().find("max_reference_std_k"), std::string::npos);
  o = SceneCorrectionOptions();
  o.min_reference_rays = 0;
  EXPECT_NE(o.Check().find("min_reference_rays"), std::string::npos);
  o = SceneCorrectionOptions();
  o.max_pixel_offset_k = 0;
  EXPECT_NE(o.Check().find("max_pixel_offset_k"), std::string::npos);
}

// A common shift of every residual is the frame's offset, whatever a few reflections say;
// the pixels learn nothing from it; with too few references the last offset is kept.
TEST(SceneCorrectionTest, FrameOffsetIsTheRobustMedianAndIsKeptWithoutReferences) {
  constexpr int kW = 40, kH = 30;
  SceneCorrectionOptions o;
  o.min_reference_rays = 100;
  SceneCorrection c(o, kW, kH);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> netd(0, 0.05);
  std::vector<SceneResidual> r;
  for (int p = 0; p < kW * kH; ++p) r.push_back({p, static_cast<float>(0.4 + netd(rng))});
  for (int p = 0; p < 60; ++p) r[p * 7].residual_k = 8.0f;  // reflections: 5 % of the rays
  const SceneCorrectionUpdate u = c.Update(r);
  EXPECT_TRUE(u.frame_estimated);
  EXPECT_EQ(u.reference_rays, kW * kH - 60);
  // Median of 1140 draws of N(0, 0.05): standard error 1.25·0.05/√1140 = 0.002 K.
  EXPECT_NEAR(u.frame_offset_k, 0.4, 0.008);
  // Each pixel moved by pixel_rate × its own noise only: RMS 0.05·0.05 = 0.0025 K.
  EXPECT_LT(u.pixel_offset_rms_k, 0.005);

  std::vector<SceneResidual> few;
  for (int p = 0; p < 50; ++p) few.push_back({p, 3.0f});
  const SceneCorrectionUpdate v = c.Update(few);
  EXPECT_FALSE(v.frame_estimated);
  EXPECT_EQ(v.frame_offset_k, u.frame_offset_k);
  EXPECT_NEAR(v.pixel_offset_rms_k, u.pixel_offset_rms_k, 1e-9);  // pixels untouched

  cv::Mat image(kH, kW, CV_32FC1, cv::Scalar(20));
  const cv::Mat corrected = c.CorrectPixels(image);
  EXPECT_NEAR(corrected.at<float>(5, 5), 20 - c.pixel_offset_k().at<float>(5, 5), 1e-6);
}

// A camera panning over a strip of surface and bobbing up and down: pixel (x, y) sees
// surface cell (x + f, y + dy(f)) — a pure sideways pan would leave each row's mean offset
// unobservable (a row only ever meets its own cells).
// The readings carry a fixed pattern (0.15 K per pixel, 0.05 K per column), a frame offset
// that drifts and jumps 0.6 K at a shutter event, and NETD 0.05 K. The model is what the
// fusion keeps: each cell's mean of the corrected readings. Every estimate must converge to
// the truth (up to the unobservable constant) and the model's error must fall accordingly.
TEST(SceneCorrectionTest, LearnsFixedPatternAndDriftFromAPanningCamera) {
  constexpr int kW = 64, kH = 16, kFrames = 240, kCells = kW + kFrames, kBob = 3, kRows = kH + 2 * kBob;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> unit(0, 1);
  std::vector<double> pattern(kW * kH), column(kW), surface(kCells * kRows);
  for (double& b : pattern) b = 0.15 * unit(rng);
  for (double& b : column) b = 0.05 * unit(rng);
  for (int s = 0; s < kCells * kRows; ++s) surface[s] = 25 + 3 * std::sin((s / kRows) * 0.05) + 0.5 * unit(rng);
  auto bob = [](int f) { return static_cast<int>(std::lround(kBob * std::sin(f * 0.45))); };
  auto frame_offset = [](int f) { return 0.002 * f + (f >= 120 ? 0.6 : 0.0); };

  double model_error[2] = {0, 0};
  std::vector<double> residual_pattern;
  for (int on = 0; on < 2; ++on) {
    SceneCorrectionOptions o;
    o.frame_offset = o.pixel_offset = on == 1;
    o.min_reference_rays = 100;
    SceneCorrection c(o, kW, kH);
    // The model: per surface row cell, sum and count of corrected readings (the plain mean).
    std::vector<double> sum(kCells * kRows, 0), count(kCells * kRows, 0);
    std::mt19937_64 noise_rng(5);
    for (int f = 0; f < kFrames; ++f) {
      const int shift = f, dy = kBob + bob(f);  // one cell sideways per frame
      cv::Mat image(kH, kW, CV_32FC1);
      for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
          image.at<float>(y, x) = static_cast<float>(surface[(x + shift) * kRows + y + dy] + pattern[y * kW + x] + column[x] +
                                                     frame_offset(f) + 0.05 * unit(noise_rng));
        }
      }
      const cv::Mat corrected = c.CorrectPixels(image);
      std::vector<SceneResidual> residuals;
      for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
          const int cell = (x + shift) * kRows + y + dy;
          if (count[cell] >= o.min_reference_views) {
            residuals.push_back({y * kW + x, static_cast<float>(static_cast<double>(corrected.at<float>(y, x)) - sum[cell] / count[cell])});
          }
        }
      }
      const double offset = on ? c.Update(residuals).frame_offset_k : 0.0;
      for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
          const int cell = (x + shift) * kRows + y + dy;
          sum[cell] += static_cast<double>(corrected.at<float>(y, x)) - offset;
          count[cell] += 1;
        }
      }
    }
    // The model's error over the cells seen by the whole image width (the second half of
    // the strip), after removing the common constant (the first frames' level).
    std::vector<double> errors;
    double mean = 0;
    for (int s = kCells / 2; s < kFrames; ++s) {
      for (int y = 0; y < kRows; ++y) {
        if (count[s * kRows + y] == 0) continue;
        errors.push_back(sum[s * kRows + y] / count[s * kRows + y] - surface[s * kRows + y]);
        mean += errors.back();
      }
    }
    mean /= errors.size();
    for (double& e : errors) e -= mean;
    model_error[on] = Rms(errors);
    if (on) {
      // The learnt pattern against the truth (both re-centred).
      double truth_mean = 0;
      for (int p = 0; p < kW * kH; ++p) truth_mean += pattern[p] + column[p % kW];
      truth_mean /= kW * kH;
      for (int p = 0; p < kW * kH; ++p) {
        residual_pattern.push_back(static_cast<double>(c.pixel_offset_k().at<float>(p / kW, p % kW)) -
                                   (pattern[p] + column[p % kW] - truth_mean));
      }
    }
  }
  // Uncorrected, the jump splits the strip's cells by up to 0.6 K and the fixed pattern
  // averages over 64 pixels a cell (0.02 K): over a tenth of a kelvin (0.13). Corrected, what is
  // left is NETD over the views (0.05/√64) and the pattern's learning error.
  EXPECT_GT(model_error[0], 0.1) << model_error[0];
  EXPECT_LT(model_error[1], 0.03) << model_error[1];
  std::printf("model error %.4f K uncorrected, %.4f K corrected; pattern learnt to %.4f K RMS\n", model_error[0],
              model_error[1], Rms(residual_pattern));
  EXPECT_LT(model_error[1], model_error[0] / 5);
  // Pattern truth RMS is 0.16 K; learnt to within a third of that (the exponential mean over
  // 20 frames leaves NETD·√(rate/2) = 0.008 K, the model's own lag the rest).
  EXPECT_LT(Rms(residual_pattern), 0.05) << Rms(residual_pattern);
}

TEST(SceneCorrectionTest, OffLeavesEverythingAlone) {
  SceneCorrectionOptions o;
  o.frame_offset = o.pixel_offset = false;
  SceneCorrection c(o, 8, 4);
  EXPECT_FALSE(c.enabled());
  std::vector<SceneResidual> r;
  for (int p = 0; p < 32; ++p) r.push_back({p, 1.0f});
  o.min_reference_rays = 1;
  const SceneCorrectionUpdate u = c.Update(r);
  EXPECT_EQ(u.frame_offset_k, 0);
  EXPECT_EQ(cv::countNonZero(c.pixel_offset_k()), 0);
}

}  // namespace
}  // namespace hw::reconstruct
