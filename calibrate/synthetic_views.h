#pragma once

// Test and bench support: a known camera observing a planar target at random poses, with
// Gaussian noise on the corners — the synthetic calibration problem the solver tests and
// bench/calibrate_speed.cc share.

#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "calibrate/intrinsics_solver.h"
#include "core/camera.h"
#include "core/rig.h"
#include "core/transform.h"

namespace hw::calibrate::test {

// A square_grid target of rows × cols holes of side square_m at pitch_m, metres.
inline core::Target SquareGridTarget(int rows, int cols, double square_m, double pitch_m) {
  core::Target target;
  target.type = core::TargetType::kSquareGrid;
  target.rows = rows;
  target.cols = cols;
  target.square_m = square_m;
  target.pitch_m = pitch_m;
  return target;
}

// 640 × 480, OpenCV 5-coefficient camera with a strong barrel distortion.
inline core::CameraModel SyntheticCamera() {
  core::CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.type = core::CameraModelType::kOpenCV;
  camera.fx = 600;
  camera.fy = 605;
  camera.cx = 322;
  camera.cy = 238;
  camera.distortion = {-0.25, 0.08, 0.001, -0.0005, -0.01};
  return camera;
}

// `count` target poses seen by `camera` with every corner inside the image: 0.35-0.6 m away,
// tilted 10-40 degrees about x and y (fronto_parallel: not tilted), rolled up to 20 degrees,
// the target's centre off the optical axis by up to lateral / 2 times its distance in x and
// y (0.4: near the centre; 2: out to 45 degrees, the edges of a wide lens).
// Gives up after a million draws (a target too large for the image): fewer poses.
inline std::vector<core::Rigid3d> RandomTargetPoses(const core::CameraModel& camera, const core::Target& target,
                                                    int count, bool fronto_parallel, unsigned seed,
                                                    double lateral = 0.4) {
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : corners) centre += p / static_cast<double>(corners.size());
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  auto tilt = [&] { return (unit(rng) < 0.5 ? -1 : 1) * (10 + 30 * unit(rng)) * M_PI / 180; };
  std::vector<core::Rigid3d> poses;
  for (int attempt = 0; static_cast<int>(poses.size()) < count && attempt < 1000000; ++attempt) {
    const double tilt_x = fronto_parallel ? 0 : tilt(), tilt_y = fronto_parallel ? 0 : tilt();
    const Eigen::Quaterniond rotation(Eigen::AngleAxisd((unit(rng) - 0.5) * 40 * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                                      Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()) *
                                      Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()));
    const double z = 0.35 + 0.25 * unit(rng);
    const Eigen::Vector3d position(z * (unit(rng) - 0.5) * lateral, z * (unit(rng) - 0.5) * lateral, z);
    const core::Rigid3d camera_from_target(rotation, position - rotation * centre);
    bool inside = true;
    for (const Eigen::Vector3d& p : corners) {
      const Eigen::Vector3d p_cam = camera_from_target * p;
      inside = inside && p_cam.z() > 0.1 && camera.IsInImage(camera.Project(p_cam));
    }
    if (inside) poses.push_back(camera_from_target);
  }
  return poses;
}

// Every corner of `target` (with keep_fraction < 1: each kept with that probability, as a
// detector missing some) projected by `camera` at each pose, plus Gaussian noise (px).
inline std::vector<ViewObservation> ObserveTarget(const core::CameraModel& camera, const core::Target& target,
                                                  const std::vector<core::Rigid3d>& poses, double noise_px,
                                                  unsigned seed, double keep_fraction = 1) {
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, noise_px);
  std::vector<ViewObservation> views;
  for (const core::Rigid3d& pose : poses) {
    ViewObservation view;
    for (size_t id = 0; id < corners.size(); ++id) {
      if (keep_fraction < 1 && std::uniform_real_distribution<double>(0, 1)(rng) > keep_fraction) continue;
      view.corner_ids.push_back(static_cast<int>(id));
      view.pixels.push_back(camera.Project(pose * corners[id]) + Eigen::Vector2d(noise(rng), noise(rng)));
    }
    views.push_back(std::move(view));
  }
  return views;
}

// Pixel q's error against the truth as ProjectionUncertaintyMap defines it (mrcal's "mean of
// frames"): a point at range_m on the truth's ray of q, fixed in every view's target frame
// (true_camera_from_target), seen through the solved poses (averaged) and intrinsics,
// projects this far from q (pixels). A point fixed in the camera frame instead would count
// as error what a small rotation of every pose absorbs (e.g. cx against the views'
// rotations). NaN when the truth cannot unproject q.
inline double ProjectionErrorPx(const IntrinsicsResult& result, const core::CameraModel& truth,
                                const std::vector<core::Rigid3d>& true_camera_from_target, const Eigen::Vector2d& q,
                                double range_m) {
  const std::optional<Eigen::Vector3d> ray = truth.Unproject(q);
  if (!ray) return std::nan("");
  const Eigen::Vector3d point_in_true_camera = range_m * ray->normalized();
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < true_camera_from_target.size(); ++i) {
    point += result.camera_from_target[i] * (true_camera_from_target[i].Inverse() * point_in_true_camera);
  }
  return (result.camera.Project(point / static_cast<double>(true_camera_from_target.size())) - q).norm();
}

}  // namespace hw::calibrate::test
