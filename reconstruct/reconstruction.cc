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
#include "reconstruct/elapsed.h"
#include "reconstruct/option_check.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Relocalisation also tries the constant-velocity extrapolation over a loss this short, s:
// a hand held rig keeps its motion for a fraction of a second, not for seconds. Two fused
// poses farther apart than this give no velocity at all.
constexpr double kMaxExtrapolationS = 0.5;

// Views cast and ICP runs that refine a relocalisation from a keyframe, at most.
constexpr int kRefinementPasses = 3;
// Integrated frames whose model conflict sets the relocalisation gate's relative part.
constexpr size_t kConflictHistory = 30;

// The colour is registered again when the rotation pre-alignment moved the start more than
// this, degrees: the registration's motion changes by about as much over the exposures' time
// difference and the readout (up to a frame period), 0.25° being 2 px at 640 columns.
constexpr double kReregisterDeg = 0.25;

// The pyramid level the rotation pre-alignment runs on: the coarsest at least 80 pixels wide
// (160×120 of a 640×480 frame; a 160×120 frame's 40×30 level held too little texture).
const DepthLevel& PrealignLevel(const DepthPyramid& pyramid) {
  for (auto level = pyramid.levels.rbegin(); level != pyramid.levels.rend(); ++level) {
    if (level->camera.width >= 80) return *level;
  }
  return pyramid.levels.front();
}

}  // namespace

Reconstruction::Reconstruction(const core::Rig& rig, const ReconstructionOptions& options)
    : rig_(rig),
      options_(internal::EffectiveOptions(options)),
      depth_undistorter_(rig.depth),
      volume_(options_.tsdf),
      keyframes_(options_.keyframes) {
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

void Reconstruction::AddMotion(double timestamp_s, const core::Rigid3d& world_from_depth) {
  if (motion_.size() == 2) motion_.erase(motion_.begin());
  motion_.push_back({timestamp_s, world_from_depth});
}

core::Rigid3d Reconstruction::PoseAt(double timestamp_s) const {
  assert(!motion_.empty());
  const auto& poses = motion_;
  const core::TimedPose& b = poses.back();
  if (poses.size() < 2) return b.world_from_sensor;
  const core::TimedPose& a = poses[poses.size() - 2];
  // Across a long loss (a relocalisation from a keyframe) the two poses say nothing of the
  // motion: a velocity from them sent the next frame's prediction 0.5 m astray.
  if (b.timestamp_s - a.timestamp_s > kMaxExtrapolationS) return b.world_from_sensor;
  const double s = (timestamp_s - a.timestamp_s) / (b.timestamp_s - a.timestamp_s);
  return core::Interpolate(a.world_from_sensor, b.world_from_sensor, s);
}

PreparedFrame Reconstruction::Prepare(const FrameInput& frame, int num_threads) const {
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
  const auto start = std::chrono::steady_clock::now();
  PreparedFrame prepared;
  // NaN / inf pixels are missing measurements, not numbers to fuse: undistortion copies them
  // (nearest neighbour), the pyramid's range limits drop them from everything downstream, and
  // registration skips them.
  // The sensor's systematic inverse-depth error is undone first, at the distorted pixel
  // whose ray it was calibrated on.
  cv::Mat corrected_depth_m;
  if (!depth_offset_map_.empty()) {
    corrected_depth_m.create(frame.depth_m.size(), CV_32FC1);
    ForEachBand(frame.depth_m.rows, num_threads, [&](int y0, int y1) {  // per pixel: in bands
      cv::Mat band = corrected_depth_m.rowRange(y0, y1);
      frame.depth_m.rowRange(y0, y1).copyTo(band);
      core::CorrectDepth(depth_offset_map_.rowRange(y0, y1), &band);
    });
  }
  const cv::Mat undistorted = depth_undistorter_.UndistortDepth(
      depth_offset_map_.empty() ? frame.depth_m : corrected_depth_m);
  // The colour frame, undistorted once for both uses: registered to the depth pixels for
  // ICP's photometric term, and projected into the volume by integration.
  const bool use_colour = rig_.rgb && !frame.rgb.empty() &&
                          (options_.integrate_colour || options_.icp.photometric_weight > 0);
  if (use_colour) prepared.rgb_pinhole = rgb_undistorter_.UndistortColour(frame.rgb);
  DepthFilterOptions depth_options = options_.depth;
  depth_options.num_threads = num_threads;
  prepared.pyramid = BuildDepthPyramid(undistorted, depth_undistorter_.pinhole(), depth_options);
  prepared.prepare_ms = internal::MsSince(start);
  return prepared;
}

const FrameRecord& Reconstruction::AddFrame(const FrameInput& frame) {
  return AddFrame(frame, Prepare(frame, options_.num_threads));
}

const FrameRecord& Reconstruction::AddFrame(const FrameInput& frame, PreparedFrame prepared) {
  assert(!volume_released_ && "Reconstruction::AddFrame after ReleaseVolume");
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
  DepthPyramid& pyramid = prepared.pyramid;
  const cv::Mat& rgb_pinhole = prepared.rgb_pinhole;
  const bool use_colour = !rgb_pinhole.empty();
  // The photometric term reads the grey levels of the levels ICP iterates on, the finest
  // first_map_level: the colour is registered to that level's pixels directly (RegisterGrey:
  // what registering every full-size pixel and averaging down gives, for a quarter of the
  // projections per level; 8.5 of 85 ms per 640×480 frame on one thread at full size).
  const int colour_level = std::min(options_.depth.first_map_level, static_cast<int>(pyramid.levels.size()) - 1);
  // The colour registered through the rig's motion between the two exposures (and, with a
  // rolling shutter, during the colour readout): world_from_depth_at(t) on the depth clock.
  // Sets the pyramid's intensity.
  const double readout_s = rig_.rgb_readout_s;
  const auto register_colour = [&](const std::function<core::Rigid3d(double)>& world_from_depth_at) {
    const core::Rigid3d depth_from_world = world_from_depth_at(frame.timestamp_s).Inverse();
    const auto rgb_from_depth_at = [&](double delta_s) {
      return (depth_from_world * world_from_depth_at(frame.rgb_timestamp_s + delta_s) * rig_.depth_from_rgb)
          .Inverse();
    };
    const DepthLevel& level = pyramid.levels[colour_level];
    SetIntensity(pyramid,
                 RegisterGrey(level.depth_m, level.camera, rgb_pinhole, rgb_undistorter_.pinhole(), 1 << colour_level,
                              rgb_from_depth_at(0), options_.num_threads, readout_s, rgb_from_depth_at),
                 colour_level, options_.num_threads);
  };
  const bool photometric = use_colour && options_.icp.photometric_weight > 0;
  if (photometric) {
    // The predicted motion (none before the second frame).
    register_colour([this](double t) {
      return trajectory_.empty() ? core::Rigid3d::Identity() : PoseAt(t);
    });
  }
  // Whatever becomes of this frame, the next one pre-aligns against it (only when it is
  // the last fused frame: PrealignedPrediction checks the time).
  // With its blurs when the pre-alignment made them (cleared when the colour is registered
  // again: they are of the grey levels before).
  std::vector<PrealignBlur> prealign_blurs;
  struct KeepImage {
    Reconstruction& self;
    const DepthPyramid& pyramid;
    double timestamp_s;
    std::vector<PrealignBlur>& blurs;
    ~KeepImage() {
      const DepthLevel& level = PrealignLevel(pyramid);
      if (level.intensity.empty()) {
        self.previous_image_.reset();
      } else {
        self.previous_image_ = PrealignImage{level.intensity, level.depth_m, level.camera, std::move(blurs)};
        self.previous_image_timestamp_s_ = timestamp_s;
      }
    }
  } keep_image{*this, pyramid, frame.timestamp_s, prealign_blurs};
  record.valid_depth_fraction =
      static_cast<double>(cv::countNonZero(pyramid.raw_depth_m)) / pyramid.raw_depth_m.total();
  // Preparation's cost to the pipeline: made here, all of it; made ahead, the wait for it.
  record.prepare_ms = internal::MsSince(start) + (prepared.ahead ? prepared.wait_ms : prepared.prepare_ms);
  record.prepare_ahead_ms = prepared.ahead ? prepared.prepare_ms : 0;

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
    if (!model_ || !model_for_tracking_) UpdateModel(motion_.back().world_from_sensor, record);
    start = std::chrono::steady_clock::now();
    // Unobserved for longer than a hand-held rig keeps its motion (a covered lens gives frames
    // without depth, a stalled stream none): the rig may be anywhere, so relocalise as after
    // a loss instead of tracking from a prediction that no velocity supports.
    if (frame.timestamp_s - motion_.back().timestamp_s > kMaxExtrapolationS) lost_ = true;
    const bool was_lost = lost_;
    // Tracking starts from the prediction, its rotation pre-aligned; when that moved it, the
    // colour is registered again with the motion from the last pose to that start (the
    // exposures' time difference and the readout sweep turn with it).
    core::Rigid3d prediction = PoseAt(frame.timestamp_s);
    if (!lost_) {
      prediction = PrealignedPrediction(pyramid, frame.timestamp_s, record, &prealign_blurs);
      if (photometric && record.prealign_deg > kReregisterDeg) {
        prealign_blurs.clear();
        const core::TimedPose last = motion_.back();
        const core::Rigid3d start_pose = prediction;
        register_colour([&](double t) {
          return core::Interpolate(last.world_from_sensor, start_pose,
                                   (t - last.timestamp_s) / (frame.timestamp_s - last.timestamp_s));
        });
      }
    }
    const bool ok = Track(pyramid, frame.timestamp_s, prediction, record, world_from_depth);
    record.track_ms = internal::MsSince(start);
    if (!ok && record.icp_status == IcpStatus::kUnconstrained) {
      // Not fused, but where ICP put it is the best guess of the motion (it is off only
      // along the free direction): the next frame is predicted from it, and the model view
      // follows it as a fused frame's would (UpdateModel: a cast, the volume unchanged).
      // The next frame is aligned as after a loss (wide gate, the best of the extrapolation
      // and this pose, the model-conflict check), so that one the depth constrains again
      // re-anchors to the model rather than carrying a slide on (README: running on from
      // here instead left the jerky sweep 187 mm off, against 70 mm).
      record.status = FrameStatus::kUnconstrained;
      lost_ = true;
      AddMotion(frame.timestamp_s, world_from_depth);
      if (!model_ || ViewTooFar(world_from_depth)) UpdateModel(world_from_depth, record);
      record.blocks = volume_.NumBlocks();
      frames_.push_back(record);
      return frames_.back();
    }
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
  AddMotion(frame.timestamp_s, world_from_depth);
  record.fused = true;
  relocalisation_views_.clear();  // the volume changes now
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
  // A place not kept yet, seen by a frame whose pose is trusted (the first, or tracked with
  // every direction constrained: not a relocalised or held one), becomes a keyframe — also
  // after a jerk (a large correction from the prediction), which is when keyframes are
  // needed next.
  if (options_.keyframes.enabled() &&
      (record.status == FrameStatus::kInitialised ||
       (record.status == FrameStatus::kTracked && record.held_directions == 0)) &&
      keyframes_.IsNewPlace(world_from_depth)) {
    const DepthLevel& coarsest = pyramid.levels.back();
    keyframes_.Add(world_from_depth,
                   DescribeFrame(coarsest.depth_m, coarsest.intensity, options_.keyframes.descriptor_width));
  }
  // Without integrate_between_raycasts a frame that reuses the model view only tracks (its
  // depth would change a volume nobody looks at until the next raycast, whose frame fuses
  // nearly the same surfaces), unless it lies as far from the last integrated frame as a
  // view may be reused: with reuse_lead a view outlasts that distance, and the volume still
  // gains a frame as often as without it (its surface averages as many readings).
  const bool moved_on = last_integrated_ && MovedOn(core::ComparePoses(*last_integrated_, world_from_depth));
  if (options_.integrate_between_raycasts || raycast || frame.world_from_depth || moved_on) {
    last_integrated_ = world_from_depth;
    Integrate(pyramid, frame, rgb_pinhole, world_from_depth, record);
  }
  if (raycast) {
    UpdateModel(normal && !frame.world_from_depth ? LeadPose() : world_from_depth, record, !frame.world_from_depth);
  } else if (frame.world_from_depth && !options_.dynamic.enabled()) {
    model_.reset();
  }
  record.blocks = volume_.NumBlocks();
  frames_.push_back(record);
  return frames_.back();
}

bool Reconstruction::Track(const DepthPyramid& pyramid, double timestamp_s, const core::Rigid3d& start,
                           FrameRecord& record, core::Rigid3d& world_from_depth) {
  assert(model_.has_value());
  const auto& poses = motion_;
  const core::Rigid3d last = poses.back().world_from_sensor;
  const double elapsed_s = timestamp_s - poses.back().timestamp_s;  // since the last posed frame
  const double w = options_.relocalisation_widening;

  // ICP runs to try, each a start pose and its options: tracking takes the first that
  // succeeds, relocalisation the best of all.
  struct Attempt {
    core::Rigid3d initial;
    IcpOptions icp;
    bool from_last_pose = false, widened = false;
    int keyframe = -1;                    // started from this keyframe's pose ...
    const ModelPyramid* model = nullptr;  // ... against this view (nullptr: model_, the last pose's)
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
      attempts.push_back({start, *icp, poses.size() < 2, icp == &wide});
      if (poses.size() >= 2) attempts.push_back({last, *icp, true, icp == &wide});
    }
  } else {
    // Relocalisation: the rig has moved for a while unobserved. Widen the gates and let the
    // allowed jump grow with the time since the last fused frame, at the nominal frame rate.
    const double period_s =
        poses.size() >= 2 ? poses.back().timestamp_s - poses[poses.size() - 2].timestamp_s : 1.0 / 30;
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
  // Relocalisation: a candidate must also agree with the model's free space
  // (relocalisation_max_conflict).
  double max_conflict = std::numeric_limits<double>::infinity();
  if (lost_ && options_.relocalisation_max_conflict < 1 && options_.dynamic.enabled()) {
    max_conflict = options_.relocalisation_max_conflict;
    if (recent_conflicts_.size() >= kMinHistory) max_conflict = std::max(max_conflict, 3 * median(recent_conflicts_));
  }
  double rejected_conflict = std::numeric_limits<double>::quiet_NaN();
  auto check_conflict = [&](IcpResult& result, const ModelPyramid& view, double& conflict) {
    if (result.status != IcpStatus::kOk || !std::isfinite(max_conflict)) return;
    const int level = options_.raycast_level;
    conflict = MeasureModelConflict(pyramid.raw_depth_m, depth_undistorter_.pinhole(), result.world_from_camera,
                                    view.maps[level], view.cameras[level], view.world_from_camera,
                                    options_.dynamic, options_.num_threads)
                   .Fraction();
    if (conflict > max_conflict) {
      result.status = IcpStatus::kModelConflict;
      ++record.conflict_rejections;
      if (!(rejected_conflict >= conflict)) rejected_conflict = conflict;
    }
  };
  // Directions constrained this much worse than usual are held at the prediction (at most
  // icp.max_held_directions of them, else the frame fails as ill-conditioned).
  IcpResult best;
  double best_conflict = std::numeric_limits<double>::quiet_NaN();
  const Attempt* best_attempt = &attempts.front();
  bool ok = false;
  for (Attempt& attempt : attempts) {
    attempt.icp.max_condition = std::min(attempt.icp.max_condition, max_condition);
    IcpResult result = AlignToModel(pyramid, *model_, attempt.initial, attempt.icp);
    if (result.status == IcpStatus::kOk && result.residual_rms_m > max_residual_m) {
      result.status = IcpStatus::kLargeResidual;
    }
    double conflict = std::numeric_limits<double>::quiet_NaN();
    check_conflict(result, *model_, conflict);
    if (result.status == IcpStatus::kOk) {
      if (!ok || result.inliers > best.inliers) {
        best = result;
        best_attempt = &attempt;
        best_conflict = conflict;
      }
      ok = true;
      if (!lost_) break;  // tracking: the first success; relocalising: the best of all
      continue;
    }
    if (&attempt == &attempts.front()) best = result;  // report the first failure
  }
  // Lost, and neither the last nor the extrapolated pose aligns the frame, or lost for longer
  // than a hand-held rig keeps its motion: the rig may be anywhere it has been. Try the
  // keyframes it looks most alike, each against the model seen from there (nothing is fused
  // while lost, so a view cast once serves the loss), the most inliers winning as above —
  // after a long loss ICP from the last pose, its jump limit grown with the time, can slide
  // along a cabinet front onto a wrong fit (measured: 26 mm off from 0.55 m away).
  std::vector<Attempt> global;
  std::vector<ModelPyramid> refined_views;  // stable: reserved before the first is added
  if (lost_ && (!ok || elapsed_s > kMaxExtrapolationS) && options_.keyframes.enabled() && keyframes_.size() > 0) {
    const DepthLevel& coarsest = pyramid.levels.back();
    const KeyframeDescriptor query =
        DescribeFrame(coarsest.depth_m, coarsest.intensity, options_.keyframes.descriptor_width);
    // A long loss meets ever new candidates: keep the cache to about one frame's.
    if (relocalisation_views_.size() > 3 * static_cast<size_t>(options_.keyframes.candidates)) {
      relocalisation_views_.clear();
    }
    for (int k : keyframes_.MostAlike(query, keyframes_.size())) {
      if (static_cast<int>(global.size()) == options_.keyframes.candidates) break;
      // Where the last pose's attempt started already.
      if (keyframes_.SamePlace(last, keyframes_.pose(k))) continue;
      if (std::none_of(relocalisation_views_.begin(), relocalisation_views_.end(),
                       [k](const auto& v) { return v.first == k; })) {
        relocalisation_views_.emplace_back(k, CastModelView(keyframes_.pose(k), true));
      }
      global.push_back({keyframes_.pose(k), wide, false, true, k, nullptr});
    }
    // Each candidate that converges is refined against the model seen from where it
    // converged, with the normal gates: from a keyframe's pose, centimetres off, the widened
    // gate stops short (measured at 160×120: three keyframes' runs ended 1–4 cm apart, and
    // the one with the most inliers was the farthest), and only views cast at each result
    // make their inlier counts comparable.
    refined_views.reserve(global.size() * kRefinementPasses);
    for (Attempt& attempt : global) {
      const ModelPyramid* view = nullptr;
      for (const auto& [k, cached] : relocalisation_views_) {
        if (k == attempt.keyframe) view = &cached;
      }
      attempt.icp.max_condition = std::min(attempt.icp.max_condition, max_condition);
      IcpResult result = AlignToModel(pyramid, *view, attempt.initial, attempt.icp);
      IcpOptions fine = options_.icp;
      fine.max_condition = std::min(fine.max_condition, max_condition);
      for (int pass = 0; pass < kRefinementPasses && result.status == IcpStatus::kOk; ++pass) {
        ModelPyramid at_result = CastModelView(result.world_from_camera, true);
        const IcpResult refined = AlignToModel(pyramid, at_result, result.world_from_camera, fine);
        if (refined.status != IcpStatus::kOk) {
          result.status = refined.status;
          break;
        }
        const core::PoseError moved = core::ComparePoses(result.world_from_camera, refined.world_from_camera);
        result = refined;
        refined_views.push_back(std::move(at_result));
        view = &refined_views.back();
        if (moved.translation_m < 1e-3 && moved.rotation_rad * kRadToDeg < 0.05) break;
      }
      if (result.status == IcpStatus::kOk && result.residual_rms_m > max_residual_m) {
        result.status = IcpStatus::kLargeResidual;
      }
      double conflict = std::numeric_limits<double>::quiet_NaN();
      check_conflict(result, *view, conflict);
      attempt.model = view;
      if (result.status == IcpStatus::kOk && (!ok || result.inliers > best.inliers)) {
        best = result;
        best_attempt = &attempt;
        best_conflict = conflict;
        ok = true;
      }
    }
  }
  // The basin check of a frame aligned on depth alone (basin_check_m): no photometric term,
  // for want of its weight, of the model's colour (UpdateModel casts it only with both) or of
  // the frame's grey.
  const DepthLevel& icp_level = pyramid.levels[std::min<size_t>(options_.raycast_level, pyramid.levels.size() - 1)];
  const bool depth_alone = !(options_.icp.photometric_weight > 0) || !options_.integrate_colour || !rig_.rgb ||
                           icp_level.intensity.empty();
  record.depth_alone = depth_alone;
  if (ok && options_.basin_check_m > 0 && depth_alone) {
    const ModelPyramid& view = best_attempt->model != nullptr ? *best_attempt->model : *model_;
    record.basin_m = IcpBasinM(pyramid, view, best, options_.basin_check_m, best_attempt->icp);
    record.unconstrained = !(record.basin_m <= 0.5 * options_.basin_check_m);
    if (record.unconstrained && options_.drop_unconstrained) {
      ok = false;
      best.status = IcpStatus::kUnconstrained;
      world_from_depth = best.world_from_camera;  // for the motion model only (AddFrame)
    }
  }
  record.icp_status = best.status;
  record.inliers = best.inliers;
  record.valid_points = best.valid_points;
  record.residual_rms_m = best.residual_rms_m;
  record.condition = best.condition;
  record.held_directions = best.held_directions;
  record.from_last_pose = best_attempt->from_last_pose;
  record.widened_gate = best_attempt->widened;
  record.keyframe = best_attempt->keyframe;
  record.iterations = best.iterations;
  record.photometric_offset = best.photometric_offset;
  if (lost_) record.model_conflict = ok ? best_conflict : rejected_conflict;
  // Every candidate that converged contradicted the model: that is why the frame is lost.
  if (!ok && record.conflict_rejections > 0) record.icp_status = IcpStatus::kModelConflict;
  // From the prediction itself (not the pre-aligned start): how much the motion changed.
  const core::PoseError correction =
      core::ComparePoses(lost_ ? attempts.front().initial : PoseAt(timestamp_s), best.world_from_camera);
  record.correction_m = correction.translation_m;
  record.correction_deg = correction.rotation_rad * kRadToDeg;
  if (ok) {
    world_from_depth = best.world_from_camera;
    // The view it was aligned against is the one its integration's dynamic mask reads.
    if (best_attempt->model) model_ = *best_attempt->model;
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

core::Rigid3d Reconstruction::PrealignedPrediction(const DepthPyramid& pyramid, double timestamp_s,
                                                   FrameRecord& record,
                                                   std::vector<PrealignBlur>* current_blurs) const {
  const core::Rigid3d prediction = PoseAt(timestamp_s);
  const auto& poses = motion_;
  const DepthLevel& level = PrealignLevel(pyramid);
  if (!options_.prealign.enabled() || options_.icp.photometric_weight <= 0 || !previous_image_ ||
      level.intensity.empty() || previous_image_timestamp_s_ != poses.back().timestamp_s ||
      previous_image_->grey.size() != level.intensity.size()) {
    return prediction;
  }
  const core::Rigid3d& last = poses.back().world_from_sensor;
  const core::Rigid3d last_from_predicted = last.Inverse() * prediction;
  const PrealignImage current{level.intensity, level.depth_m, level.camera, {}};
  const RotationPrealignResult aligned =
      PrealignRotation(*previous_image_, current, last_from_predicted.rotation, last_from_predicted.translation,
                       options_.prealign, current_blurs);
  record.prealign_rejected_by_depth = aligned.rejected_by_depth;
  if (!aligned.ok) return prediction;
  record.prealign_deg = aligned.correction_deg;
  core::Rigid3d last_from_current = last_from_predicted;
  last_from_current.rotation = aligned.previous_from_current;
  return last * last_from_current;
}

core::Rigid3d Reconstruction::LeadPose() const {
  const auto& poses = motion_;
  const core::Rigid3d& current = poses.back().world_from_sensor;
  if (!(options_.reuse_lead > 0) || poses.size() < 2) return current;
  const core::Rigid3d& previous = poses[poses.size() - 2].world_from_sensor;
  const core::PoseError step = core::ComparePoses(previous, current);
  // Frames until the motion would reach a limit (no motion: raycast_interval).
  double frames = options_.raycast_interval;
  if (step.translation_m > 0) frames = std::min(frames, options_.reuse_max_motion_m / step.translation_m);
  if (step.rotation_rad > 0) {
    frames = std::min(frames, options_.reuse_max_motion_deg / (step.rotation_rad * kRadToDeg));
  }
  // A view that can serve only the next frame (raycast_interval 1, or motion that reaches
  // the limits within a frame) is cast for every frame anyway: leading it saves no cast (and
  // on the 10 Hz walk, 45 mm per frame along a cabinet front that constrains little, views
  // cast 0.7-0.9 frames ahead let the drift run away: 4 → 73 mm).
  if (frames <= 1) return current;
  return core::Interpolate(previous, current, 1 + options_.reuse_lead * frames);
}

bool Reconstruction::ViewTooFar(const core::Rigid3d& world_from_depth) const {
  assert(model_.has_value());
  // The next frame's pose at constant velocity: this one's motion since the last frame the
  // motion model holds, once more (no previous frame: no motion). Called after this frame's
  // pose was added to motion_.
  const auto& poses = motion_;
  core::Rigid3d next = world_from_depth;
  if (poses.size() >= 2) {
    const core::Rigid3d& previous = poses[poses.size() - 2].world_from_sensor;
    next = world_from_depth * (previous.Inverse() * world_from_depth);
  }
  return Beyond(core::ComparePoses(model_->world_from_camera, next));
}

bool Reconstruction::Beyond(const core::PoseError& moved) const {
  return moved.translation_m > options_.reuse_max_motion_m ||
         moved.rotation_rad * kRadToDeg > options_.reuse_max_motion_deg;
}

bool Reconstruction::MovedOn(const core::PoseError& moved) const {
  return moved.translation_m > options_.integrate_max_motion_m ||
         moved.rotation_rad * kRadToDeg > options_.integrate_max_motion_deg;
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
    // A rolling shutter: the pose of each band of rows at its own exposure time (the rows of
    // the undistorted image stand for the sensor's, a few pixels apart at most).
    if (rig_.rgb_readout_s > 0) {
      const int bands = kColourBands, height = colour->camera.height;
      for (int k = 0; k < bands; ++k) {
        const double delta_s = BandOffsetS(k, bands, height, rig_.rgb_readout_s);
        colour->world_from_camera_bands.push_back(PoseAt(frame.rgb_timestamp_s + delta_s) * rig_.depth_from_rgb);
      }
    }
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
    // The same measure as a relocalisation's (ModelConflict), from these counts.
    ModelConflict conflict;
    conflict.in_front = record.dynamic_pixels;
    // raw_depth_m holds 0 or in-range depth: AddFrame's count of its valid pixels, not again.
    conflict.depth_pixels = static_cast<int>(std::lround(record.valid_depth_fraction * pyramid.raw_depth_m.total()));
    conflict.seen_through = record.carved_points;
    conflict.model_points = model_->maps[level].NumValid();
    record.model_conflict = conflict.Fraction();
    if (!frame.world_from_depth && record.status != FrameStatus::kRecovered) {
      recent_conflicts_.push_back(record.model_conflict);
      if (recent_conflicts_.size() > kConflictHistory) recent_conflicts_.erase(recent_conflicts_.begin());
    }
    if (!through.empty()) volume_.CarveFreeSpace(through, world_from_depth.translation.cast<float>());
  }
  const IntegrateStats stats =
      volume_.Integrate(depth_m, depth_undistorter_.pinhole(), world_from_depth, colour ? &*colour : nullptr);
  record.blocks_updated = stats.blocks_visible;
  record.blocks_coarse = stats.blocks_coarse;
  record.integrated = true;
  record.integrate_ms = internal::MsSince(start);
}

void Reconstruction::UpdateModel(const core::Rigid3d& world_from_depth, FrameRecord& record, bool for_tracking) {
  const auto start = std::chrono::steady_clock::now();
  model_ = CastModelView(world_from_depth, for_tracking);
  fused_since_raycast_ = 0;
  model_for_tracking_ = for_tracking;
  record.raycast_ms = internal::MsSince(start);
}

ModelPyramid Reconstruction::CastModelView(const core::Rigid3d& world_from_depth, bool for_tracking) const {
  PinholeCamera camera = depth_undistorter_.pinhole();
  for (int l = 0; l < options_.raycast_level; ++l) camera = camera.Half();
  RaycastOptions raycast = options_.raycast;
  // The photometric term compares the live colour with the model's.
  raycast.with_colour = for_tracking && options_.icp.photometric_weight > 0 && options_.integrate_colour && rig_.rgb;
  PointMap level = Raycast(volume_, camera, world_from_depth, raycast);
  const int num_levels = static_cast<int>(options_.icp.iterations.size());
  ModelPyramid model = BuildModelPyramid(std::move(level), camera, world_from_depth,
                                         num_levels - options_.raycast_level);
  if (options_.raycast_level == 0) return model;
  // Finer levels than the raycast stay empty: ICP skips them (their iterations are 0).
  ModelPyramid padded;
  padded.world_from_camera = model.world_from_camera;
  PinholeCamera finer = depth_undistorter_.pinhole();
  for (int l = 0; l < options_.raycast_level; ++l) {
    padded.cameras.push_back(finer);
    padded.maps.emplace_back();
    finer = finer.Half();
  }
  for (size_t l = 0; l < model.maps.size(); ++l) {
    padded.cameras.push_back(model.cameras[l]);
    padded.maps.push_back(std::move(model.maps[l]));
  }
  return padded;
}

TriangleMesh Reconstruction::ExtractMesh(MeshStats* stats) const {
  return reconstruct::ExtractMesh(volume_, options_.mesh, stats);
}

void Reconstruction::ReleaseVolume() {
  volume_ = TsdfVolume(options_.tsdf);
  volume_released_ = true;
}

}  // namespace hw::reconstruct
