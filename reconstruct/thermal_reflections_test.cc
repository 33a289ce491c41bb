#include "reconstruct/thermal_reflections.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "reconstruct/raycast.h"
#include "reconstruct/thermal_fusion.h"
#include "reconstruct/thermal_fusion_test_support.h"

namespace hw::reconstruct {
namespace {

using namespace test;  // thermal_fusion_test_support.h: the rig, the plane z = 1, LookAt

constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(ThermalReflections, CheckNamesTheField) {
  EXPECT_EQ(ThermalReflectionOptions().Check(), "");
  ThermalReflectionOptions o;
  o.min_specular_weight = 1.5;
  EXPECT_NE(o.Check().find("min_specular_weight"), std::string::npos) << o.Check();
  o = {};
  o.operator_half_width_m = 0;
  EXPECT_NE(o.Check().find("operator_half_width_m"), std::string::npos) << o.Check();
  o = {};
  o.max_distance_m = kInf;
  EXPECT_NE(o.Check().find("max_distance_m"), std::string::npos) << o.Check();
  ThermalFusionOptions f;
  f.reflections.operator_distance_m = -1;
  EXPECT_NE(f.Check().find("reflections.operator_distance_m"), std::string::npos) << f.Check();
}

TEST(ThermalReflections, SpecularFractionByLawUnlessGiven) {
  SurfaceEmissivity s;
  s.law = core::EmissivityLaw::kMetal;
  EXPECT_EQ(SpecularFraction(s), 0.9);
  s.law = core::EmissivityLaw::kDielectric;
  EXPECT_EQ(SpecularFraction(s), 0.2);
  s.specular_fraction = 0.55;
  EXPECT_EQ(SpecularFraction(s), 0.55);
  EXPECT_TRUE(MirrorDirection(Eigen::Vector3f(0.6f, 0, 0.8f), Eigen::Vector3f(0, 0, -1))
                  .isApprox(Eigen::Vector3f(0.6f, 0, -0.8f)));
}

// The body: an ellipse 0.4 m behind the camera, semi-axes 0.2 (x) and 0.35 (y), centred
// 0.15 m below the axis (camera y down). Camera at (1, 2, 3) looking along world +x, so
// camera z = world x and the body's plane is world x = 0.6.
TEST(ThermalReflections, OperatorBodyIsAnEllipseBehindTheCamera) {
  ThermalReflectionOptions o;
  const core::Rigid3d pose = LookAt(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(2, 2, 3), Eigen::Vector3d(0, 0, 1));
  const Eigen::Vector3d down = pose.rotation * Eigen::Vector3d::UnitY();  // world +z here
  const Eigen::Vector3d right = pose.rotation * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d back(-1, 0, 0);
  // From a surface 2 m in front, straight back through the camera: 2.4 m to the body.
  const Eigen::Vector3d surface(3, 2, 3);
  const std::optional<double> t = IntersectOperatorBody(o, pose, surface, back);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 2.4, 1e-12);
  // Aimed at the body's plane 0.19 m right of the centre line (inside the 0.2 half width, at
  // the centre's height), then 0.21 m (outside).
  const Eigen::Vector3d centre = Eigen::Vector3d(0.6, 2, 3) + 0.15 * down;
  for (const auto& [offset, hits] : std::vector<std::pair<double, bool>>{{0.19, true}, {0.21, false}}) {
    const Eigen::Vector3d target = centre + offset * right;
    const std::optional<double> d = IntersectOperatorBody(o, pose, surface, (target - surface).normalized());
    EXPECT_EQ(d.has_value(), hits) << offset;
    if (d) {
      EXPECT_NEAR(*d, (target - surface).norm(), 1e-9);
    }
  }
  // Along y: 0.34 below the centre is in, 0.36 out; above the axis by 0.15 + 0.34 likewise.
  for (const auto& [offset, hits] :
       std::vector<std::pair<double, bool>>{{0.34, true}, {0.36, false}, {-0.34, true}, {-0.36, false}}) {
    const Eigen::Vector3d target = centre + offset * down;
    EXPECT_EQ(IntersectOperatorBody(o, pose, surface, (target - surface).normalized()).has_value(), hits) << offset;
  }
  // Forwards (away from the body), parallel to its plane, or with the body switched off: none.
  EXPECT_FALSE(IntersectOperatorBody(o, pose, surface, -back).has_value());
  EXPECT_FALSE(IntersectOperatorBody(o, pose, surface, right).has_value());
  o.operator_body = false;
  EXPECT_FALSE(IntersectOperatorBody(o, pose, surface, back).has_value());
}

TEST(ThermalReflections, TraceSurfaceFindsThePlaneFromTheFrontOnly) {
  const TsdfVolume volume = PlaneVolume();
  TsdfSampler sampler(volume);
  const OccupiedRegions occupied(volume);
  // Regions of 64 cm at 1 cm voxels: the plane z = 1 m lies in z-region 1; at z = −1 m
  // (region −2) there is nothing.
  EXPECT_FLOAT_EQ(occupied.region_m(), 0.64f);
  EXPECT_TRUE(occupied.Contains(0, 0, 1));
  EXPECT_FALSE(occupied.Contains(0, 0, -2));
  // Block by block and region by region: the same answers.
  for (const OccupiedRegions* regions : {static_cast<const OccupiedRegions*>(nullptr), &occupied}) {
    SCOPED_TRACE(regions ? "regions" : "blocks");
    auto trace = [&](const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float start_m, float max_m) {
      return TraceSurface(volume, sampler, origin, direction, start_m, max_m, regions);
    };
    // From 0.5 m in front and from 2 m (through absent blocks and regions): the plane at
    // z = 1, to the raycast's tolerance (a fraction of a voxel).
    for (const double z0 : {0.5, -1.0}) {
      EXPECT_NEAR(trace(Eigen::Vector3f(0.02f, -0.01f, static_cast<float>(z0)), Eigen::Vector3f(0, 0, 1), 0, 5),
                  1.0 - z0, 0.003)
          << z0;
    }
    // Obliquely (40°): the same plane at 0.5 / cos 40°.
    const Eigen::Vector3f oblique(std::sin(0.698f), 0, std::cos(0.698f));
    EXPECT_NEAR(trace(Eigen::Vector3f(-0.1f, 0, 0.5f), oblique, 0, 5), 0.5 / std::cos(0.698), 0.004);
    // Away from it, from behind it, and starting on it towards the cameras: nothing.
    EXPECT_EQ(trace(Eigen::Vector3f(0, 0, 0.5f), Eigen::Vector3f(0, 0, -1), 0, 5), kInf);
    EXPECT_EQ(trace(Eigen::Vector3f(0, 0, 1.5f), Eigen::Vector3f(0, 0, -1), 0, 5), kInf);
    EXPECT_EQ(trace(Eigen::Vector3f(0, 0, 1.0f), Eigen::Vector3f(0.3f, 0, -0.954f), 0.015f, 5), kInf);
    // Beyond max_m: nothing.
    EXPECT_EQ(trace(Eigen::Vector3f(0, 0, 0.5f), Eigen::Vector3f(0, 0, 1), 0, 0.4f), kInf);
  }
}

// A thermal raycast of the plane from 0.8 m: a metal plane's every hit is traced (weight
// (1 − ε)·0.9 ≥ 0.6), a paint's seen within 40° of its normal none ((1 − 0.95)·0.2 = 0.01,
// below 0.05); the mirror rays go back past the camera, where the model has nothing: +inf.
TEST(ThermalReflections, ReflectPixelsTracesWhereTheSpecularWeightIsEnough) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = PlaneVolume();
  const core::Rigid3d pose = LookAt(Eigen::Vector3d(0, 0, 0.2), Eigen::Vector3d(0, 0, kPlaneZ));
  const CameraRays rays(*rig.thermal);
  RaycastOptions raycast;
  const PointMap map = Raycast(volume, rays, pose, raycast);
  const int valid = map.NumValid();
  ASSERT_GT(valid, 1000);
  for (const bool metal : {true, false}) {
    const EmissivityMap emissivity = EmissivityMap::FromLookup(
        *rig.thermal_settings, [metal](const Eigen::Vector3f&, SurfaceEmissivity& out) {
          out.emissivity = metal ? 0.3 : 0.95;
          out.law = metal ? core::EmissivityLaw::kMetal : core::EmissivityLaw::kDielectric;
          return true;
        });
    int traced = -1;
    const std::vector<PixelReflection> pixels = ReflectPixels(volume, map, pose.translation.cast<float>(), emissivity,
                                                              ThermalReflectionOptions(), 0.0f, 2, &traced);
    int with_normal = 0, infinite = 0;
    for (size_t i = 0; i < pixels.size(); ++i) {
      if (!IsValid(map.points[i]) || !IsValid(map.normals[i])) {
        EXPECT_TRUE(std::isnan(pixels[i].mirror_m));
        continue;
      }
      ++with_normal;
      infinite += std::isinf(pixels[i].mirror_m);
      EXPECT_GT(pixels[i].emissivity_at_angle, metal ? 0.29f : 0.9f);
    }
    EXPECT_GT(with_normal, valid * 9 / 10);
    EXPECT_EQ(traced, metal ? with_normal : 0) << metal;
    EXPECT_EQ(infinite, metal ? with_normal : 0) << metal;
  }
}

// Metal (ε 0.3, the mirror share of its reflectance 0.9) seen head-on reflects the operator:
// each pixel's mirror ray leaves the plane towards the camera and meets the body (32 °C)
// where the ellipse is, the room (18 °C) elsewhere. Rendered so (the reflection computed here
// from the geometry), the surface temperature comes back to the splat's error with the
// reflections traced, and is tens of kelvin off under the body without.
TEST(ThermalReflections, MetalSeenHeadOnReflectsTheOperator) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = PlaneVolume();
  const core::BandRadiance band(rig.thermal_settings->spectral_band_um[0], rig.thermal_settings->spectral_band_um[1]);
  const double room = band.Radiance(core::CelsiusToKelvin(rig.thermal_settings->reflected_c));
  const double body = band.Radiance(core::CelsiusToKelvin(32.0));
  constexpr double kEmissivity = 0.3, kSpecular = 0.9;
  const auto lookup = [](const Eigen::Vector3f&, SurfaceEmissivity& out) {
    out.emissivity = kEmissivity;
    out.law = core::EmissivityLaw::kMetal;
    out.specular_fraction = kSpecular;
    return true;
  };
  // Head-on, a slow sideways sweep.
  std::vector<core::Rigid3d> poses;
  for (int i = 0; i <= 6; ++i) {
    const double x = -0.03 + 0.01 * i;
    poses.push_back(LookAt(Eigen::Vector3d(x, 0, 0.2), Eigen::Vector3d(x, 0, kPlaneZ)));
  }
  const core::Trajectory trajectory = TrajectoryThrough(poses);
  const ThermalReflectionOptions geometry;  // the body's size and place
  auto render = [&](const core::Rigid3d& world_from_thermal) {
    const core::CameraModel& camera = *rig.thermal;
    cv::Mat image(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
    const Eigen::Matrix3d camera_from_world = world_from_thermal.rotation.conjugate().toRotationMatrix();
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const Eigen::Vector3d d = (world_from_thermal.rotation * *camera.Unproject(Eigen::Vector2d(x, y))).normalized();
        const Eigen::Vector3d c = world_from_thermal.translation;
        const Eigen::Vector3d p = c + (kPlaneZ - c.z()) / d.z() * d;
        const Eigen::Vector3d m(d.x(), d.y(), -d.z());  // mirrored about the plane's normal
        // The body's plane, 0.4 m behind the camera: z_camera = −0.4.
        const Eigen::Vector3d o_c = camera_from_world * (p - c), m_c = camera_from_world * m;
        const double s = (-geometry.operator_distance_m - o_c.z()) / m_c.z();
        const Eigen::Vector3d h = o_c + s * m_c;
        const bool on_body = s > 0 && std::pow(h.x() / 0.2, 2) + std::pow((h.y() - 0.15) / 0.35, 2) <= 1;
        const double e = core::DirectionalEmissivity(core::EmissivityLaw::kMetal, kEmissivity, d.z());
        const double mirror = on_body ? body : room;
        const double radiance = e * band.Radiance(core::CelsiusToKelvin(TrueSurfaceC(p))) +
                                (1 - e) * (kSpecular * mirror + (1 - kSpecular) * room);
        image.at<float>(y, x) = static_cast<float>(core::KelvinToCelsius(band.Temperature(radiance)));
      }
    }
    return image;
  };
  std::vector<double> errors[2];
  int64_t on_operator = 0;
  for (const bool trace : {false, true}) {
    ThermalFusionOptions options = TestOptions();
    options.reflections.trace = trace;
    ThermalFusion fusion(rig, options, EmissivityMap::FromLookup(*rig.thermal_settings, lookup), {});
    for (int i = 0; i < 6; ++i) {
      const double t = (i + 0.5) / 30.0;
      const core::Rigid3d world_from_thermal = *trajectory.At(t) * rig.depth_from_thermal;
      const ThermalFrameRecord& record = fusion.AddFrame(volume, {i, t, render(world_from_thermal)}, trajectory);
      ASSERT_EQ(record.status, ThermalFrameStatus::kFused);
      EXPECT_EQ(record.mirror_traced > 0, trace);
      if (trace) on_operator += record.mirror_operator;
    }
    fusion.Finish();
    const std::vector<Eigen::Vector3f> points = PlanePoints();
    const PointTemperatures t = fusion.Sample(points, ThermalMethod::kOffline);
    for (size_t i = 0; i < points.size(); ++i) {
      ASSERT_TRUE(std::isfinite(t.surface_c[i]));
      errors[trace].push_back(std::abs(static_cast<double>(t.surface_c[i]) - TrueSurfaceC(points[i].cast<double>())));
    }
  }
  EXPECT_GT(on_operator, 1000);
  auto quantile = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    return v[static_cast<size_t>(q * (v.size() - 1))];
  };
  // Traced: the splat's error (a voxel's rays' mean position off its centre, 0.03 K of the
  // field's gradient, ×1/ε on metal at most; measured 0.003 K median, 0.007 K at the 90th
  // percentile), and near the body's outline a voxel's views may disagree (the outline moves
  // with the camera, 1 cm a frame). Uniform: the body's 14 K over the room, × 0.63/ε.
  // (The body's reflection covers ~0.16 × 0.28 m of the plane: a third of the test points.)
  auto fraction_above = [](const std::vector<double>& v, double bound) {
    return static_cast<double>(std::count_if(v.begin(), v.end(), [bound](double e) { return e > bound; })) / v.size();
  };
  EXPECT_LT(quantile(errors[1], 0.5), 0.02);
  EXPECT_LT(quantile(errors[1], 0.9), 0.05);
  EXPECT_EQ(fraction_above(errors[1], 0.5), 0.0);
  EXPECT_GT(fraction_above(errors[0], 10.0), 0.2);
}

// A corner: a metal floor z = 1 (ε 0.3, specular share 0.9, facing the cameras at z < 1) for
// x < 0.5 and a black wall x = 0.5 (ε 1) at 60 °C for z < 1. A view of the floor at 35–55°
// from its normal mirrors the wall.
constexpr double kWallX = 0.5, kWallC = 60;

cv::Mat CornerDepth(const PinholeCamera& camera, const core::Rigid3d& pose) {
  const cv::Mat floor = RenderPlane(camera, pose, Eigen::Vector3d(0, 0, 1), kPlaneZ);
  const cv::Mat wall = RenderPlane(camera, pose, Eigen::Vector3d(1, 0, 0), kWallX);
  cv::Mat depth(floor.size(), CV_32FC1);
  for (int y = 0; y < depth.rows; ++y) {
    for (int x = 0; x < depth.cols; ++x) {
      const float a = floor.at<float>(y, x), b = wall.at<float>(y, x);
      depth.at<float>(y, x) = a > 0 && b > 0 ? std::min(a, b) : std::max(a, b);
    }
  }
  return depth;
}

core::Rigid3d WallView() { return LookAt(Eigen::Vector3d(-0.2, 0, 0.6), Eigen::Vector3d(kWallX, 0, 0.6)); }

TsdfVolume CornerVolume() {
  TsdfVolume volume(test::SmallOptions());
  const PinholeCamera camera = SmallCamera();
  for (const core::Rigid3d& pose :
       {WallView(), LookAt(Eigen::Vector3d(-0.5, 0, 0.5), Eigen::Vector3d(0.2, 0, 1)),
        LookAt(Eigen::Vector3d(-0.5, 0.1, 0.4), Eigen::Vector3d(0.3, 0, 0.8)),
        LookAt(Eigen::Vector3d(-0.4, -0.1, 0.6), Eigen::Vector3d(0.1, 0, 1)),
        LookAt(Eigen::Vector3d(-0.5, 0, 0.5), Eigen::Vector3d(0, 0, 1)),
        LookAt(Eigen::Vector3d(0.2, 0, 0.3), Eigen::Vector3d(0.25, 0, 1)),
        LookAt(Eigen::Vector3d(-0.1, 0, 0.4), Eigen::Vector3d(0.0, 0, 1))}) {
    for (int i = 0; i < 3; ++i) volume.Integrate(CornerDepth(camera, pose), camera, pose);
  }
  return volume;
}

bool CornerLookup(const Eigen::Vector3f& p, SurfaceEmissivity& out) {
  const bool floor = p.z() > 0.99f;
  out.emissivity = floor ? 0.3 : 1.0;
  out.law = floor ? core::EmissivityLaw::kMetal : core::EmissivityLaw::kDielectric;
  out.specular_fraction = 0.9;
  return true;
}

// The corner's thermal image: the wall reads 60 °C; a floor point reads ε(θ)·L(T_s) +
// (1 − ε(θ))·(0.9·L(wall) + 0.1·L(room)) where its mirror ray meets the wall (z < 1: always,
// the floor's mirror rays rise), with T_s = TrueSurfaceC.
cv::Mat RenderCorner(const core::Rig& rig, const core::Rigid3d& world_from_thermal) {
  const core::CameraModel& camera = *rig.thermal;
  const core::BandRadiance band(rig.thermal_settings->spectral_band_um[0], rig.thermal_settings->spectral_band_um[1]);
  const double room = band.Radiance(core::CelsiusToKelvin(rig.thermal_settings->reflected_c));
  const double wall = band.Radiance(core::CelsiusToKelvin(kWallC));
  cv::Mat image(camera.height, camera.width, CV_32FC1, cv::Scalar(rig.thermal_settings->reflected_c));
  const Eigen::Vector3d c = world_from_thermal.translation;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector3d d = (world_from_thermal.rotation * *camera.Unproject(Eigen::Vector2d(x, y))).normalized();
      const double t_floor = d.z() > 0 ? (kPlaneZ - c.z()) / d.z() : kInf;
      const double t_wall = d.x() > 0 ? (kWallX - c.x()) / d.x() : kInf;
      if (t_wall < t_floor) {
        image.at<float>(y, x) = static_cast<float>(kWallC);
        continue;
      }
      if (!std::isfinite(t_floor)) continue;
      const Eigen::Vector3d p = c + t_floor * d;
      const double e = core::DirectionalEmissivity(core::EmissivityLaw::kMetal, 0.3, d.z());
      const double mirror = d.x() > 0 ? wall : room;
      const double radiance = e * band.Radiance(core::CelsiusToKelvin(TrueSurfaceC(p))) +
                              (1 - e) * (0.9 * mirror + 0.1 * room);
      image.at<float>(y, x) = static_cast<float>(core::KelvinToCelsius(band.Temperature(radiance)));
    }
  }
  return image;
}

// Floor points near the middle of a view's floor whose mirror ray (from camera_in_world)
// meets the wall within `wall_z` and |y| < 0.2 m: where the wall is in the model.
std::vector<Eigen::Vector3f> FloorPointsMirroring(const Eigen::Vector3d& camera_in_world, double wall_z_min,
                                                  double wall_z_max) {
  std::vector<Eigen::Vector3f> points;
  for (double y = -0.1; y <= 0.1; y += 0.02) {
    for (double x = -0.2; x <= 0.35; x += 0.02) {
      const Eigen::Vector3d p(x, y, kPlaneZ);
      const Eigen::Vector3d d = (p - camera_in_world).normalized();
      const Eigen::Vector3d m(d.x(), d.y(), -d.z());
      const Eigen::Vector3d q = p + (kWallX - p.x()) / m.x() * m;
      if (q.z() >= wall_z_min && q.z() <= wall_z_max && std::abs(q.y()) < 0.2) points.push_back(p.cast<float>());
    }
  }
  return points;
}

// Fuses `thermal_poses` (world_from_depth, one thermal frame each) with and without tracing
// and returns, for each, the largest |error| of the offline estimate over `points` (all of
// them observed) and the fused rays whose mirror met a surface.
std::array<std::pair<double, int64_t>, 2> FuseCorner(const core::Rig& rig, const TsdfVolume& volume,
                                                     const std::vector<core::Rigid3d>& thermal_poses,
                                                     const std::vector<Eigen::Vector3f>& points) {
  std::vector<core::Rigid3d> depth_poses;  // each pose twice: thermal frames between them see it alone
  for (const core::Rigid3d& pose : thermal_poses) {
    depth_poses.push_back(pose);
    depth_poses.push_back(pose);
  }
  const core::Trajectory trajectory = TrajectoryThrough(depth_poses);
  std::array<std::pair<double, int64_t>, 2> result;
  for (const bool trace : {false, true}) {
    ThermalFusionOptions options = TestOptions();
    options.reflections.trace = trace;
    ThermalFusion fusion(rig, options, EmissivityMap::FromLookup(*rig.thermal_settings, CornerLookup), {});
    int64_t surface = 0;
    for (size_t i = 0; i < thermal_poses.size(); ++i) {
      const double t = (2 * i + 0.5) / 30.0;
      const core::Rigid3d world_from_thermal = *trajectory.At(t) * rig.depth_from_thermal;
      const ThermalFrameRecord& record =
          fusion.AddFrame(volume, {static_cast<int>(i), t, RenderCorner(rig, world_from_thermal)}, trajectory);
      EXPECT_EQ(record.status, ThermalFrameStatus::kFused);
      surface += record.mirror_surface;
    }
    fusion.Finish();
    const PointTemperatures estimate = fusion.Sample(points, ThermalMethod::kOffline);
    double max_error = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      EXPECT_TRUE(std::isfinite(estimate.surface_c[i])) << points[i].transpose();
      max_error = std::max(max_error, std::abs(static_cast<double>(estimate.surface_c[i]) -
                                               TrueSurfaceC(points[i].cast<double>())));
    }
    result[trace] = {max_error, surface};
  }
  return result;
}

// One frame that sees both the floor and, 13–23° off its axis, the part of the wall the floor
// mirrors: the wall's reading comes from this very frame (no region has a temperature yet).
TEST(ThermalReflections, AHotWallMirroredInMetalIsReadFromTheSameFrame) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = CornerVolume();
  const core::Rigid3d pose = LookAt(Eigen::Vector3d(-0.5, 0, 0.5), Eigen::Vector3d(0.2, 0, 1));
  const std::vector<Eigen::Vector3f> points =
      FloorPointsMirroring((pose * rig.depth_from_thermal).translation, 0.6, 0.9);
  ASSERT_GT(points.size(), 30u);
  const auto [uniform, traced] = FuseCorner(rig, volume, {pose}, points);
  EXPECT_GT(traced.second, 500);
  EXPECT_EQ(uniform.second, 0);
  // The wall's 42 K over the room, × 0.9 (1 − ε)/ε: tens of kelvin uniform (measured 70 K at
  // most); traced, the splat's error — a voxel's rays' mean position off its centre, 0.03 K
  // of the field's gradient, × 1/ε(θ) ≈ 3 on this metal — and none from the mirror hit (the
  // wall is uniform): measured 0.074 K at most.
  EXPECT_GT(uniform.first, 20.0);
  EXPECT_LT(traced.first, 0.15);
}

// Frames of the wall first, then a view of the floor at 45°, which mirrors the wall 45° off
// its axis, out of its 64° field of view: the wall's reading comes from its regions.
TEST(ThermalReflections, AHotWallOutOfViewIsReadFromTheModel) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = CornerVolume();
  const core::Rigid3d floor_view = LookAt(Eigen::Vector3d(-0.5, 0, 0.5), Eigen::Vector3d(0, 0, 1));
  const std::vector<Eigen::Vector3f> points =
      FloorPointsMirroring((floor_view * rig.depth_from_thermal).translation, 0.4, 0.85);
  ASSERT_GT(points.size(), 30u);
  const auto [uniform, traced] = FuseCorner(rig, volume, {WallView(), floor_view}, points);
  EXPECT_GT(traced.second, 500);
  EXPECT_GT(uniform.first, 20.0);  // as above (measured 71 K and 0.052 K)
  EXPECT_LT(traced.first, 0.15);
}

}  // namespace
}  // namespace hw::reconstruct
