#pragma once

// Intrinsic calibration of one camera from target detections, solved by mrcal
// (https://mrcal.secretsauce.net, libmrcal 2.2's C API), with the covariance of the solution
// and mrcal's projection uncertainty.

#include <Eigen/Core>
#include <limits>
#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/rig.h"
#include "core/transform.h"

namespace hw::calibrate {

// The lens models solved for: mrcal's LENSMODEL_OPENCV5, LENSMODEL_OPENCV8 and
// LENSMODEL_SPLINED_STEREOGRAPHIC (core::CameraModelType::kSplined, configured by the
// spline_* options).
enum class LensModel { kOpenCv5, kOpenCv8, kSplined };

struct IntrinsicsOptions {
  LensModel model = LensModel::kOpenCv5;
  // Outlier rejection threshold, in (1, 100]: after each full solve a corner whose residual
  // norm (pixels) exceeds outlier_sigmas times the RMS residual norm of the current inliers
  // is marked an outlier, and the problem is re-solved until no new outlier appears. (mrcal
  // 2.2 rejects outliers only for chessboard-grid observations, with a fixed threshold, so
  // this loop is ours.)
  double outlier_sigmas = 3;
  // true: solve in stages, poses only -> + core (fx fy cx cy) -> + distortion, each stage
  // seeded by the previous one (robust to a poor seed); false: everything at once.
  bool staged = true;
  // Estimate, with the camera, how the squares the detector sees differ from the target's
  // (mrcal_problem.h, TargetShapeModel): square_grid (a heated mask) the edges' shift as a
  // function of the viewing angle and a shift in the image, aprilgrid a shift in the image
  // and one on the target (the detector's bias grows with the tags' size in pixels);
  // chessboards nothing (their saddle corners do not move with the edges).
  // Without it, on the fixtures' thermal sessions, the holes' apparent shrinkage (heat
  // bleeding) and their side walls (seen only when they face the camera) bias the focal
  // length by 3-4 sigma.
  bool estimate_target_shape = true;
  // kSplined only: mrcal's splined configuration (core::SplinedConfig). 0 = chosen by
  // ChooseSplinedConfig from the image and the opencv8 fit that seeds the spline.
  int spline_order = 3;      // 2 (quadratic) or 3 (cubic, mrcal's usual choice)
  int spline_nx = 0;         // knots across: 0 or [4, 64]
  int spline_ny = 0;         // knots down: 0 or [4, 64]
  int spline_fov_x_deg = 0;  // horizontal field of view the spline spans: 0 or [1, 179] deg
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

struct ViewObservation {                // one accepted detection
  std::vector<int> corner_ids;          // into core::TargetCorners(target)
  std::vector<Eigen::Vector2d> pixels;  // OpenCV pixel convention; same size as corner_ids
};

struct IntrinsicsResult {
  core::CameraModel camera;              // opencv 5 or 8, or splined; width/height as given
  // e.g. "LENSMODEL_OPENCV5", "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=13_fov_x_deg=70"
  std::string mrcal_lensmodel;
  std::vector<double> mrcal_intrinsics;  // mrcal's parameters: fx fy cx cy k... (= camera's)
  // kSplined: the converged opencv8 solve that seeded the spline (mrcal's workflow: fit
  // the parametric model first), for comparing the two (ProjectionDifference). nullopt for
  // the parametric models.
  std::optional<core::CameraModel> parametric_camera;
  std::vector<core::Rigid3d> camera_from_target;  // per view
  // RMS over all inlier corners of the residual NORM (pixels): sqrt(sum |r|^2 / N_inliers),
  // as mrcal's rms_reproj_error__pixels (sqrt(norm2(x) / (len(x) / 2))). For isotropic
  // Gaussian noise of sigma per coordinate it is about sigma * sqrt(2 (1 - Nstate / Nmeas)).
  double rms_px = 0;
  double worst_px = 0;              // largest residual norm of an inlier corner, pixels
  std::vector<double> view_rms_px;  // per view, as rms_px (NaN: every corner an outlier)
  // Per view, per corner (order of ViewObservation): observed - projected, pixels.
  std::vector<std::vector<Eigen::Vector2d>> residuals_px;
  std::vector<std::vector<bool>> outlier;  // per view, per corner
  int outliers = 0;
  // Per-coordinate noise estimated from the inlier residuals with the degrees of freedom
  // removed: sqrt(sum |r|^2 / (2 N_inliers - Nstate)), pixels.
  double observation_sigma_px = 0;
  // Covariance of the whole solved state, sigma^2 (J^T J)^-1 with J the Jacobian of the
  // inlier residuals at the optimum (physical units, not mrcal's packed state). State order:
  // mrcal_intrinsics, then per view mrcal's rt of camera_from_target (Rodrigues r in rad,
  // t in m). J: the inlier corners' reprojection terms (outliers carry no information) and
  // mrcal's regularisation terms (differentiated through mrcal_optimizer_callback), as
  // mrcal's own covariance. The packed, scaled state of mrcal's optimiser is not used.
  Eigen::MatrixXd state_covariance;
  // Its leading block: the covariance of mrcal_intrinsics with the poses marginalised.
  Eigen::MatrixXd intrinsics_covariance;
  // The target shape (IntrinsicsOptions::estimate_target_shape; mrcal_problem.h,
  // TargetShapeModel): the outward shift of the squares' edges, metres, at the viewing-angle
  // tangents edge_shift_knots_u, and its standard deviation. Empty when not estimated.
  // Marginalised out of the covariances above.
  std::vector<double> edge_shift_knots_u, edge_shift_m, edge_shift_sigma_m;
  // The shift of every edge in the image, pixels along its normal (> 0 outwards), and its
  // standard deviation; NaN when not estimated.
  double edge_shift_px = std::numeric_limits<double>::quiet_NaN();
  double edge_shift_sigma_px = std::numeric_limits<double>::quiet_NaN();
  double solve_seconds = 0;  // wall time of SolveIntrinsics
};

// Solves the intrinsics of a width_px x height_px camera observing `target` in `views`.
//
// Seed: the focal length (fx = fy) from the views' homographies (Zhang's constraints with
// the principal point at the image centre), poses by cv::solvePnP (IPPE, planar), zero
// distortion. Then mrcal_optimize: the target frame is mrcal's reference frame, its corners
// fixed points; each view is one camera pose (mrcal "extrinsics", rt camera_from_target)
// sharing one set of intrinsics; staged per options.staged; then the outlier loop. mrcal's
// regularisation is on (as in its calibration tool; opencv8 needs it, and it makes J^T J of
// a splined model invertible: it pulls each control towards 0 where no corner constrains it).
//
// kSplined, mrcal's own workflow: the opencv8 problem above is solved first (staged, with
// its outlier loop); the spline is seeded from it (SplinedApproximation, poses carried over),
// then solved staged (poses only, then the spline), its outliers found afresh. The core
// (fx fy cx cy) stays the opencv8 fit's, as mrcal's calibration tool does: the spline can
// shift and scale u itself, so core and spline together are (nearly) redundant. Its
// covariance rows and columns are then 0.
//
// Throws std::invalid_argument (clear message) for invalid options or target, an image
// size outside CameraModel's range, fewer than 3 views, a view with fewer than 4 corners
// or mismatched sizes, a corner id out of range or repeated in a view, a non-finite pixel,
// or views that do not constrain the focal length (all (nearly) fronto-parallel: the
// homography focal estimate is not positive or its relative standard error exceeds 10 %).
// Throws std::runtime_error when mrcal fails, converges to an invalid camera (outside
// CameraModel::Check's ranges), or J^T J is singular at the optimum.
IntrinsicsResult SolveIntrinsics(const core::Target& target, int width_px, int height_px,
                                 const std::vector<ViewObservation>& views,
                                 const IntrinsicsOptions& options = {});

// The splined configuration of a solve: options.spline_* where given, else
//   fov_x_deg  the horizontal field of view of `parametric` (its image border unprojected),
//              5 % wider and rounded up: mrcal's spline is valid over fov_x_deg and
//              extrapolates beyond, so it must span the whole image
//   nx         about one knot per 40 px across, in [8, 30]: mrcal's examples use 30 on a
//              6000 px wide image filled with chessboard corners; thermal targets give
//              far fewer corners, and each knot must see some
//   ny         the fewest knots (same spacing as across) whose valid span covers the image
//              height, 5 % margin, in [4, 64]
// `parametric` is the seed camera (opencv), width and height those of the image.
core::SplinedConfig ChooseSplinedConfig(const IntrinsicsOptions& options,
                                        const core::CameraModel& parametric);

// The splined camera with `config` that projects like `parametric` (same fx fy cx cy):
// its controls by linear least squares on pixels every ~1/40 of the image, each ray
// unprojected by `parametric`; controls no pixel constrains stay near 0 (a tiny ridge).
core::CameraModel SplinedApproximation(const core::CameraModel& parametric,
                                       const core::SplinedConfig& config);

// How differently two models of one camera project (mrcal-show-projection-diff's idea, at
// infinite range): each pixel is unprojected by `from`, rotated by the one rotation that best
// aligns the two camera frames (least squares over the pixels: separate solves may define
// the frame differently), and projected by `to`. Pixels either model cannot (un)project
// are skipped (`points` counts the rest).
struct ModelDifference {
  double rms_px = 0;    // RMS of the pixel differences' norms
  double worst_px = 0;  // largest norm
  int points = 0;
  double rotation_rad = 0;  // angle of the fitted rotation
};
ModelDifference ProjectionDifference(const core::CameraModel& from, const core::CameraModel& to,
                                     const std::vector<Eigen::Vector2d>& pixels);

// mrcal's projection uncertainty ("mean of frames" reference, mrcal 2.2's Python
// mrcal.projection_uncertainty(what = 'worstdirection-stdev'), here in C++): for pixel q
// the point p_cam at `range_m` metres along q's ray; p_target_i = camera_from_target_i^-1
// p_cam for every view i; with the state perturbed, p_cam' = mean_i(camera_from_target'_i
// p_target_i) projected with the perturbed intrinsics gives q'. Linearised, Cov(q') = G
// state_covariance G^T (G = dq'/dstate: intrinsics and every view's pose); the value is the
// square root of its largest eigenvalue, pixels (1-sigma in the worst direction).
// Evaluated at q = (c (width - 1) / (grid_cols - 1), r (height - 1) / (grid_rows - 1))
// (the centre for a count of 1); returns grid_rows x grid_cols values, row-major. A pixel
// whose ray cannot be unprojected gives NaN. Throws std::invalid_argument for grid counts
// outside [1, 1000], range_m not finite and > 0, or a result without state_covariance.
std::vector<double> ProjectionUncertaintyMap(const IntrinsicsResult& result, int grid_cols,
                                             int grid_rows, double range_m);

}  // namespace hw::calibrate
