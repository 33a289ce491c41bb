#include "bench/peer_common.h"

#include <sys/resource.h>

#include <cassert>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

// CLI11 2.1's string helpers trip GCC 12's -Wnull-dereference (a false positive, as
// cli/command.h says).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <CLI/CLI.hpp>
#pragma GCC diagnostic pop
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/json.h"

namespace hw::bench {
namespace {

std::string Fail(const std::string& field, double value, const std::string& constraint) {
  std::ostringstream s;
  s.precision(17);
  s << field << ": must be " << constraint << ", got " << value;
  return s.str();
}

}  // namespace

std::string PeerOptions::Check() const {
  if (!(voxel_size_m >= 0.0005 && voxel_size_m <= 0.5)) {
    return Fail("voxel_size_m", voxel_size_m, "in [0.0005, 0.5] m");
  }
  if (!(truncation_m >= 2 * voxel_size_m && truncation_m <= 1)) {
    return Fail("truncation_m", truncation_m, "in [2 voxels, 1] m");
  }
  if (!(min_depth_m >= 0 && std::isfinite(min_depth_m))) {
    return Fail("min_depth_m", min_depth_m, ">= 0 m");
  }
  if (!(max_depth_m > min_depth_m && std::isfinite(max_depth_m))) {
    return Fail("max_depth_m", max_depth_m, "> min_depth_m");
  }
  if (max_frames < 0) return Fail("max_frames", max_frames, ">= 0");
  return "";
}

PeerOptions ParsePeerOptions(int argc, char** argv, const std::string& what) {
  PeerOptions options;
  CLI::App app(what);
  std::string scan, trajectory, summary;
  app.add_option("scan", scan, "scan folder (scan-format.md)")->required();
  app.add_option("--out", trajectory, "TUM trajectory to write (world_from_depth)")->required();
  app.add_option("--summary", summary, "JSON summary to write (fps, peak memory, ...)");
  app.add_option("--voxel-size", options.voxel_size_m, "TSDF voxel size, m")
      ->capture_default_str();
  app.add_option("--truncation", options.truncation_m, "TSDF truncation distance, m")
      ->capture_default_str();
  app.add_option("--min-depth", options.min_depth_m, "nearer depth is dropped, m")
      ->capture_default_str();
  app.add_option("--max-depth", options.max_depth_m, "farther depth is dropped, m")
      ->capture_default_str();
  app.add_option("--frames", options.max_frames, "process at most this many frames, 0: all")
      ->capture_default_str();
  std::string poses;
  app.add_option("--poses", poses,
                 "fuse along this TUM trajectory (world_from_depth) instead of tracking: integration only");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    std::exit(app.exit(e));
  }
  options.scan = scan;
  options.trajectory = trajectory;
  options.summary = summary;
  options.poses = poses;
  if (const std::string problem = options.Check(); !problem.empty()) {
    std::fprintf(stderr, "%s\n", problem.c_str());
    std::exit(2);
  }
  return options;
}

DepthFrames::DepthFrames(const PeerOptions& options)
    : options_(options), scan_(core::Scan::Open(options.scan)) {
  num_frames_ = scan_.NumFrames(core::Stream::kDepth);
  if (options.max_frames > 0) num_frames_ = std::min(num_frames_, options.max_frames);
  const core::CameraModel& camera = scan_.rig().depth;
  width_ = camera.width;
  height_ = camera.height;
  fx_ = camera.fx;
  fy_ = camera.fy;
  cx_ = camera.cx;
  cy_ = camera.cy;
  bool distorted = false;
  for (const double k : camera.distortion) distorted = distorted || k != 0;
  if (camera.type == core::CameraModelType::kSplined) {
    // OpenCV has no splined model: the same map (pinhole pixel -> camera pixel) by Project.
    undistort_map_x_.create(height_, width_, CV_32FC1);
    undistort_map_y_.create(height_, width_, CV_32FC1);
    for (int v = 0; v < height_; ++v) {
      for (int u = 0; u < width_; ++u) {
        const Eigen::Vector2d q = camera.Project(Eigen::Vector3d((u - cx_) / fx_, (v - cy_) / fy_, 1));
        undistort_map_x_.at<float>(v, u) = static_cast<float>(q.x());
        undistort_map_y_.at<float>(v, u) = static_cast<float>(q.y());
      }
    }
  } else if (distorted) {
    // Same pinhole as the distorted camera: the peers take pinhole depth only.
    const cv::Matx33d K(fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1);
    cv::initUndistortRectifyMap(K, camera.distortion, cv::noArray(), K,
                                cv::Size(width_, height_), CV_32FC1, undistort_map_x_,
                                undistort_map_y_);
  }
}

Eigen::Matrix3d DepthFrames::K() const {
  Eigen::Matrix3d K;
  K << fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1;
  return K;
}

cv::Mat DepthFrames::Load(int i) const {
  assert(Exists(i));
  cv::Mat depth_m = scan_.LoadDepth(i);
  if (!undistort_map_x_.empty()) {
    cv::Mat undistorted;
    cv::remap(depth_m, undistorted, undistort_map_x_, undistort_map_y_, cv::INTER_NEAREST,
              cv::BORDER_CONSTANT, 0);
    depth_m = undistorted;
  }
  const float lo = static_cast<float>(options_.min_depth_m);
  const float hi = static_cast<float>(options_.max_depth_m);
  for (int y = 0; y < depth_m.rows; ++y) {
    float* row = depth_m.ptr<float>(y);
    for (int x = 0; x < depth_m.cols; ++x) {
      if (!(row[x] >= lo && row[x] <= hi)) row[x] = 0;
    }
  }
  return depth_m;
}

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux: KiB
}

void WriteResults(const PeerOptions& options, const core::Trajectory& trajectory,
                  const PeerResult& result) {
  if (!options.poses.empty() && result.frames == 0) {
    throw core::InputError(options.poses, "no depth frame of the scan lies within these poses");
  }
  core::WriteTumTrajectory(options.trajectory, trajectory);
  char line[512];
  std::snprintf(line, sizeof line,
                "%s: %d frames in %.3f s = %.2f frames/s (track %.3f, integrate %.3f, "
                "raycast %.3f s; decoding %.3f s excluded), peak RSS %.1f MB, %d failed, "
                "%d skipped",
                result.method.c_str(), result.frames, result.loop_s, result.fps(),
                result.track_s, result.integrate_s, result.raycast_s, result.decode_s,
                result.peak_rss_mb, result.failed_frames, result.skipped_frames);
  std::printf("%s\n", line);
  if (options.summary.empty()) return;
  std::ostringstream json;
  json.precision(9);
  json << "{\n  \"method\": " << core::JsonString(result.method)
       << ",\n  \"scan\": " << core::JsonString(options.scan.string())
       << ",\n  \"voxel_size_m\": " << options.voxel_size_m
       << ",\n  \"truncation_m\": " << options.truncation_m
       << ",\n  \"min_depth_m\": " << options.min_depth_m
       << ",\n  \"max_depth_m\": " << options.max_depth_m << ",\n  \"frames\": " << result.frames
       << ",\n  \"failed_frames\": " << result.failed_frames
       << ",\n  \"skipped_frames\": " << result.skipped_frames
       << ",\n  \"loop_s\": " << result.loop_s << ",\n  \"track_s\": " << result.track_s
       << ",\n  \"integrate_s\": " << result.integrate_s
       << ",\n  \"raycast_s\": " << result.raycast_s << ",\n  \"decode_s\": " << result.decode_s
       << ",\n  \"fps\": " << result.fps() << ",\n  \"peak_rss_mb\": " << result.peak_rss_mb
       << "\n}\n";
  core::WriteFileAtomically(options.summary, json.str());
}

int RunHarness(const char* peer, const std::function<int()>& body) {
  try {
    return body();
  } catch (const core::InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
  } catch (const core::OutputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", peer, e.what());
  }
  return 1;
}

std::optional<core::Trajectory> ReadGivenPoses(const PeerOptions& options) {
  if (options.poses.empty()) return std::nullopt;
  core::Trajectory poses = core::ReadTumTrajectory(options.poses);
  if (poses.empty()) throw core::InputError(options.poses, "holds no pose");
  return poses;
}

std::optional<Eigen::Matrix4d> GivenPoseAt(const core::Trajectory& poses, double timestamp_s) {
  const std::optional<core::Rigid3d> pose = poses.At(timestamp_s);
  if (!pose) return std::nullopt;
  return pose->ToMatrix4();
}

}  // namespace hw::bench
