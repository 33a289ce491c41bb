#include "reconstruct/reconstruction.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "core/error.h"
#include "core/strings.h"
#include "reconstruct/option_check.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

namespace {

// The stage options with the pipeline-wide depth range and thread count applied.
ReconstructionOptions Effective(ReconstructionOptions o) {
  o.tsdf.min_depth_m = o.depth.min_depth_m = o.raycast.min_depth_m = o.min_depth_m;
  o.tsdf.max_depth_m = o.depth.max_depth_m = o.raycast.max_depth_m = o.max_depth_m;
  o.tsdf.num_threads = o.depth.num_threads = o.icp.num_threads = o.raycast.num_threads =
      o.mesh.num_threads = o.num_threads;
  if (o.raycast_level >= 0 && o.raycast_level < static_cast<int>(o.icp.iterations.size())) {
    for (int l = 0; l < o.raycast_level; ++l) o.icp.iterations[l] = 0;
    if (o.raycast_level < o.depth.num_levels) o.depth.first_map_level = o.raycast_level;
  }
  return o;
}

double Ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Largest time between a depth frame and the colour frame used with it, s: three frames at
// 30 Hz (a dropped frame or two), short enough for the predicted motion to bridge.
constexpr double kMaxColourGapS = 0.1;

}  // namespace

cv::Mat RegisterColour(const cv::Mat& depth_m, const PinholeCamera& depth_camera,
                       const cv::Mat& rgb, const PinholeCamera& rgb_camera,
                       const core::Rigid3d& rgb_from_depth, int num_threads) {
  assert(depth_m.type() == CV_32FC1 && rgb.type() == CV_8UC3);
  cv::Mat registered(depth_m.size(), CV_8UC3, cv::Scalar(0, 0, 0));
  // In float, without Eigen or lround in the per-pixel loop (a full-size frame per frame).
  const Eigen::Matrix3f R = rgb_from_depth.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f t = rgb_from_depth.translation.cast<float>();
  const float inv_fx = 1.0f / depth_camera.fx, inv_fy = 1.0f / depth_camera.fy;
  const float u_max = rgb_camera.width - 0.5f, v_max = rgb_camera.height - 0.5f;
  ForEachBand(depth_m.rows, num_threads, [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* depth_row = depth_m.ptr<float>(y);
      cv::Vec3b* out = registered.ptr<cv::Vec3b>(y);
      const float ray_y = (static_cast<float>(y) - depth_camera.cy) * inv_fy;
      for (int x = 0; x < depth_m.cols; ++x) {
        const float z = depth_row[x];
        if (!(z > 0) || std::isinf(z)) continue;
        const float px = (static_cast<float>(x) - depth_camera.cx) * inv_fx * z, py = ray_y * z;
        const float cx = R(0, 0) * px + R(0, 1) * py + R(0, 2) * z + t.x();
        const float cy = R(1, 0) * px + R(1, 1) * py + R(1, 2) * z + t.y();
        const float cz = R(2, 0) * px + R(2, 1) * py + R(2, 2) * z + t.z();
        if (!(cz > 0)) continue;
        const float inv_z = 1.0f / cz;
        const float u = rgb_camera.fx * cx * inv_z + rgb_camera.cx;
        const float v = rgb_camera.fy * cy * inv_z + rgb_camera.cy;
        // The nearest pixel, when inside the image (the test also rejects NaN).
        if (!(u > -0.5f && v > -0.5f && u < u_max && v < v_max)) continue;
        out[x] = rgb.at<cv::Vec3b>(static_cast<int>(v + 0.5f), static_cast<int>(u + 0.5f));
      }
    }
  });
  return registered;
}

std::string FrameStatusName(FrameStatus status) {
  switch (status) {
    case FrameStatus::kInitialised: return "initialised";
    case FrameStatus::kTracked: return "tracked";
    case FrameStatus::kRecovered: return "recovered";
    case FrameStatus::kLost: return "lost";
    case FrameStatus::kNoDepth: return "no_depth";
    case FrameStatus::kPosed: return "posed";
  }
  return "?";
}

std::string ReconstructionOptions::Check() const {
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return Fail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return Fail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (!InRange(min_valid_depth_fraction, 0, 1)) {
    return Fail("min_valid_depth_fraction", min_valid_depth_fraction, "in [0, 1]");
  }
  if (!(relocalisation_widening >= 1) || !std::isfinite(relocalisation_widening)) {
    return Fail("relocalisation_widening", relocalisation_widening, ">= 1");
  }
  if (!(max_condition_ratio > 1) || !std::isfinite(max_condition_ratio)) {
    return Fail("max_condition_ratio", max_condition_ratio, "> 1 and finite");
  }
  if (!(max_residual_ratio > 1) || !std::isfinite(max_residual_ratio)) {
    return Fail("max_residual_ratio", max_residual_ratio, "> 1 and finite");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  if (raycast_level < 0 || raycast_level > 2 || raycast_level >= depth.num_levels) {
    return Fail("raycast_level", raycast_level, "in [0, 2] and < depth.num_levels");
  }
  if (icp.iterations[raycast_level] == 0 &&
      (raycast_level + 1 >= 3 || icp.iterations[raycast_level + 1] == 0) &&
      (raycast_level + 2 >= 3 || icp.iterations[raycast_level + 2] == 0)) {
    return Fail("icp.iterations", 0, "> 0 at raycast_level or a coarser level");
  }
  if (raycast_interval < 1 || raycast_interval > 8) return Fail("raycast_interval", raycast_interval, "in [1, 8]");
  if (!(reuse_max_correction_m > 0) || !std::isfinite(reuse_max_correction_m)) {
    return Fail("reuse_max_correction_m", reuse_max_correction_m, "> 0 and finite");
  }
  if (!(reuse_max_correction_deg > 0) || !std::isfinite(reuse_max_correction_deg)) {
    return Fail("reuse_max_correction_deg", reuse_max_correction_deg, "> 0 and finite");
  }
  if (!(reuse_max_motion_m > 0) || !std::isfinite(reuse_max_motion_m)) {
    return Fail("reuse_max_motion_m", reuse_max_motion_m, "> 0 and finite");
  }
  if (!(reuse_max_motion_deg > 0) || !std::isfinite(reuse_max_motion_deg)) {
    return Fail("reuse_max_motion_deg", reuse_max_motion_deg, "> 0 and finite");
  }
  const ReconstructionOptions e = Effective(*this);
  if (std::string m = e.tsdf.Check(); !m.empty()) return "tsdf." + m;
  if (std::string m = e.depth.Check(); !m.empty()) return "depth." + m;
  if (std::string m = e.icp.Check(); !m.empty()) return "icp." + m;
  if (std::string m = e.raycast.Check(); !m.empty()) return "raycast." + m;
  if (std::string m = e.mesh.Check(); !m.empty()) return "mesh." + m;
  if (std::string m = e.dynamic.Check(); !m.empty()) return "dynamic." + m;
  return "";
}

std::string ScanReconstructionOptions::Check() const {
  if (first_frame < 0) return Fail("first_frame", first_frame, ">= 0");
  if (max_frames < 0) return Fail("max_frames", max_frames, ">= 0 (0: all)");
  return "";
}

Reconstruction::Reconstruction(const core::Rig& rig, const ReconstructionOptions& options)
    : rig_(rig),
      options_(Effective(options)),
      depth_undistorter_(rig.depth),
      volume_(options_.tsdf) {
  assert(options.Check().empty());
  assert(rig.Check().empty());
  if (rig_.rgb) rgb_undistorter_ = Undistorter(*rig_.rgb);
  if (rig_.depth_correction) {
    depth_offset_map_ = core::DepthOffsetMap(*rig_.depth_correction, rig_.depth);
  }
}

void Reconstruction::SetInitialPose(const core::Rigid3d& world_from_depth) {
  assert(trajectory_.empty());
  initial_pose_ = world_from_depth;
}

core::Rigid3d Reconstruction::PoseAt(double timestamp_s) const {
  assert(!trajectory_.empty());
  const auto& poses = trajectory_.poses();
  const core::TimedPose& b = poses.back();
  if (poses.size() < 2) return b.world_from_sensor;
  const core::TimedPose& a = poses[poses.size() - 2];
  const double s = (timestamp_s - a.timestamp_s) / (b.timestamp_s - a.timestamp_s);
  return core::Interpolate(a.world_from_sensor, b.world_from_sensor, s);
}

const FrameRecord& Reconstruction::AddFrame(const FrameInput& frame) {
  if (frame.depth_m.type() != CV_32FC1 || frame.depth_m.cols != rig_.depth.width ||
      frame.depth_m.rows != rig_.depth.height) {
    throw std::invalid_argument(core::StringPrintf(
        "depth frame at %.6f s: expected a %dx%d CV_32FC1 image in metres, got %dx%d type %d",
        frame.timestamp_s, rig_.depth.width, rig_.depth.height, frame.depth_m.cols,
        frame.depth_m.rows, frame.depth_m.type()));
  }
  if (!frame.rgb.empty() && rig_.rgb &&
      (frame.rgb.type() != CV_8UC3 || frame.rgb.cols != rig_.rgb->width ||
       frame.rgb.rows != rig_.rgb->height)) {
    throw std::invalid_argument(core::StringPrintf(
        "rgb frame at %.6f s: expected a %dx%d CV_8UC3 image, got %dx%d type %d",
        frame.rgb_timestamp_s, rig_.rgb->width, rig_.rgb->height, frame.rgb.cols,
        frame.rgb.rows, frame.rgb.type()));
  }
  if (!(frame.timestamp_s > last_timestamp_s_) || !std::isfinite(frame.timestamp_s)) {
    throw std::invalid_argument(core::StringPrintf(
        "depth frame at %.6f s: timestamps must increase (previous %.6f s)", frame.timestamp_s,
        last_timestamp_s_));
  }
  last_timestamp_s_ = frame.timestamp_s;

  FrameRecord record;
  record.index = static_cast<int>(frames_.size());
  record.timestamp_s = frame.timestamp_s;

  auto start = std::chrono::steady_clock::now();
  // NaN / inf pixels are missing measurements, not numbers to fuse: undistortion copies them
  // (nearest neighbour), the pyramid's range limits drop them from everything downstream, and
  // registration skips them.
  // The sensor's systematic inverse-depth error is undone first, at the distorted pixel
  // whose ray it was calibrated on.
  cv::Mat corrected_depth_m;
  if (!depth_offset_map_.empty()) {
    corrected_depth_m = frame.depth_m.clone();
    core::CorrectDepth(depth_offset_map_, &corrected_depth_m);
  }
  const cv::Mat undistorted = depth_undistorter_.UndistortDepth(
      depth_offset_map_.empty() ? frame.depth_m : corrected_depth_m);
  // The colour frame, undistorted once for both uses: registered to the depth pixels for
  // ICP's photometric term, and projected into the volume by integration.
  cv::Mat rgb_pinhole, registered_rgb;
  const bool use_colour = rig_.rgb && !frame.rgb.empty() &&
                          (options_.integrate_colour || options_.icp.photometric_weight > 0);
  if (use_colour) {
    rgb_pinhole = rgb_undistorter_.UndistortColour(frame.rgb);
    if (options_.icp.photometric_weight > 0) {
      // The rig moved between the two exposures: register with the predicted motion.
      core::Rigid3d depth_from_rgb_now = rig_.depth_from_rgb;
      if (!trajectory_.empty()) {
        depth_from_rgb_now = PoseAt(frame.timestamp_s).Inverse() *
                             PoseAt(frame.rgb_timestamp_s) * rig_.depth_from_rgb;
      }
      registered_rgb = RegisterColour(undistorted, depth_undistorter_.pinhole(), rgb_pinhole,
                                      rgb_undistorter_.pinhole(), depth_from_rgb_now.Inverse(),
                                      options_.num_threads);
    }
  }
  const DepthPyramid pyramid = BuildDepthPyramid(undistorted, depth_undistorter_.pinhole(),
                                                 options_.depth, registered_rgb);
  record.valid_depth_fraction =
      static_cast<double>(cv::countNonZero(pyramid.raw_depth_m)) / pyramid.raw_depth_m.total();
  record.prepare_ms = Ms(start);

  if (record.valid_depth_fraction < options_.min_valid_depth_fraction ||
      record.valid_depth_fraction == 0) {
    record.status = FrameStatus::kNoDepth;
    record.blocks = volume_.NumBlocks();
    frames_.push_back(record);
    return frames_.back();
  }

  core::Rigid3d world_from_depth;
  if (frame.world_from_depth) {
    world_from_depth = *frame.world_from_depth;
    record.status = FrameStatus::kPosed;
  } else if (trajectory_.empty()) {
    world_from_depth = initial_pose_.value_or(core::Rigid3d::Identity());
    record.status = FrameStatus::kInitialised;
  } else {
    // After posed frames the model view is stale (and without colour): raycast it at the
    // last pose first.
    if (!model_ || !model_for_tracking_) UpdateModel(trajectory_.poses().back().world_from_sensor, record);
    start = std::chrono::steady_clock::now();
    const bool was_lost = lost_;
    const bool ok = Track(pyramid, frame.timestamp_s, record, world_from_depth);
    record.track_ms = Ms(start);
    if (!ok) {
      lost_ = true;
      record.status = FrameStatus::kLost;
      record.blocks = volume_.NumBlocks();
      frames_.push_back(record);
      return frames_.back();
    }
    lost_ = false;
    record.status = was_lost ? FrameStatus::kRecovered : FrameStatus::kTracked;
  }
  trajectory_.Add(frame.timestamp_s, world_from_depth);
  record.fused = true;
  // After a frame tracked normally, the view may wait for raycast_interval fused frames;
  // after any other (the first, a recovery, a retry, held directions) it is cast at once.
  const bool normal = record.status == FrameStatus::kTracked && !record.widened_gate &&
                      !record.from_last_pose && record.held_directions == 0 &&
                      record.correction_m <= options_.reuse_max_correction_m &&
                      record.correction_deg <= options_.reuse_max_correction_deg;
  // Posed frames track against nothing: they keep a model view only for the dynamic mask
  // (what moved in front of it is not integrated), cast as often as for tracking.
  const bool due = model_ && (++fused_since_raycast_ >= options_.raycast_interval || ViewTooFar(world_from_depth));
  const bool raycast = frame.world_from_depth ? options_.dynamic.enabled() && (!model_ || due)
                                              : !model_ || !normal || due;
  // Without integrate_between_raycasts a frame that reuses the model view only tracks: its
  // depth would change a volume nobody looks at until the next raycast, whose frame fuses
  // nearly the same surfaces.
  if (options_.integrate_between_raycasts || raycast || frame.world_from_depth) {
    Integrate(pyramid, frame, rgb_pinhole, world_from_depth, record);
  }
  if (raycast) {
    UpdateModel(world_from_depth, record, !frame.world_from_depth);
  } else if (frame.world_from_depth && !options_.dynamic.enabled()) {
    model_.reset();
  }
  record.blocks = volume_.NumBlocks();
  frames_.push_back(record);
  return frames_.back();
}

namespace {
// Relocalisation also tries the constant-velocity extrapolation over a loss this short, s:
// a hand held rig keeps its motion for a fraction of a second, not for seconds.
constexpr double kMaxExtrapolationS = 0.5;
}  // namespace

bool Reconstruction::Track(const DepthPyramid& pyramid, double timestamp_s, FrameRecord& record,
                           core::Rigid3d& world_from_depth) {
  assert(model_.has_value());
  const auto& poses = trajectory_.poses();
  const core::Rigid3d last = poses.back().world_from_sensor;
  const double w = options_.relocalisation_widening;

  // ICP runs to try, each a start pose and its options: tracking takes the first that
  // succeeds, relocalisation the best of all.
  struct Attempt {
    core::Rigid3d initial;
    IcpOptions icp;
    bool from_last_pose = false, widened = false;
  };
  std::vector<Attempt> attempts;
  IcpOptions wide = options_.icp;
  wide.max_distance_m *= w;
  if (!lost_) {
    // Constant velocity (the normal case), then the last pose itself — a hand-held rig that
    // stops or turns abruptly breaks the constant-velocity guess. Then both again with the
    // association gate widened (the jump limits kept): at the start of a scan there is no
    // velocity yet, and a 10 Hz stream or a dropped frame moves the view further than the
    // gate between two frames (measured: 45 mm and 1.8° per frame on a loop at 10 Hz, which
    // converged at the normal gate on 13 % inliers and was lost for 25 frames). With one
    // pose there is no velocity: the prediction is the last pose, tried once per gate.
    for (const IcpOptions* icp : {&options_.icp, &wide}) {
      if (icp == &wide && w == 1) break;
      attempts.push_back({PoseAt(timestamp_s), *icp, poses.size() < 2, icp == &wide});
      if (poses.size() >= 2) attempts.push_back({last, *icp, true, icp == &wide});
    }
  } else {
    // Relocalisation: the rig has moved for a while unobserved. Widen the gates and let the
    // allowed jump grow with the time since the last fused frame, at the nominal frame rate.
    const double period_s =
        poses.size() >= 2 ? poses.back().timestamp_s - poses[poses.size() - 2].timestamp_s : 1.0 / 30;
    const double elapsed_s = timestamp_s - poses.back().timestamp_s;
    const double frames_elapsed = std::max(1.0, elapsed_s / std::max(period_s, 1e-3));
    wide.max_jump_m *= w * frames_elapsed;
    wide.max_jump_deg = std::min(180.0, wide.max_jump_deg * w * frames_elapsed);
    // From where the last velocity carries the rig while the loss is short (it usually
    // keeps moving the way it was: a hand over the lens, a person passing, a burst of blurred
    // frames), and from the last pose (it may have stopped). Both are run and the one with
    // more inliers kept: along a row of alike parts (breakers, terminals) the wrong start
    // converges too, one part over, with a fine residual (measured on a 10 Hz walk past
    // breakers after 0.3 s hidden: from the last pose 53 mm off on 54.7k inliers, 4.0 mm
    // RMS, and the tracking then ran away by 0.67 m; from the extrapolation 21 mm on 60.5k).
    if (poses.size() >= 2 && elapsed_s <= kMaxExtrapolationS) {
      attempts.push_back({PoseAt(timestamp_s), wide, false, true});
    }
    attempts.push_back({last, wide, true, true});
  }

  // The residual gate relative to the frames tracked before.
  double max_residual_m = std::numeric_limits<double>::infinity();
  double max_condition = std::numeric_limits<double>::infinity();
  constexpr size_t kMinHistory = 5, kHistory = 30;
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  if (recent_residuals_m_.size() >= kMinHistory) {
    max_residual_m = options_.max_residual_ratio * median(recent_residuals_m_);
    max_condition = options_.max_condition_ratio * median(recent_conditions_);
  }
  // Directions constrained this much worse than usual are held at the prediction (at most
  // icp.max_held_directions of them, else the frame fails as ill-conditioned).
  IcpResult best;
  const Attempt* best_attempt = &attempts.front();
  bool ok = false;
  for (Attempt& attempt : attempts) {
    attempt.icp.max_condition = std::min(attempt.icp.max_condition, max_condition);
    IcpResult result = AlignToModel(pyramid, *model_, attempt.initial, attempt.icp);
    if (result.status == IcpStatus::kOk && result.residual_rms_m > max_residual_m) {
      result.status = IcpStatus::kLargeResidual;
    }
    if (result.status == IcpStatus::kOk) {
      if (!ok || result.inliers > best.inliers) {
        best = result;
        best_attempt = &attempt;
      }
      ok = true;
      if (!lost_) break;  // tracking: the first success; relocalising: the best of all
      continue;
    }
    if (&attempt == &attempts.front()) best = result;  // report the first failure
  }
  record.icp_status = best.status;
  record.inliers = best.inliers;
  record.valid_points = best.valid_points;
  record.residual_rms_m = best.residual_rms_m;
  record.condition = best.condition;
  record.held_directions = best.held_directions;
  record.from_last_pose = best_attempt->from_last_pose;
  record.widened_gate = best_attempt->widened;
  record.iterations = best.iterations;
  const core::PoseError correction =
      core::ComparePoses(attempts.front().initial, best.world_from_camera);
  record.correction_m = correction.translation_m;
  record.correction_deg = correction.rotation_rad * kRadToDeg;
  if (ok) {
    world_from_depth = best.world_from_camera;
    // The gates' history holds fully constrained frames only: a run of held ones must not
    // raise what counts as usual.
    if (best.held_directions == 0) {
      recent_residuals_m_.push_back(best.residual_rms_m);
      recent_conditions_.push_back(best.condition);
      if (recent_residuals_m_.size() > kHistory) {
        recent_residuals_m_.erase(recent_residuals_m_.begin());
        recent_conditions_.erase(recent_conditions_.begin());
      }
    }
  }
  return ok;
}

bool Reconstruction::ViewTooFar(const core::Rigid3d& world_from_depth) const {
  assert(model_.has_value());
  // The next frame's pose at constant velocity: this one's motion since the last fused
  // frame, once more (no previous frame: no motion).
  const auto& poses = trajectory_.poses();
  core::Rigid3d next = world_from_depth;
  if (poses.size() >= 2) {
    const core::Rigid3d& previous = poses[poses.size() - 2].world_from_sensor;
    next = world_from_depth * (previous.Inverse() * world_from_depth);
  }
  const core::PoseError moved = core::ComparePoses(model_->world_from_camera, next);
  return moved.translation_m > options_.reuse_max_motion_m ||
         moved.rotation_rad * kRadToDeg > options_.reuse_max_motion_deg;
}

void Reconstruction::Integrate(const DepthPyramid& pyramid, const FrameInput& frame,
                               const cv::Mat& rgb_pinhole,
                               const core::Rigid3d& world_from_depth, FrameRecord& record) {
  const auto start = std::chrono::steady_clock::now();
  std::optional<ColourView> colour;
  if (options_.integrate_colour && !rgb_pinhole.empty()) {
    colour.emplace();
    colour->rgb = rgb_pinhole;
    colour->camera = rgb_undistorter_.pinhole();
    // The colour camera's pose at its own exposure time: interpolated between the last two
    // fused depth poses (this frame's included), extrapolated just beyond them.
    colour->world_from_camera = PoseAt(frame.rgb_timestamp_s) * rig_.depth_from_rgb;
    record.coloured = true;
  }
  cv::Mat depth_m = pyramid.raw_depth_m;
  if (options_.dynamic.enabled() && model_) {
    // The view this frame was tracked against: what lies in front of it moved in.
    const int level = options_.raycast_level;
    depth_m = depth_m.clone();
    record.dynamic_pixels =
        MaskInFrontOfModel(depth_m, depth_undistorter_.pinhole(), world_from_depth, model_->maps[level],
                           model_->cameras[level], model_->world_from_camera, options_.dynamic, options_.num_threads);
    // ... and what the model still shows where this frame sees through it has left.
    const std::vector<Eigen::Vector3f> through =
        ModelSeenThrough(pyramid.raw_depth_m, depth_undistorter_.pinhole(), world_from_depth, model_->maps[level],
                         options_.dynamic, options_.num_threads);
    record.carved_points = static_cast<int>(through.size());
    if (!through.empty()) volume_.CarveFreeSpace(through, world_from_depth.translation.cast<float>());
  }
  volume_.Integrate(depth_m, depth_undistorter_.pinhole(), world_from_depth, colour ? &*colour : nullptr);
  record.integrated = true;
  record.integrate_ms = Ms(start);
}

void Reconstruction::UpdateModel(const core::Rigid3d& world_from_depth, FrameRecord& record, bool for_tracking) {
  const auto start = std::chrono::steady_clock::now();
  PinholeCamera camera = depth_undistorter_.pinhole();
  for (int l = 0; l < options_.raycast_level; ++l) camera = camera.Half();
  RaycastOptions raycast = options_.raycast;
  // The photometric term compares the live colour with the model's.
  raycast.with_colour = for_tracking && options_.icp.photometric_weight > 0 && options_.integrate_colour && rig_.rgb;
  PointMap level = Raycast(volume_, camera, world_from_depth, raycast);
  const int num_levels = static_cast<int>(options_.icp.iterations.size());
  model_ = BuildModelPyramid(std::move(level), camera, world_from_depth,
                             num_levels - options_.raycast_level);
  // Finer levels than the raycast stay empty: ICP skips them (their iterations are 0).
  if (options_.raycast_level > 0) {
    ModelPyramid padded;
    padded.world_from_camera = model_->world_from_camera;
    PinholeCamera finer = depth_undistorter_.pinhole();
    for (int l = 0; l < options_.raycast_level; ++l) {
      padded.cameras.push_back(finer);
      padded.maps.emplace_back();
      finer = finer.Half();
    }
    for (size_t l = 0; l < model_->maps.size(); ++l) {
      padded.cameras.push_back(model_->cameras[l]);
      padded.maps.push_back(std::move(model_->maps[l]));
    }
    model_ = std::move(padded);
  }
  fused_since_raycast_ = 0;
  model_for_tracking_ = for_tracking;
  record.raycast_ms = Ms(start);
}

TriangleMesh Reconstruction::ExtractMesh(MeshStats* stats) const {
  return reconstruct::ExtractMesh(volume_, options_.mesh, stats);
}

FrameInput LoadScanFrame(const core::Scan& scan, int depth_index, bool with_rgb) {
  using core::Stream;
  FrameInput frame;
  frame.timestamp_s = scan.Timestamp(Stream::kDepth, depth_index);
  frame.depth_m = scan.LoadDepth(depth_index);
  if (with_rgb && scan.rig().rgb) {
    // The nearest colour frame within kMaxColourGapS, not only an associated one (within half a
    // frame): a dropped colour frame must not leave the depth frame without its photometric
    // term — on a wall, geometry alone lets ICP slide (measured: 80 mm in one frame). The
    // motion between the two exposures is compensated (registration and integration use the
    // pose at the colour frame's own time).
    const std::optional<int> j =
        scan.NearestFrame(Stream::kRgb, scan.DepthClockTime(Stream::kDepth, depth_index), kMaxColourGapS);
    if (j && scan.FrameExists(Stream::kRgb, *j)) {
      frame.rgb = scan.LoadRgb(*j);
      frame.rgb_timestamp_s = scan.DepthClockTime(Stream::kRgb, *j);
    }
  }
  return frame;
}

namespace {

// Feeds a scan's thermal frames to a ThermalFusion in time order, each once the fused depth
// poses reach it.
class ThermalFeeder {
 public:
  ThermalFeeder(const core::Scan& scan, ThermalFusion* fusion, ScanReconstruction& out)
      : scan_(scan), fusion_(fusion), out_(out),
        n_(fusion ? scan.NumFrames(core::Stream::kThermal) : 0) {
    const double period_s = scan.MedianPeriod(core::Stream::kDepth);
    max_live_dt_s_ = std::isfinite(period_s) ? 1.5 * period_s : 0.05;
  }

  // A fused depth frame (as recorded, distorted) and its pose: the thermal frames fed next
  // test occlusion against the last two (ThermalFusionOptions).
  void AddDepth(double timestamp_s, const cv::Mat& depth_m, const core::Rigid3d& world_from_depth) {
    if (!fusion_) return;
    if (live_.size() == 2) live_.erase(live_.begin());
    live_.push_back({timestamp_s, LiveDepth{depth_m, world_from_depth}});
  }

  // Fuses the frames the trajectory now reaches; with `flush`, all remaining ones (those past
  // the trajectory's end are only counted).
  void Feed(const Reconstruction& reconstruction, bool flush) {
    using core::Stream;
    while (next_ < n_) {
      const double t = scan_.Timestamp(Stream::kThermal, next_);
      if (!flush && !fusion_->PoseAvailable(t, reconstruction.trajectory())) return;
      const int i = next_++;
      if (flush && !fusion_->PoseAvailable(t, reconstruction.trajectory())) {
        ++out_.thermal_after_end;
        continue;
      }
      if (!scan_.FrameExists(Stream::kThermal, i)) {
        ++out_.thermal_missing_frames;
        out_.warnings.push_back(core::StringPrintf("thermal frame %d at %.6f s: %s is missing, skipped", i, t,
                                                   scan_.FramePath(Stream::kThermal, i).c_str()));
        continue;
      }
      auto start = std::chrono::steady_clock::now();
      ThermalFrameInput frame;
      frame.index = i;
      frame.timestamp_s = t;
      frame.apparent_c = scan_.LoadThermal(i);
      out_.thermal_load_seconds += Ms(start) / 1000;
      start = std::chrono::steady_clock::now();
      // The fused depth frames around it: within a depth period and a half of its time.
      std::vector<LiveDepth> live;
      const double t_depth = fusion_->DepthClockTime(t);
      for (const auto& [t_live, depth] : live_) {
        if (std::abs(t_live - t_depth) <= max_live_dt_s_) live.push_back(depth);
      }
      fusion_->AddFrame(reconstruction.volume(), frame, reconstruction.trajectory(), live);
      out_.thermal_seconds += Ms(start) / 1000;
      ++out_.thermal_frames;
    }
  }

 private:
  const core::Scan& scan_;
  ThermalFusion* fusion_;
  ScanReconstruction& out_;
  int n_ = 0, next_ = 0;
  std::vector<std::pair<double, LiveDepth>> live_;  // the last two fused depth frames, oldest first
  double max_live_dt_s_ = 0.05;
};

}  // namespace

double PoseGapLimitS(const core::Scan& scan) {
  const double period_s = scan.MedianPeriod(core::Stream::kDepth);
  return std::isfinite(period_s) ? std::max(0.1, 3 * period_s) : 0.1;
}

ScanReconstruction ReconstructScan(const core::Scan& scan, Reconstruction& reconstruction,
                                   const ScanReconstructionOptions& options,
                                   const std::function<void(int, int)>& frame_done, ThermalFusion* thermal) {
  assert(options.Check().empty());
  using core::Stream;
  ScanReconstruction out;
  const int n = scan.NumFrames(Stream::kDepth);
  const int first = std::min(options.first_frame, n);
  const int last = options.max_frames > 0 ? std::min(n, first + options.max_frames) : n;
  const bool use_rgb = reconstruction.options().integrate_colour && scan.rig().rgb &&
                       scan.NumFrames(Stream::kRgb) > 0;
  ThermalFeeder feeder(scan, thermal, out);
  const double pose_gap_s = PoseGapLimitS(scan);
  for (int i = first; i < last; ++i) {
    const double t = scan.Timestamp(Stream::kDepth, i);
    if (!scan.FrameExists(Stream::kDepth, i)) {
      ++out.missing_frames;
      out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: %s is missing, skipped",
                                                i, t, scan.FramePath(Stream::kDepth, i).c_str()));
      if (frame_done) frame_done(i - first + 1, last - first);
      continue;
    }
    auto load_start = std::chrono::steady_clock::now();
    FrameInput frame = LoadScanFrame(scan, i, use_rgb);
    out.load_seconds += Ms(load_start) / 1000;

    if (options.poses) {
      frame.world_from_depth = options.poses->At(t, pose_gap_s);
      if (!frame.world_from_depth) {
        ++out.unposed_frames;
        out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: no given pose, skipped", i, t));
        if (frame_done) frame_done(i - first + 1, last - first);
        continue;
      }
    }
    if (options.start_at_groundtruth && reconstruction.trajectory().empty()) {
      const std::optional<core::Rigid3d> gt =
          scan.groundtruth() ? scan.groundtruth()->At(t) : std::nullopt;
      if (!gt) {
        throw std::invalid_argument(core::StringPrintf(
            "start at groundtruth: %s has no pose at %.6f s (depth frame %d)",
            scan.groundtruth() ? "groundtruth.txt" : "the scan has no groundtruth.txt, so it", t, i));
      }
      reconstruction.SetInitialPose(*gt);
    }
    const auto process_start = std::chrono::steady_clock::now();
    const FrameRecord& record = reconstruction.AddFrame(frame);
    out.process_seconds += Ms(process_start) / 1000;
    out.depth_frame_index.push_back(i);
    if (record.status == FrameStatus::kLost) {
      out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: tracking lost (%s), not fused",
                                                i, t, IcpStatusName(record.icp_status).c_str()));
    } else if (record.status == FrameStatus::kRecovered) {
      out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: tracking recovered", i, t));
    } else if (record.status == FrameStatus::kNoDepth) {
      out.warnings.push_back(core::StringPrintf(
          "depth frame %d at %.6f s: only %.1f %% of pixels have depth, skipped", i, t,
          100 * record.valid_depth_fraction));
    }
    if (thermal && record.fused) {
      feeder.AddDepth(t, frame.depth_m, reconstruction.trajectory().poses().back().world_from_sensor);
      feeder.Feed(reconstruction, false);
    }
    if (frame_done) frame_done(i - first + 1, last - first);
  }
  if (thermal) {
    feeder.Feed(reconstruction, true);
    const auto finish_start = std::chrono::steady_clock::now();
    thermal->Finish();
    out.thermal_finish_seconds = Ms(finish_start) / 1000;
  }
  if (reconstruction.trajectory().empty() && options.poses && out.unposed_frames > 0 &&
      out.unposed_frames + out.missing_frames == last - first) {
    throw core::InputError(scan.IndexPath(Stream::kDepth),
                           core::StringPrintf("none of the %d depth frames used lies within the given poses "
                                              "(%.6f to %.6f s)",
                                              last - first, options.poses->StartTime(), options.poses->EndTime()));
  }
  if (reconstruction.trajectory().empty()) {
    throw core::InputError(scan.IndexPath(Stream::kDepth),
                           core::StringPrintf("no usable depth: none of the %d depth frames used has "
                                              "valid depth on %.0f %% of its pixels",
                                              last - first,
                                              100 * reconstruction.options().min_valid_depth_fraction));
  }
  return out;
}

}  // namespace hw::reconstruct
