#pragma once

// The intrinsics problem as libmrcal 2.2 sees it (internal to SolveIntrinsics and
// ProjectionUncertaintyMap). mrcal's chessboard observations need a regular grid of
// corners, which square_grid and aprilgrid targets are not; so the target frame is mrcal's
// reference frame, every corner a fixed discrete point in it, and every view one camera pose
// (an mrcal "extrinsics", rt camera_from_target) sharing the one set of intrinsics.

#include <Eigen/Core>
#include <array>
#include <vector>

#include "calibrate/intrinsics_solver.h"
#include "core/mrcal_c.h"

namespace hw::calibrate {

// Projection of a camera-frame point with mrcal (pixels) and its Jacobians: dq/dp_cam 2x3
// and dq/dintrinsics 2xN (may be null).
Eigen::Vector2d MrcalProject(const mrcal_lensmodel_t& lensmodel,
                             const std::vector<double>& intrinsics, const Eigen::Vector3d& p_cam,
                             Eigen::Matrix<double, 2, 3>* dq_dp, Eigen::MatrixXd* dq_dintrinsics);

// p_cam = camera_from_target(rt) p_target and dp_cam/drt, 3x6 (may be null).
Eigen::Vector3d MrcalTransform(const mrcal_pose_t& rt, const Eigen::Vector3d& p_target,
                               Eigen::Matrix<double, 3, 6>* dp_drt);

// How the corners a detector finds on a target of squares (square_grid holes, aprilgrid
// tags) sit relative to the target's true corners: every square edge is seen shifted
// outwards (into the plate: the square looks larger; < 0 into the square) by F(u) metres
// in the target plane, where u is the tangent of the viewing angle across the edge: the
// camera's distance from the edge's line along the edge's inward normal (towards the
// square's centre), in the target plane, over its distance from the plane (u > 0: the
// camera looks at the face of the square's side wall that belongs to this edge). F is
// piecewise linear between values at `knots_u` (constant beyond them), estimated with the
// camera (MrcalProblem::EstimateShapeStep); one knot: a constant edge offset.
// Why: a heated mask's holes look smaller than they are (heat bleeding onto the background
// behind them), their side walls (the plate's thickness, at a temperature between the
// plate's and the background's) show only when they face the camera, and the bled
// background behind a hole is seen shifted by parallax — all functions of u. Printed tags
// look larger or smaller with blur and gamma, by an amount that changes with their size in
// the image (a constant F beside the pixel offset: a shift linear in that size; and the
// print's ink spread, which is one in metres).
// A linear F (F = α u) moves every corner of a view by α (c − p)/d in the plane (c the
// camera centre, d its distance): exactly the target plane moved α along its normal, which
// the poses absorb. That direction is fixed by a stiff prior (F's least-squares line
// through the knots has zero slope), so the covariance stays finite.
// Besides F (metres on the target: physical), a shift of every edge in the IMAGE, pixels
// along the edge's image normal (pixel_offset): what a detector's edge model, blur and gamma
// do to squares; in target metres it grows with distance and obliquity. (An outward shift
// grows the squares about their centres: no pose does that.) One for all views: one per
// view was tried and fitted the fixtures' sessions worse (the focal length's error against
// truth grew from 2.6 to 4.1 sigma on an aprilgrid session: 16 more unknowns that trade
// with the poses' distances).
// Parameters, in this order: [the pixel offset,] F at the knots.
struct TargetShapeModel {
  bool pixel_offset = false;
  std::vector<double> knots_u;  // increasing; may be empty
  int NumParams() const { return (pixel_offset ? 1 : 0) + static_cast<int>(knots_u.size()); }
  // The weights of F's knot values at u (hat functions; clamped outside the knots).
  Eigen::VectorXd Basis(double u) const;
};

class MrcalProblem {
 public:
  // `lensmodel`: LENSMODEL_OPENCV5, LENSMODEL_OPENCV8 or a configured
  // LENSMODEL_SPLINED_STEREOGRAPHIC (core::MrcalLensModel).
  // corners_target: core::TargetCorners (every 4 consecutive ids one square when `shape`
  // has a parameter).
  MrcalProblem(const mrcal_lensmodel_t& lensmodel, int width_px, int height_px,
               const std::vector<Eigen::Vector3d>& corners_target,
               const std::vector<ViewObservation>& views, TargetShapeModel shape = {});

  int NumIntrinsics() const;
  int NumState() const;  // intrinsics + 6 per view (the shape parameters not included)
  int NumObservations() const { return static_cast<int>(observations_.size()); }
  int NumViews() const { return static_cast<int>(view_begin_.size()) - 1; }
  int NumShape() const { return shape_.NumParams(); }

  // One Gauss-Newton step of the shape parameters with the intrinsics and poses
  // re-adjusted (the step minimises the linearised residuals over all of them; the state's
  // part is left to the next Optimize), then the view points moved accordingly. Returns the
  // step's size (metres, largest knot). No-op (0) without shape parameters.
  double EstimateShapeStep();

  // Every view's copy of the target points at the current shape parameters, poses and
  // intrinsics, and their derivatives with respect to the shape parameters (u and the
  // metres per pixel held at the current state). Call after setting poses and intrinsics.
  void UpdatePoints();

  // mrcal_optimize from the current intrinsics and poses, all poses free, the core and the
  // distortion free as asked, mrcal's regularisation on, no mrcal outlier rejection; the
  // known outliers are left out. Throws std::runtime_error when mrcal fails.
  void Optimize(bool optimize_core, bool optimize_distortion);

  // Marks as outliers the inlier corners whose residual norm exceeds `sigmas` times the RMS
  // residual norm of the inliers. Returns how many were marked.
  int MarkOutliers(double sigmas);

  // The result at the current state, with its covariance (throws std::runtime_error when
  // J^T J is singular, e.g. more unknowns than inlier measurements). core_free = false: the
  // core (fx fy cx cy) was held fixed (splined models), so it has zero covariance and does
  // not count as an unknown.
  IntrinsicsResult Result(bool core_free = true) const;

  std::vector<double> intrinsics;   // mrcal order: fx fy cx cy k... (or spline controls)
  std::vector<mrcal_pose_t> poses;  // rt camera_from_target per view
  Eigen::VectorXd shape_params;     // the TargetShapeModel parameters: [pixels,] metres

 private:
  // observed - projected of every observation; with J, d(projected)/d(state, then the shape
  // parameters) stacked 2 rows per observation (outliers included).
  std::vector<Eigen::Vector2d> Residuals(Eigen::MatrixXd* J) const;
  // d(point in target)/d(shape parameters) of observation o, 3 x NumShape().
  Eigen::MatrixXd PointShapeJacobian(int o) const;
  // Jacobian of mrcal's regularisation measurements with respect to the intrinsics (they
  // depend on nothing else), from mrcal_optimizer_callback's measurement vector.
  Eigen::MatrixXd RegularizationJacobian() const;

  mrcal_lensmodel_t lensmodel_{};
  std::array<int, 2> imagersize_{};
  TargetShapeModel shape_;
  std::vector<Eigen::Vector3d> corners_;  // the target's true corners, by id
  std::vector<Eigen::MatrixXd> shape_basis_;  // per point: dp/d(shape_params), 3 x NumShape
  // The gauge prior's row (zero slope of F), or empty.
  Eigen::RowVectorXd ShapePrior() const;
  // Every view has its own copy of the target's corners (view v's point for corner id k is
  // v * corners_.size() + k): with walls, where a corner is seen depends on the view.
  std::vector<mrcal_point3_t> points_;
  std::vector<mrcal_observation_point_t> observations_;  // view-major; px.z < 0: outlier
  std::vector<int> view_begin_;  // index of each view's first observation, plus the end
};

}  // namespace hw::calibrate
