#pragma once

// The dense reconstruction pipeline (KinectFusion on the CPU): each depth frame is
// undistorted and filtered, tracked frame-to-model by ICP against a raycast of the fused
// volume, then fused into the sparse TSDF (with colour from the rgb stream at its own time),
// and the volume raycast again for the next frame. A frame whose tracking fails is reported,
// not fused, and later frames relocalise against the model (near the last pose, or from a
// keyframe of a place mapped before).
//
// Fed frame by frame (live capture) through AddFrame, or over a whole scan folder by
// ReconstructScan (scan_reconstruction.cc). The volume and trajectory are what thermal fusion and analysis build on.

#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/rig.h"
#include "core/scan.h"
#include "core/trajectory.h"
#include "reconstruct/colour_registration.h"
#include "reconstruct/depth_frame.h"
#include "reconstruct/dynamic_mask.h"
#include "reconstruct/icp.h"
#include "reconstruct/keyframes.h"
#include "reconstruct/marching_cubes.h"
#include "reconstruct/raycast.h"
#include "reconstruct/rotation_prealign.h"
#include "reconstruct/thermal_fusion.h"
#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct {

struct ReconstructionOptions {
  // Depth range fused and tracked, m: these override the ranges of `tsdf`, `depth` and
  // `raycast` (one range for the whole pipeline). Structured-light and ToF sensors measure
  // from ~0.4 m to 4–5 m; farther depth is noisier than the model needs.
  double min_depth_m = 0.3;  // >= 0
  double max_depth_m = 5.0;  // > min_depth_m
  TsdfOptions tsdf;
  DepthFilterOptions depth;
  // ICP, with the photometric term on (weight 0.3 m per grey level): hand-held scans spend
  // whole seconds looking at one wall, where geometry leaves the pose free along the wall;
  // the texture pins it (measured on the equipment scan: 8.6 mm drift per second with it,
  // 185 mm without).
  IcpOptions icp = [] {
    IcpOptions o;
    o.photometric_weight = 0.3;
    return o;
  }();
  RaycastOptions raycast;
  // Pyramid level the model is raycast at for tracking: 0 full resolution, 1 half, ... ICP
  // then runs on that level and coarser ones only (icp.iterations of finer levels are
  // ignored). A raycast costs per pixel: at 640×480, level 1 is 4× cheaper and tracks as
  // well (bench/reconstruct_peers.sh). In [0, 2].
  int raycast_level = 1;
  // Fused frames between two model raycasts for tracking, in [1, 8]: 1 raycasts after every
  // frame (KinectFusion); n > 1 lets n − 1 frames track against a view of the model up to
  // n − 1 frames old (it is still the fused model, seen from a pose a few centimetres back:
  // projective association finds the same surfaces, less the sliver that came into view).
  // A frame that was not tracked normally (recovered, retried on the widened gate, with
  // held directions, or after a posed frame) always raycasts after it, and so does one whose
  // pose ICP moved from the constant-velocity prediction by more than the two limits below
  // (the motion changed: a jerk, a stop; the next prediction is unreliable and a stale view
  // lets a wrong pose pass as tracked — measured on the jerky path), and so does one after
  // which the camera would be too far from the view (reuse_max_motion_m / _deg). The raycast is the
  // costliest stage (README, Reconstruction: Speed); what skipping it costs in accuracy is
  // measured there too. The default, 8, leaves the casts to the motion limits: a frame
  // integrates only when it casts (integrate_between_raycasts), so between casts the model
  // does not change and only motion ages the view; a camera held still casts every 8th.
  int raycast_interval = 8;
  // Integrate the depth of the frames tracked between two raycasts too (true), or only of
  // the frames after which the model is raycast (false: every raycast_interval-th frame
  // tracked normally and every frame that raycasts at once; posed frames always) and of those
  // as far from the last integrated frame as integrate_max_motion_m / _deg. The frames
  // between still get their pose (the trajectory, thermal mapping) but add nothing to the
  // volume: at 30 Hz a surface is seen in dozens of frames, and integration is, with the
  // raycast, the costliest stage (README, Reconstruction: Speed, where both are measured).
  bool integrate_between_raycasts = false;
  // Depth that moved in front of the model (a person walking by) is not integrated, and
  // what the model shows where the depth sees through it is carved as free space
  // (dynamic_mask.h); against the model view the frame was tracked with (posed frames: one
  // cast as often, for this only). margin_m and margin_fraction 0: off.
  DynamicMaskOptions dynamic;
  // m, > 0: 10 mm is above 90 % of the corrections of smooth hand-held frames (3 mm median,
  // 6-8 mm at the 90th percentile at 30 Hz and at 10 Hz), below a jerk's (57 mm).
  double reuse_max_correction_m = 0.01;
  // degrees, > 0: likewise (0.15-0.2° median, 0.24-0.45° at the 90th percentile; a jerk's 3°).
  double reuse_max_correction_deg = 0.5;
  // The model view is also cast again, before raycast_interval is reached, when the next
  // frame's constant-velocity pose would lie farther than these from the pose the view was
  // cast at: what bounds a reused view is how far the camera has moved from it (the sliver
  // of the image the view does not cover, surfaces seen from another side), not how many
  // frames have passed — a slow sweep can reuse a view for several frames, a fast one not
  // for one. m and degrees, > 0. 2.5° is 11 pixels of a 320-pixel-wide model view at a
  // Kinect's 58° field (3.5 % of it uncovered); 40 mm is 2.5° of parallax at 1 m. Measured
  // (README, Reconstruction: Speed): on the 3 s full-size sweep, 27 casts of 88 frames
  // instead of 45 at a fixed interval of 2, ATE unchanged with the true depth field.
  double reuse_max_motion_m = 0.04;
  double reuse_max_motion_deg = 2.5;
  // Without integrate_between_raycasts, a frame tracked between raycasts is integrated all the
  // same when it lies farther than these from the last integrated frame (with reuse_lead a
  // view outlasts the reuse limits, and the volume must still gain readings as the camera
  // moves). m and degrees, > 0. The defaults are the reuse limits' (40 mm, 2.5°): on the 10 s
  // sweeps 85–87 of 297 frames integrated. Each integration is the costliest step of its frame
  // (55 ms on the far `building` sweep), so 1.5× these (60 mm, 3.75°) integrates 58–66 frames
  // and runs 12–18 % faster, at the price of the averaging: the shape's error (registered
  // median) +0.2–0.4 mm (README, Reconstruction: Integrating less often).
  double integrate_max_motion_m = 0.04;
  double integrate_max_motion_deg = 2.5;
  // A frame tracked normally casts the view it leaves for the next frames not from its own
  // pose but from where the camera will be this fraction of the reuse window later: the
  // pose extrapolated at its constant velocity by reuse_lead · n frames, n the frames after
  // which that motion would pass reuse_max_motion_m / _deg (at most raycast_interval; when
  // n <= 1 the frame's own pose: such a view is recast after every frame anyway). The
  // frames that reuse the view then lie on both sides of it, so at the same distance limit
  // one view serves up to (1 + reuse_lead)× as many frames. [0, 1]; 0: the frame's own pose.
  // Measured (README, Reconstruction: Speed): on the 3 s full-size sweep 16 casts instead of
  // 27 (1.17–1.23× frames/s); ATE within ±0.4 mm on the 10 s renders (equipment better, building
  // worse).
  double reuse_lead = 1;
  MeshOptions mesh;
  // Paint the model with the rgb stream (when the rig has one and frames are given).
  bool integrate_colour = true;
  // Frames with fewer valid depth pixels than this fraction of the image are not used
  // (a covered lens, a sensor glitch). In [0, 1].
  double min_valid_depth_fraction = 0.05;
  // A frame that fails to track is retried with the association gate widened by this factor
  // (jump limits kept) before it counts as lost; after a loss, frames are aligned from the
  // extrapolated and the last fused pose with the gate and the jump limits widened by it (the
  // jump limits also by the frames elapsed), until one succeeds. >= 1 (1: no retry).
  double relocalisation_widening = 2.0;
  // A frame whose ICP residual exceeds this multiple of the median residual of the last
  // tracked frames (at least 5 of them; the last 30) counts as failed: a fixed threshold
  // cannot tell misalignment from a noisier sensor or scene, a relative one can (fast motion
  // blurs depth, and a wrong pose leaves a residual well above the frames before it). > 1.
  double max_residual_ratio = 2.0;
  // Likewise for the condition of the ICP system: directions that the geometry and texture
  // constrain this many times worse than the median of the last tracked frames are held at
  // the constant-velocity prediction rather than left to slide with noise; more than
  // icp.max_held_directions of them (a frame without colour facing a flat wall) and the
  // frame counts as failed. > 1.
  double max_condition_ratio = 5.0;
  // The basin check, on frames tracked on depth alone (no photometric term: no colour, or
  // icp.photometric_weight 0). ICP is run once more, from its result moved this far along
  // the direction its system constrains least (WeakestDirection, rotation at a 1 m lever);
  // where the second run ends more than half of that from the first, the depth does not fix
  // the pose along it — a plain wall, a wall and a floor — and the frame is counted
  // unconstrained (FrameRecord::basin_m). Neither the residual nor the condition number
  // tells such a frame (README, Tracking without colour: both alike on a sweep that slid
  // 0.27 m and on one that tracked to 1.8 mm); how far ICP comes back does. One more ICP
  // run per such frame; frames with the photometric term are not checked. m, in [0, 0.1]
  // (0: off).
  double basin_check_m = 0.01;
  // Unconstrained frames (basin_check_m) are not fused (FrameStatus::kUnconstrained,
  // IcpStatus::kUnconstrained), as the issue asks of an ill-conditioned frame, rather than
  // fused where ICP stopped; their poses still carry the motion model, the next frame aligned
  // as after a loss, so that one such frame of a fast walk does not lose the next ones (stop
  // 59 reported them lost: at 10 Hz, 45 mm between frames, one drop lost every frame after
  // it). README, Tracking without colour.
  bool drop_unconstrained = true;
  // A relocalised pose (a frame recovering from a loss, from the last or extrapolated pose
  // or a keyframe's) must agree with the model seen from there: the live depth standing in
  // front of the model's surface or seeing through it (ModelConflict, by dynamic's margins)
  // may be at most this fraction, or 3× the median of the last integrated frames' when that
  // is higher (a person who has been in view all along, a mirror). ICP alone accepts a pose
  // one part over along a row of alike parts, or slid along a wall, when enough points pair
  // up; the free space around them does not (measured: 0–2 % at tracked poses on the 160×120
  // test scans, under 0.01 % on a full-size sweep; 5–9 % at the 160×120 jerky scan's
  // relocalisations 0.25 m off, which were fused and held the frames after them). A rejected
  // candidate leaves the frame lost, and the next frame tries again: a recovery can come
  // later, not wrong. Needs dynamic's margins (off: no check). [0, 1]; 1: off.
  double relocalisation_max_conflict = 0.03;
  // Global relocalisation (keyframes.h): tracked frames at new places are kept as small
  // blurred images; a lost frame that neither the last pose nor the extrapolated one aligns,
  // or one lost (or unobserved) for over 0.5 s, is tried from the poses of the keyframes it
  // looks most alike, against the model raycast there — so tracking comes back when the rig
  // returns to a place it mapped, however far it went unobserved. candidates 0: off.
  KeyframeOptions keyframes;
  // Rotation pre-alignment (rotation_prealign.h): before ICP, each frame's coarsest grey
  // image is aligned by rotation to the previous frame's, and ICP starts from that rotation
  // (the translation of the constant-velocity prediction): a jerk turns the rig degrees per
  // frame past the prediction, beyond ICP's basin along a textured wall. Needs colour and
  // the photometric term; iterations 0: off.
  RotationPrealignOptions prealign;
  // Threads of every stage (0: hardware concurrency); overrides the stages' own.
  int num_threads = 0;

  // "" when valid, else a message naming the field (with its stage, e.g.
  // "tsdf.voxel_size_m: ..."), value and constraint.
  std::string Check() const;
};

namespace internal {
// The stage options with the pipeline-wide depth range and thread count applied (what a
// Reconstruction runs with).
ReconstructionOptions EffectiveOptions(ReconstructionOptions options);
}  // namespace internal

// One depth frame given to the pipeline.
struct FrameInput {
  double timestamp_s = 0;  // depth clock, s; strictly after the previous frame's
  cv::Mat depth_m;         // CV_32FC1 metres as the depth camera saw it (distorted), 0 = none
  cv::Mat rgb;             // empty, or CV_8UC3 RGB of the rig's rgb camera
  double rgb_timestamp_s = 0;  // rgb exposure time on the depth clock, s
  // A known pose (motion capture, another SLAM system, ground truth): the frame is fused
  // there and not tracked (status kPosed).
  std::optional<core::Rigid3d> world_from_depth;
};

// A frame's depth and colour made ready for the pipeline: the rig's depth correction, lens
// undistortion, range limits, the depth pyramid (bilateral filter, half levels, point maps)
// and the undistorted colour. It depends on the frame and the rig only, not on the
// reconstruction's state, so ReconstructScan makes the next frame's on a thread of its own
// while the current one is tracked and fused (Reconstruction::Prepare).
struct PreparedFrame {
  DepthPyramid pyramid;
  cv::Mat rgb_pinhole;        // CV_8UC3 undistorted colour; empty without colour
  double prepare_ms = 0;      // wall time Prepare took, ms
  double wait_ms = 0;         // set by a caller that made it ahead: time spent waiting for it, ms
  bool ahead = false;         // set by that caller: made beside the previous frame's processing
};

enum class FrameStatus {
  kInitialised,  // first usable frame: defines the world frame (or initial_world_from_depth)
  kTracked,      // ICP succeeded; fused
  kRecovered,    // first success after lost frames (relocalised against the model); fused
  kLost,         // ICP failed; not fused, no pose
  kNoDepth,      // too few valid depth pixels; not used, no pose
  kPosed,        // fused at the pose it came with (FrameInput::world_from_depth), not tracked
  // ICP converged, but the depth leaves a direction free (the basin check,
  // ReconstructionOptions::drop_unconstrained): not fused and not in the trajectory; its pose
  // carries the motion on to the next frame's prediction, which is aligned as after a loss
  kUnconstrained,
};
std::string FrameStatusName(FrameStatus status);  // "initialised", "tracked", ...

// What the pipeline did with one frame.
struct FrameRecord {
  int index = 0;            // order of arrival
  double timestamp_s = 0;   // depth clock, s
  FrameStatus status = FrameStatus::kNoDepth;
  bool fused = false;       // given a pose in the trajectory (tracked, recovered, posed)
  // Its depth went into the volume: every fused frame, or only those after which the model
  // is raycast and those as far as the reuse limits from the last integrated frame
  // (ReconstructionOptions::integrate_between_raycasts false).
  bool integrated = false;
  bool coloured = false;    // an rgb frame was fused with it
  // Depth pixels not integrated because they lay in front of the model (dynamic_mask.h).
  int dynamic_pixels = 0;
  // Model view points this frame's depth saw through (dynamic_mask.h), carved as free space.
  int carved_points = 0;
  double valid_depth_fraction = 0;
  IcpStatus icp_status = IcpStatus::kOk;  // of the last attempt (tracked / lost frames)
  int inliers = 0, valid_points = 0;
  double residual_rms_m = 0, condition = 0;
  // Directions of the pose the frame left at the constant-velocity prediction (IcpResult).
  int held_directions = 0;
  // ICP had no photometric term (no colour frame, no model colour, or photometric_weight 0):
  // the frame was aligned on depth alone (tracked, recovered and lost frames).
  bool depth_alone = false;
  // The basin check (ReconstructionOptions::basin_check_m) of a frame tracked on depth
  // alone: how far apart ICP's result and its rerun from the displaced start ended, m
  // (translation and rotation at a 1 m lever, combined); NaN when not checked.
  // `unconstrained`: more than half the displacement.
  double basin_m = std::numeric_limits<double>::quiet_NaN();
  bool unconstrained = false;
  // Which ICP run gave the result (tracked / recovered frames; lost ones: the first run):
  // started from the last fused pose rather than the prediction (when relocalising, the
  // constant-velocity extrapolation over the loss), and with the association gate widened
  // by relocalisation_widening (a retry, or relocalisation).
  bool from_last_pose = false;
  bool widened_gate = false;
  // Recovered frames: the keyframe (index in Reconstruction::keyframes()) whose pose ICP
  // started from, against the model raycast there; -1 when none (relocalised from the last
  // or the extrapolated pose).
  int keyframe = -1;
  int iterations = 0;
  // The live depth's disagreement with the model view at the frame's pose (ModelConflict::
  // Fraction): of integrated frames (against the view they were tracked with) and of
  // relocalisation candidates (the best one's, for a frame that stayed lost the largest
  // rejected); NaN when not measured.
  double model_conflict = std::numeric_limits<double>::quiet_NaN();
  // Relocalisation candidates that ICP aligned but relocalisation_max_conflict rejected.
  int conflict_rejections = 0;
  // Brightness offset of ICP's photometric term (IcpResult::photometric_offset), grey levels.
  double photometric_offset = 0;
  // Rotation pre-alignment (ReconstructionOptions::prealign): how far it moved ICP's start
  // from the prediction, degrees; NaN when it did not run or was not accepted.
  double prealign_deg = std::numeric_limits<double>::quiet_NaN();
  // The pre-alignment found a rotation that the depth contradicted
  // (RotationPrealignOptions::max_depth_misfit_ratio): ICP started from the prediction.
  bool prealign_rejected_by_depth = false;
  // Change from the constant-velocity prediction to the estimate.
  double correction_m = 0, correction_deg = 0;
  size_t blocks = 0;  // voxel blocks in the volume after this frame, fused or not (memory
                      // follows them)
  // Blocks its integration updated, and of those the ones updated coarsely (far, never seen
  // nearer: TsdfOptions::coarse_far); 0 when not integrated.
  int blocks_updated = 0, blocks_coarse = 0;
  // Wall time of each stage, ms. raycast_ms is 0 when the model view was not cast after
  // this frame (ReconstructionOptions::raycast_interval). prepare_ms is what preparation
  // cost the pipeline: with the frame prepared ahead (PreparedFrame::ahead), the wait for it
  // and the colour's registration only; prepare_ahead_ms then holds Prepare's own time,
  // spent beside the previous frame (0 otherwise).
  double prepare_ms = 0, track_ms = 0, integrate_ms = 0, raycast_ms = 0;
  double prepare_ahead_ms = 0;
};

class Reconstruction {
 public:
  // Asserts options.Check() is empty and rig.Check() is empty.
  Reconstruction(const core::Rig& rig, const ReconstructionOptions& options);

  // The pose of the first usable frame (default identity: the world frame is that frame's
  // depth camera). Set before the first AddFrame.
  void SetInitialPose(const core::Rigid3d& world_from_depth);

  // Processes one frame: AddFrame(frame, Prepare(frame, options().num_threads)). Throws
  // std::invalid_argument when depth_m is not CV_32FC1 of the rig's depth size, rgb (when
  // given) not CV_8UC3 of the rgb size, or timestamps do not increase. Non-finite depth
  // pixels count as missing.
  const FrameRecord& AddFrame(const FrameInput& frame);
  // The same with the frame already prepared (by Prepare on the same frame).
  const FrameRecord& AddFrame(const FrameInput& frame, PreparedFrame prepared);
  // The part of a frame's processing that depends on the frame and the rig only
  // (PreparedFrame), on num_threads threads (0: all; 1: the calling thread only, for a caller
  // running it beside AddFrame: two callers of the shared pool would take turns). Safe to
  // call from another thread while AddFrame runs; the result is the same whatever the thread
  // count. Throws std::invalid_argument on a frame of the wrong size or type, as AddFrame.
  PreparedFrame Prepare(const FrameInput& frame, int num_threads) const;

  const TsdfVolume& volume() const { return volume_; }
  // world_from_depth at every fused frame (tracked, recovered, initialised), depth clock.
  const core::Trajectory& trajectory() const { return trajectory_; }
  const std::vector<FrameRecord>& frames() const { return frames_; }
  const core::Rig& rig() const { return rig_; }
  const ReconstructionOptions& options() const { return options_; }
  // True while the last frame was lost (no model view to track against is current).
  bool lost() const { return lost_; }
  // The keyframes kept for relocalisation (options().keyframes).
  const KeyframeDatabase& keyframes() const { return keyframes_; }

  // Marching cubes of the volume (options().mesh).
  TriangleMesh ExtractMesh(MeshStats* stats = nullptr) const;
  // Frees the volume's blocks — most of a large scan's memory — once the mesh is extracted:
  // volume() is empty afterwards (the trajectory and the frame records stay). Call after the
  // last AddFrame: AddFrame asserts that it was not called.
  void ReleaseVolume();

 private:
  // Tracks the frame (from `start`, the pre-aligned prediction, when not lost; relocalises
  // when lost); true with world_from_depth set on success.
  bool Track(const DepthPyramid& pyramid, double timestamp_s, const core::Rigid3d& start, FrameRecord& record,
             core::Rigid3d& world_from_depth);
  // The constant-velocity prediction at timestamp_s with its rotation replaced by the
  // pre-alignment of `pyramid`'s coarsest level against the previous frame's (when that
  // frame is the last fused one and the alignment is accepted; else the prediction).
  // current_blurs receives the level's blurs the alignment made (PrealignRotation).
  core::Rigid3d PrealignedPrediction(const DepthPyramid& pyramid, double timestamp_s, FrameRecord& record,
                                     std::vector<PrealignBlur>* current_blurs) const;
  void Integrate(const DepthPyramid& pyramid, const FrameInput& frame, const cv::Mat& rgb_pinhole,
                 const core::Rigid3d& world_from_depth, FrameRecord& record);
  // Whether the next frame, predicted at constant velocity from this pose, would be beyond
  // reuse_max_motion_m / _deg from the pose the model view was cast at.
  bool ViewTooFar(const core::Rigid3d& world_from_depth) const;
  // Whether a motion passes reuse_max_motion_m or _deg.
  bool Beyond(const core::PoseError& moved) const;
  // Whether the motion since the last integrated frame passes integrate_max_motion_m or _deg.
  bool MovedOn(const core::PoseError& moved) const;
  // Where a frame tracked normally (the trajectory's last pose) casts its view: reuse_lead.
  core::Rigid3d LeadPose() const;
  // Raycasts the model view at world_from_depth; with colour only `for_tracking` (the
  // photometric term; a posed frame's view serves the dynamic mask alone).
  void UpdateModel(const core::Rigid3d& world_from_depth, FrameRecord& record, bool for_tracking = true);
  // The model view at world_from_depth as ICP takes it (levels finer than raycast_level
  // empty), with colour when for_tracking and the photometric term is on.
  ModelPyramid CastModelView(const core::Rigid3d& world_from_depth, bool for_tracking) const;
  // world_from_depth at time t from the two last poses of motion_ (interpolated between
  // them, or extrapolated at constant velocity beyond the last); the last pose when they lie
  // more than half a second apart (a loss between them: no velocity to go by).
  core::Rigid3d PoseAt(double timestamp_s) const;
  // Appends a frame's pose to motion_ (keeping the last two).
  void AddMotion(double timestamp_s, const core::Rigid3d& world_from_depth);

  core::Rig rig_;
  ReconstructionOptions options_;
  Undistorter depth_undistorter_;
  // δ per depth pixel (1/m, core/depth_correction.h) when the rig has a depth_correction;
  // empty otherwise.
  cv::Mat depth_offset_map_;
  Undistorter rgb_undistorter_;
  TsdfVolume volume_;
  bool volume_released_ = false;  // ReleaseVolume
  core::Trajectory trajectory_;
  // The last two poses the motion model goes by: fused frames' and unconstrained ones'
  // (FrameStatus::kUnconstrained), oldest first.
  std::vector<core::TimedPose> motion_;
  std::vector<FrameRecord> frames_;
  std::optional<core::Rigid3d> initial_pose_;
  std::optional<ModelPyramid> model_;  // raycast at a recent fused pose
  KeyframeDatabase keyframes_;
  // While lost: the model views cast at keyframe poses for relocalisation, by keyframe (the
  // volume does not change while no frame is fused, so each is cast once per loss).
  std::vector<std::pair<int, ModelPyramid>> relocalisation_views_;
  int fused_since_raycast_ = 0;        // frames fused since model_ was raycast
  std::optional<core::Rigid3d> last_integrated_;  // world_from_depth of the last integrated frame
  bool model_for_tracking_ = false;    // model_ was cast for tracking (with colour), not for a posed frame
  bool lost_ = false;
  std::vector<double> recent_residuals_m_;  // of the last tracked frames, oldest first
  std::vector<double> recent_conditions_;   // likewise
  std::vector<double> recent_conflicts_;    // model_conflict of the last integrated frames
  double last_timestamp_s_ = -1e300;
  // The last frame's coarsest level (grey and depth) for the rotation pre-alignment, and its time.
  std::optional<PrealignImage> previous_image_;
  double previous_image_timestamp_s_ = 0;
};

// Depth frame `depth_index` of `scan` as a FrameInput (its depth-clock time), with the rgb
// frame nearest in time within 0.1 s (at that frame's depth-clock time) when with_rgb and its
// file exists. Throws core::InputError as Scan::Load*.
FrameInput LoadScanFrame(const core::Scan& scan, int depth_index, bool with_rgb);

// The longest gap between two poses that interpolation bridges for this scan, s: three
// depth frame periods (a dropped frame and the stamps' jitter), at least 0.1 s. A fixed
// 0.1 s would be less than one period of a 10 Hz depth stream plus jitter: half the frames
// of such a scan would find no pose.
double PoseGapLimitS(const core::Scan& scan);

// Options of ReconstructScan beyond the pipeline's.
struct ScanReconstructionOptions {
  // Start at the scan's groundtruth pose of the first frame instead of identity, so that the
  // model is in the scan's world frame (synthetic scans, comparisons with truth/). Needs
  // groundtruth.txt covering the first used frame.
  bool start_at_groundtruth = false;
  int first_frame = 0;  // first depth frame to use, >= 0
  int max_frames = 0;   // frames to use from first_frame, 0 = all
  // Fuse along these poses (world_from_depth, depth clock; interpolated, gaps over
  // PoseGapLimitS(scan) not bridged) instead of tracking: frames they do not cover are
  // skipped with a warning.
  std::optional<core::Trajectory> poses;
  // Prepare each frame (Reconstruction::Prepare, on one thread) beside the previous frame's
  // tracking and fusion instead of before it: the same results, sooner — the pipeline's
  // stages leave part of the cores idle (serial steps, waits), which the preparation fills.
  // Not with ReconstructionOptions::num_threads 1.
  bool prepare_ahead = true;

  std::string Check() const;
};

struct ScanReconstruction {
  std::vector<int> depth_frame_index;  // per FrameRecord: the scan's depth frame index
  int missing_frames = 0;              // depth frames whose file is missing (skipped)
  int unposed_frames = 0;              // with options.poses: frames they do not cover (skipped)
  // Thermal frames (with a ThermalFusion): given to it, missing files (skipped), and those
  // after the last depth frame used (never posed, not given).
  int thermal_frames = 0, thermal_missing_frames = 0, thermal_after_end = 0;
  double thermal_load_seconds = 0;     // decoding thermal frames
  double thermal_seconds = 0;          // ThermalFusion::AddFrame calls
  double thermal_finish_seconds = 0;   // ThermalFusion::Finish (the offline estimate)
  std::vector<std::string> warnings;   // one line each: missing frames, lost frames, ...
  double load_seconds = 0;             // decoding frames
  double process_seconds = 0;          // AddFrame calls (and waits for frames prepared ahead)
};

// Runs `reconstruction` over the depth frames of `scan` in order, with their associated rgb
// frames (Scan::AssociatedFrame; the rgb exposure time is the rgb frame's depth-clock time).
// With `thermal`, every thermal frame of the scan is fused into it as soon as the fused depth
// poses reach its depth-clock time (as live capture would: the model then holds every depth
// frame up to it), and ThermalFusion::Finish() is called at the end; thermal frames whose
// file is missing are skipped with a warning, and Scan::LoadThermal's InputError (wrong size
// or type) propagates.
// Frames whose file is missing are skipped with a warning. Throws core::InputError (from
// Scan::Load*) on a frame that cannot be decoded or has the wrong size or type, and when
// no frame of the scan has usable depth; std::invalid_argument when start_at_groundtruth
// finds no groundtruth pose. `frame_done(i, n)` is called after every frame.
ScanReconstruction ReconstructScan(const core::Scan& scan, Reconstruction& reconstruction,
                                   const ScanReconstructionOptions& options,
                                   const std::function<void(int, int)>& frame_done = nullptr,
                                   ThermalFusion* thermal = nullptr);

}  // namespace hw::reconstruct
