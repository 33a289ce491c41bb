#pragma once

// The depth camera's systematic error as an inverse-depth offset field (heatwave extension
// of rig.yaml, key `depth_correction`). A structured-light sensor measures disparity
// d = f·b/z; its per-device error is a smooth field Δd over the image (Smisek et al. 2011,
// Herrera et al. 2012), the same at every distance, so in inverse depth it is an additive
// field δ(x, y) = Δd / (f·b), 1/m, over the ray's normalised coordinates (x, y) = (X/Z, Y/Z)
// (undistorted, so it does not depend on the image size):
//   1/z_true = 1/z_measured − δ(x, y),   z_true = z_measured / (1 − z_measured·δ(x, y)).
// A bowl of 0.2 px of disparity at f·b = 570 px · 0.075 m is δ = −0.0047 /m at the corners:
// 19 mm at 2 m, 57 mm at 3.5 m. δ is stored at the nodes of a regular nx × ny grid over
// [x_range] × [y_range] and interpolated bilinearly (clamped beyond the grid's border).

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/camera.h"

namespace hw::core {

struct DepthCorrection {
  static constexpr int kMinNodes = 2, kMaxNodes = 256;
  static constexpr double kMaxAbsRange = 10;        // normalised coordinates (84° off axis)
  static constexpr double kMaxAbsOffsetPerM = 1.0;  // 1/m: 1 m reads 0.5 m or infinite

  int nx = 0;  // nodes along x, [2, 256]
  int ny = 0;  // nodes along y, [2, 256]
  std::array<double, 2> x_range = {0, 0};  // x/z of the first and last column of nodes, lo < hi
  std::array<double, 2> y_range = {0, 0};  // y/z of the first and last row of nodes, lo < hi
  std::vector<double> offset_per_m;        // δ at node (ix, iy) = [iy·nx + ix], 1/m
  // The affine part (a, c_x, c_y; 1/m) of the field that was measured by what sees it — the
  // plate of `calibrate extrinsics`, folded in with AddAffine — and is included in
  // offset_per_m; a term not measured is 0. Absent: the field's affine part is not measured
  // (a wall-only calibration, whose fit has none). rig.yaml key `plate_affine_per_m`.
  // `reconstruct` reads a measured scale (a ≠ 0) as depth free of systematic error.
  std::optional<std::array<double, 3>> plate_affine_per_m;
  bool ScaleMeasured() const { return plate_affine_per_m && (*plate_affine_per_m)[0] != 0; }

  // "" when valid (node counts and ranges as above, |range| <= 10, nx·ny finite offsets of
  // |δ| <= 1 /m), else one message naming the field, value and constraint.
  std::string Check() const;

  // The four nodes around (x, y) (indices into offset_per_m) and their bilinear weights,
  // the border nodes' beyond the grid: δ(x, y) = Σ weight[k]·offset_per_m[node[k]]. Needs
  // only nx, ny and the ranges (a fit uses it on a grid whose offsets it is solving for).
  struct Stencil {
    int node[4];
    double weight[4];
  };
  Stencil StencilAt(double x, double y) const;
  // δ at normalised coordinates (x, y), 1/m: bilinear between the four nodes around it,
  // the border node's value beyond the grid.
  double OffsetAt(double x, double y) const;
  // Normalised coordinates (x, y) of node (ix, iy): the grid spans x_range × y_range.
  std::array<double, 2> NodePosition(int ix, int iy) const {
    return {x_range[0] + (x_range[1] - x_range[0]) * ix / (nx - 1),
            y_range[0] + (y_range[1] - y_range[0]) * iy / (ny - 1)};
  }
  // RMS of offset_per_m over the nodes, 1/m (0 for none): the field's size.
  double RmsPerM() const;
  // Adds the affine field a + c_x·x + c_y·y (1/m; x, y normalised coordinates) to every
  // node: exactly that field added to OffsetAt inside the grid (bilinear interpolation
  // reproduces an affine function). The part of a depth error no wall shows, measured
  // elsewhere (calibrate extrinsics' plate of known size), folded into the field.
  void AddAffine(double a_per_m, double c_x_per_m, double c_y_per_m);
  // The corrected depth z / (1 − z·δ(x, y)), m; 0 for z <= 0 (no measurement) and for a
  // correction that would send the point to or beyond infinity (1 − z·δ <= 0.05).
  double Correct(double z_m, double x, double y) const;

  // A grid of nx × ny zero offsets spanning the rays of `camera`'s image (its four borders'
  // extreme normalised coordinates, with half a pixel's margin). Asserts nx, ny in range and
  // that the corners of the image undistort.
  static DepthCorrection ZeroOver(const CameraModel& camera, int nx, int ny);
};

// δ at every pixel of `camera` (CV_32FC1, 1/m), at the pixel centre's undistorted ray;
// pixels whose ray does not undistort get 0. Build once per camera, apply per frame.
cv::Mat DepthOffsetMap(const DepthCorrection& correction, const CameraModel& camera);

// Corrects a depth image in place (CV_32FC1 metres along the optical axis, 0 = none) with
// a map from DepthOffsetMap of the same size: z := z / (1 − z·δ); 0, NaN and inf stay; a
// pixel whose correction diverges (1 − z·δ <= 0.05) becomes 0. Asserts types and sizes.
void CorrectDepth(const cv::Mat& offset_map_per_m, cv::Mat* depth_m);

}  // namespace hw::core
