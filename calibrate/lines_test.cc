// Unit tests of the line extraction of the targetless extrinsics: 3D lines of a synthetic
// depth image (calibrate/lines_3d.h), 2D lines of a synthetic image (calibrate/lines_2d.h).

#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "calibrate/lines_2d.h"
#include "calibrate/lines_3d.h"

namespace hw::calibrate {
namespace {

core::CameraModel DepthCamera() {
  core::CameraModel k = core::CameraModel::Pinhole(320, 240, 285, 285);
  k.cx = 159.5;
  k.cy = 119.5;
  return k;
}

// Ray-traced depth of planes n·p + d = 0 (nearest hit in front), quantised like a
// structured-light sensor (disparity steps of 1/8 px at f 285, baseline 7.5 cm) plus noise.
cv::Mat RenderPlanes(const core::CameraModel& k, const std::vector<Eigen::Vector4d>& planes, double noise_m,
                     uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, 1);
  cv::Mat depth(k.height, k.width, CV_32FC1, cv::Scalar(0));
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const Eigen::Vector3d ray = *k.Unproject(Eigen::Vector2d(u, v));
      double z = 0;
      for (const Eigen::Vector4d& p : planes) {
        const double denom = p.head<3>().dot(ray);
        if (std::abs(denom) < 1e-9) continue;
        const double zz = -p[3] / denom;
        if (zz > 0.3 && (z == 0 || zz < z)) z = zz;
      }
      if (z == 0) continue;
      z += noise_m * z * z * noise(rng);
      const double disparity = 285 * 0.075 / z;
      z = 285 * 0.075 / (std::round(disparity * 8) / 8);
      depth.at<float>(v, u) = static_cast<float>(z);
    }
  }
  return depth;
}

double PointLineDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& on_line, const Eigen::Vector3d& dir) {
  const Eigen::Vector3d d = p - on_line;
  return (d - d.dot(dir) * dir).norm();
}

// Two planes meeting at a vertical edge 2.5 m away (a room corner: the renderer keeps each
// ray's nearest hit, so the edge is the farthest line), with structured-light quantisation (1.8 cm
// steps at 2.5 m) and noise: one fold line, within 1 cm of the true intersection (each
// plane is fitted to ~30 000 points, so its offset is good to a millimetre; the line's
// position errs by offset / sin(90°) plus the tilt × the half-length, 0.05° × 1 m ≈ 1 mm;
// 1 cm leaves margin for the quantisation's correlated error) and within 1° of its
// direction, spanning most of the image height.
TEST(DepthLines, TwoPlanesGiveTheirIntersection) {
  const core::CameraModel k = DepthCamera();
  const Eigen::Vector3d corner(0.1, 0, 2.5);
  const Eigen::Vector3d n1 = Eigen::Vector3d(1, 0, -1).normalized();
  const Eigen::Vector3d n2 = Eigen::Vector3d(-1, 0, -1).normalized();
  // Planes n·p + d = 0 through the edge.
  const std::vector<Eigen::Vector4d> planes = {Eigen::Vector4d(-n1.x(), -n1.y(), -n1.z(), n1.dot(corner)),
                                               Eigen::Vector4d(-n2.x(), -n2.y(), -n2.z(), n2.dot(corner))};
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const cv::Mat depth = RenderPlanes(k, planes, 0.002, seed);
    DepthLineStats stats;
    const auto lines = ExtractDepthLines(depth, DepthRays(k), 285, DepthLineOptions{}, &stats);
    EXPECT_EQ(stats.planes, 2) << "seed " << seed;
    int folds = 0;
    for (const Segment3d& s : lines) {
      if (s.kind != LineKind::kFold) continue;
      ++folds;
      const Eigen::Vector3d dir = Eigen::Vector3d::UnitY();
      EXPECT_LT(PointLineDistance(s.a, corner, dir), 0.01) << "seed " << seed;
      EXPECT_LT(PointLineDistance(s.b, corner, dir), 0.01) << "seed " << seed;
      const double angle_deg = std::acos(std::abs((s.b - s.a).normalized().dot(dir))) * 180 / M_PI;
      EXPECT_LT(angle_deg, 1.0) << "seed " << seed;
      // The corner spans the image height: ±119.5 px at 285 px → ±1.05 m at 2.5 m.
      EXPECT_GT(s.Length(), 1.5) << "seed " << seed;
    }
    EXPECT_EQ(folds, 1) << "seed " << seed;
  }
}

// A box face in front of a wall: its outline is an occlusion line on the FOREGROUND plane
// (z = 1.2 m), within 1.5 cm of the true outline (the edge pixel is placed half a pixel
// towards the background, so the error is the quantised outline's, < 0.5 px ≈ 2 mm, plus
// the plane fit; 1.5 cm also covers the fit's tilt at the segment ends), never on the wall.
TEST(DepthLines, OcclusionEdgeIsOnTheForeground) {
  const core::CameraModel k = DepthCamera();
  // Wall z = 3; a square plate z = 1.2 spanning x in [-0.3, 0.25], y in [-0.2, 0.3].
  cv::Mat depth = RenderPlanes(k, {Eigen::Vector4d(0, 0, -1, 3.0)}, 0.002, 7);
  const cv::Mat plate = RenderPlanes(k, {Eigen::Vector4d(0, 0, -1, 1.2)}, 0.002, 8);
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      const double x = (u - k.cx) / k.fx * 1.2, y = (v - k.cy) / k.fy * 1.2;
      if (x >= -0.3 && x <= 0.25 && y >= -0.2 && y <= 0.3) depth.at<float>(v, u) = plate.at<float>(v, u);
    }
  }
  const auto lines = ExtractDepthLines(depth, DepthRays(k), 285, DepthLineOptions{});
  int occlusions = 0;
  for (const Segment3d& s : lines) {
    ASSERT_EQ(s.kind, LineKind::kOcclusion);
    ++occlusions;
    EXPECT_NEAR(s.a.z(), 1.2, 0.02);
    EXPECT_NEAR(s.b.z(), 1.2, 0.02);
    // Each end lies on one of the four outline lines.
    for (const Eigen::Vector3d& p : {s.a, s.b}) {
      const double d = std::min({std::abs(p.x() + 0.3), std::abs(p.x() - 0.25), std::abs(p.y() + 0.2), std::abs(p.y() - 0.3)});
      EXPECT_LT(d, 0.015) << p.transpose();
    }
    EXPECT_GT(s.edge_shift_per_px.norm(), 0.0);
  }
  EXPECT_EQ(occlusions, 4);
}

TEST(DepthLines, OptionsCheckNamesTheField) {
  DepthLineOptions o;
  EXPECT_EQ(o.Check(), "");
  o.max_depth_m = 0.1;
  EXPECT_NE(o.Check().find("max_depth_m"), std::string::npos);
}

// A blurred, noisy image of a bright quadrilateral (σ 1.2 px blur: a thermal lens; noise
// 2 % of the contrast, 1 °C over 21 °C: a low-contrast thermal scene): LSD finds its four
// sides, every segment's midpoint within 0.4 px and its ends within 0.6 px of a true side,
// direction within 4° (the noise moves a short piece's ends by a few tenths of a pixel,
// with alternating signs: no bias; measured up to 0.37 px at the midpoint, 0.48 px at an
// end).
TEST(ImageLines, FindsTheSidesOfABlurredLowContrastShape) {
  const std::vector<Eigen::Vector2d> corners = {{40.3, 30.2}, {120.6, 36.9}, {112.4, 95.1}, {35.8, 88.4}};
  cv::Mat image(120, 160, CV_32FC1);
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      // Supersampled coverage of the convex quadrilateral.
      int inside = 0;
      for (int sy = 0; sy < 4; ++sy) {
        for (int sx = 0; sx < 4; ++sx) {
          const Eigen::Vector2d p(u - 0.375 + 0.25 * sx, v - 0.375 + 0.25 * sy);
          bool in = true;
          for (int i = 0; i < 4; ++i) {
            const Eigen::Vector2d a = corners[i], b = corners[(i + 1) % 4];
            const Eigen::Vector2d d = b - a;
            in = in && (d.x() * (p.y() - a.y()) - d.y() * (p.x() - a.x())) > 0;
          }
          inside += in;
        }
      }
      image.at<float>(v, u) = static_cast<float>(21.0 + 1.0 * inside / 16.0);  // 21–22 °C
    }
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.2);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0, 0.02);
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) image.at<float>(v, u) += static_cast<float>(noise(rng));
  }
  ImageLineOptions options;
  const auto segments = DetectImageLines(StretchThermal(image, cv::Mat(), options), cv::Mat(), options);
  // Every segment lies on a side.
  std::vector<double> covered(4, 0.0);
  for (const Segment2d& s : segments) {
    bool on_a_side = false;
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector2d a = corners[i], b = corners[(i + 1) % 4];
      const Eigen::Vector2d dir = (b - a).normalized(), n(-dir.y(), dir.x());
      const double angle_deg = std::acos(std::min(1.0, std::abs((s.b - s.a).normalized().dot(dir)))) * 180 / M_PI;
      const double da = n.dot(s.a - a), db = n.dot(s.b - a);
      if (angle_deg > 4.0 || std::abs(da) > 0.6 || std::abs(db) > 0.6 || std::abs(da + db) / 2 > 0.4) continue;
      on_a_side = true;
      covered[i] += s.Length() / (b - a).norm();
    }
    // Pieces ending near a corner, which the blur rounds over a few pixels, may bend.
    bool near_corner = false;
    for (const auto& c : corners) near_corner = near_corner || (s.a - c).norm() < 8 || (s.b - c).norm() < 8;
    if (!near_corner) {
      EXPECT_TRUE(on_a_side) << s.a.transpose() << " " << s.b.transpose();
    }
  }
  // Each side found (LSD fragments a noisy low-contrast edge: pieces covered 23–100 % of
  // a side here; the alignment uses every piece).
  for (int i = 0; i < 4; ++i) EXPECT_GT(covered[i], 0.1) << "side " << i;
}

// The rectifier of a distorting lens: a straight 3D line images as a curve in the raw
// image and, resampled, as a straight line of the pinhole camera.
TEST(ImageLines, RectifierMapsToThePinholeCamera) {
  core::CameraModel k = core::CameraModel::Pinhole(160, 120, 148, 148);
  k.type = core::CameraModelType::kOpenCV;
  k.distortion = {-0.27, 0.12, 0.0008, -0.0005, -0.02};
  const Rectifier rectifier(k);
  EXPECT_EQ(rectifier.pinhole().type, core::CameraModelType::kPinhole);
  // A raw image whose value is the raw pixel's x: rectified, pixel (u, v) holds the x of
  // Project(K⁻¹ (u, v)).
  cv::Mat raw(120, 160, CV_32FC1);
  for (int v = 0; v < 120; ++v) {
    for (int u = 0; u < 160; ++u) raw.at<float>(v, u) = static_cast<float>(u);
  }
  const cv::Mat rect = rectifier.Apply(raw);
  for (const auto& [u, v] : std::vector<std::pair<int, int>>{{20, 15}, {80, 60}, {140, 100}}) {
    const Eigen::Vector2d src = k.Project(Eigen::Vector3d((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1));
    // cv::remap interpolates with 5-bit weights: within 1/32 px.
    EXPECT_NEAR(rect.at<float>(v, u), src.x(), 1.0 / 32) << u << " " << v;
  }
}

}  // namespace
}  // namespace hw::calibrate
