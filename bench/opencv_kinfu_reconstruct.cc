// Peer harness: OpenCV-contrib 4.6's rgbd module over a heatwave scan's depth frames, for
// bench/reconstruct_peers.sh: cv::rgbd::FastICPOdometry frame to frame (each frame against
// the previous one, not against the model) and cv::kinfu's hashed TSDF volume
// (makeVolume(VolumeType::HASHTSDF, ...)) integrating every frame at its tracked pose.
//
//   build/bench/bench_opencv_kinfu_reconstruct SCAN --out traj.txt
//       [--voxel-size 0.005] [--truncation 0.02] [--summary summary.json] [--poses TUM]
//
// Odometry settings are FastICPOdometry's defaults (max depth difference 0.07 m, normal
// angle 30°, bilateral sigma 0.04 m / 4.5 px, kernel 7, its default iteration counts); the
// volume has heatwave's voxel size, truncation, depth range and weight cap (64). No raycast
// per frame: frame-to-frame odometry does not need one. A frame whose odometry fails
// (compute() returns false) keeps the previous pose, is counted and is still fused, which is
// what a plain frame-to-frame loop does. With --poses (bench/scale.sh) each frame is
// integrated at its pose in the trajectory (interpolated at the frame's time; frames outside
// it skipped) and nothing is tracked: the volume alone, beside heatwave's on the same poses.
#include <cstdio>
#include <exception>
#include <optional>

#include <opencv2/core/affine.hpp>
#include <opencv2/rgbd.hpp>
#include <opencv2/rgbd/volume.hpp>

#include "bench/peer_common.h"
#include "core/error.h"

namespace {

constexpr int kMaxWeight = 64;              // frames, as heatwave's TsdfOptions::max_weight
constexpr float kRaycastStepFactor = 0.25f;  // VolumeParams::defaultParams (unused: no raycast)

}  // namespace

int main(int argc, char** argv) {
  const hw::bench::PeerOptions options = hw::bench::ParsePeerOptions(
      argc, argv, "OpenCV-contrib FastICPOdometry + kinfu HashTSDF over a heatwave scan");
  return hw::bench::RunHarness("opencv", [&] {
    const hw::bench::DepthFrames frames(options);
    const cv::Matx33f K(static_cast<float>(frames.fx()), 0, static_cast<float>(frames.cx()), 0,
                        static_cast<float>(frames.fy()), static_cast<float>(frames.cy()), 0, 0,
                        1);
    const cv::Ptr<cv::rgbd::FastICPOdometry> odometry =
        cv::rgbd::FastICPOdometry::create(cv::Mat(K));
    const cv::kinfu::Intr intrinsics(K);
    const cv::Ptr<cv::kinfu::Volume> volume = cv::kinfu::makeVolume(
        cv::kinfu::VolumeType::HASHTSDF, static_cast<float>(options.voxel_size_m),
        cv::Matx44f::eye(), kRaycastStepFactor, static_cast<float>(options.truncation_m),
        kMaxWeight, static_cast<float>(options.max_depth_m), cv::Vec3i(16, 16, 16));

    hw::core::Trajectory trajectory;
    hw::bench::PeerResult result;
    result.method = "opencv-kinfu";
    hw::bench::LoopTimer loop, decode, track_timer, integrate_timer;
    cv::Affine3d world_from_depth = cv::Affine3d::Identity();
    cv::Ptr<cv::rgbd::OdometryFrame> previous;
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
        cv::Matx44d m;
        for (int r = 0; r < 4; ++r) {
          for (int c = 0; c < 4; ++c) m(r, c) = (*pose)(r, c);
        }
        world_from_depth = cv::Affine3d(m);
      }
      decode.Start();
      const cv::Mat depth_m = frames.Load(i);
      decode.Stop();

      loop.Start();
      track_timer.Start();
      cv::Ptr<cv::rgbd::OdometryFrame> current;
      if (!given) {
        current = cv::rgbd::OdometryFrame::create(cv::Mat(), depth_m);
        // Pyramids, normals and masks once per frame: as source now, as destination next time.
        odometry->prepareFrameCache(current, cv::rgbd::OdometryFrame::CACHE_ALL);
      }
      if (previous) {
        // Rt maps points of the source (current) frame into the destination (previous) one:
        // previous_from_current.
        cv::Mat Rt;
        if (odometry->compute(current, previous, Rt)) {
          world_from_depth = world_from_depth * cv::Affine3d(cv::Matx44d(Rt));
        } else {
          ++result.failed_frames;
        }
      }
      track_timer.Stop();
      integrate_timer.Start();
      volume->integrate(depth_m, 1.0f, cv::Matx44f(world_from_depth.matrix), intrinsics, i);
      previous = current;
      integrate_timer.Stop();
      loop.Stop();

      const cv::Matx44d& m = world_from_depth.matrix;
      Eigen::Matrix<double, 3, 4> Rt;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) Rt(r, c) = m(r, c);
      }
      trajectory.Add(frames.Timestamp(i), hw::core::Rigid3d::FromMatrix(Rt));
      ++result.frames;
    }
    result.loop_s = loop.seconds();
    result.decode_s = decode.seconds();
    result.track_s = track_timer.seconds();
    result.integrate_s = integrate_timer.seconds();
    result.peak_rss_mb = hw::bench::PeakRssMb();
    hw::bench::WriteResults(options, trajectory, result);
    return 0;
  });
}
