#pragma once

// Rotation pre-alignment of a frame against the previous one before ICP (the "SO(3)
// pre-alignment" of Kintinuous / ElasticFusion, Whelan et al.): a hand-held rig that jerks
// turns up to ~100°/s faster than the constant-velocity prediction assumed, a degree or more
// per frame — beyond the basin of frame-to-model ICP where geometry leaves the pose to the
// colour term (a wall: its bricks repeat every few centimetres, and ICP locks on the wrong
// course). A direct photometric alignment of the two frames' coarse grey images, rotation
// only (the translation stays at the prediction), on blurred images whose basin is many
// pixels wide, gives ICP a start inside its own basin.
//
// Measured (README, Reconstruction: *Jerky motion, full size*): on the full-size jerky
// `equipment` path the tracker followed a 110°/s swing along a brick wall 48 mm, then
// 0.1–0.5 m, astray; started from the true rotation it stayed within 13 mm, and from this
// alignment's (rendered without the colour camera's rolling shutter) within 26 mm, ATE 56 → 6 mm.
// Coarse to fine (stop 43): across a dropped frame the swing turned the rig 4° past the
// prediction, and aligned at the finest blur alone the start moved 7° (the brick courses
// repeat every 5 px at 160×120); from the coarsest, 4.1°. Checked against the depth (stop
// 44, max_depth_misfit_ratio): grey levels also follow a person walking across the view.

#include <limits>
#include <string>

#include <Eigen/Geometry>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "reconstruct/camera_maps.h"

namespace hw::reconstruct {

struct RotationPrealignOptions {
  // Gauss–Newton iterations (0: off), in [0, 50].
  int iterations = 10;
  // Gaussian blur of both grey images before aligning, px of the level aligned, in [0, 5]:
  // widens the basin (a mortar line a pixel wide pulls only from a pixel away).
  double blur_sigma_px = 1.5;
  // Largest change from the predicted rotation accepted, degrees, (0, 90]: beyond it the
  // alignment found another view, not the rig's motion (a hand-held rig turns < 180°/s,
  // and the prediction already carries the last frame's rate).
  double max_rotation_deg = 15;
  // Smallest change from the predicted rotation used, degrees, in [0, max_rotation_deg): on
  // a smooth path the constant-velocity prediction is better than aligning two blurred
  // coarse images (measured: 0.05–0.4° corrections on smooth frames of the full-size
  // `equipment` sweeps, which only moved ICP's start; 0.8–2° in the jerky path's swings).
  double min_correction_deg = 0.5;
  // Huber threshold of the grey-level residuals, grey levels in (0, 1].
  double huber = 0.05;
  // Fewest pixels with depth and colour on both sides, >= 10: below it, no alignment.
  int min_pixels = 300;
  // Blur scales aligned coarse to fine, each twice the blur of the next, the finest
  // blur_sigma_px, in [1, 4]; `iterations` at each.
  int scales = 3;
  // The depth must agree: the rotation found is accepted only when the current frame's
  // points, moved by it onto the previous frame, meet the previous frame's depth no worse
  // than at the guess — the mean |Δz| (each capped at kDepthMisfitCapM) at the end at most
  // this times the one at the guess. Grey levels alone follow whatever moves in the image: a
  // person walking across the view pulled the rotation 0.7–3.9° per frame off a smooth
  // path, ICP started there settled millimetres astray each frame, the person was fused,
  // and the full-size 4 s passer sweep tracked 593 mm off (16 mm with the pre-alignment
  // off); the rig's own turn moves every static surface alike, so a right rotation brings
  // the depth closer. Ratio, >= 1; 0: off.
  double max_depth_misfit_ratio = 1.0;
  // Worker threads for the normal equations, >= 0 (0: all cores). The result does not
  // depend on it.
  int num_threads = 0;

  bool enabled() const { return iterations > 0; }
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// A grey image blurred over its pixels with depth at one scale (σ sigma_px), and the blurred
// coverage of those pixels (1 inside, falling to 0 outside).
struct PrealignBlur {
  double sigma_px = 0;
  cv::Mat grey, coverage;
};

// One frame as the pre-alignment reads it: the grey image (CV_32FC1 in [0, 1]) and depth
// (CV_32FC1, m, 0 = none) of one pyramid level, with that level's camera. Pixels without
// depth carry no colour (the registration gives none there).
struct PrealignImage {
  cv::Mat grey;
  cv::Mat depth_m;
  PinholeCamera camera;
  // Its blurs at the alignment's scales when already made (PrealignRotation's
  // `current_blurs` when this frame was the current one): as the previous frame it is then
  // not blurred again (1.6 of the alignment's 2.9 ms per 640×480 frame were blurs).
  std::vector<PrealignBlur> blurs;
};

struct RotationPrealignResult {
  // At least min_pixels, the residual lowered, the correction in [min_correction_deg,
  // max_rotation_deg], and the depth no worse (max_depth_misfit_ratio).
  bool ok = false;
  // The estimate of previous_from_current's rotation (the input guess when !ok).
  Eigen::Quaterniond previous_from_current = Eigen::Quaterniond::Identity();
  double correction_deg = 0;  // from the guess
  double rms_before = 0, rms_after = 0;  // grey levels, robust-weighted, at the guess and at the end
  // Mean |Δz| of the current points against the previous depth at the guess and at the end
  // (m, each capped at kDepthMisfitCapM; NaN when not measured: check off, or no rotation
  // within the accepted range); rejected_by_depth: the only test that failed was that one.
  double depth_misfit_before_m = std::numeric_limits<double>::quiet_NaN();
  double depth_misfit_after_m = std::numeric_limits<double>::quiet_NaN();
  bool rejected_by_depth = false;
  int pixels = 0;          // pairs used in the last iteration
  int iterations = 0;
};

// A point's depth misfit counts at most this (m): an occluding edge or a moving object then
// weighs like any point 10 cm off, not by how far behind it the background lies.
inline constexpr double kDepthMisfitCapM = 0.1;

// Aligns `current` to `previous` by rotation: minimises over R the robust sum over current
// pixels p with depth d of (I_prev(π(R·d·K⁻¹p + t)) − I_cur(p) − b)², b a brightness offset
// (auto exposure), on every second pixel of each row and column of a level at least 120 px
// wide (every pixel of a smaller one), coarse to fine over options.scales blur scales (σ
// blur_sigma_px · 2^k, the coarsest kept within 4 % of the width: fewer scales on a small
// level), each starting from the last one's rotation and offset (a coarser scale with too
// few samples, or whose iteration fails, is skipped); the residual test compares the finest
// scale's residual at the guess with its residual at the end. `guess` is the prediction of
// previous_from_current (its rotation the start, its translation t kept fixed). The result is
// then checked against the depth (max_depth_misfit_ratio). previous.blurs are used where
// their σ matches a scale's; `current_blurs` (optional) receives the current image's blurs,
// for when it is the previous one. Both images
// must have one size and camera (asserted). Never throws; ok = false when the images hold too
// few usable pixels, the iteration diverges or leaves the allowed range.
RotationPrealignResult PrealignRotation(const PrealignImage& previous, const PrealignImage& current,
                                        const Eigen::Quaterniond& guess_rotation,
                                        const Eigen::Vector3d& guess_translation_m,
                                        const RotationPrealignOptions& options,
                                        std::vector<PrealignBlur>* current_blurs = nullptr);

namespace internal {

// The previous frame as the alignment reads it: per pixel (CV_32FC4, side by side for one
// read per bilinear corner) the grey image and coverage blurred over the pixels with depth
// and the grey image's central differences along x and y; its camera.
struct PrealignImages {
  cv::Mat packed;
  PinholeCamera camera;
};

// The previous frame's images as PrealignRotation aligns against them: from its blur at
// blur_sigma_px (made here unless previous.blurs holds it).
PrealignImages PreparePrevious(const PrealignImage& previous, double blur_sigma_px);

// One current point's residual I_prev(π(R·X + t)) − grey − offset (X: the point in the
// current camera frame, m) and its derivative by [ω; offset], ω the left increment of R
// (Exp(ω)·R); false when the point leaves the image or lands beside a hole (coverage < 0.5).
// Computed in float: the per-point term AccumulatePrealign sums, exposed for the
// finite-difference test and as that sum's reference.
bool PrealignResidual(const PrealignImages& previous, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& t,
                      const Eigen::Vector3d& point, float grey, double offset, double& residual,
                      Eigen::Vector4d& jacobian);

// The current frame's samples: points in its camera frame (m) and their grey levels, as
// columns.
struct PrealignPoints {
  std::vector<float> x, y, z, grey;
  size_t size() const { return x.size(); }
};

// The robust normal equations over all `points` at (rotation, t, offset): Σ w J Jᵀ and
// −Σ w r J with PrealignResidual's r and J and Huber weights w (threshold `huber`), Σ w r²,
// Σ w and the number of points used. The per-point work in float (a frame's thousands of
// points at up to 30 evaluations per frame: the double, one-thread version cost 4.6 ms per
// frame at 640×480), summed in fixed chunks of points whose partial sums add up in double in
// chunk order: the same result for any num_threads (0: all cores).
struct PrealignSums {
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
  double sum_wr2 = 0, sum_w = 0;
  int used = 0;
};
PrealignSums AccumulatePrealign(const PrealignImages& previous, const Eigen::Matrix3d& rotation,
                                const Eigen::Vector3d& t, const PrealignPoints& points, double offset,
                                double huber, int num_threads);

// Mean over the current frame's pixels with depth (every `step`-th of each row and column,
// inner pixels) of min(|z_prev − z|, kDepthMisfitCapM): z the depth of the point moved by
// (rotation, t) into the previous camera, z_prev the previous depth at the nearest pixel it
// lands on. Points landing outside the image or on a pixel without depth are skipped; 0 when
// none is left (m).
double DepthMisfit(const PrealignImage& previous, const PrealignImage& current, const Eigen::Matrix3d& rotation,
                   const Eigen::Vector3d& t, int step);

}  // namespace internal

}  // namespace hw::reconstruct
