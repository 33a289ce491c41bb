// Peer harness: Open3D 0.16's tensor frame-to-model reconstruction loop on the CPU, over a
// heatwave scan's depth frames, for bench/reconstruct_peers.sh.
//
//   OMP_WAIT_POLICY=PASSIVE build/bench/bench_open3d_reconstruct SCAN --out traj.txt
//       [--voxel-size 0.005] [--truncation 0.02] [--summary summary.json] [--poses TUM]
//
// With --poses (bench/scale.sh) each frame is integrated at its pose in the trajectory
// (interpolated at the frame's time; frames outside it skipped) and nothing is tracked or
// raycast: Open3D's fusion alone, for its time and memory beside heatwave's on the same poses.
//
// The loop is Open3D's own dense SLAM (examples/python/t_reconstruction_system/dense_slam.py,
// t::pipelines::slam::Model) assembled from its pieces, because Model::TrackFrameToModel goes
// through RGBDOdometryMultiScale, which bilateral-filters the model depth with
// Image::FilterBilateral — IPP-only on the CPU, and Debian builds Open3D without IPP, so it
// throws. Per frame:
//   track      the frame's depth against the model raycast at the previous pose:
//              ComputeOdometryResultPointToPlane iterated over a 3-level pyramid (6, 3, 1
//              iterations coarse to fine: Model's defaults), depth_outlier_trunc 0.07 m,
//              Huber delta 0.05 m (OdometryLossParams' defaults); the fine level takes the
//              raycast's normals (TSDF gradient, camera frame) and the vertices of its depth,
//              coarser levels are made from the raycast depth with PyrDownDepth,
//              CreateVertexMap and CreateNormalMap;
//   integrate  VoxelBlockGrid "tsdf" + "weight", Float32 (the python examples' layout, depth
//              only: the peer is spared colour fusion), blocks of 16³ voxels;
//   raycast    "depth" and "normal" in the frustum blocks of the last integration,
//              weight threshold min(frame index, 3) as Model::SynthesizeModelFrame.
// No constant-velocity prediction and no failure handling: Open3D's loop has neither.
// Open3D's CPU kernels use OpenMP: run with OMP_WAIT_POLICY=PASSIVE (the script does), as
// spinning waits collapse on 2 shared cores.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <optional>
#include <vector>

#include <open3d/core/EigenConverter.h>
#include <open3d/core/Tensor.h>
#include <open3d/t/geometry/Image.h>
#include <open3d/t/geometry/VoxelBlockGrid.h>
#include <open3d/t/pipelines/odometry/RGBDOdometry.h>
#include <open3d/utility/Logging.h>

#include "bench/peer_common.h"
#include "core/error.h"

namespace {

namespace o3c = open3d::core;
namespace o3g = open3d::t::geometry;
namespace odometry = open3d::t::pipelines::odometry;

constexpr int kBlockResolution = 16;    // voxels per block side: Open3D's default
constexpr int kInitialBlocks = 4000;    // hash capacity; Open3D's hash map grows past it
constexpr float kDepthOutlierTrunc = 0.07f;  // m, OdometryLossParams default
constexpr float kDepthHuberDelta = 0.05f;    // m, OdometryLossParams default
const std::vector<int> kIterations = {6, 3, 1};  // coarse to fine, slam::Model default

o3c::Tensor ToTensor(const Eigen::Matrix4d& m) {
  return o3c::eigen_converter::EigenMatrixToTensor(m);
}

Eigen::Matrix4d ToEigen4d(const o3c::Tensor& t) {
  return o3c::eigen_converter::TensorToEigenMatrixXd(t);
}

// Odometry pyramids, index 0 the coarsest as RGBDOdometryMultiScale orders them.
struct Pyramid {
  std::vector<o3c::Tensor> vertex, normal, intrinsics;
};

std::vector<o3c::Tensor> IntrinsicsPyramid(const o3c::Tensor& K, int levels) {
  std::vector<o3c::Tensor> pyramid(levels);
  o3c::Tensor k = K.Clone();
  for (int i = levels - 1; i >= 0; --i) {
    pyramid[i] = k.Clone();
    k = k / 2;
    k[2][2] = 1.0;
  }
  return pyramid;
}

}  // namespace

int main(int argc, char** argv) {
  const hw::bench::PeerOptions options = hw::bench::ParsePeerOptions(
      argc, argv, "Open3D 0.16 tensor frame-to-model reconstruction over a heatwave scan");
  if (const char* policy = std::getenv("OMP_WAIT_POLICY");
      policy == nullptr || std::string(policy) != "PASSIVE") {
    std::fprintf(stderr, "note: OMP_WAIT_POLICY is not PASSIVE: OpenMP threads spin\n");
  }
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Warning);
  return hw::bench::RunHarness("open3d", [&] {
    const hw::bench::DepthFrames frames(options);
    const int levels = static_cast<int>(kIterations.size());
    const o3c::Device cpu("CPU:0");
    const o3c::Tensor K = o3c::eigen_converter::EigenMatrixToTensor(frames.K());  // Float64
    const std::vector<o3c::Tensor> K_pyramid = IntrinsicsPyramid(K, levels);
    const auto voxel_size = static_cast<float>(options.voxel_size_m);
    const auto trunc_multiplier = static_cast<float>(options.truncation_m / options.voxel_size_m);
    const auto depth_min = static_cast<float>(options.min_depth_m);
    const auto depth_max = static_cast<float>(options.max_depth_m);
    // RayCast bounds each ray by a range map at 1/8 resolution (Open3D's default); on tiny
    // test images that buffer comes out empty and the raycast never ends, so go finer there.
    const int range_map_down_factor = frames.width() >= 320 ? 8 : 2;

    o3g::VoxelBlockGrid grid({"tsdf", "weight"}, {o3c::Float32, o3c::Float32}, {{1}, {1}},
                             voxel_size, kBlockResolution, kInitialBlocks, cpu);

    hw::core::Trajectory trajectory;
    hw::bench::PeerResult result;
    result.method = "open3d";
    hw::bench::LoopTimer loop, decode, track_timer, integrate_timer, raycast_timer;
    Eigen::Matrix4d world_from_depth = Eigen::Matrix4d::Identity();
    Pyramid model;  // raycast of the model at the previous pose
    bool have_model = false;
    int fused = 0;
    const std::optional<hw::core::Trajectory> given = hw::bench::ReadGivenPoses(options);
    for (int i = 0; i < frames.size(); ++i) {
      if (!frames.Exists(i)) {
        ++result.skipped_frames;
        continue;
      }
      if (given) {
        const std::optional<Eigen::Matrix4d> pose = hw::bench::GivenPoseAt(*given, frames.Timestamp(i));
        if (!pose) {
          ++result.skipped_frames;
          continue;
        }
        world_from_depth = *pose;
      }
      decode.Start();
      const cv::Mat depth_m = frames.Load(i);
      decode.Stop();

      loop.Start();
      // Wrap the decoded frame (contiguous CV_32FC1) and copy it into Open3D's storage.
      const o3c::Tensor depth_tensor(reinterpret_cast<const float*>(depth_m.data),
                                     {depth_m.rows, depth_m.cols, 1}, o3c::Float32, cpu);
      // Invalid (0) becomes NaN for odometry, as RGBDOdometryMultiScale's ClipTransform does.
      const o3g::Image depth(depth_tensor);
      const o3g::Image depth_nan = depth.ClipTransform(1.0f, depth_min, depth_max, NAN);

      track_timer.Start();
      if (have_model) {  // never with given poses: nothing is raycast then
        // Source pyramid: the frame; target: the model raycast. The result maps source to
        // target, i.e. previous_from_current.
        std::vector<o3c::Tensor> source_vertex(levels);
        o3g::Image level = depth_nan;
        for (int l = levels - 1; l >= 0; --l) {
          source_vertex[l] = level.CreateVertexMap(K_pyramid[l], NAN).AsTensor();
          if (l > 0) level = level.PyrDownDepth(kDepthOutlierTrunc * 2, NAN);
        }
        odometry::OdometryResult track(o3c::Tensor::Eye(4, o3c::Float64, cpu), 0.0, 1.0);
        for (int l = 0; l < levels; ++l) {
          for (int iter = 0; iter < kIterations[l]; ++iter) {
            const odometry::OdometryResult delta = odometry::ComputeOdometryResultPointToPlane(
                source_vertex[l], model.vertex[l], model.normal[l], K_pyramid[l],
                track.transformation_, kDepthOutlierTrunc, kDepthHuberDelta);
            track.transformation_ = delta.transformation_.Matmul(track.transformation_);
            // Open3D's early exit (RGBDOdometryMultiScalePointToPlane).
            if (std::abs(track.fitness_ - delta.fitness_) / track.fitness_ < 1e-6 &&
                std::abs(track.inlier_rmse_ - delta.inlier_rmse_) / track.inlier_rmse_ < 1e-6) {
              break;
            }
            track.inlier_rmse_ = delta.inlier_rmse_;
            track.fitness_ = delta.fitness_;
          }
        }
        world_from_depth = world_from_depth * ToEigen4d(track.transformation_);
      }
      track_timer.Stop();

      integrate_timer.Start();
      const o3c::Tensor depth_from_world = ToTensor(world_from_depth.inverse());
      const o3c::Tensor blocks = grid.GetUniqueBlockCoordinates(depth, K, depth_from_world, 1.0f,
                                                                depth_max, trunc_multiplier);
      grid.Integrate(blocks, depth, K, depth_from_world, 1.0f, depth_max, trunc_multiplier);
      ++fused;
      integrate_timer.Stop();

      if (given) {  // nothing to track against
        loop.Stop();
        trajectory.Add(frames.Timestamp(i), hw::core::Rigid3d::FromMatrix(world_from_depth.topRows<3>()));
        ++result.frames;
        continue;
      }
      // Model raycast at this pose, for tracking the next frame.
      raycast_timer.Start();
      const float weight_threshold = std::min(static_cast<float>(fused - 1), 3.0f);
      o3g::TensorMap cast = grid.RayCast(blocks, K, depth_from_world, frames.width(),
                                         frames.height(), {"depth", "normal"}, 1.0f,
                                         depth_min, depth_max, weight_threshold, trunc_multiplier,
                                         range_map_down_factor);
      model.vertex.assign(levels, {});
      model.normal.assign(levels, {});
      // The fine level's vertices come from the raycast depth rather than its "vertex" map
      // (equal where a ray hit, verified): pixels without a hit must be NaN, which the
      // odometry kernel skips, not the zero vertex the raycast leaves there.
      o3g::Image level = o3g::Image(cast["depth"]).ClipTransform(1.0f, depth_min, depth_max, NAN);
      model.vertex[levels - 1] = level.CreateVertexMap(K_pyramid[levels - 1], NAN).AsTensor();
      model.normal[levels - 1] = cast["normal"];
      for (int l = levels - 2; l >= 0; --l) {
        level = level.PyrDownDepth(kDepthOutlierTrunc * 2, NAN);
        o3g::Image vertex = level.CreateVertexMap(K_pyramid[l], NAN);
        model.vertex[l] = vertex.AsTensor();
        model.normal[l] = vertex.CreateNormalMap(NAN).AsTensor();
      }
      have_model = true;
      raycast_timer.Stop();
      loop.Stop();

      trajectory.Add(frames.Timestamp(i),
                     hw::core::Rigid3d::FromMatrix(world_from_depth.topRows<3>()));
      ++result.frames;
    }
    result.loop_s = loop.seconds();
    result.decode_s = decode.seconds();
    result.track_s = track_timer.seconds();
    result.integrate_s = integrate_timer.seconds();
    result.raycast_s = raycast_timer.seconds();
    result.peak_rss_mb = hw::bench::PeakRssMb();
    hw::bench::WriteResults(options, trajectory, result);
    return 0;
  });
}
