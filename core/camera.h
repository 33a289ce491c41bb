#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hw::core {

// Lens models of rig.yaml (scan-format.md). kOpenCV is OpenCV's distortion model with
// 4, 5 or 8 coefficients in OpenCV order: k1 k2 p1 p2 [k3 [k4 k5 k6]]. kSplined is mrcal's
// LENSMODEL_SPLINED_STEREOGRAPHIC (an extension of scan-format.md, which lists pinhole and
// opencv only): configured by SplinedConfig, its 2 nx ny control values in `distortion`.
enum class CameraModelType { kPinhole, kOpenCV, kSplined };

// "pinhole" / "opencv" / "splined"; ParseCameraModelType returns nullopt for anything else.
std::string CameraModelTypeName(CameraModelType type);
std::optional<CameraModelType> ParseCameraModelType(const std::string& name);

// Options of iterative unprojection (inverting the distortion).
struct UndistortOptions {
  int max_iterations = 100;        // Gauss-Newton iterations, > 0
  double tolerance_px = 1e-10;     // stop when the reprojection error is below this (pixels), > 0
  // Check() returns "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// Configuration of mrcal's splined stereographic model (mrcal's lens model name
// LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=14_fov_x_deg=60). A normalised point
// xy = (x/z, y/z) maps to its stereographic projection u = xy 2 / (1 + sqrt(1 + |xy|^2))
// (|u| = 2 tan(theta / 2), theta the angle off the optical axis); a B-spline surface on an
// nx x ny grid of knots, regularly spaced in u, adds a correction: the "distorted
// normalised" point is u + spline(u), the pixel fx (u + spline(u)).x + cx, likewise y. The
// knots span fov_x_deg horizontally (u_x in +-2 tan(fov_x_deg / 4)) and ny is spaced as nx,
// so the spline's domain does not depend on fx, fy, cx, cy. mrcal stores the config as
// unsigned 16-bit integers: fov_x_deg is a whole number of degrees.
struct SplinedConfig {
  int order = 3;      // degree of the spline: 2 (quadratic, C1) or 3 (cubic, C2)
  int nx = 0;         // knots across, [4, 64]
  int ny = 0;         // knots down, [4, 64]
  int fov_x_deg = 0;  // horizontal field of view the knots span, degrees, [1, 179]
  bool operator==(const SplinedConfig&) const = default;
  // 2 nx ny: one (du_x, du_y) pair per knot, in mrcal's order.
  int NumControls() const { return 2 * nx * ny; }
  // "" when valid, else "splined.<field>: must be ..., got ...".
  std::string Check() const;
};

// An intrinsic camera model in OpenCV conventions: camera frame x right, y down, z
// forward (metres); pixel (0, 0) is the centre of the top-left pixel, so a 640-wide
// image has its centre at x = 319.5.
//
// Parameters, in this order (Params()/SetParams(), intrinsic Jacobians):
//   fx fy cx cy  [k1 k2 p1 p2 [k3 [k4 k5 k6]]]      (pinhole, opencv)
//   fx fy cx cy  control values of the spline       (splined: mrcal's intrinsics vector)
//
// Ranges (Check(), so rig.yaml and .cameramodel readers and writers all hold to them):
//   width, height  [1, 16384] px: beyond the largest sensors (150 MP is 14204 x 10652), and
//                  width * height stays far inside int
//   fx, fy         [1, 1e6] px: 1 px is a ~150° view on an 8 px image; 1e6 px a 1000 mm
//                  lens on 1 µm pixels. Below 1 a denormal (1e-320) would make 1/fx inf
//   cx             [-width, 2 width] px, cy [-height, 2 height] px: off-centre crops and
//                  shift lenses put it off the image, but not a whole image further
//   distortion     |k| <= 1e4 each: OpenCV's rational model on wide lenses reaches tens
//                  to hundreds (numerator and denominator nearly cancel), real k are < 1e3;
//                  splined controls are offsets in u (a few 0.01 on real lenses), same bound
//   splined        SplinedConfig's ranges, 2 nx ny controls
struct CameraModel {
  static constexpr int kMaxSidePx = 16384;
  static constexpr double kMinFocalPx = 1, kMaxFocalPx = 1e6;
  static constexpr double kMaxAbsDistortion = 1e4;

  int width = 0;   // pixels
  int height = 0;  // pixels
  CameraModelType type = CameraModelType::kPinhole;
  double fx = 0, fy = 0;  // focal lengths, pixels
  double cx = 0, cy = 0;  // principal point, pixels
  std::vector<double> distortion;  // empty for pinhole; 4, 5 or 8 values for opencv;
                                   // 2 nx ny spline controls for splined
  SplinedConfig splined;           // kSplined only; ignored (and not compared) otherwise

  // A pinhole camera with the given size and focal length, principal point at the centre.
  static CameraModel Pinhole(int width, int height, double fx, double fy);

  // "" when the model is valid, else one message naming the field, value and constraint
  // (e.g. "fx: must be in [1, 1e6] px, got 1e-320"). Checked: the ranges above (NaN and
  // inf are "must be finite"), distortion size (0 for pinhole; 4, 5 or 8 for opencv;
  // 2 nx ny for splined, after splined.Check()).
  std::string Check() const;

  int NumParams() const { return 4 + static_cast<int>(distortion.size()); }
  Eigen::VectorXd Params() const;
  void SetParams(const Eigen::VectorXd& params);  // asserts the size

  // Distortion on normalised coordinates (x/z, y/z): undistorted -> distorted.
  // Optional Jacobians: d(distorted)/d(undistorted) 2x2, and d(distorted)/d(k...) 2xN.
  // Splined: distorted = u + spline(u) (SplinedConfig), by mrcal_project, so the pixel is
  // exactly mrcal's; outside the knots' span mrcal extrapolates the outermost segment.
  Eigen::Vector2d Distort(const Eigen::Vector2d& xy_undistorted,
                          Eigen::Matrix2d* J_xy = nullptr,
                          Eigen::Matrix<double, 2, Eigen::Dynamic>* J_dist = nullptr) const;

  // Inverse of Distort: Newton from the distorted point, then a continuation from the centre
  // when that fails (each phase up to options.max_iterations). Only the physical preimage is
  // returned — the one on the monotone branch from the centre, proven so, never a solution
  // beyond a fold of the polynomial model. Returns nullopt when it does not converge to
  // options.tolerance_px (in pixels through fx, fy), e.g. far outside a strongly distorted
  // image. Callers must have checked the model with Check(). Splined: Newton from the
  // inverse stereographic projection of the distorted point, the same continuation, and a
  // preimage is accepted where the map is orientation-preserving (det J > 0); rays 90
  // degrees or more off axis (z <= 0) have no normalised point and give nullopt.
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& xy_distorted,
                                           const UndistortOptions& options = {}) const;

  // Projects a point in the camera frame (metres) to pixels. Not asserted: callers must cull
  // z <= 0, which gives meaningless or infinite pixels.
  // J_point: d(pixel)/d(point_in_camera), 2x3. J_params: d(pixel)/d(Params()), 2xNumParams.
  Eigen::Vector2d Project(const Eigen::Vector3d& point_in_camera,
                          Eigen::Matrix<double, 2, 3>* J_point = nullptr,
                          Eigen::Matrix<double, 2, Eigen::Dynamic>* J_params = nullptr) const;

  // Unprojects a pixel to the ray through it, as a point on the z = 1 plane of the camera
  // frame (multiply by depth z to get the point). nullopt when undistortion fails.
  std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& pixel,
                                           const UndistortOptions& options = {}) const;

  // True when the pixel lies inside the image: -0.5 <= x < width - 0.5, likewise y.
  bool IsInImage(const Eigen::Vector2d& pixel) const;

  // The same camera for an image scaled by `factor` (e.g. 0.5 for half resolution). Only
  // fx fy cx cy change: distortion (and the spline, which lives in normalised
  // stereographic coordinates) are independent of the pixel grid.
  CameraModel Scaled(double factor) const;

  // 3x3 matrix K. For splined, the pinhole approximation near the axis (u ~ xy there).
  Eigen::Matrix3d K() const;
};

bool operator==(const CameraModel& a, const CameraModel& b);

}  // namespace hw::core
