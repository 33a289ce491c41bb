#pragma once

// Frame-to-model tracking: point-to-plane ICP of a depth pyramid against the model's raycast
// (KinectFusion): projective data association with distance and normal-angle gates, Huber
// weights, coarse to fine, and checks that tell a failed alignment from a good one.

#include <array>
#include <string>
#include <vector>

#include "core/transform.h"
#include "reconstruct/camera_maps.h"
#include "reconstruct/depth_frame.h"
#include "reconstruct/depth_noise.h"

namespace hw::reconstruct {

struct IcpOptions {
  // Iterations per pyramid level, finest (level 0) first, each in [0, 100], at least one
  // > 0; a level with 0 is skipped.
  std::array<int, 3> iterations = {4, 5, 10};
  // Association gates: a live point and the model point it projects onto pair up when they
  // are at most max_distance_m apart and their normals within max_normal_angle_deg.
  double max_distance_m = 0.05;       // m, > 0 (at the coarsest level; halves per finer level
                                      // down to min_distance_m)
  double min_distance_m = 0.01;       // m, in (0, max_distance_m]
  double max_normal_angle_deg = 30;   // degrees, in (0, 90]
  double huber_m = 0.01;              // Huber threshold of point-to-plane residuals, m, > 0
  // Depth-dependent noise (0: off, the default): a depth sensor's error grows with the
  // distance, so the point-to-plane residual of a live point at depth z is divided by
  // z / this before its Huber weight, and its row scaled alike: a point at this depth keeps
  // weight 1, one at 4 m counts 1/16. Measured (README, Reconstruction): on the full-size
  // `equipment` sweeps (surfaces at 1–2 m) it helps — ATE over 3 s 2.28 → 1.70 mm with
  // rig.yaml's depth correction, 11.1 → 8.5 mm without; over 10 s 11.6 → 10.0 and
  // 55.9 → 15.9 mm — but on the `building` sweep (walls at 3–4 m) it loses the pose, 4 s:
  // 20.6 → 72.7 mm: every geometric row there shrinks ~10× against the photometric term's and
  // the Huber threshold grows 3–4×. Hence off by default. Relative to the frame's median
  // depth instead of a fixed one (tried: 19.2 and 2.19 mm) it was about neutral. Dividing by
  // (z / this)², the disparity noise law, was worse with the correction (10 s: 17.1 mm).
  // m, 0 or in [0.1, 10].
  double noise_reference_depth_m = 0;
  // Depth-noise gate (0: off, the default): a live point at depth z is paired up to
  // max(gate, noise_gate_sigmas · σ_z(z)) from its model point (gate: the level's
  // max_distance_m … min_distance_m), its residual's Huber threshold is
  // max(huber_m, noise_gate_sigmas · σ_z(z)), and the residual check (max_residual_m) reads
  // its residual times huber_m / that threshold — metres as at near range. A fixed 1 cm gate
  // at the finest level keeps a third of the points of a view reaching 3–4 m, where σ_z is
  // 14–26 mm. It pays only where the depth is free of systematic error: measured (README,
  // Reconstruction), 3 vs 0, full-size sweeps corrected with the sensor's exact field: 10 s
  // `equipment` ATE 5.04 → 3.27 mm, 4 s `building` 2.27 → 1.59 mm; corrected with the field
  // `heatwave calibrate depth` estimates (its depth scale unobservable): 4.16 → 4.57 and
  // 1.82 → 2.36 mm; uncorrected: 41.9 → 58.3 and 10.4 → 12.3 mm — far points then carry
  // tens of mm of distortion that a wider gate lets in; with the depth scale measured on the
  // extrinsics plate folded in as well: 3.69 → 3.06 and 1.73 → 1.55 mm. Off here;
  // `heatwave reconstruct` sets 3 when rig.yaml's depth_correction includes that scale
  // (core::DepthCorrection::ScaleMeasured). In [0, 10].
  double noise_gate_sigmas = 0;
  DepthNoiseModel depth_noise;  // σ_z(z) for the gate (the pipeline passes the TSDF's)
  // Stop a level when the update is smaller than this (rad for rotation, m for translation)
  // times 2^level: a level's pixel is 2^level times the full image's, and a coarse level's
  // updates below that scale are association chatter its finer levels redo anyway.
  double min_update_rad = 1e-5;
  double min_update_m = 1e-5;
  // Failure checks on the finest level used:
  double min_inlier_fraction = 0.15;  // inliers / valid live points, in [0, 1]
  int min_inliers = 300;              // absolute floor, >= 6
  // Largest ratio of largest to smallest eigenvalue of the 6×6 normal matrix (after
  // scaling rotation by a 1 m lever): above it the geometry does not constrain all six
  // degrees of freedom (a flat wall, a corridor). Directions weaker than that get no update
  // (the estimate keeps the initial pose there). > 1.
  double max_condition = 1e5;
  // Weak directions the frame may leave at the initial pose and still be aligned, [0, 5]:
  // wall + ceiling, or pipes running along a wall, leave one translation free (a corridor),
  // which the constant-velocity prediction then carries — sliding along it changes nothing
  // the depth sees, so fusing the frame is harmless, while declaring it lost left a scan
  // turning up to pipes under a ceiling lost for good (the view stays degenerate, so
  // relocalisation fails too). A single flat wall leaves three: beyond 2, the frame fails.
  int max_held_directions = 2;
  double max_residual_m = 0.02;       // RMS point-to-plane residual of inliers, m, > 0
  // Largest plausible change from the predicted pose in one frame; a bigger jump is a
  // failed alignment, not motion (a hand-held rig moves < 2 m/s, < 180°/s).
  double max_jump_m = 0.10;           // m, > 0
  double max_jump_deg = 10;           // degrees, > 0
  // Photometric term (0: off), for geometry that does not constrain the pose (a flat wall):
  // each geometric inlier also contributes the difference of grey levels (in [0, 1]) between
  // the model (PointMap::colours, bilinear at the projected pixel) and the live frame
  // (DepthLevel::intensity), times this weight: a black/white difference counts as this many
  // metres of point-to-plane error (same Huber threshold). Used only when both sides have
  // colour. m per grey level, in [0, 1]; 0.1 balances 2 mm depth noise with 0.02 grey noise.
  // On the near-planar synthetic `equipment-small` scan (noisy, 320×240, frame to frame
  // against the previous frame at its true pose) 0.2–0.5 cut the per-frame error from
  // 5.9 mm to 1.0 mm RMS; geometry alone drifts along the wall there.
  double photometric_weight = 0;
  // With the photometric term: estimate a brightness offset between the model's grey levels
  // and the live frame's (auto exposure moves the live frame's; the model holds a blend of
  // earlier exposures) and subtract it from the term's residuals. Each pass re-estimates it
  // as the robust-weighted mean difference of the pairs (alternating with the pose: a
  // uniform offset is nearly orthogonal to image motion). Measured on the full-size jerky
  // `equipment` path: offsets up to 0.019 grey levels in a swing along a brick wall, where the
  // uncompensated term pulled the pose 10–20 mm off the truth even when started at it.
  bool photometric_offset = true;
  int num_threads = 0;  // 0: hardware concurrency

  std::string Check() const;
};

// The model as ICP sees it: a raycast (world-frame points and normals, Raycast()) per
// pyramid level, with the camera and pose it was cast from. Level 0 is the finest and matches
// the size of the live pyramid's level 0 (or of the finest level ICP uses).
struct ModelPyramid {
  core::Rigid3d world_from_camera;  // where the raycast was taken from
  std::vector<PinholeCamera> cameras;
  std::vector<PointMap> maps;  // world frame
};

// Downsamples a raycast (level 0) into `num_levels` levels by taking one valid point per
// 2×2 block (nearest to the block's mean depth along the camera axis) with its normal and
// colour. num_threads: row bands run at once (0: hardware concurrency). Pass level0 by
// std::move to avoid copying it.
ModelPyramid BuildModelPyramid(PointMap level0, const PinholeCamera& camera,
                               const core::Rigid3d& world_from_camera, int num_levels,
                               int num_threads = 0);

enum class IcpStatus {
  kOk,
  kTooFewInliers,    // fewer than min_inliers / min_inlier_fraction
  kIllConditioned,   // more than max_held_directions directions weaker than largest / max_condition
  kLargeResidual,    // inlier RMS above max_residual_m
  kImplausibleJump,  // change from the initial pose above max_jump_m / max_jump_deg
  // Set by the pipeline, not by AlignToModel: a relocalised pose whose live depth
  // contradicts the model's free space (ReconstructionOptions::relocalisation_max_conflict).
  kModelConflict,
  // Set by the pipeline: a frame aligned on depth alone whose pose ICP does not come back to
  // when moved along its weakest direction (ReconstructionOptions::basin_check_m).
  kUnconstrained,
};
std::string IcpStatusName(IcpStatus status);  // "ok", "too_few_inliers", ...

// The figures below come from the last association pass (the finest level used, at the pose
// before that pass's update, which is below min_update_* once converged).
struct IcpResult {
  IcpStatus status = IcpStatus::kOk;
  core::Rigid3d world_from_camera;  // the estimate (also returned when status is not ok)
  int inliers = 0;                  // at the finest level used
  int valid_points = 0;             // live points with a normal at that level (the candidates)
  double residual_rms_m = 0;        // RMS point-to-plane residual of the inliers, m (scaled
                                    // as IcpOptions::noise_gate_sigmas says when that is on)
  double condition = 0;             // of the last normal matrix (inf when singular)
  // Directions of that matrix weaker than largest / max_condition: left at the initial pose.
  int held_directions = 0;
  int iterations = 0;               // total over levels
  // Brightness offset of the photometric term at the end (model − live grey level, in
  // [-1, 1]; 0 when the term or its offset is off).
  double photometric_offset = 0;
  // The 6×6 normal matrix Σ w J Jᵀ of the final iteration (photometric rows included when
  // that term is on; geometric rows scaled by noise_reference_depth_m / z when that is on), in the tangent the updates use:
  // world_from_camera · Exp(ξ), ξ = [rotation (rad); translation (m)] in the camera frame
  // (core::Rigid3d::Exp). Its inverse times residual_rms_m² approximates the covariance of ξ.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

// Aligns the live pyramid (camera frame) to the model, starting at initial_world_from_camera
// (the constant-velocity prediction). Per level, coarse to fine: each live point is moved to
// the world by the current estimate, projected into the model camera (model.world_from_camera),
// paired with the model point at that pixel when it passes the gates, and the pose updated
// by a Gauss-Newton step of the Huber-weighted point-to-plane error (linearised rotation,
// applied on the right in the camera frame: world_from_camera · Exp(ξ)). Live points need a
// normal (for the angle gate). The 6×6 system is summed per row in eight float lanes (eight
// pixels at a time), then in double in row order: the result does not depend on num_threads
// nor on the CPU's vector extensions. Checks, in this order:
// too few inliers, condition, residual, jump. Never throws; failures are in status.
IcpResult AlignToModel(const DepthPyramid& live, const ModelPyramid& model,
                       const core::Rigid3d& initial_world_from_camera, const IcpOptions& options);

// The direction of pose change ξ = [ω; v] (rad, m; IcpResult's convention: world_from_camera ·
// Exp(ξ), camera frame) that `information` (IcpResult::information) constrains least, with
// rotation measured at a 1 m lever as in the condition number: a unit vector in that metric
// (|v|² + |ω|² · 1 m² = 1 m²). Zero when the information is zero.
Eigen::Matrix<double, 6, 1> WeakestDirection(const Eigen::Matrix<double, 6, 6>& information);

// How well the depth fixes `aligned` (AlignToModel's result for `live` against `model`): ICP
// rerun with `options` from that result moved step_m along its WeakestDirection; returns how
// far apart the two results end, m (translation and rotation at a 1 m lever, combined). Near
// 0 where the data pull the pose back; near step_m where the minimum is flat along that
// direction (a plain wall, a corridor). step_m > 0.
double IcpBasinM(const DepthPyramid& live, const ModelPyramid& model, const IcpResult& aligned, double step_m,
                 const IcpOptions& options);

}  // namespace hw::reconstruct
