#include "reconstruct/icp.h"

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace hw::reconstruct {
namespace {

using ::testing::HasSubstr;
using Vector6d = Eigen::Matrix<double, 6, 1>;

constexpr double kDeg = M_PI / 180.0;

PinholeCamera SmallCamera() {
  return PinholeCamera::Of(core::CameraModel::Pinhole(160, 120, 140, 140));
}

// A scene of planes {p : n · p = d} (world frame, n unit, facing the camera) seen from inside:
// each ray takes the nearest plane in front of it. Three orthogonal walls x = 0, y = 0, z = 0
// seen from inside the positive octant make a box corner, which constrains all six degrees
// of freedom; one wall alone leaves three free.
struct Scene {
  std::vector<Eigen::Vector3d> normals;
  std::vector<double> offsets;

  static Scene Corner() {
    return {{Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()},
            {0, 0, 0}};
  }
  static Scene Wall() { return {{Eigen::Vector3d::UnitZ()}, {0}}; }

  // Distance along the ray (origin + t dir) to the nearest plane it meets from the front, and
  // that plane; false when it meets none.
  bool Hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double& t, int& plane) const {
    t = std::numeric_limits<double>::infinity();
    plane = -1;
    for (size_t k = 0; k < normals.size(); ++k) {
      const double along = normals[k].dot(dir);
      if (along >= 0) continue;  // parallel, or leaving through the plane's back
      const double tk = (offsets[k] - normals[k].dot(origin)) / along;
      if (tk > 0 && tk < t) {
        t = tk;
        plane = static_cast<int>(k);
      }
    }
    return plane >= 0;
  }

  // Depth image (z along the optical axis, m) seen from world_from_camera.
  cv::Mat Depth(const PinholeCamera& camera, const core::Rigid3d& world_from_camera) const {
    cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0.0f));
    const Eigen::Matrix3d R = world_from_camera.rotation.toRotationMatrix();
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) {
        // The ray with z = 1 in the camera: t along it is the depth.
        const Eigen::Vector3d ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1);
        double t;
        int plane;
        if (Hit(world_from_camera.translation, R * ray, t, plane)) depth.at<float>(v, u) = float(t);
      }
    }
    return depth;
  }

  // The exact world-frame point and normal maps seen from world_from_camera (what a perfect
  // raycast of the model gives).
  PointMap Map(const PinholeCamera& camera, const core::Rigid3d& world_from_camera) const {
    PointMap map(camera.width, camera.height);
    const Eigen::Matrix3d R = world_from_camera.rotation.toRotationMatrix();
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) {
        const Eigen::Vector3d ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1);
        const Eigen::Vector3d dir = R * ray;
        double t;
        int plane;
        if (!Hit(world_from_camera.translation, dir, t, plane)) continue;
        map.points[map.Index(u, v)] = (world_from_camera.translation + t * dir).cast<float>();
        map.normals[map.Index(u, v)] = normals[plane].cast<float>();
      }
    }
    return map;
  }
};

// A camera at `eye` looking at `target`, y down, with world +z up.
core::Rigid3d LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d y = -(up - up.dot(z) * z).normalized();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d R;
  R << x, y, z;
  return core::Rigid3d(Eigen::Quaterniond(R), eye);
}

core::Rigid3d Reference() { return LookAt({1.6, 1.3, 1.2}, {0.2, 0.25, 0.15}); }

// A motion of 4.1 cm and 3° between the reference (the model's view, and the initial guess)
// and the live camera.
core::Rigid3d Motion() {
  Vector6d xi;
  xi << Eigen::Vector3d(0.4, -0.7, 0.6).normalized() * 3 * kDeg, 0.03, -0.02, 0.02;
  return core::Rigid3d::Exp(xi);
}

ModelPyramid ModelOf(const Scene& scene, const core::Rigid3d& world_from_camera) {
  return BuildModelPyramid(scene.Map(SmallCamera(), world_from_camera), SmallCamera(),
                           world_from_camera, 3);
}

DepthPyramid LiveOf(const Scene& scene, const core::Rigid3d& world_from_camera, double noise_m = 0,
                    unsigned seed = 1) {
  cv::Mat depth = scene.Depth(SmallCamera(), world_from_camera);
  if (noise_m > 0) {
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.0f, static_cast<float>(noise_m));
    for (int v = 0; v < depth.rows; ++v) {
      for (int u = 0; u < depth.cols; ++u) {
        if (depth.at<float>(v, u) > 0) depth.at<float>(v, u) += noise(rng);
      }
    }
  }
  return BuildDepthPyramid(depth, SmallCamera(), DepthFilterOptions());
}

TEST(IcpOptions, CheckNamesTheField) {
  EXPECT_EQ(IcpOptions().Check(), "");
  auto with = [](auto change) {
    IcpOptions o;
    change(o);
    return o.Check();
  };
  EXPECT_THAT(with([](auto& o) { o.iterations = {0, -1, 0}; }), HasSubstr("iterations[1]"));
  EXPECT_THAT(with([](auto& o) { o.iterations = {0, 0, 0}; }), HasSubstr("iterations"));
  EXPECT_THAT(with([](auto& o) { o.max_distance_m = 0; }), HasSubstr("max_distance_m"));
  EXPECT_THAT(with([](auto& o) { o.min_distance_m = 0.1; }), HasSubstr("min_distance_m"));
  EXPECT_THAT(with([](auto& o) { o.max_normal_angle_deg = 91; }),
              HasSubstr("max_normal_angle_deg"));
  EXPECT_THAT(with([](auto& o) { o.huber_m = NAN; }), HasSubstr("huber_m"));
  EXPECT_THAT(with([](auto& o) { o.noise_reference_depth_m = 0.05; }), HasSubstr("noise_reference_depth_m"));
  EXPECT_THAT(with([](auto& o) { o.noise_reference_depth_m = NAN; }), HasSubstr("noise_reference_depth_m"));
  EXPECT_EQ(with([](auto& o) { o.noise_reference_depth_m = 0; }), "");
  EXPECT_THAT(with([](auto& o) { o.noise_gate_sigmas = -1; }), HasSubstr("noise_gate_sigmas"));
  EXPECT_THAT(with([](auto& o) { o.noise_gate_sigmas = 11; }), HasSubstr("noise_gate_sigmas"));
  EXPECT_THAT(with([](auto& o) { o.depth_noise.base_m = -1e-3; }), HasSubstr("depth_noise.base_m"));
  EXPECT_THAT(with([](auto& o) { o.depth_noise.quadratic_per_m = NAN; }), HasSubstr("depth_noise.quadratic_per_m"));
  EXPECT_THAT(with([](auto& o) { o.depth_noise.reference_m = INFINITY; }), HasSubstr("depth_noise.reference_m"));
  EXPECT_THAT(with([](auto& o) { o.min_update_rad = -1; }), HasSubstr("min_update_rad"));
  EXPECT_THAT(with([](auto& o) { o.min_update_m = -1; }), HasSubstr("min_update_m"));
  EXPECT_THAT(with([](auto& o) { o.min_inlier_fraction = 1.5; }), HasSubstr("min_inlier_fraction"));
  EXPECT_THAT(with([](auto& o) { o.min_inliers = 5; }), HasSubstr("min_inliers"));
  EXPECT_THAT(with([](auto& o) { o.max_condition = 1; }), HasSubstr("max_condition"));
  EXPECT_THAT(with([](auto& o) { o.max_held_directions = 6; }), HasSubstr("max_held_directions"));
  EXPECT_THAT(with([](auto& o) { o.max_residual_m = 0; }), HasSubstr("max_residual_m"));
  EXPECT_THAT(with([](auto& o) { o.max_jump_m = 0; }), HasSubstr("max_jump_m"));
  EXPECT_THAT(with([](auto& o) { o.max_jump_deg = 0; }), HasSubstr("max_jump_deg"));
  EXPECT_THAT(with([](auto& o) { o.photometric_weight = -0.1; }), HasSubstr("photometric_weight"));
  EXPECT_THAT(with([](auto& o) { o.photometric_weight = 2; }), HasSubstr("photometric_weight"));
  EXPECT_THAT(with([](auto& o) { o.num_threads = -2; }), HasSubstr("num_threads"));
  EXPECT_EQ(IcpStatusName(IcpStatus::kIllConditioned), "ill_conditioned");
  EXPECT_EQ(IcpStatusName(IcpStatus::kImplausibleJump), "implausible_jump");
}

TEST(BuildModelPyramid, KeepsOneBlockPointNearestTheMeanDepth) {
  const core::Rigid3d pose = Reference();
  const PointMap level0 = Scene::Corner().Map(SmallCamera(), pose);
  const ModelPyramid model = BuildModelPyramid(level0, SmallCamera(), pose, 3);
  ASSERT_EQ(model.maps.size(), 3u);
  ASSERT_EQ(model.cameras.size(), 3u);
  EXPECT_EQ(model.cameras[2].width, 40);
  EXPECT_EQ(model.cameras[1].cx, SmallCamera().Half().cx);
  const core::Rigid3d camera_from_world = pose.Inverse();
  for (int l = 1; l < 3; ++l) {
    const PointMap& above = model.maps[l - 1];
    const PointMap& map = model.maps[l];
    for (int y = 0; y < map.height; ++y) {
      for (int x = 0; x < map.width; ++x) {
        std::vector<double> depths;
        std::vector<Eigen::Vector3f> points;
        for (int k = 0; k < 4; ++k) {
          const Eigen::Vector3f& p = above.points[above.Index(2 * x + k % 2, 2 * y + k / 2)];
          if (!IsValid(p)) continue;
          points.push_back(p);
          depths.push_back((camera_from_world * p.cast<double>()).z());
        }
        const Eigen::Vector3f& chosen = map.points[map.Index(x, y)];
        ASSERT_EQ(IsValid(chosen), !points.empty());
        if (points.empty()) continue;
        double mean = 0;
        for (double d : depths) mean += d / depths.size();
        const double chosen_depth = (camera_from_world * chosen.cast<double>()).z();
        bool from_block = false;
        for (size_t k = 0; k < points.size(); ++k) {
          from_block = from_block || points[k] == chosen;
          EXPECT_LE(std::abs(chosen_depth - mean), std::abs(depths[k] - mean) + 1e-6);
        }
        EXPECT_TRUE(from_block);
      }
    }
  }
}

// Noise-free: at the true pose projective association pairs every live pixel with the model
// point of the same pixel, i.e. the same surface point, so every residual vanishes and the
// truth is a fixed point of the iteration (without the bilateral filter the error is 0 to
// float rounding). What is left is the filter's rounding of the corner's creases (pixels
// within 2 px of a crease lifted by up to ~1 mm; measured effect 40 µm, 0.002°), float
// rounding (1e-7 × 2 m) and the stop threshold (1e-5): 0.5 mm and 0.05° leave a margin of
// 10× while catching any biased filter or Jacobian (a one-sided filter window at the image
// border alone gave 0.9 mm here).
TEST(AlignToModel, RecoversTheCornersPoseFromAFewCentimetresAndDegrees) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = Reference();
  const core::Rigid3d truth = reference * Motion();
  const IcpResult result =
      AlignToModel(LiveOf(scene, truth), ModelOf(scene, reference), reference, IcpOptions());
  EXPECT_EQ(result.status, IcpStatus::kOk) << IcpStatusName(result.status);
  const core::PoseError start = core::ComparePoses(reference, truth);
  EXPECT_GT(start.translation_m, 0.04);
  EXPECT_GT(start.rotation_rad, 2.9 * kDeg);
  const core::PoseError error = core::ComparePoses(result.world_from_camera, truth);
  EXPECT_LT(error.translation_m, 0.0005);
  EXPECT_LT(error.rotation_rad, 0.05 * kDeg);
  EXPECT_GT(result.inliers, 0.9 * result.valid_points);
  EXPECT_LT(result.residual_rms_m, 0.001);
  EXPECT_LT(result.condition, 100);
  EXPECT_GT(result.iterations, 3);
  EXPECT_GT(result.information.trace(), 0);
}

// Depth noise sigma on the live frame (the model is exact): the estimate is a weighted
// least-squares one whose tangent covariance is about sigma² A⁻¹ (A = result.information;
// the bilateral filter averages the noise but, being a linear smoother, not the estimate's
// precision). Each component of the error must be within 5 standard deviations plus the
// noise-free floor (40 µm, 0.002°: the filter rounding the corner's creases), for two noise
// levels 4× apart, so the error scales with the noise.
TEST(AlignToModel, ErrorWithNoiseScalesWithTheNoise) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = Reference();
  const core::Rigid3d truth = reference * Motion();
  for (const double sigma : {0.001, 0.004}) {
    const IcpResult result = AlignToModel(LiveOf(scene, truth, sigma, 5), ModelOf(scene, reference),
                                          reference, IcpOptions());
    ASSERT_EQ(result.status, IcpStatus::kOk) << IcpStatusName(result.status) << " sigma " << sigma;
    const Vector6d error = (truth.Inverse() * result.world_from_camera).Log();
    const Eigen::Matrix<double, 6, 6> covariance = sigma * sigma * result.information.inverse();
    for (int k = 0; k < 6; ++k) {
      EXPECT_LT(std::abs(error(k)), 5 * std::sqrt(covariance(k, k)) + 5e-5)
          << "component " << k << " sigma " << sigma;
    }
    const core::PoseError pose_error = core::ComparePoses(result.world_from_camera, truth);
    EXPECT_LT(pose_error.translation_m, sigma) << "sigma " << sigma;
  }
}

TEST(AlignToModel, ThreadCountDoesNotChangeTheResult) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = Reference();
  const DepthPyramid live = LiveOf(scene, reference * Motion(), 0.002);
  const ModelPyramid model = ModelOf(scene, reference);
  IcpOptions one, three;
  one.num_threads = 1;
  three.num_threads = 3;
  const IcpResult a = AlignToModel(live, model, reference, one);
  const IcpResult b = AlignToModel(live, model, reference, three);
  EXPECT_EQ(a.world_from_camera.translation, b.world_from_camera.translation);
  EXPECT_EQ(a.world_from_camera.rotation.coeffs(), b.world_from_camera.rotation.coeffs());
  EXPECT_EQ(a.information, b.information);
}

// The association runs eight pixels at a time; rows whose width is not a multiple of eight
// end in a partial group. On a camera 157 px wide (levels 157, 78, 39: partial groups of 5,
// 6 and 7), one pass at the finest level from the true pose must pair up the same pixels and
// sum the same normal matrix as a plain per-pixel loop over the same maps (in double here:
// the pass sums in float lanes, 1e-4 relative covers that rounding over ~15 000 terms).
TEST(AlignToModel, OnePassMatchesAPerPixelLoopWithPartialGroups) {
  const PinholeCamera camera = PinholeCamera::Of(core::CameraModel::Pinhole(157, 117, 140, 140));
  const Scene scene = Scene::Corner();
  const core::Rigid3d truth = Reference() * Motion();
  const DepthPyramid live =
      BuildDepthPyramid(scene.Depth(camera, truth), camera, DepthFilterOptions());
  // The model seen from slightly elsewhere, so that some pixels fail the gates.
  const core::Rigid3d model_pose = Reference();
  const ModelPyramid model =
      BuildModelPyramid(scene.Map(camera, model_pose), camera, model_pose, 3);
  // With and without the depth-dependent weights (rows scaled by z_ref / z), and with the
  // depth-noise gate under a noise model steep enough to widen gate and Huber threshold over
  // part of the corner (σ 1 cm at 1.14 m, 4 cm at 1.85 m: 3σ beyond the 5 cm gate from
  // 1.34 m, beyond the 1 cm Huber threshold everywhere).
  for (const auto& [reference_depth_m, gate_sigmas] : {std::pair{0.0, 0.0}, {1.0, 0.0}, {0.0, 3.0}, {1.0, 3.0}}) {
  SCOPED_TRACE("noise_reference_depth_m " + std::to_string(reference_depth_m) + " noise_gate_sigmas " +
               std::to_string(gate_sigmas));
  IcpOptions options;
  options.iterations = {1, 0, 0};
  options.noise_reference_depth_m = reference_depth_m;
  options.noise_gate_sigmas = gate_sigmas;
  options.depth_noise = {0.001, 0.03, 0.6};
  // From 6 cm off the truth, so that the pairs lie about that far apart: beyond the fixed
  // 5 cm gate in part, within the widened one where the noise model allows.
  const core::Rigid3d start = truth * core::Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.02, -0.03, 0.05));
  const IcpResult result = AlignToModel(live, model, start, options);

  const PointMap& live_map = live.levels[0].map;
  const PointMap& model_map = model.maps[0];
  const Eigen::Matrix3d R = start.rotation.toRotationMatrix();
  const core::Rigid3d model_from_live = model_pose.Inverse() * start;
  const double gate = options.max_distance_m;  // level 0 is the coarsest level used
  const double min_cos = std::cos(options.max_normal_angle_deg * kDeg);
  int valid = 0, inliers = 0, widened = 0;
  double sum_r_sq = 0;
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  for (int y = 0; y < live_map.height; ++y) {
    for (int x = 0; x < live_map.width; ++x) {
      const size_t i = live_map.Index(x, y);
      if (!IsValid(live_map.normals[i])) continue;
      ++valid;
      const Eigen::Vector3d p = live_map.points[i].cast<double>();
      const Eigen::Vector3d in_model = model_from_live * p;
      if (!(in_model.z() > 0)) continue;
      const double u = double(camera.fx) * in_model.x() / in_model.z() + double(camera.cx);
      const double v = double(camera.fy) * in_model.y() / in_model.z() + double(camera.cy);
      if (!(u > -0.5 && v > -0.5 && u < camera.width - 0.5 && v < camera.height - 0.5)) continue;
      const size_t j = model_map.Index(int(u + 0.5), int(v + 0.5));
      if (!IsValid(model_map.normals[j])) continue;
      const Eigen::Vector3d d = start * p - model_map.points[j].cast<double>();
      const Eigen::Vector3d n_model = model_map.normals[j].cast<double>();
      const Eigen::Vector3d n_c = R.transpose() * n_model;
      const double allowance = gate_sigmas * options.depth_noise.SigmaAt(p.z());
      const double gate_here = std::max(gate, allowance), huber = std::max(options.huber_m, allowance);
      if (d.squaredNorm() > gate_here * gate_here) continue;
      if (n_c.dot(live_map.normals[i].cast<double>()) < min_cos) continue;
      ++inliers;
      widened += d.norm() > gate;
      const double scale = reference_depth_m > 0 ? reference_depth_m / p.z() : 1.0;
      const double r = scale * n_model.dot(d);
      const double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
      sum_r_sq += std::pow(n_model.dot(d) * options.huber_m / huber, 2);
      Vector6d jac;
      jac << p.cross(n_c), n_c;
      information += w * scale * scale * jac * jac.transpose();
    }
  }
  EXPECT_EQ(result.valid_points, valid);
  ASSERT_GT(inliers, 1000);
  EXPECT_LT(inliers, valid);  // the gates did reject some
  // A pixel exactly at a gate may go either way between float and double.
  EXPECT_NEAR(result.inliers, inliers, 2);
  EXPECT_LT((result.information - information).norm(), 1e-4 * information.norm());
  EXPECT_NEAR(result.residual_rms_m, std::sqrt(sum_r_sq / inliers), 1e-4 * result.residual_rms_m);
  if (gate_sigmas > 0) {
    EXPECT_GT(widened, 100);  // the wider gate paired what the fixed one would not
  }
  }
}

// A corner 3.3–4.6 m away seen with the sensor's noise there (22 mm added to every pixel,
// σ_z at 3.8 m by the default model; the depth filter smooths part of it): the fixed 1 cm
// gate of the finest level pairs only the points whose error happens to be small (63–65 %
// over seeds 3–7), the 3σ gate nearly all (92 %); the residual check reads the far
// residuals at near range (1.1–1.2 mm against 3.7 mm), so the sensor's own noise does not
// make the frame lost; the pose is as good (0.3–2.6 mm against 1.0–1.9 mm, 0.01–0.05°).
TEST(AlignToModel, TheNoiseGatePairsFarPointsByTheirNoise) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = LookAt({2.8, 2.4, 2.2}, {0.2, 0.25, 0.15});
  const core::Rigid3d truth = reference * Motion();
  const DepthPyramid live = LiveOf(scene, truth, 0.022, 3);
  const ModelPyramid model = ModelOf(scene, reference);
  IcpOptions fixed, gated;
  gated.noise_gate_sigmas = 3;
  const IcpResult a = AlignToModel(live, model, reference, fixed);
  const IcpResult b = AlignToModel(live, model, reference, gated);
  const double fraction_fixed = double(a.inliers) / a.valid_points, fraction_gated = double(b.inliers) / b.valid_points;
  const core::PoseError error_fixed = core::ComparePoses(a.world_from_camera, truth);
  const core::PoseError error_gated = core::ComparePoses(b.world_from_camera, truth);
  ASSERT_EQ(a.status, IcpStatus::kOk) << IcpStatusName(a.status);
  ASSERT_EQ(b.status, IcpStatus::kOk) << IcpStatusName(b.status);
  EXPECT_LT(fraction_fixed, 0.75);
  EXPECT_GT(fraction_gated, 0.88);
  EXPECT_LT(b.residual_rms_m, 0.5 * a.residual_rms_m);
  EXPECT_LT(error_fixed.translation_m, 0.004);
  EXPECT_LT(error_gated.translation_m, 0.004);
  EXPECT_LT(error_gated.rotation_rad, 0.1 * kDeg);
}

// A single wall constrains only the motion along its normal and the two tilts: the normal
// matrix has three (near) zero eigenvalues.
TEST(AlignToModel, AFlatWallIsIllConditioned) {
  const Scene scene = Scene::Wall();
  const core::Rigid3d reference = LookAt({0.3, 0.2, 1.5}, {0.35, 0.3, 0});
  Vector6d xi;
  xi << 0.01, -0.01, 0.005, 0.01, 0.01, 0.01;
  const IcpResult result = AlignToModel(LiveOf(scene, reference * core::Rigid3d::Exp(xi)),
                                        ModelOf(scene, reference), reference, IcpOptions());
  EXPECT_EQ(result.status, IcpStatus::kIllConditioned) << IcpStatusName(result.status);
  EXPECT_GT(result.condition, IcpOptions().max_condition);
  EXPECT_EQ(result.held_directions, 3);  // in-plane translation and rotation about the normal
  EXPECT_GT(result.inliers, 0.9 * result.valid_points);  // not a failure of association
  // What the wall constrains is found: the camera's height above it (measured 1 µm; float
  // rounding at 1.5 m is ~0.2 µm per point)...
  const core::Rigid3d truth = reference * core::Rigid3d::Exp(xi);
  EXPECT_NEAR(result.world_from_camera.translation.z(), truth.translation.z(), 2e-5);
  // ...and the free directions are left at the prediction instead of sliding with noise
  // (the true motion is 1.7 cm; measured 1.1 cm from the prediction, the constrained part).
  const DepthPyramid noisy = LiveOf(scene, truth, 0.004, 3);
  const IcpResult noisy_result =
      AlignToModel(noisy, ModelOf(scene, reference), reference, IcpOptions());
  EXPECT_EQ(noisy_result.status, IcpStatus::kIllConditioned);
  EXPECT_LT(core::ComparePoses(noisy_result.world_from_camera, reference).translation_m, 0.03);
}

// Two walls meeting along the x axis (a wall and a ceiling, or pipes along a wall) leave
// one direction free: translation along x. That direction is held at the initial pose (the
// prediction) and the frame is aligned in the other five; with max_held_directions 0 it
// fails as ill-conditioned, as before.
TEST(AlignToModel, ACorridorHoldsItsFreeDirectionAtThePrediction) {
  const Scene scene{{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()}, {0, 0}};
  const core::Rigid3d reference = LookAt({0.3, 1.1, 1.0}, {0.4, 0, 0});
  Vector6d xi;
  xi << 0.01, -0.01, 0.008, 0.012, -0.01, 0.015;
  const core::Rigid3d truth = reference * core::Rigid3d::Exp(xi);
  IcpOptions options;
  const IcpResult result = AlignToModel(LiveOf(scene, truth), ModelOf(scene, reference), reference, options);
  ASSERT_EQ(result.status, IcpStatus::kOk) << IcpStatusName(result.status);
  EXPECT_EQ(result.held_directions, 1);
  EXPECT_GT(result.condition, options.max_condition);
  // The constrained part found (height above the floor, distance from the wall, the
  // rotation)...
  EXPECT_NEAR(result.world_from_camera.translation.y(), truth.translation.y(), 1e-4);
  EXPECT_NEAR(result.world_from_camera.translation.z(), truth.translation.z(), 1e-4);
  EXPECT_LT(core::ComparePoses(result.world_from_camera, truth).rotation_rad, 1e-4);
  // ...and x left where the prediction put it (the true motion moved it 1.5 cm).
  EXPECT_GT(std::abs(truth.translation.x() - reference.translation.x()), 0.01);
  EXPECT_NEAR(result.world_from_camera.translation.x(), reference.translation.x(), 1e-4);

  options.max_held_directions = 0;
  const IcpResult strict = AlignToModel(LiveOf(scene, truth), ModelOf(scene, reference), reference, options);
  EXPECT_EQ(strict.status, IcpStatus::kIllConditioned) << IcpStatusName(strict.status);
  EXPECT_EQ(strict.held_directions, 1);
}

// The basin check's probe (ReconstructionOptions::basin_check_m): the direction the system
// constrains least, and whether ICP comes back when moved along it. A corridor's free
// direction is translation along its axis; ICP moved 1 cm along it stays there (held), while
// a box corner, which fixes every direction, brings it back.
TEST(WeakestDirection, IsTheCorridorsAxisAndICPComesBackOnlyWhereTheDepthFixesThePose) {
  EXPECT_TRUE(WeakestDirection(Eigen::Matrix<double, 6, 6>::Zero()).isZero());
  const Scene corridor{{Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()}, {0, 0}};
  const core::Rigid3d reference = LookAt({0.3, 1.1, 1.0}, {0.4, 0, 0});
  const IcpResult aligned =
      AlignToModel(LiveOf(corridor, reference), ModelOf(corridor, reference), reference, IcpOptions());
  ASSERT_EQ(aligned.status, IcpStatus::kOk) << IcpStatusName(aligned.status);
  const Vector6d weakest = WeakestDirection(aligned.information);
  EXPECT_NEAR(weakest.norm(), 1.0, 1e-9);  // unit at a 1 m lever: rotation and translation alike
  // Translation along world x, in the camera frame (ξ's convention), either sign.
  const Eigen::Vector3d axis_in_camera = reference.rotation.inverse() * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(std::abs(weakest.tail<3>().dot(axis_in_camera)), 1.0, 1e-6);
  EXPECT_LT(weakest.head<3>().norm(), 1e-6);

  const auto probe_apart_m = [](const Scene& scene, const core::Rigid3d& truth) {
    const DepthPyramid live = LiveOf(scene, truth, 0.001, 5);
    const ModelPyramid model = ModelOf(scene, truth);
    const IcpResult first = AlignToModel(live, model, truth, IcpOptions());
    return IcpBasinM(live, model, first, 0.01, IcpOptions());
  };
  // The corridor: 1 cm along its axis, and ICP leaves it there (measured 1.0 cm; more than half:
  // unconstrained).
  EXPECT_GT(probe_apart_m(corridor, reference), 0.005);
  // The corner: back to within a tenth of a millimetre (1 mm depth noise; measured 0.06 µm).
  EXPECT_LT(probe_apart_m(Scene::Corner(), Reference()), 1e-4);
}

TEST(AlignToModel, AJumpBeyondTheLimitIsImplausible) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = Reference();
  const core::Rigid3d truth = reference * Motion();
  IcpOptions options;
  options.max_jump_m = 0.02;  // the true motion is 4.1 cm
  const IcpResult result =
      AlignToModel(LiveOf(scene, truth), ModelOf(scene, reference), reference, options);
  EXPECT_EQ(result.status, IcpStatus::kImplausibleJump) << IcpStatusName(result.status);
  // Still the (good) estimate: the check judges it, it does not discard it.
  EXPECT_LT(core::ComparePoses(result.world_from_camera, truth).translation_m, 0.0005);
  options = IcpOptions();
  options.max_jump_deg = 2;  // the true rotation is 3°
  EXPECT_EQ(
      AlignToModel(LiveOf(scene, truth), ModelOf(scene, reference), reference, options).status,
      IcpStatus::kImplausibleJump);
}

// A model of random points and normals: nothing passes the gates.
TEST(AlignToModel, AGarbageModelHasTooFewInliers) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = Reference();
  ModelPyramid model = ModelOf(scene, reference);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> uniform(-3.0f, 3.0f);
  for (PointMap& map : model.maps) {
    for (size_t i = 0; i < map.points.size(); ++i) {
      map.points[i] = {uniform(rng), uniform(rng), uniform(rng)};
      map.normals[i] = Eigen::Vector3f(uniform(rng), uniform(rng), uniform(rng)).normalized();
    }
  }
  const IcpResult result = AlignToModel(LiveOf(scene, reference), model, reference, IcpOptions());
  EXPECT_EQ(result.status, IcpStatus::kTooFewInliers) << IcpStatusName(result.status);
  EXPECT_LT(result.inliers, IcpOptions().min_inliers);
  EXPECT_GT(result.valid_points, 10000);
}

// The model's walls roughened by ±1.5 cm along their normals (RMS 8.7 mm; ~80 % within the
// finest level's 1.25 cm gate): pairs pass the gates but do not fit.
TEST(AlignToModel, AModelThatDoesNotFitHasALargeResidual) {
  const Scene scene = Scene::Corner();
  const core::Rigid3d reference = Reference();
  ModelPyramid model = ModelOf(scene, reference);
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> uniform(-0.015f, 0.015f);
  for (PointMap& map : model.maps) {
    for (size_t i = 0; i < map.points.size(); ++i) {
      if (IsValid(map.points[i])) map.points[i] += map.normals[i] * uniform(rng);
    }
  }
  IcpOptions options;
  options.max_residual_m = 0.005;
  const IcpResult result = AlignToModel(LiveOf(scene, reference), model, reference, options);
  EXPECT_EQ(result.status, IcpStatus::kLargeResidual) << IcpStatusName(result.status);
  EXPECT_GT(result.residual_rms_m, 0.005);
}

// A smooth texture on the wall z = 0 (grey level of a world point), periods of 40 and 33 cm:
// 30–40 px at 1.5 m on the 160×120 camera, so the coarsest level still resolves it.
std::uint8_t WallGrey(const Eigen::Vector3d& point_in_world) {
  const double g = 0.5 + 0.35 * std::sin(2 * M_PI * point_in_world.x() / 0.4) *
                             std::cos(2 * M_PI * point_in_world.y() / 0.33);
  return static_cast<std::uint8_t>(std::lround(255 * g));
}

// The same texture over a ramp of illumination, brighter towards +x by 0.3 per metre (a
// lamp to one side), in [0, 1].
double LitWallGrey(const Eigen::Vector3d& point_in_world) {
  return 0.35 + 0.3 * point_in_world.x() +
         0.2 * std::sin(2 * M_PI * point_in_world.x() / 0.4) * std::cos(2 * M_PI * point_in_world.y() / 0.33);
}

// The colour image registered to the wall's depth image seen from world_from_camera, grey
// levels from `grey` in [0, 1] (default: WallGrey's).
cv::Mat WallRgb(const PinholeCamera& camera, const core::Rigid3d& world_from_camera,
                const std::function<double(const Eigen::Vector3d&)>& grey = {}) {
  cv::Mat rgb(camera.height, camera.width, CV_8UC3, cv::Scalar(0, 0, 0));
  const Eigen::Matrix3d R = world_from_camera.rotation.toRotationMatrix();
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d dir =
          R * Eigen::Vector3d((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1);
      double t;
      int plane;
      if (!Scene::Wall().Hit(world_from_camera.translation, dir, t, plane)) continue;
      const Eigen::Vector3d hit = world_from_camera.translation + t * dir;
      const std::uint8_t g = grey ? static_cast<std::uint8_t>(std::lround(255 * std::clamp(grey(hit), 0.0, 1.0)))
                                  : WallGrey(hit);
      rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(g, g, g);
    }
  }
  return rgb;
}

// The textured-wall case of the photometric tests: the model cast from `reference` 1.5 m
// from the wall, the live frame from `truth`, a 2 cm / 1.5° in-plane motion away.
struct WallCase {
  Scene scene = Scene::Wall();
  PinholeCamera camera = SmallCamera();
  core::Rigid3d reference = LookAt({0.3, 0.2, 1.5}, {0.35, 0.3, 0});
  core::Rigid3d truth;
  WallCase() {
    Vector6d xi;
    xi << 0.002, -0.003, 1.5 * kDeg, 0.015, -0.012, 0.004;
    truth = reference * core::Rigid3d::Exp(xi);
  }
  // The model pyramid at `reference`, its colours 8-bit grey levels of grey(point) in [0, 1].
  ModelPyramid Model(const std::function<double(const Eigen::Vector3d&)>& grey) const {
    PointMap level0 = scene.Map(camera, reference);
    level0.colours.assign(level0.points.size(), Rgb8::Zero());
    for (size_t i = 0; i < level0.points.size(); ++i) {
      if (!IsValid(level0.points[i])) continue;
      const double g = std::clamp(grey(level0.points[i].cast<double>()), 0.0, 1.0);
      level0.colours[i].setConstant(static_cast<std::uint8_t>(std::lround(255 * g)));
    }
    return BuildModelPyramid(level0, camera, reference, 3);
  }
};

// A flat wall leaves the in-plane motion and the rotation about its normal free; its
// texture pins them. Geometry alone is ill-conditioned; with the photometric term the pose
// of a 2 cm / 1.5° in-plane motion comes back within 1 mm and 0.1° (8-bit grey levels and
// bilinear sampling of a texture 30–40 px in period: a grey-level error of 1/255 over a
// gradient of ~0.05 per px is ~0.1 px = 1 mm at 1.5 m on one pixel, averaged over 19 000;
// measured 2 µm, 0.0002°).
TEST(AlignToModel, ThePhotometricTermPinsATexturedWall) {
  const WallCase wall;
  const core::Rigid3d& reference = wall.reference;
  const core::Rigid3d& truth = wall.truth;
  const DepthPyramid live = BuildDepthPyramid(wall.scene.Depth(wall.camera, truth), wall.camera,
                                              DepthFilterOptions(), WallRgb(wall.camera, truth));
  ASSERT_FALSE(live.levels[2].intensity.empty());
  const ModelPyramid model = wall.Model([](const Eigen::Vector3d& p) { return WallGrey(p) / 255.0; });
  const IcpResult geometric = AlignToModel(live, model, reference, IcpOptions());
  EXPECT_EQ(geometric.status, IcpStatus::kIllConditioned) << IcpStatusName(geometric.status);

  IcpOptions options;
  options.photometric_weight = 0.1;
  const IcpResult result = AlignToModel(live, model, reference, options);
  EXPECT_EQ(result.status, IcpStatus::kOk) << IcpStatusName(result.status);
  EXPECT_LT(result.condition, options.max_condition);
  const core::PoseError error = core::ComparePoses(result.world_from_camera, truth);
  EXPECT_LT(error.translation_m, 0.001);
  EXPECT_LT(error.rotation_rad, 0.1 * kDeg);
  // Without a live colour image the term has nothing to compare: geometry alone again.
  const DepthPyramid grey_less =
      BuildDepthPyramid(wall.scene.Depth(wall.camera, truth), wall.camera, DepthFilterOptions());
  EXPECT_EQ(AlignToModel(grey_less, model, reference, options).status, IcpStatus::kIllConditioned);
}

// Auto exposure: the live frame 0.05 grey levels brighter than the model's colours, on a
// wall lit more from one side. Uncompensated, the term slides the pose along the light's
// ramp towards where the brightness matches (0.05 / 0.3 per metre would be 17 cm; the
// texture holds it nearer: measured 5.8 mm, > 3 mm required); with the offset estimated, the
// pose comes back as in the test above (measured 8 µm, 0.0001°) and the offset within 0.002
// grey levels, half a quantisation step (measured 0.00002).
TEST(AlignToModel, ThePhotometricOffsetAbsorbsAnExposureChange) {
  const WallCase wall;
  const core::Rigid3d& reference = wall.reference;
  const core::Rigid3d& truth = wall.truth;
  constexpr double kBrighter = 0.05;
  const DepthPyramid live = BuildDepthPyramid(
      wall.scene.Depth(wall.camera, truth), wall.camera, DepthFilterOptions(),
      WallRgb(wall.camera, truth, [](const Eigen::Vector3d& p) { return LitWallGrey(p) + kBrighter; }));
  const ModelPyramid model = wall.Model(LitWallGrey);
  IcpOptions options;
  options.photometric_weight = 0.1;
  options.photometric_offset = false;
  const IcpResult biased = AlignToModel(live, model, reference, options);
  const core::PoseError biased_error = core::ComparePoses(biased.world_from_camera, truth);
  EXPECT_GT(biased_error.translation_m, 0.003);
  EXPECT_EQ(biased.photometric_offset, 0.0);

  options.photometric_offset = true;
  const IcpResult result = AlignToModel(live, model, reference, options);
  EXPECT_EQ(result.status, IcpStatus::kOk) << IcpStatusName(result.status);
  const core::PoseError error = core::ComparePoses(result.world_from_camera, truth);
  EXPECT_LT(error.translation_m, 0.001) << "uncompensated: " << biased_error.translation_m;
  EXPECT_LT(error.rotation_rad, 0.1 * kDeg);
  EXPECT_NEAR(result.photometric_offset, -kBrighter, 0.002);  // model − live
}

}  // namespace
}  // namespace hw::reconstruct
