#pragma once

// Target-based extrinsics (issue 13): depth_from_thermal and depth_from_rgb from stills of a
// square_grid heated mask seen by depth, colour and thermal at once
// (fixtures session "extrinsics-target").
//
// Per still (a depth frame with a thermal and a colour frame associated in time):
//  - the grid's corners in thermal (°C image) and colour (luma), calibrate/square_grid.h;
//  - a first depth_from_target from a PnP in each camera and the rig's extrinsics;
//  - the plate's points in depth: valid depth pixels (on a grid of depth_stride_px, so
//    that the depth noise's spatial correlation does not count as information) that fall on
//    the plate (not in a hole, dilated by hole_margin_m, not past its outline) near the
//    predicted plane, then a RANSAC plane among them (holes seeing the background 3 cm
//    behind, the hands, flying pixels on the edges are outliers).
// Then one joint least-squares (Ceres) over depth_from_thermal, depth_from_rgb and one
// depth_from_target per still, with reprojection residuals of the corners in thermal and
// colour (px; the rig's intrinsics and distortion, fixed; core::CameraModel::Project with its
// analytic Jacobian inside autodiff; each corner where the camera sees it through a plate of
// target.yaml's thickness_m, calibrate/hole_corner.h) and plate residuals in depth: the signed distance to
// the plane z = 0 of the target frame of the mean point of each plane_cell_m cell (m). Each
// residual is divided by its σ and under a Huber loss. Nuisance parameters that keep the
// covariance honest: each camera's apparent edge shift of the holes (edge_shift), the depth
// camera's radial disparity bowl (depth_model) and, with a calibrated depth_correction, the
// affine part of its error no wall shows (depth_affine), and each still's depth plane error (offset,
// two tilts) as random effects with σ estimated by EM (still_errors), plus the depth's
// common range bias with a prior of the depth's correlated σ. The σ of every residual type
// (corners per camera; plate points' white σ and cells' correlated σ) are re-estimated from
// the residuals (robust RMS) and the problem solved again, `reweight_iterations` times; the
// plate points are re-selected with the refined poses after the first solve.
//
// Covariance: of each extrinsic's 6 parameters in calibrate/extrinsics.h's parameterisation
// (ω rad left rotation in the depth frame; δt m), by ceres::Covariance (sparse QR: a
// rank-deficient Jacobian, stills that do not fix every dof, is refused) on the whole problem: the still poses and every nuisance
// parameter are marginalised.
//
// Measured (fixtures' extrinsics-target sessions, true intrinsics, nominal extrinsics
// 1°/1 cm off as the start): full size (20 stills), 5 seeds, with the depth correction
// calibrated on the depth-wall session: rotation 0.026–0.098°, translation 0.54–1.67 mm,
// truth within 2.8σ; without a correction 0.08–0.16°, 0.6–1.9 mm, within 3.3σ; small (6
// stills, no correction) 0.06–0.53°, 1.0–3.5 mm, within 3.5σ. Thermal and colour errors are
// nearly equal in every run: what limits both is the depth camera's systematic error.

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calibrate/extrinsics.h"
#include "calibrate/square_grid.h"
#include "core/rig.h"
#include "core/scan.h"

namespace hw::calibrate {

struct TargetExtrinsicsOptions {
  // The detector, in thermal and in colour. Its edges at the mid-level: the outline the
  // visible hole corners model (hole_corner.h); with the steepest point, which lands inside
  // the wall's strip, the full-size sessions' translation errors grew from 0.5-1.7 mm to
  // 0.9-2.9 mm (truth up to 4.1 sigma).
  SquareGridOptions grid{.edge = EdgeLocator::kMidLevel};
  // Stills with corners in both cameras and a plate plane in depth needed, [3, 10000].
  // Fewer: InputError. Each still adds 6 unknowns (its pose) and ~2·4·holes + plate points
  // of residuals; three non-parallel plate orientations fix the translation along the
  // normals.
  int min_stills = 3;
  // A camera's detection is used when it has at least this many corners, [4, 10000].
  int min_corners = 8;
  // Plate points per still needed, [10, 1e6].
  int min_plane_points = 50;
  // Depth pixels sampled on this grid, px; 0: automatic, 4 px of a 640-wide depth image
  // (the depth noise decorrelates over ~3 native pixels), scaled with the image width. [0, 64].
  int depth_stride_px = 0;
  // Plate points are kept at least this far (in the target plane) from a hole's edge and
  // from the plate's outline, m, [0, 0.05]: room for the first pose's error.
  double hole_margin_m = 0.006;
  // How far beyond the holes' extent the plate is taken to reach, m, [0, 0.5]: target.yaml
  // does not give the plate's border; the fixtures' masks have 4 cm, the hands hold its
  // outer centimetre.
  double plate_border_m = 0.02;
  // Side of the square cells of the target plane whose plate points are averaged into one
  // residual, m, [0.005, 0.5] (see sigma_cell_m).
  double plane_cell_m = 0.03;
  // Before RANSAC: points farther than this from the predicted plate plane are dropped,
  // m, (0, 1]. The nominal extrinsics (1°, 1 cm off) misplace the plane by a few cm.
  double plane_gate_m = 0.08;
  // RANSAC inlier threshold, m, (0, 0.2].
  double ransac_threshold_m = 0.015;
  int ransac_iterations = 200;  // [1, 100000]
  // Estimate the depth camera's radial disparity bowl with the extrinsics: the b of the
  // depth model z' = z + z² (a + b r² + c_x x + c_y y) (r, x, y of the pixel's ray on the
  // z = 1 plane). Structured-light depth carries one (mm at 1 m) unless the rig's
  // depth_correction removed it; unmodelled, it tilts the plate planes (on the fixtures'
  // small sessions: rotation errors 0.21 / 0.53 / 0.09° with it vs 0.37 / 0.55 / 0.27°
  // without).
  bool depth_model = true;
  // With a calibrated depth_correction in the rig: estimate the affine part (a, c_x, c_y)
  // of the depth error left, each under a zero-mean prior of σ depth_affine_sigma_per_m.
  // It is the part of the field that `calibrate depth` cannot see (a wall at any pose stays
  // a plane under it) and that only the plate's known size, seen by the cameras at several
  // distances, measures: a offsets inverse depth (z² a: 1.9 mm at 1 m on the fixtures'
  // device) and c_x, c_y tilt it. Held at 0 it biased the extrinsics by that much with a σ
  // that did not know it (fixtures' full sessions: truth 2.2–4.8σ off; estimated, within
  // 2σ). Without a depth_correction the whole field is left, the bowl b and the common
  // range offset carry it, and freeing a, c_x, c_y as well only added variance (rotation
  // 0.06–0.22° vs 0.08–0.14°, full sessions): not estimated then.
  bool depth_affine = true;
  // Prior σ of a, c_x and c_y, 1/m: 0 (automatic) takes the RMS of the rig's calibrated
  // depth_correction over its nodes (at least 1e-5) — a device's unseen affine error as
  // large as its seen field; else in [1e-5, 0.1].
  static constexpr double kMinDepthAffineSigmaPerM = 1e-5;
  double depth_affine_sigma_per_m = 0;
  // Estimate each camera's apparent edge shift of the holes with the extrinsics: corners
  // found outside (or inside) the true hole edges by the same distance in every view
  // (blur and threshold, the holes' walls, heat bleeding). Unmodelled, a hole that looks
  // 0.5 % too large moves the camera's distance to the plate by 0.5 % — 5 mm at 1 m —
  // against the depth camera's, and biases the translation along the view axis.
  bool edge_shift = true;
  // Give each still's depth plane an error of its own — an offset and two tilts, zero-mean
  // with σ estimated from the stills (random effects) — so that the depth camera's
  // systematic errors, which move a whole plate's points together (a device's disparity
  // distortion: mm at 1 m), enter the extrinsics' covariance instead of being averaged away
  // as if independent per point.
  bool still_errors = true;
  // Huber loss on the whitened residuals: quadratic up to this many σ, [0.5, 100].
  double huber_sigmas = 2.5;
  // Solve, re-estimate each residual type's σ, solve again: this many re-estimations, [0, 20].
  int reweight_iterations = 3;
  std::string Check() const;
};

// One still: the frames it uses, what was found, whether it went into the solve.
struct TargetExtrinsicsStill {
  int depth_frame = -1;
  int thermal_frame = -1;  // -1: no thermal frame near in time
  int rgb_frame = -1;
  int thermal_corners = 0;  // corners of the accepted detection (0: none)
  int rgb_corners = 0;
  int plane_points = 0;     // plate points kept (after RANSAC)
  bool used = false;
  std::string reason;       // why not used ("" when used)
};

// A residual for the diagnostics: where it is (image pixel, or depth pixel) and its value.
struct ResidualSample {
  int still = 0;              // index into TargetExtrinsicsResult::stills
  Eigen::Vector2d pixel;      // observed corner (thermal / rgb) or depth pixel (plane)
  Eigen::Vector2d residual;   // projected − observed, px; plane: (distance m, 0)
};

struct TargetExtrinsicsResult {
  ExtrinsicsEstimate thermal;  // camera "thermal", residual_unit "px"
  ExtrinsicsEstimate rgb;      // camera "rgb", residual_unit "px"
  std::vector<TargetExtrinsicsStill> stills;
  int stills_used = 0;
  // Final noise estimates of the three residual types (robust RMS of the residuals).
  double sigma_thermal_px = 0;
  double sigma_rgb_px = 0;
  double sigma_plane_m = 0;  // white noise of a plate point
  // Correlated error of a cell's mean (plane_cell_m): what the depth's low-frequency
  // errors add to a cell's mean beyond sigma_plane_m / sqrt(n), m.
  double sigma_cell_m = 0;
  // The stills' depth plane errors (random effects, options.still_errors): σ of a still's
  // plane offset, m, and tilt, rad.
  double sigma_still_offset_m = 0;
  double sigma_still_tilt_rad = 0;
  int plane_points = 0;
  double plane_rms_m = 0;
  // The depth model [a, b, c_x, c_y] (1/m, TargetExtrinsicsOptions::depth_model) estimated
  // (b zero without options.depth_model; a, c_x, c_y zero without options.depth_affine).
  Eigen::Vector4d depth_model = Eigen::Vector4d::Zero();
  // Its covariance (1/m²), the extrinsics and the still poses marginalised; rows and columns
  // of the parts not estimated are zero.
  Eigen::Matrix4d depth_model_covariance = Eigen::Matrix4d::Zero();
  double target_thickness_m = 0;        // target.yaml's plate thickness, modelled, m
  double depth_affine_sigma_per_m = 0;  // the prior σ used for a, c_x, c_y, 1/m (0: not estimated)
  // Apparent edge shift of the holes in thermal and colour, m (+: holes look larger).
  double thermal_edge_shift_m = 0;
  double rgb_edge_shift_m = 0;
  std::vector<ResidualSample> thermal_residuals, rgb_residuals, plane_residuals;
  double detect_seconds = 0;  // detection and plate segmentation, s
  double solve_seconds = 0;   // the joint solves and the covariance, s
};

// Called with (stills done, stills total) during detection.
using TargetExtrinsicsProgressFn = std::function<void(int done, int total)>;

// Estimates depth_from_thermal and depth_from_rgb from the scan's stills of `target` (a
// square_grid), starting from the scan's rig (its intrinsics are used as they are, fixed;
// its extrinsics are the first guess). Throws core::InputError naming the scan folder when:
// the rig has no thermal or rgb camera or the scan no such stream; target is not a
// square_grid; fewer than min_stills stills have corners in both cameras and a plate in
// depth; the solve does not converge; the covariance cannot be computed or leaves an
// extrinsic undetermined (a 1σ above 5 cm or 5°: a degenerate configuration, e.g. every
// still at the same plate orientation; sparse QR does not always see the rank deficiency in
// rounding noise). Asserts options.Check().
TargetExtrinsicsResult EstimateTargetExtrinsics(const core::Scan& scan, const core::Target& target,
                                                const TargetExtrinsicsOptions& options,
                                                const TargetExtrinsicsProgressFn& progress = nullptr);

}  // namespace hw::calibrate
