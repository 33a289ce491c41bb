#pragma once

// What the reconstruction peer harnesses (open3d_reconstruct.cc, opencv_kinfu_reconstruct.cc)
// share: their command line, reading a heatwave scan's depth frames, timing, peak memory and
// the result files. They run other projects' pipelines on the same frames as `heatwave
// reconstruct`, for bench/reconstruct_peers.sh; nothing here is used by heatwave itself.

#include <chrono>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/scan.h"
#include "core/trajectory.h"

namespace hw::bench {

// Settings shared by every peer, chosen to match heatwave reconstruct's defaults
// (reconstruct/tsdf_volume.h) so that all methods fuse the same frames the same way.
struct PeerOptions {
  std::filesystem::path scan;         // scan folder (scan-format.md)
  std::filesystem::path trajectory;   // TUM trajectory written here, world_from_depth
  std::filesystem::path summary;      // optional JSON summary (empty: none)
  double voxel_size_m = 0.005;        // TSDF voxel side, m, in [0.0005, 0.5]
  double truncation_m = 0.02;         // TSDF truncation band half-width, m, >= 2 voxels
  double min_depth_m = 0.3;           // depth pixels nearer are dropped, m, >= 0
  double max_depth_m = 4.0;           // ... farther are dropped, m, > min_depth_m
  int max_frames = 0;                 // process at most this many depth frames, 0: all
  // TUM trajectory (world_from_depth, e.g. groundtruth.txt) to fuse along instead of
  // tracking: only integration runs (empty: track, as the peer's own loop does).
  std::filesystem::path poses;

  std::string Check() const;  // "" when valid, else names the field, value and constraint
};

// Parses the command line shared by the harnesses (--help lists it). `what` is the
// harness's one-line description. Exits the process on --help (0) or a bad option (2).
PeerOptions ParsePeerOptions(int argc, char** argv, const std::string& what);

// The depth frames of a scan as the peers take them: metres, CV_32FC1, 0 = no measurement,
// pixels outside [min_depth_m, max_depth_m] set to 0, undistorted onto a pinhole camera when
// the rig's depth camera has distortion (nearest-neighbour remap: depth must not be blended
// across edges). Throws core::InputError as core::Scan does.
class DepthFrames {
 public:
  explicit DepthFrames(const PeerOptions& options);

  const core::Scan& scan() const { return scan_; }
  int size() const { return num_frames_; }
  int width() const { return width_; }
  int height() const { return height_; }
  // Pinhole intrinsics of the returned frames, pixels.
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }
  Eigen::Matrix3d K() const;
  bool Exists(int i) const { return scan_.FrameExists(core::Stream::kDepth, i); }
  double Timestamp(int i) const { return scan_.Timestamp(core::Stream::kDepth, i); }
  // Frame i (see the class comment). Asserts Exists(i).
  cv::Mat Load(int i) const;

 private:
  PeerOptions options_;
  core::Scan scan_;
  int num_frames_ = 0;
  int width_ = 0, height_ = 0;
  double fx_ = 0, fy_ = 0, cx_ = 0, cy_ = 0;
  cv::Mat undistort_map_x_, undistort_map_y_;  // empty when the depth camera is pinhole
};

// Wall time of the processing only: frame decoding is excluded by pausing around it.
class LoopTimer {
 public:
  void Start() { start_ = Clock::now(); }
  void Stop() { seconds_ += std::chrono::duration<double>(Clock::now() - start_).count(); }
  double seconds() const { return seconds_; }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
  double seconds_ = 0;
};

// Peak resident memory of this process so far, MiB (getrusage ru_maxrss).
double PeakRssMb();

// PeerOptions::poses read once (nullopt when none was given), and a frame's world_from_depth
// in them as a 4×4 matrix: interpolated at its time, nullopt outside the trajectory (the
// harness skips the frame). Throws core::InputError for an unreadable or empty file
// (WriteResults, when no frame lay within the poses).
std::optional<core::Trajectory> ReadGivenPoses(const PeerOptions& options);
std::optional<Eigen::Matrix4d> GivenPoseAt(const core::Trajectory& poses, double timestamp_s);

// What a harness run measured.
struct PeerResult {
  std::string method;         // e.g. "open3d", "opencv-kinfu"
  int frames = 0;             // depth frames processed (tracked and fused)
  int skipped_frames = 0;     // frames whose file is missing
  int failed_frames = 0;      // frames whose tracking the peer reported as failed
  double loop_s = 0;          // wall time of processing, decoding excluded, s
  // ... of which tracking, integration and raycasting (0 when the peer has no raycast), s
  double track_s = 0, integrate_s = 0, raycast_s = 0;
  double decode_s = 0;        // wall time of decoding the frames, s
  double peak_rss_mb = 0;     // PeakRssMb() at the end
  double fps() const { return loop_s > 0 ? frames / loop_s : 0; }
};

// Writes the trajectory (TUM) and, when options.summary is set, the JSON summary, and
// prints the one-line result on stdout. Throws core::OutputError, and core::InputError
// (naming options.poses) when poses were given and no frame lay within them.
void WriteResults(const PeerOptions& options, const core::Trajectory& trajectory,
                  const PeerResult& result);

// Runs a harness's body: its return value, or 1 after printing one line on stderr for a
// bad scan (core::InputError), an unwritable output (core::OutputError) or the peer library's
// own error (any other std::exception: Open3D's runtime_error, cv::Exception), prefixed with
// `peer`.
int RunHarness(const char* peer, const std::function<int()>& body);

}  // namespace hw::bench
