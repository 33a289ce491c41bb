#include "calibrate/depth_correction_fit.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace hw::calibrate {
namespace {

core::CameraModel Kinect() {
  core::CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.type = core::CameraModelType::kOpenCV;
  camera.fx = camera.fy = 570;
  camera.cx = 319.5;
  camera.cy = 239.5;
  camera.distortion = {0.04, -0.08, 0, 0};
  return camera;
}

// A field the grid represents exactly: a bowl and a ripple sampled at the nodes (the
// estimator then has no interpolation error, so its error is noise alone).
core::DepthCorrection TrueField(const core::CameraModel& camera) {
  core::DepthCorrection field = core::DepthCorrection::ZeroOver(camera, 17, 13);
  for (int iy = 0; iy < field.ny; ++iy) {
    for (int ix = 0; ix < field.nx; ++ix) {
      const double x = field.x_range[0] + (field.x_range[1] - field.x_range[0]) * ix / (field.nx - 1);
      const double y = field.y_range[0] + (field.y_range[1] - field.y_range[0]) * iy / (field.ny - 1);
      field.offset_per_m[iy * field.nx + ix] =
          -0.0047 * (x * x + y * y) / 0.49 + 0.0015 * std::cos(2 * M_PI * (0.8 * x + 0.6 * y) / 0.4 + 1.0);
    }
  }
  return field;
}

struct Recording {
  std::vector<DepthFrameSamples> frames;
  int clutter_samples = 0;
};

// num_frames planes from 0.8 to 3.5 m, tilted up to 30°, read through `field` with
// Gaussian inverse-depth noise sigma_per_m; a box 0.5 m before the plane covers a quarter of
// the image in every other frame (clutter the fit must drop).
Recording Record(const core::CameraModel& camera, const core::DepthCorrection& field,
                 int num_frames, double sigma_per_m, uint64_t seed, int step = 8) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::normal_distribution<double> noise(0, sigma_per_m);
  Recording rec;
  for (int p = 0; p < num_frames; ++p) {
    const double distance = 0.8 + 2.7 * uniform(random);
    const double tilt = 30 * M_PI / 180 * uniform(random), azimuth = 2 * M_PI * uniform(random);
    const Eigen::Vector3d normal(std::sin(tilt) * std::cos(azimuth), std::sin(tilt) * std::sin(azimuth),
                                 std::cos(tilt));
    // Plane n·X = distance·cos... : w = n·(x, y, 1) / d with d the plane's distance.
    const double d = distance * std::cos(tilt);
    DepthFrameSamples s;
    s.frame = p;
    s.timestamp_s = p;
    for (int v = step / 2; v < camera.height; v += step) {
      for (int u = step / 2; u < camera.width; u += step) {
        const Eigen::Vector3d ray = *camera.Unproject({double(u), double(v)});
        double w = normal.dot(ray) / d;
        if (p % 2 == 1 && u < camera.width / 2 && v > camera.height / 2) {
          w = 1 / (1 / w - 0.5);  // the box, 0.5 m nearer
          if (!(w > 0 && w < 1 / 0.4)) continue;  // nearer than the sensor reads
          ++rec.clutter_samples;
        }
        s.x.push_back(ray.x());
        s.y.push_back(ray.y());
        s.w.push_back(w + field.OffsetAt(ray.x(), ray.y()) + noise(random));
      }
    }
    s.valid = static_cast<int>(s.w.size());
    rec.frames.push_back(std::move(s));
  }
  return rec;
}

TEST(DepthCorrectionFit, RecoversTheFieldWithinItsUncertaintyAndDropsClutter) {
  const core::CameraModel camera = Kinect();
  const core::DepthCorrection truth = TrueField(camera);
  const std::vector<double> truth_projected = WithoutAffinePart(truth, truth.offset_per_m);
  DepthCorrectionOptions options;
  // Seeds: the normalised error's spread must hold for any noise draw, not one.
  for (const uint64_t seed : {1, 2, 3}) {
    const Recording rec = Record(camera, truth, 24, 0.002, seed);
    const DepthCorrectionResult r = FitDepthCorrection(rec.frames, truth, options);
    ASSERT_EQ(r.frames_used, 24);
    double sum_z2 = 0, max_z = 0;
    for (size_t k = 0; k < truth_projected.size(); ++k) {
      const double z = (r.correction.offset_per_m[k] - truth_projected[k]) / r.sigma_per_m[k];
      sum_z2 += z * z;
      max_z = std::max(max_z, std::abs(z));
    }
    const double rms_z = std::sqrt(sum_z2 / truth_projected.size());
    // Gaussian noise, the model exact: normalised errors of RMS ~1 (221 nodes: 0.5–1.4 holds
    // the sandwich's extra spread from 24 clusters) and none beyond 5.5σ (a sandwich from 24
    // clusters scatters ~15 %, so a node's 4.5σ error can read 5σ; 663 nodes over 3 seeds).
    EXPECT_GT(rms_z, 0.5) << "seed " << seed << ": the uncertainty is inflated";
    EXPECT_LT(rms_z, 1.4) << "seed " << seed;
    EXPECT_LT(max_z, 5.5) << "seed " << seed;
    // The box (0.5 m nearer: > 0.04 /m off the plane, 20σ) is never an inlier.
    EXPECT_LE(r.samples_used, 24 * static_cast<int>(rec.frames[0].w.size()) - rec.clutter_samples);
    EXPECT_GT(r.samples_used, 0.97 * (24 * rec.frames[0].w.size() - rec.clutter_samples));
    // The field (0.002 /m RMS) is as large as this noise: removing it leaves the noise.
    EXPECT_LT(r.rms_after_mm, 0.9 * r.rms_before_mm);
    for (const DepthPlaneFit& f : r.frames) {
      EXPECT_LT(f.rms_after_mm, f.rms_before_mm);
    }
    EXPECT_NEAR(r.distance_min_m, 0.8, 0.5);
    EXPECT_EQ(r.coverage, 1.0);
    // 4800 samples per frame (every 8th pixel) of σ 0.002 /m: a corner node, with a quarter
    // of an inner node's support, is known to ~0.0004 /m = 3.6 mm at 3 m.
    EXPECT_LT(r.max_sigma_mm_at_3m, 6.0);
    // Per frame: the noise σ is found (inlier sigma ~ the Gaussian's, a bit less from the
    // 4σ gate).
    for (const DepthPlaneFit& f : r.frames) EXPECT_NEAR(f.sigma_per_m, 0.002, 0.0003);
  }
}

TEST(DepthCorrectionFit, AnAffineFieldIsInvisibleAndLeftOut) {
  const core::CameraModel camera = Kinect();
  const core::DepthCorrection truth = TrueField(camera);
  core::DepthCorrection tilted = truth;
  for (int k = 0; k < tilted.nx * tilted.ny; ++k) {
    const double x = tilted.x_range[0] + (tilted.x_range[1] - tilted.x_range[0]) * (k % tilted.nx) / (tilted.nx - 1);
    const double y = tilted.y_range[0] + (tilted.y_range[1] - tilted.y_range[0]) * (k / tilted.nx) / (tilted.ny - 1);
    tilted.offset_per_m[k] += 0.003 - 0.004 * x + 0.002 * y;
  }
  DepthCorrectionOptions options;
  options.num_threads = 1;
  const DepthCorrectionResult a = FitDepthCorrection(Record(camera, truth, 10, 0.001, 7).frames, truth, options);
  const DepthCorrectionResult b = FitDepthCorrection(Record(camera, tilted, 10, 0.001, 7).frames, truth, options);
  for (size_t k = 0; k < a.correction.offset_per_m.size(); ++k) {
    // Identical up to the RANSAC/gating decisions' rounding: 1e-7 /m is 1 µm at 3 m.
    EXPECT_NEAR(a.correction.offset_per_m[k], b.correction.offset_per_m[k], 1e-7);
  }
  // The estimate itself has no affine part.
  const std::vector<double> projected = WithoutAffinePart(a.correction, a.correction.offset_per_m);
  for (size_t k = 0; k < projected.size(); ++k) {
    EXPECT_NEAR(projected[k], a.correction.offset_per_m[k], 1e-12);
  }
}

// Frames are built on several threads but summed in frame order: the same data give the
// same bits on every run.
TEST(DepthCorrectionFit, SameDataSameBits) {
  const core::CameraModel camera = Kinect();
  const core::DepthCorrection truth = TrueField(camera);
  const Recording rec = Record(camera, truth, 12, 0.002, 11);
  DepthCorrectionOptions options;
  options.num_threads = 3;
  const DepthCorrectionResult a = FitDepthCorrection(rec.frames, truth, options);
  for (int run = 0; run < 3; ++run) {
    const DepthCorrectionResult b = FitDepthCorrection(rec.frames, truth, options);
    EXPECT_EQ(a.correction.offset_per_m, b.correction.offset_per_m);
    EXPECT_EQ(a.sigma_per_m, b.sigma_per_m);
  }
}

TEST(DepthCorrectionFit, TooFewPlanesIsAnErrorThatSaysWhy) {
  const core::CameraModel camera = Kinect();
  const core::DepthCorrection truth = TrueField(camera);
  Recording rec = Record(camera, truth, 8, 0.002, 3);
  // Half the frames are scattered points (a cluttered room): no plane holds 40 % of them.
  std::mt19937_64 random(5);
  std::uniform_real_distribution<double> far(0.2, 2.0);
  for (int p = 0; p < 4; ++p) {
    for (double& w : rec.frames[p].w) w = far(random);
  }
  DepthCorrectionOptions options;
  options.min_frames = 6;
  try {
    FitDepthCorrection(rec.frames, truth, options);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    {
      const std::string what = e.what();
      EXPECT_NE(what.find("4 of 8 depth frames show a usable plane, at least 6 are needed"), std::string::npos) << what;
      EXPECT_NE(what.find("frame 0: its largest plane"), std::string::npos) << what;
    }
  }
  options.min_frames = 4;
  const DepthCorrectionResult r = FitDepthCorrection(rec.frames, truth, options);
  EXPECT_EQ(r.frames_used, 4);
  EXPECT_FALSE(r.frames[0].used);
  EXPECT_FALSE(r.frames[0].skipped_because.empty());
}

TEST(DepthCorrectionFit, OptionsCheckNamesTheField) {
  DepthCorrectionOptions o;
  EXPECT_EQ(o.Check(), "");
  o.nx = 1;
  EXPECT_EQ(o.Check(), "nx: must be in [2, 256], got 1");
  o = {};
  o.nx = 100;
  o.ny = 100;
  EXPECT_NE(o.Check().find("nx*ny: must be at most 2500"), std::string::npos);
  o = {};
  o.max_depth_m = 0.3;
  EXPECT_EQ(o.Check(), "max_depth_m: must be > min_depth_m m, got 0.29999999999999999");
  o = {};
  o.smoothness_sigma_per_m = 0;
  EXPECT_EQ(o.Check(), "smoothness_sigma_per_m: must be > 0 1/m, got 0");
}

}  // namespace
}  // namespace hw::calibrate
