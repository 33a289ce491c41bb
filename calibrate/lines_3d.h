#pragma once

// 3D line segments of one depth frame, for the targetless thermal↔depth extrinsics
// (calibrate/extrinsics_targetless.h, after Moghadam, Bosse & Zlot, ICRA 2013).
//
// Method
//   1. Points: every depth pixel through the depth camera's model (distortion included,
//      DepthRays), z in [min_depth_m, max_depth_m].
//   2. Normals: cross product of central differences normal_step_px apart, where the four
//      neighbours are on the same surface (no depth jump).
//   3. Planes: region growing from the pixels with the flattest neighbourhood, a neighbour
//      joining when its normal is within plane_normal_deg of the region's plane and its point
//      within the plane distance tolerance; regions of at least min_plane_fraction of the
//      image are refitted (PCA) and then dilated over the pixels without a valid normal
//      (the band of normal_step_px along folds and jumps) that lie on their plane, so that
//      a region reaches the real fold or edge.
//   4. Boundaries: walking from a region's border pixel outwards (up to a few pixels,
//      skipping holes): another plane reached without a depth jump → a fold pixel of that
//      pair; a farther surface (a jump of more than occlusion_jump_ratio) → an occlusion
//      pixel: the region is the FOREGROUND there, so the edge is real (the background side
//      of a jump is only where the foreground stops hiding it); a nearer surface → nothing.
//   5. Fold lines: the intersection line of the two planes (normals at least
//      min_fold_angle_deg apart), limited to the runs of its fold pixels' projections
//      (split at gaps of max_gap_px).
//   6. Occlusion lines: sequential RANSAC of 2D lines on the region's occlusion pixels
//      (moved half a pixel towards the background: the edge is between the two pixels),
//      split at gaps, each run's end pixels back-projected onto the region's plane.
// Kinect holes are skipped (never an edge by themselves); edge noise and flying pixels
// fall outside the plane tolerance and do not join a region.

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/camera.h"

namespace hw::calibrate {

enum class LineKind { kFold, kOcclusion };

// A 3D line segment, depth camera frame, metres.
struct Segment3d {
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  LineKind kind = LineKind::kFold;
  int support_px = 0;  // depth pixels the segment was fitted to
  // Occlusion lines: the 3D displacement (m, depth frame, in the foreground plane) of moving
  // the edge one depth pixel towards the background, at the segment's midpoint (scale it
  // by z / z_mid elsewhere). Lets the alignment estimate how far a sensor's depth edges sit
  // from the true outline (structured light "fattens" the foreground by a pixel or two).
  // Zero for folds.
  Eigen::Vector3d edge_shift_per_px = Eigen::Vector3d::Zero();
  double Length() const { return (b - a).norm(); }
};

struct DepthLineOptions {
  double min_depth_m = 0.3;           // ignore nearer pixels, m, > 0
  double max_depth_m = 6.0;           // ignore farther pixels, m, > min_depth_m
  int normal_step_px = 0;             // normal's difference step, px, >= 0; 0: width / 80, at least 2
  double plane_normal_deg = 15;       // region growing: normal within this of the plane's, deg, (0, 90)
  // Plane distance tolerance: plane_distance_m + plane_distance_per_m × z² (structured-light
  // noise grows with z²), m, > 0 and >= 0.
  double plane_distance_m = 0.008;
  double plane_distance_per_m = 0.004;  // m per m², >= 0
  double min_plane_fraction = 0.004;    // smallest plane, fraction of the image's pixels, (0, 1)
  double min_fold_angle_deg = 20;       // planes meeting at a fold: normals at least this apart, deg, (0, 90)
  double occlusion_jump_ratio = 0.06;   // a jump: the farther depth > z (1 + ratio) + 0.02 m, > 0
  double line_inlier_px = 1.0;          // RANSAC inlier distance of occlusion pixels, px, > 0
  double min_segment_fraction = 0.05;   // shortest segment in the image, fraction of the diagonal, (0, 1)
  double max_gap_px = 0;                // split runs at gaps larger than this, px, >= 0; 0: 2 normal steps + 2
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// Per-pixel rays of the depth camera: CV_32FC2 of the normalised point (x/z, y/z) of each
// pixel (undistorted with the camera's model), NaN where the model cannot unproject it.
cv::Mat DepthRays(const core::CameraModel& depth_camera);

// Diagnostics of one extraction.
struct DepthLineStats {
  int planes = 0;
  int fold_lines = 0;
  int occlusion_lines = 0;
};

// The 3D segments of a depth frame (CV_32FC1 metres, 0 = no measurement; the size of
// `rays`, which DepthRays made for the same camera). `focal_px` (the depth camera's mean
// focal length) converts pixel gaps to metres. Asserts options.Check() is empty and the
// sizes match. Never throws; a frame without planes gives no segments.
std::vector<Segment3d> ExtractDepthLines(const cv::Mat& depth_m, const cv::Mat& rays,
                                         double focal_px, const DepthLineOptions& options,
                                         DepthLineStats* stats = nullptr);

}  // namespace hw::calibrate
