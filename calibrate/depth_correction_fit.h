#pragma once

// The depth camera's systematic error (core/depth_correction.h: an inverse-depth offset
// field δ(x, y), 1/m) from a recording of flat surfaces — a wall seen from several distances
// and angles, as Herrera's and CLAMS's tools calibrate Kinect-class sensors.
//
// Why it is linear: a plane n·X = 1 in the camera frame has inverse depth
// w = 1/z = n·(x, y, 1) at the ray (x, y) = (X/Z, Y/Z), linear in x and y. A sensor reading
// w_measured = w_true + δ(x, y) therefore gives, for every pixel i of frame p,
//   w_i = a_p·x_i + b_p·y_i + c_p + Σ_k B_k(x_i, y_i)·θ_k + noise,
// with θ the field's grid nodes and B_k their bilinear weights: one linear least-squares
// problem. Each frame's plane (a, b, c) is eliminated (Schur complement) so the reduced
// system has only the nodes. Noise in w is near constant for structured light (disparity
// quantisation and correlator noise live in disparity), so pixels are weighted per frame by
// that frame's robust σ.
//
// What it cannot see: an affine field δ = α + β·x + γ·y maps every plane to a plane, so the
// data cannot tell it from the planes' own parameters. The estimate is the field with no
// affine part over its nodes (Σ θ_k·(1, x_k, y_k) = 0); the affine part left is a depth
// scale (α: 1/z shifted by a constant) and a tilt, which frame-to-model tracking tolerates
// (bench: 2.23 mm ATE with the whole true field, 2.42 mm without its affine part, 11.0 mm
// uncorrected). Metric depth scale needs a target of known size (not done here).
//
// Pixels off the plane (the floor, furniture, people, edges) are rejected: a RANSAC plane
// per frame in (x, y, w) first, then pixels within inlier_sigmas robust σ of plane + field
// at each refit.

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/camera.h"
#include "core/depth_correction.h"
#include "core/scan.h"

namespace hw::calibrate {

struct DepthCorrectionOptions {
  // Grid nodes across and down the image. A Kinect's field has its shortest wavelengths
  // near 150 native px, so 17 × 13 nodes (one per 40 px at 640 × 480) follow it.
  int nx = 17;  // [2, 256]
  int ny = 13;  // [2, 256]
  int pixel_step = 4;        // every pixel_step-th pixel along rows and columns, px, [1, 64]
  double min_depth_m = 0.4;  // nearer pixels are not used, m, > 0
  double max_depth_m = 5.0;  // farther pixels are not used, m, > min_depth_m
  // Band around a RANSAC plane hypothesis, in inverse depth, 1/m: wide enough for the field
  // itself (a Kinect's: under 0.01 /m) and the noise, narrow enough to part a wall from
  // furniture 0.3 m before it at 3.5 m (0.026 /m). 0.02 /m is 8 cm at 2 m.
  double ransac_threshold_per_m = 0.02;  // (0, 1]
  int ransac_iterations = 200;           // hypotheses per frame, [10, 100000]
  // After the first fit, a pixel is used when within this many robust σ (its frame's) of its
  // plane plus the field: 4σ keeps 99.99 % of Gaussian noise and drops what is not the plane.
  double inlier_sigmas = 4;  // > 0
  int iterations = 4;        // gate-and-solve rounds after the RANSAC, [1, 20]
  // A frame is used only if its plane holds at least this fraction of its valid pixels and
  // at least min_plane_samples samples: a frame mostly of clutter says little and risks a
  // plane that is not one.
  double min_plane_fraction = 0.4;  // [0, 1]
  int min_plane_samples = 300;      // >= 3
  // Prior σ of the field's second difference between neighbouring nodes, 1/m: it only fills
  // nodes no plane reached (a Kinect's field changes by < 0.003 /m between nodes, and a
  // node holds hundreds of samples of σ ≈ 0.002 /m), > 0.
  double smoothness_sigma_per_m = 0.01;
  int min_frames = 6;   // fewer usable frames is an error, [2, 100000]
  int max_frames = 0;   // frames used at most, evenly spread; 0 = all, >= 0
  int num_threads = 0;  // frame reading and plane search; 0 = hardware concurrency, >= 0

  // "" when valid, else a message naming the field, its value and the constraint.
  std::string Check() const;
};

// The samples of one frame: ray coordinates and measured inverse depth.
struct DepthFrameSamples {
  int frame = -1;          // depth frame index in the scan
  double timestamp_s = 0;  // depth clock
  std::vector<double> x, y;  // normalised ray coordinates X/Z, Y/Z (undistorted)
  std::vector<double> w;     // 1/z measured, 1/m
  int valid = 0;             // pixels with depth in range (== x.size())
};

struct DepthPlaneFit {
  int frame = -1;
  double timestamp_s = 0;
  bool used = false;
  std::string skipped_because;  // when !used
  int samples = 0;              // valid samples of the frame
  int inliers = 0;              // samples on the plane at the last round
  double distance_m = 0;        // plane depth on the optical axis, m
  double tilt_deg = 0;          // plane normal vs optical axis, degrees
  double sigma_per_m = 0;       // robust σ of the inverse-depth residual, 1/m
  double rms_before_mm = 0;     // inliers' depth residual to a plane fitted alone, mm
  double rms_after_mm = 0;      // ... to the plane with the field removed, mm
};

struct DepthCorrectionResult {
  core::DepthCorrection correction;  // no affine part over its nodes (see above)
  // 1σ of each node, 1/m: the larger of the cluster sandwich over frames (a frame's pixels
  // share correlated noise, quantisation steps and their plane) and the independent-pixel
  // covariance, affine directions projected out of both.
  std::vector<double> sigma_per_m;
  Eigen::MatrixXd covariance;  // of the nodes, (1/m)²: the cluster sandwich
  std::vector<int> node_samples;     // samples weighing on each node (bilinear weight ≥ 0.25)
  std::vector<DepthPlaneFit> frames;
  int frames_used = 0;
  int samples_used = 0;
  double rms_before_mm = 0;  // all inliers: plane only
  double rms_after_mm = 0;   // all inliers: plane and field
  double distance_min_m = 0, distance_max_m = 0;  // over the frames used
  double field_rms_mm_at_3m = 0;   // size of the field, as depth error at 3 m (z²·δ)
  double max_sigma_mm_at_3m = 0;   // largest node σ as depth at 3 m, over nodes with samples
  double coverage = 0;             // fraction of nodes with ≥ 50 samples
  std::vector<std::string> warnings;
};

// Fits the field on given samples (grid: nodes and ranges of `grid`, its offsets ignored).
// Throws std::invalid_argument when fewer than options.min_frames frames hold a usable
// plane (the message says how many and why the others were skipped). Asserts
// options.Check() is empty and the grid's Check().
DepthCorrectionResult FitDepthCorrection(const std::vector<DepthFrameSamples>& frames,
                                         const core::DepthCorrection& grid,
                                         const DepthCorrectionOptions& options);

// The samples of depth frame `index` of `scan` (every pixel_step-th pixel in range, through
// the undistorted rays of `depth_camera`). Throws InputError for an unreadable frame.
DepthFrameSamples SampleDepthFrame(const core::Scan& scan, int index,
                                   const core::CameraModel& depth_camera,
                                   const DepthCorrectionOptions& options);

// Reads the scan's depth frames (missing ones skipped) and fits. Throws core::InputError
// naming the scan when it has no depth frame or too few frames hold a plane; progress is
// called with (frames read, frames to read).
DepthCorrectionResult CalibrateDepthCorrection(
    const core::Scan& scan, const core::CameraModel& depth_camera,
    const DepthCorrectionOptions& options,
    const std::function<void(int, int)>& progress = nullptr);

// The affine part of node values (least squares over the nodes) removed: how estimates and
// truth are compared. Asserts values.size() == nx·ny.
std::vector<double> WithoutAffinePart(const core::DepthCorrection& grid,
                                      const std::vector<double>& values);

// An image of node values over the camera's image (BGR, the camera's size, × 2 below 640 px
// wide): each pixel the bilinear value at its ray, coloured on a diverging blue–white–red
// scale from −max_abs to +max_abs (signed) or turbo from 0 to max_abs (!signed), with the
// title and the scale's end printed. Asserts values.size() == nx·ny of grid.
cv::Mat DrawNodeField(const core::DepthCorrection& grid, const std::vector<double>& values,
                      const core::CameraModel& camera, bool is_signed, double max_abs,
                      const std::string& title);

}  // namespace hw::calibrate
