#pragma once

// The thermal fusion tests' scene (thermal_fusion_test.cc, thermal_fusion_window_test.cc): a
// plane with an analytic surface temperature, a small rig, its thermal images rendered in
// closed form through the lens model, and camera sweeps over it.

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/radiometry.h"
#include "core/rig.h"
#include "core/trajectory.h"
#include "reconstruct/thermal_fusion.h"
#include "reconstruct/tsdf_test_support.h"

namespace hw::reconstruct::test {

// The scene: the plane z = 1 m (world), facing the cameras at z < 1, with the analytic
// surface temperature field below; emissivity and reflected temperature from the rig.
inline constexpr double kPlaneZ = 1.0;
inline double TrueSurfaceC(const Eigen::Vector3d& p) { return 30.0 + 5.0 * p.x() + 3.0 * p.y(); }

inline core::Rig ThermalRig(bool distorted) {
  core::Rig rig;
  const PinholeCamera depth = SmallCamera();
  rig.depth = core::CameraModel::Pinhole(depth.width, depth.height, depth.fx, depth.fy);
  rig.depth.cx = depth.cx;
  rig.depth.cy = depth.cy;
  core::CameraModel thermal = core::CameraModel::Pinhole(80, 60, 64, 64);
  if (distorted) {
    thermal.type = core::CameraModelType::kOpenCV;
    thermal.distortion = {-0.25, 0.08, 0.0005, -0.0004, 0.0};
  }
  rig.thermal = thermal;
  rig.depth_from_thermal = core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitY())),
                                         Eigen::Vector3d(0.03, -0.01, 0.0));
  rig.thermal_time_offset_s = 0.0;
  rig.thermal_settings = core::ThermalSettings();
  rig.thermal_settings->emissivity = 0.9;
  rig.thermal_settings->reflected_c = 18.0;
  EXPECT_EQ(rig.Check(), "");
  return rig;
}

// A volume of the plane, fused from a few views around the thermal views.
inline TsdfVolume PlaneVolume() {
  TsdfVolume volume(test::SmallOptions());
  const PinholeCamera camera = SmallCamera();
  for (double x : {-0.15, 0.0, 0.15}) {
    const core::Rigid3d pose = LookAt(Eigen::Vector3d(x, 0.05, 0.0), Eigen::Vector3d(0, 0, kPlaneZ));
    volume.Integrate(RenderPlane(camera, pose, Eigen::Vector3d(0, 0, 1), kPlaneZ), camera, pose);
  }
  return volume;
}

// The thermal image of the plane from world_from_thermal: each pixel's ray through the lens
// model, the apparent temperature of the analytic surface at the emissivity the correction
// assumes (so that it inverts exactly), plus noise of std netd_k.
inline cv::Mat RenderThermal(const core::Rig& rig, const core::Rigid3d& world_from_thermal, double netd_k,
                      std::mt19937_64& rng, double offset_k = 0, double vignetting = 0) {
  const core::CameraModel& camera = *rig.thermal;
  const core::BandRadiance band(rig.thermal_settings->spectral_band_um[0], rig.thermal_settings->spectral_band_um[1]);
  std::normal_distribution<double> noise(0.0, netd_k);
  cv::Mat image(camera.height, camera.width, CV_32FC1, cv::Scalar(rig.thermal_settings->reflected_c));
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(Eigen::Vector2d(x, y));
      if (!ray) continue;
      const Eigen::Vector3d d = world_from_thermal.rotation * *ray;
      const double t = (kPlaneZ - world_from_thermal.translation.z()) / d.z();
      if (!(t > 0)) continue;
      const Eigen::Vector3d p = world_from_thermal.translation + t * d;
      const double cos_angle = d.normalized().z();
      const double e = core::DirectionalEmissivity(core::EmissivityLaw::kDielectric,
                                                   rig.thermal_settings->emissivity, cos_angle);
      double apparent = core::ApparentFromSurface(band, TrueSurfaceC(p), e, rig.thermal_settings->reflected_c);
      if (vignetting > 0) {  // radiance lost towards the corners (an independent form of the model)
        const double corner2 = std::pow(std::max(camera.cx + 0.5, camera.width - 0.5 - camera.cx), 2) +
                               std::pow(std::max(camera.cy + 0.5, camera.height - 0.5 - camera.cy), 2);
        const double r2 = (std::pow(x - camera.cx, 2) + std::pow(y - camera.cy, 2)) / corner2;
        apparent = core::KelvinToCelsius(
            band.Temperature(band.Radiance(core::CelsiusToKelvin(apparent)) * (1 - vignetting * r2)));
      }
      image.at<float>(y, x) = static_cast<float>(apparent + offset_k + (netd_k > 0 ? noise(rng) : 0.0));
    }
  }
  return image;
}

// Depth poses (world_from_depth) every 1/30 s around a thermal view.
inline core::Trajectory TrajectoryThrough(const std::vector<core::Rigid3d>& poses, double start_s = 0) {
  core::Trajectory trajectory;
  for (size_t i = 0; i < poses.size(); ++i) trajectory.Add(start_s + i / 30.0, poses[i]);
  return trajectory;
}

// Points of the plane inside the region every view sees.
inline std::vector<Eigen::Vector3f> PlanePoints() {
  std::vector<Eigen::Vector3f> points;
  for (double y = -0.1; y <= 0.1; y += 0.013) {
    for (double x = -0.15; x <= 0.15; x += 0.013) points.emplace_back(x, y, kPlaneZ);
  }
  return points;
}

// The rules on their own: without the scene-based offset correction, which would take out
// the offsets some tests give a frame on purpose (tested on its own), without frame
// selection, and with the uniform reflection RenderThermal draws (traced reflections:
// thermal_reflections_test.cc).
inline ThermalFusionOptions TestOptions() {
  ThermalFusionOptions o;
  o.num_threads = 2;
  o.scene_correction.frame_offset = o.scene_correction.pixel_offset = false;
  o.reflections.trace = false;
  o.frame_interval_s = 0;  // every frame, as it comes (frame selection: thermal_fusion_window_test.cc)
  return o;
}

struct Views {
  core::Trajectory trajectory;
  std::vector<double> thermal_times_s;  // thermal clock = depth clock here
};

// A slow sideways sweep: depth poses every 1/30 s, a thermal frame between each two.
inline Views Sweep(int frames, double speed_mps = 0.05) {
  Views v;
  std::vector<core::Rigid3d> poses;
  for (int i = 0; i <= frames; ++i) {
    const double x = -0.05 + speed_mps * i / 30.0;
    poses.push_back(LookAt(Eigen::Vector3d(x, 0.02, 0.2), Eigen::Vector3d(x, 0.0, kPlaneZ)));
  }
  v.trajectory = TrajectoryThrough(poses);
  for (int i = 0; i < frames; ++i) v.thermal_times_s.push_back((i + 0.5) / 30.0);
  return v;
}

}  // namespace hw::reconstruct::test
