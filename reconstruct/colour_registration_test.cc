#include "reconstruct/colour_registration.h"

#include <cmath>
#include <cstdint>

#include <Eigen/Geometry>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "reconstruct/depth_frame.h"

namespace hw::reconstruct {
namespace {

// A rolling-shutter colour camera moving sideways at 2 m/s during a 30 ms readout: row v of
// its image was exposed at δ_v = 0.03 (v − 59.5) / 120 s, from x_v = 0.05 + 2 δ_v m, and each
// row shows the wall z = 1 m red left of x = 0 and blue right of it (the boundary at column
// 79.5 − 120 x_v of that row: 6 columns apart from top to bottom). Registered with the pose
// of each band of rows, every depth pixel farther than 1.5 px from the boundary gets its side's
// grey level (32 bands: a band's pose is within 0.25 px of its rows'; the nearest pixel
// 0.5 px); with the middle row's pose alone the top and bottom rows are 3 px off.
TEST(RegisterGrey, RollingShutterRowsAreProjectedWithThePoseOfTheirExposure) {
  const PinholeCamera camera{160, 120, 120.0f, 120.0f, 79.5f, 59.5f};
  const cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(1.0f));
  const double readout_s = 0.03;
  const auto x_at = [](double delta_s) { return 0.05 + 2.0 * delta_s; };
  cv::Mat rgb(camera.height, camera.width, CV_8UC3, cv::Scalar(255, 0, 0));
  for (int v = 0; v < camera.height; ++v) {
    const double boundary = 79.5 - 120 * x_at(readout_s * (v - 59.5) / 120);
    for (int u = 0; u < camera.width; ++u) {
      if (u > boundary) rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(0, 0, 255);
    }
  }
  const auto rgb_from_depth_at = [&](double delta_s) {
    return core::Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-x_at(delta_s), 0, 0));
  };
  const auto wrong_pixels = [&](const cv::Mat& registered) {
    int wrong = 0, checked = 0;
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const double world_x = (x - 79.5) / 120;  // the depth pixel's point on the wall
        if (std::abs(world_x) < 1.5 / 120) continue;
        const float expected = world_x < 0 ? 0.299f : 0.114f;  // red, blue: Rec. 601 luma
        const float got = registered.at<float>(y, x);
        if (got == 0) continue;  // beyond the colour image's edge
        ++checked;
        wrong += std::abs(got - expected) > 1e-6f;
      }
    }
    EXPECT_GT(checked, 15000);
    return wrong;
  };
  EXPECT_EQ(wrong_pixels(RegisterGrey(depth, camera, rgb, camera, 1, rgb_from_depth_at(0), 1, readout_s,
                                      rgb_from_depth_at)),
            0);
  EXPECT_GT(wrong_pixels(RegisterGrey(depth, camera, rgb, camera, 1, rgb_from_depth_at(0), 1)), 100);
}

// Registration runs eight pixels at a time with the row's end per pixel: a pixel's grey
// level must not depend on where it falls. The same depth image registered with 3 columns
// more on its left (the principal point moved with them, so every pixel has the same ray)
// must give the same grey levels bit for bit, on an odd width (157: both paths at every
// column), with holes, NaN and inf depths, samples beyond the colour image, a rolling shutter
// turning fast enough that rows of pixels straddle bands, at levels n = 1 and 2.
TEST(RegisterGrey, APixelsGreyDoesNotDependOnWhereItFallsInARow) {
  const int width = 157, height = 41, shift = 3;
  cv::Mat wide(height, width + shift, CV_32FC1);
  cv::RNG rng(7);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < wide.cols; ++u) {
      const float r = static_cast<float>(rng.uniform(0.0, 1.0));
      wide.at<float>(v, u) = r < 0.05f ? 0.0f : r < 0.07f ? NAN : r < 0.09f ? INFINITY : 0.8f + 0.01f * u + 0.4f * r;
    }
  }
  cv::Mat rgb(100, 140, CV_8UC3);
  rng.fill(rgb, cv::RNG::UNIFORM, 0, 256);
  const PinholeCamera rgb_camera{140, 100, 95.0f, 95.0f, 69.5f, 49.5f};
  const double readout_s = 0.03;
  // Turning at 6 rad/s about the vertical axis: 0.18 rad during the readout, the bands'
  // poses 0.3 px apart at the image's centre.
  const auto rgb_from_depth_at = [](double delta_s) {
    return core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.02 + 6.0 * delta_s, Eigen::Vector3d::UnitY())),
                         Eigen::Vector3d(-0.03, 0.01, 0));
  };
  for (const int n : {1, 2}) {
    const PinholeCamera left{width, height, 110.0f, 110.0f, 70.5f, 20.5f};
    PinholeCamera shifted = left;
    shifted.width += shift;
    shifted.cx += shift;
    const cv::Mat a = wide(cv::Rect(shift, 0, width, height)).clone();
    const cv::Mat ga = RegisterGrey(a, left, rgb, rgb_camera, n, rgb_from_depth_at(0), 1, readout_s, rgb_from_depth_at);
    const cv::Mat gb =
        RegisterGrey(wide, shifted, rgb, rgb_camera, n, rgb_from_depth_at(0), 1, readout_s, rgb_from_depth_at);
    int grey = 0, none = 0;
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const float value = ga.at<float>(v, u);
        ASSERT_EQ(value, gb.at<float>(v, u + shift)) << "n " << n << " pixel " << u << ", " << v;
        (value > 0 ? grey : none)++;
      }
    }
    // Most pixels registered, and holes and pixels off the colour image left at 0.
    EXPECT_GT(grey, width * height / 2);
    EXPECT_GT(none, width * height / 20);
  }
}

// A slanted wall (z = 1.5 m + 0.25 x) seen by a 160×120 depth camera, the colour camera
// 3 cm beside it (2.4 px of parallax), its image a smooth pattern whose grey level changes at
// most 0.033 per pixel. At full size (n = 1) each pixel is the luma of the colour pixel
// nearest to where its point lands (all but points within float rounding of a pixel
// border). RegisterGrey on pyramid level 1 (n = 2) and 2 (n = 4) against that registration
// averaged down (SetIntensity): one projection per coarse pixel and offsets of a fine
// pixel's footprint land where the fine pixels' own projections land, up to the wall's
// perspective (hundredths of a pixel) and the coarse depth (the fine depths' mean): a sample
// may round to the neighbouring pixel, which moves a level-1 mean by at most 0.033 / 4 — most
// pixels agree exactly, none by more than two such samples.
TEST(RegisterGrey, EqualsTheFullSizeRegistrationAveragedDown) {
  const PinholeCamera camera{160, 120, 120.0f, 120.0f, 79.5f, 59.5f};
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double ray_x = (x - 79.5) / 120.0;
      depth.at<float>(y, x) = static_cast<float>(1.5 / (1 - 0.25 * ray_x));  // z = 1.5 + 0.25 X
    }
  }
  cv::Mat rgb(camera.height, camera.width, CV_8UC3);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const double g = 0.5 + 0.3 * std::sin(u / 9.0) * std::cos(v / 11.0);
      const auto level = static_cast<std::uint8_t>(std::lround(255 * g));
      rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(level, static_cast<std::uint8_t>(level / 2), 255 - level);
    }
  }
  const core::Rigid3d rgb_from_depth(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.03, 0, 0));
  DepthFilterOptions filter;
  filter.num_threads = 1;
  DepthPyramid reference = BuildDepthPyramid(depth, camera, filter);
  const cv::Mat full = RegisterGrey(reference.levels[0].depth_m, camera, rgb, camera, 1, rgb_from_depth, 1);
  int nearest = 0, inner = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 10; x + 10 < camera.width; ++x) {
      const double z = reference.levels[0].depth_m.at<float>(y, x);
      const double u = 120.0 * ((x - 79.5) / 120.0 * z - 0.03) / z + 79.5;  // v = y: no vertical offset
      const cv::Vec3b c = rgb.at<cv::Vec3b>(y, static_cast<int>(std::lround(u)));
      const double luma = (0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]) / 255;
      ++inner;
      nearest += std::abs(double{full.at<float>(y, x)} - luma) < 1e-6;
    }
  }
  EXPECT_GT(nearest, inner * 99 / 100);
  SetIntensity(reference, full, 0, 1);

  for (int level : {1, 2}) {
    const DepthLevel& coarse = reference.levels[level];
    const cv::Mat grey = RegisterGrey(coarse.depth_m, coarse.camera, rgb, camera, 1 << level, rgb_from_depth, 2);
    int compared = 0, equal = 0;
    double worst = 0;
    // Inner pixels: at the border a fine pixel's colour may lie outside the image where the
    // coarse one's samples differ.
    for (int y = 2; y + 2 < coarse.camera.height; ++y) {
      for (int x = 2; x + 2 < coarse.camera.width; ++x) {
        const double d = std::abs(double{grey.at<float>(y, x)} - double{coarse.intensity.at<float>(y, x)});
        ++compared;
        equal += d < 1e-6;
        worst = std::max(worst, d);
      }
    }
    EXPECT_GT(equal, compared * 9 / 10) << "level " << level;
    EXPECT_LT(worst, 2 * 0.033 / 4 + 1e-6) << "level " << level;
  }
}

// Samples beyond the colour image count black, a coarse pixel without depth gets 0: a white
// image seen 8 px shifted (the colour camera 0.1 m aside at 1.5 m, f 120) leaves the coarse
// pixels whose footprint crosses its edge partly black.
TEST(RegisterGrey, SamplesOutsideTheImageCountBlack) {
  const PinholeCamera fine{160, 120, 120.0f, 120.0f, 79.5f, 59.5f};
  const PinholeCamera coarse = fine.Half();
  cv::Mat depth(coarse.height, coarse.width, CV_32FC1, cv::Scalar(1.5f));
  depth.at<float>(10, 10) = 0;
  const cv::Mat rgb(fine.height, fine.width, CV_8UC3, cv::Scalar(255, 255, 255));
  // u_colour = u_depth − 8 fine pixels: fine column u lands on u − 8.
  const core::Rigid3d rgb_from_depth(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1, 0, 0));
  const cv::Mat grey = RegisterGrey(depth, coarse, rgb, fine, 2, rgb_from_depth, 1);
  EXPECT_FLOAT_EQ(grey.at<float>(10, 10), 0.0f);
  EXPECT_NEAR(grey.at<float>(20, 40), 1.0f, 1e-6);
  // Coarse column 3 covers fine columns 6 and 7, which land on −2 and −1: outside.
  EXPECT_NEAR(grey.at<float>(20, 3), 0.0f, 1e-6);
  // Coarse column 4 covers fine columns 8 and 9, landing on 0 and 1: inside.
  EXPECT_NEAR(grey.at<float>(20, 4), 1.0f, 1e-6);
}

}  // namespace
}  // namespace hw::reconstruct
