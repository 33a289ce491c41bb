#include "reconstruct/depth_frame.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

namespace hw::reconstruct {
namespace {

using ::testing::HasSubstr;

PinholeCamera SmallCamera() {
  return PinholeCamera::Of(core::CameraModel::Pinhole(160, 120, 140, 140));
}

// Depth of the plane {p : a · p = 1} (camera frame) at each pixel: the ray (x̄, ȳ, 1) meets
// it at z = 1 / (a · ray).
cv::Mat PlaneDepth(const PinholeCamera& camera, const Eigen::Vector3f& a) {
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3f ray = camera.Unproject(float(u), float(v), 1.0f);
      depth.at<float>(v, u) = 1.0f / a.dot(ray);
    }
  }
  return depth;
}

double StdDev(const cv::Mat& image, int border, double mean) {
  double sum_sq = 0;
  int n = 0;
  for (int v = border; v < image.rows - border; ++v) {
    for (int u = border; u < image.cols - border; ++u) {
      const double d = double(image.at<float>(v, u)) - mean;
      sum_sq += d * d;
      ++n;
    }
  }
  return std::sqrt(sum_sq / n);
}

TEST(DepthFilterOptions, CheckNamesTheField) {
  EXPECT_EQ(DepthFilterOptions().Check(), "");
  auto with = [](auto change) {
    DepthFilterOptions o;
    change(o);
    return o.Check();
  };
  EXPECT_THAT(with([](auto& o) { o.min_depth_m = -1; }), HasSubstr("min_depth_m"));
  EXPECT_THAT(with([](auto& o) { o.max_depth_m = 0.2; }), HasSubstr("max_depth_m"));
  EXPECT_THAT(with([](auto& o) { o.bilateral_radius_px = 11; }), HasSubstr("bilateral_radius_px"));
  EXPECT_THAT(with([](auto& o) { o.bilateral_sigma_px = 0; }), HasSubstr("bilateral_sigma_px"));
  EXPECT_THAT(with([](auto& o) { o.bilateral_sigma_depth_m = NAN; }),
              HasSubstr("bilateral_sigma_depth_m"));
  EXPECT_THAT(with([](auto& o) { o.edge_jump_fraction = 0; }), HasSubstr("edge_jump_fraction"));
  EXPECT_THAT(with([](auto& o) { o.num_levels = 6; }), HasSubstr("num_levels"));
  EXPECT_THAT(with([](auto& o) { o.normal_max_jump_fraction = 1.5; }),
              HasSubstr("normal_max_jump_fraction"));
  EXPECT_THAT(with([](auto& o) { o.num_threads = -1; }), HasSubstr("num_threads"));
  EXPECT_EQ(with([](auto& o) { o.bilateral_radius_px = 0; }), "");
}

TEST(Undistorter, PinholeAndZeroDistortionAreTheIdentity) {
  core::CameraModel camera = core::CameraModel::Pinhole(160, 120, 140, 140);
  const cv::Mat depth(120, 160, CV_32FC1, cv::Scalar(1.5f));
  const Undistorter pinhole(camera);
  EXPECT_TRUE(pinhole.is_identity());
  EXPECT_EQ(pinhole.UndistortDepth(depth).data, depth.data);  // no copy
  camera.type = core::CameraModelType::kOpenCV;
  camera.distortion = {0, 0, 0, 0, 0};
  const Undistorter zero(camera);
  EXPECT_TRUE(zero.is_identity());
  EXPECT_EQ(zero.pinhole().fx, 140.0f);
}

core::CameraModel DistortedCamera() {
  core::CameraModel camera = core::CameraModel::Pinhole(160, 120, 140, 138);
  camera.type = core::CameraModelType::kOpenCV;
  camera.cx = 81.3;
  camera.cy = 58.7;
  camera.distortion = {-0.25, 0.08, 0.002, -0.0015, -0.01};
  return camera;
}

// A point seen at a distorted pixel with depth z must appear, with the same z, at the pinhole
// pixel where PinholeCamera projects it (within the nearest-neighbour footprint: the distorted
// pixel covers at most ~1 px of the pinhole image on this barrel lens, so within 1 px).
TEST(Undistorter, PointsLandAtTheirPinholePixelWithTheirDepth) {
  const core::CameraModel camera = DistortedCamera();
  const Undistorter undistorter(camera);
  ASSERT_FALSE(undistorter.is_identity());
  const PinholeCamera& pinhole = undistorter.pinhole();
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0.0f));
  struct Dot {
    int u, v;
    float z;
    Eigen::Vector2f pinhole_pixel;
  };
  std::vector<Dot> dots;
  for (int v = 4; v < camera.height - 4; v += 9) {
    for (int u = 4; u < camera.width - 4; u += 9) {
      const float z = 0.5f + 0.001f * static_cast<float>(dots.size());
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(Eigen::Vector2d(u, v));
      ASSERT_TRUE(ray.has_value());
      const Eigen::Vector3f point = (*ray * z).cast<float>();
      dots.push_back({u, v, z, pinhole.Project(point)});
      depth.at<float>(v, u) = z;
    }
  }
  const cv::Mat out = undistorter.UndistortDepth(depth);
  ASSERT_EQ(out.type(), CV_32FC1);
  std::vector<int> hits(dots.size(), 0);
  for (int v = 0; v < out.rows; ++v) {
    for (int u = 0; u < out.cols; ++u) {
      const float z = out.at<float>(v, u);
      if (z == 0) continue;
      const int k = static_cast<int>(std::lround((z - 0.5f) / 0.001f));
      ASSERT_GE(k, 0);
      ASSERT_LT(k, static_cast<int>(dots.size()));
      EXPECT_EQ(z, dots[k].z);  // z is copied, never interpolated
      EXPECT_LT((Eigen::Vector2f(u, v) - dots[k].pinhole_pixel).norm(), 1.0f)
          << "dot " << k << " at pinhole pixel " << u << " " << v;
      ++hits[k];
    }
  }
  for (size_t k = 0; k < dots.size(); ++k) {
    // Pinhole pixels beyond the image are not produced; every dot inside is.
    const Eigen::Vector2f p = dots[k].pinhole_pixel;
    if (p.x() < 0 || p.y() < 0 || p.x() > camera.width - 1 || p.y() > camera.height - 1) continue;
    EXPECT_GE(hits[k], 1) << "dot " << k;
  }
}

// A linear ramp (red = distorted x, green = distorted y) resampled bilinearly reads, at each
// pinhole pixel, the distorted pixel CameraModel::Project gives for its ray, to the 8-bit
// rounding (0.5) plus OpenCV's 1/32 px quantisation of the interpolation weights. On a
// pincushion lens (k1 > 0) the pinhole image's corners see beyond the distorted image: black,
// and 0 depth.
TEST(Undistorter, ColourIsResampledBilinearlyThroughTheLens) {
  core::CameraModel pincushion = DistortedCamera();
  pincushion.distortion = {0.2, 0.02, 0.001, 0.002, 0};
  for (const core::CameraModel& camera : {DistortedCamera(), pincushion}) {
    const bool is_pincushion = camera.distortion[0] > 0;
    const Undistorter undistorter(camera);
    cv::Mat rgb(camera.height, camera.width, CV_8UC3);
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(u, v, 200);
    }
    const cv::Mat out = undistorter.UndistortColour(rgb);
    const cv::Mat depth =
        undistorter.UndistortDepth(cv::Mat(rgb.size(), CV_32FC1, cv::Scalar(1.5f)));
    ASSERT_EQ(out.type(), CV_8UC3);
    int checked = 0, black = 0;
    for (int v = 0; v < out.rows; ++v) {
      for (int u = 0; u < out.cols; ++u) {
        const Eigen::Vector3d ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1);
        const Eigen::Vector2d d = camera.Project(ray);
        const cv::Vec3b c = out.at<cv::Vec3b>(v, u);
        if (d.x() >= 0 && d.y() >= 0 && d.x() <= camera.width - 1 && d.y() <= camera.height - 1) {
          EXPECT_NEAR(c[0], d.x(), 0.5 + 1.0 / 32) << u << " " << v;
          EXPECT_NEAR(c[1], d.y(), 0.5 + 1.0 / 32) << u << " " << v;
          EXPECT_EQ(c[2], 200);
          EXPECT_EQ(depth.at<float>(v, u), 1.5f);
          ++checked;
        } else if (d.x() < -1 || d.y() < -1 || d.x() > camera.width || d.y() > camera.height) {
          EXPECT_EQ(c, cv::Vec3b(0, 0, 0));
          EXPECT_EQ(depth.at<float>(v, u), 0.0f);
          ++black;
        }
      }
    }
    EXPECT_GT(checked, 15000);
    if (is_pincushion) {
      EXPECT_GT(black, 100);
    } else {
      EXPECT_EQ(black, 0);  // a barrel lens sees beyond the pinhole image
    }
  }
}

TEST(BuildDepthPyramid, RangeLimitsAndFlyingPixels) {
  const PinholeCamera camera = SmallCamera();
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(1.0f));
  depth.colRange(80, 160).setTo(1.3f);  // a step: both sides' edge pixels jump 30 %
  depth.at<float>(10, 10) = 0.1f;       // too near
  depth.at<float>(20, 20) = 5.0f;       // too far
  depth.at<float>(30, 30) = NAN;
  const DepthPyramid pyramid = BuildDepthPyramid(depth, camera, DepthFilterOptions());
  const cv::Mat& raw = pyramid.raw_depth_m;
  EXPECT_EQ(raw.at<float>(10, 10), 0);
  EXPECT_EQ(raw.at<float>(20, 20), 0);
  EXPECT_EQ(raw.at<float>(30, 30), 0);
  for (int v = 40; v < 120; ++v) {
    EXPECT_EQ(raw.at<float>(v, 78), 1.0f);
    EXPECT_EQ(raw.at<float>(v, 79), 0);
    EXPECT_EQ(raw.at<float>(v, 80), 0);
    EXPECT_EQ(raw.at<float>(v, 81), 1.3f);
  }
  // Holes do not make their neighbours "jump": (10, 11) keeps its depth.
  EXPECT_EQ(raw.at<float>(10, 11), 1.0f);
}

// The range limits and the flying-pixel test, vectorised eight pixels at a time with
// scalar row ends, against their per-pixel definition on an odd width (every pixel position
// in and out of a vector) with every kind of depth: in range, too near or far, zero,
// negative, NaN, ±inf, and neighbours on both sides of the jump limit.
TEST(BuildDepthPyramid, CleaningMatchesThePerPixelDefinition) {
  const PinholeCamera camera = PinholeCamera::Of(core::CameraModel::Pinhole(157, 23, 140, 140));
  DepthFilterOptions options;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  const float specials[] = {0.0f, -1.0f, NAN, INFINITY, -INFINITY, 0.1f, 9.0f};
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const float r = uniform(rng);
      // Mostly 2 m ± 8 %: neighbours fall on both sides of the 5 % limit.
      depth.at<float>(v, u) = r < 0.15f ? specials[int(uniform(rng) * 7) % 7] : 2.0f * (0.92f + 0.16f * uniform(rng));
    }
  }
  const float min_m = float(options.min_depth_m), max_m = float(options.max_depth_m);
  const float fraction = float(options.edge_jump_fraction);
  auto limited = [&](int v, int u) {
    if (v < 0 || v >= depth.rows || u < 0 || u >= depth.cols) return 0.0f;
    const float z = depth.at<float>(v, u);
    return z >= min_m && z <= max_m && z > 0 ? z : 0.0f;
  };
  const cv::Mat raw = BuildDepthPyramid(depth, camera, options).raw_depth_m;
  int kept = 0, dropped = 0;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const float z = limited(v, u);
      bool jump = false;
      for (const auto& [dv, du] : {std::pair{0, -1}, {0, 1}, {-1, 0}, {1, 0}}) {
        const float n = limited(v + dv, u + du);
        jump = jump || (n > 0 && std::abs(n - z) > fraction * z);
      }
      const float expected = z > 0 && jump ? 0.0f : z;
      ASSERT_EQ(raw.at<float>(v, u), expected) << "pixel " << u << ", " << v;
      kept += expected > 0;
      dropped += z > 0 && expected == 0;
    }
  }
  // Both outcomes occur often (not a test that cannot fail).
  EXPECT_GT(kept, depth.total() / 10);
  EXPECT_GT(dropped, depth.total() / 10);
}

// A step edge 1.0 m | 1.3 m with 2 mm noise: the 0.3 m step is 10 range sigmas at 1 m, so
// the filter must not blend the sides. A blend of even one neighbour column (spatial weight
// >= 0.08 of the window) would move the edge columns' mean by > 5 mm; we allow 1 mm (the
// mean of 120 samples of the filtered noise has a standard deviation < 0.2 mm).
TEST(BuildDepthPyramid, BilateralKeepsAStepEdgeSharp) {
  const PinholeCamera camera = SmallCamera();
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u)
      depth.at<float>(v, u) = (u < 80 ? 1.0f : 1.3f) + noise(rng);
  }
  DepthFilterOptions options;
  options.edge_jump_fraction = 1;  // keep the edge pixels
  const DepthPyramid pyramid = BuildDepthPyramid(depth, camera, options);
  const cv::Mat& filtered = pyramid.levels[0].depth_m;
  for (int u : {77, 78, 79, 80, 81, 82}) {
    double mean = 0;
    for (int v = 0; v < camera.height; ++v) mean += double(filtered.at<float>(v, u));
    mean /= camera.height;
    EXPECT_NEAR(mean, u < 80 ? 1.0 : 1.3, 0.001) << "column " << u;
  }
}

// On a fronto-parallel plane with noise far below the range sigma (1 mm vs 30 mm: range
// weights >= 0.99), the filter is a normalised Gaussian of the window, which scales white
// noise by sqrt(Σ w²) / Σ w. The measured factor (18 000 correlated samples, ~2 % standard
// error) must match within 8 %.
TEST(BuildDepthPyramid, BilateralReducesNoiseByTheSpatialKernelsFactor) {
  const PinholeCamera camera = SmallCamera();
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 0.001f);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) depth.at<float>(v, u) = 1.0f + noise(rng);
  }
  DepthFilterOptions options;
  const DepthPyramid pyramid = BuildDepthPyramid(depth, camera, options);
  double sum_w = 0, sum_w_sq = 0;
  const int r = options.bilateral_radius_px;
  for (int dy = -r; dy <= r; ++dy) {
    for (int dx = -r; dx <= r; ++dx) {
      const double w = std::exp(-(dx * dx + dy * dy) /
                                (2 * options.bilateral_sigma_px * options.bilateral_sigma_px));
      sum_w += w;
      sum_w_sq += w * w;
    }
  }
  const double expected = std::sqrt(sum_w_sq) / sum_w;
  const double before = StdDev(depth, r, 1.0);
  const double after = StdDev(pyramid.levels[0].depth_m, r, 1.0);
  EXPECT_NEAR(after / before, expected, 0.08 * expected);
  EXPECT_LT(expected, 0.3);  // the test means something: the filter removes > 70 % of the noise
}

// The bilateral runs eight pixels at a time with a scalar loop for the rest of each row;
// every pixel must get the same result wherever it falls. Shifting a noisy image with holes
// and a step by 3 columns (width 157: the groups of eight and the tail move over different
// pixels) must shift the filtered image by 3 columns, bit for bit, away from the borders.
TEST(BuildDepthPyramid, BilateralDoesNotDependOnWhereAPixelFallsInARow) {
  const PinholeCamera camera = PinholeCamera::Of(core::CameraModel::Pinhole(157, 37, 140, 140));
  const int shift = 3;
  cv::Mat wide(camera.height, camera.width + shift, CV_32FC1);
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.004f);
  std::uniform_real_distribution<float> hole(0.0f, 1.0f);
  for (int v = 0; v < wide.rows; ++v) {
    for (int u = 0; u < wide.cols; ++u) {
      const float z = (u < 70 ? 1.0f : 1.4f) + 0.002f * float(u) + noise(rng);
      wide.at<float>(v, u) = hole(rng) < 0.05f ? 0.0f : z;
    }
  }
  DepthFilterOptions options;
  options.num_levels = 1;
  const cv::Mat a = wide(cv::Rect(0, 0, camera.width, camera.height)).clone();
  const cv::Mat b = wide(cv::Rect(shift, 0, camera.width, camera.height)).clone();
  const cv::Mat fa = BuildDepthPyramid(a, camera, options).levels[0].depth_m;
  const cv::Mat fb = BuildDepthPyramid(b, camera, options).levels[0].depth_m;
  const int border = options.bilateral_radius_px + 1;  // the flying-pixel test reaches 1 px
  int compared = 0, filtered = 0;
  for (int v = border; v < camera.height - border; ++v) {
    for (int u = border; u + shift < camera.width - border; ++u) {
      ASSERT_EQ(fa.at<float>(v, u + shift), fb.at<float>(v, u)) << "pixel " << u << ", " << v;
      ++compared;
      filtered += fa.at<float>(v, u + shift) != a.at<float>(v, u + shift);
    }
  }
  EXPECT_GT(filtered, compared / 2);  // the filter did change most pixels
}

TEST(BuildDepthPyramid, LevelsHalveTheImageAndTheCamera) {
  const PinholeCamera camera = SmallCamera();
  const cv::Mat depth = PlaneDepth(camera, {0, 0, 0.5f});
  DepthFilterOptions options;
  options.num_levels = 3;
  const DepthPyramid pyramid = BuildDepthPyramid(depth, camera, options);
  ASSERT_EQ(pyramid.levels.size(), 3u);
  PinholeCamera expected = camera;
  for (int l = 0; l < 3; ++l) {
    const DepthLevel& level = pyramid.levels[l];
    EXPECT_EQ(level.camera.width, expected.width);
    EXPECT_EQ(level.camera.height, expected.height);
    EXPECT_EQ(level.camera.fx, expected.fx);
    EXPECT_EQ(level.camera.cx, expected.cx);
    EXPECT_EQ(level.camera.cy, expected.cy);
    EXPECT_EQ(level.depth_m.cols, expected.width);
    EXPECT_EQ(level.depth_m.rows, expected.height);
    EXPECT_EQ(level.map.width, expected.width);
    EXPECT_EQ(level.map.points.size(), size_t(expected.width) * expected.height);
    EXPECT_EQ(level.map.NumValid(), expected.width * expected.height);
    expected = expected.Half();
  }
  EXPECT_EQ(pyramid.levels[2].camera.width, 40);
  EXPECT_EQ(pyramid.levels[2].camera.height, 30);
}

// Points of a plane must lie on it and normals be its normal, at every level. A
// fronto-parallel plane is exact to float rounding. On a tilted plane z = 1 / (affine in u,
// v) is convex, so averaging depths (bilateral window, 2×2 blocks) lifts points off the plane
// by ½ z'' var: here z'' <= 2 (a_u)² z³ ≈ 1e-5 m/px² and var <= 2.3 px² (window) + 1.25 px²
// (4×4 block) per axis, < 50 µm (measured 27 µm); normals of such a smooth bias tilt by
// < 0.1° (measured 0.034°). This holds up to the image border only because the filter's
// support is symmetric: a one-sided window there is biased to first order (the depth
// gradient, ~3 mm/px here, times the window's offset: 4 mm measured).
TEST(BuildDepthPyramid, PlanePointsAndNormalsAreExactAtEveryLevel) {
  const PinholeCamera camera = SmallCamera();
  struct Case {
    Eigen::Vector3f a;
    double point_tolerance_m, normal_tolerance_rad;
  };
  for (const Case& c :
       {Case{{0, 0, 0.5f}, 2e-6, 1e-5}, Case{{0.12f, -0.09f, 0.55f}, 5e-5, 0.1 * M_PI / 180}}) {
    const cv::Mat depth = PlaneDepth(camera, c.a);
    const DepthPyramid pyramid = BuildDepthPyramid(depth, camera, DepthFilterOptions());
    const Eigen::Vector3f unit = c.a.normalized();
    const float offset = 1.0f / c.a.norm();  // plane: unit · p = offset
    for (size_t l = 0; l < pyramid.levels.size(); ++l) {
      const PointMap& map = pyramid.levels[l].map;
      double worst_point = 0, worst_normal = 0;
      int normals = 0;
      for (size_t i = 0; i < map.points.size(); ++i) {
        ASSERT_TRUE(IsValid(map.points[i]));
        worst_point = std::max(worst_point, double(std::abs(unit.dot(map.points[i]) - offset)));
        if (!IsValid(map.normals[i])) continue;
        ++normals;
        EXPECT_LT(map.normals[i].dot(map.points[i]), 0);  // faces the camera
        // atan2 of sine and cosine: acos near 1 would read float rounding as 3e-4 rad.
        const Eigen::Vector3d n = map.normals[i].cast<double>(), u = -unit.cast<double>();
        worst_normal = std::max(worst_normal, std::atan2(n.cross(u).norm(), n.dot(u)));
      }
      EXPECT_EQ(normals, map.width * map.height) << "level " << l;
      EXPECT_LT(worst_point, c.point_tolerance_m) << "level " << l;
      EXPECT_LT(worst_normal, c.normal_tolerance_rad) << "level " << l;
    }
  }
}

// Normals use one-sided differences where a neighbour is missing or beyond the jump limit,
// so a plane's normal stays exact next to a hole and at a step (no normal straddles it).
TEST(BuildDepthPyramid, NormalsAtHolesAndStepsAreOneSided) {
  const PinholeCamera camera = SmallCamera();
  cv::Mat depth = PlaneDepth(camera, {0, 0, 0.5f});
  depth.colRange(100, 160).setTo(3.0f);
  depth.at<float>(60, 40) = 0;
  DepthFilterOptions options;
  options.edge_jump_fraction = 1;
  options.bilateral_radius_px = 0;
  const DepthPyramid pyramid = BuildDepthPyramid(depth, camera, options);
  const PointMap& map = pyramid.levels[0].map;
  for (const auto& [x, y] :
       {std::pair{39, 60}, {41, 60}, {40, 59}, {40, 61}, {99, 30}, {100, 30}}) {
    const Eigen::Vector3f n = map.normals[map.Index(x, y)];
    ASSERT_TRUE(IsValid(n)) << x << " " << y;
    EXPECT_NEAR(n.z(), -1.0f, 1e-6) << x << " " << y;
  }
  EXPECT_FALSE(IsValid(map.points[map.Index(40, 60)]));
  EXPECT_FALSE(IsValid(map.normals[map.Index(40, 60)]));
}

// The normals, vectorised eight pixels at a time inside a row, against their per-pixel
// definition (central differences of the points, one-sided at a missing or jumping
// neighbour, towards the camera) on an odd width, with holes and jumps both sides of the
// limit: every normal equal, bit for bit.
TEST(BuildDepthPyramid, NormalsMatchThePerPixelDefinition) {
  const PinholeCamera camera = PinholeCamera::Of(core::CameraModel::Pinhole(157, 23, 140, 140));
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  cv::Mat depth = PlaneDepth(camera, {0.1f, 0.05f, 0.5f});
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const float r = uniform(rng);
      float& z = depth.at<float>(v, u);
      z = r < 0.1f ? 0.0f : z * (1.0f + 0.12f * (uniform(rng) - 0.5f));  // ±6 %: limit 5 %
    }
  }
  DepthFilterOptions options;
  options.num_levels = 1;
  options.bilateral_radius_px = 0;
  options.edge_jump_fraction = 1;  // the pyramid keeps every valid depth
  const PointMap map = BuildDepthPyramid(depth, camera, options).levels[0].map;
  const float limit_fraction = float(options.normal_max_jump_fraction);
  auto point = [&](int u, int v) -> const Eigen::Vector3f* {
    if (u < 0 || v < 0 || u >= camera.width || v >= camera.height) return nullptr;
    return &map.points[map.Index(u, v)];
  };
  int valid = 0, one_sided = 0;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3f& p = *point(u, v);
      const Eigen::Vector3f& n = map.normals[map.Index(u, v)];
      auto usable = [&](const Eigen::Vector3f* q) {
        return q != nullptr && std::abs((*q).z() - p.z()) <= limit_fraction * p.z() ? q : nullptr;
      };
      const Eigen::Vector3f *right = usable(point(u + 1, v)), *left = usable(point(u - 1, v));
      const Eigen::Vector3f *below = usable(point(u, v + 1)), *above = usable(point(u, v - 1));
      if (!IsValid(p) || (!right && !left) || (!below && !above)) {
        ASSERT_FALSE(IsValid(n)) << u << " " << v;
        continue;
      }
      const Eigen::Vector3f du = (right ? *right : p) - (left ? *left : p);
      const Eigen::Vector3f dv = (below ? *below : p) - (above ? *above : p);
      const float nx = du.y() * dv.z() - du.z() * dv.y(), ny = du.z() * dv.x() - du.x() * dv.z(),
                  nz = du.x() * dv.y() - du.y() * dv.x();
      const float scale =
          (nx * p.x() + ny * p.y() + nz * p.z() > 0 ? -1.0f : 1.0f) / std::sqrt(nx * nx + ny * ny + nz * nz);
      ASSERT_TRUE(IsValid(n)) << u << " " << v;
      ASSERT_EQ(n, Eigen::Vector3f(nx * scale, ny * scale, nz * scale)) << u << " " << v;
      ++valid;
      one_sided += !right || !left || !below || !above;
    }
  }
  EXPECT_GT(valid, camera.width * camera.height / 2);
  EXPECT_GT(one_sided, camera.width * camera.height / 10);
}

TEST(BuildDepthPyramid, ThreadCountDoesNotChangeTheResult) {
  const PinholeCamera camera = SmallCamera();
  cv::Mat depth = PlaneDepth(camera, {0.1f, 0.05f, 0.5f});
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 0.003f);
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) depth.at<float>(v, u) += noise(rng);
  }
  DepthFilterOptions one, three;
  one.num_threads = 1;
  three.num_threads = 3;
  const DepthPyramid a = BuildDepthPyramid(depth, camera, one);
  const DepthPyramid b = BuildDepthPyramid(depth, camera, three);
  for (size_t l = 0; l < a.levels.size(); ++l) {
    EXPECT_EQ(cv::norm(a.levels[l].depth_m, b.levels[l].depth_m, cv::NORM_INF), 0);
    for (size_t i = 0; i < a.levels[l].map.normals.size(); ++i) {
      const Eigen::Vector3f& na = a.levels[l].map.normals[i];
      const Eigen::Vector3f& nb = b.levels[l].map.normals[i];
      ASSERT_EQ(IsValid(na), IsValid(nb));
      if (IsValid(na)) {
        ASSERT_EQ(na, nb);
      }
    }
  }
}

TEST(BuildDepthPyramid, FirstMapLevelSkipsOnlyTheFinerMaps) {
  const PinholeCamera camera = SmallCamera();
  const cv::Mat depth = PlaneDepth(camera, {0.1f, 0.05f, 0.5f});
  DepthFilterOptions all, coarse;
  coarse.first_map_level = 1;
  const DepthPyramid a = BuildDepthPyramid(depth, camera, all);
  const DepthPyramid b = BuildDepthPyramid(depth, camera, coarse);
  ASSERT_EQ(a.levels.size(), b.levels.size());
  EXPECT_TRUE(b.levels[0].map.points.empty());
  EXPECT_EQ(cv::norm(a.levels[0].depth_m, b.levels[0].depth_m, cv::NORM_INF), 0);
  for (size_t l = 1; l < a.levels.size(); ++l) {
    EXPECT_EQ(cv::norm(a.levels[l].depth_m, b.levels[l].depth_m, cv::NORM_INF), 0);
    ASSERT_EQ(a.levels[l].map.points.size(), b.levels[l].map.points.size());
    for (size_t i = 0; i < a.levels[l].map.points.size(); ++i) {
      ASSERT_EQ(IsValid(a.levels[l].map.points[i]), IsValid(b.levels[l].map.points[i]));
      if (IsValid(a.levels[l].map.points[i])) {
        ASSERT_EQ(a.levels[l].map.points[i], b.levels[l].map.points[i]);
      }
    }
  }
  coarse.first_map_level = 3;
  EXPECT_NE(coarse.Check().find("first_map_level"), std::string::npos);
}

}  // namespace
}  // namespace hw::reconstruct
