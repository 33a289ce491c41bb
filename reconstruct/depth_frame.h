#pragma once

// Preparing a depth frame for tracking and fusion: lens distortion removed once (everything
// downstream is pinhole, camera_maps.h), edge noise removed, a bilateral filter (KinectFusion:
// smooth the sensor's noise, keep depth edges), and a pyramid of point and normal maps.

#include <array>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/camera.h"
#include "reconstruct/camera_maps.h"

namespace hw::reconstruct {

// Resamples images of a distorted camera into the pinhole camera with the same fx fy cx cy
// and size (PinholeCamera::Of). Built once per camera (the map costs an undistortion per
// pixel); applying it is a table lookup. For a pinhole camera it is the identity (no copy).
class Undistorter {
 public:
  Undistorter() = default;
  explicit Undistorter(const core::CameraModel& camera);
  const PinholeCamera& pinhole() const { return pinhole_; }
  bool is_identity() const { return identity_; }
  // Depth (CV_32FC1 metres, 0 = none): nearest-neighbour, so that no depth is interpolated
  // across an edge; z along the optical axis is unchanged by undistortion. Pinhole pixels
  // whose ray falls outside the distorted image are 0.
  cv::Mat UndistortDepth(const cv::Mat& depth_m) const;
  // Colour (CV_8UC3): bilinear. Outside the distorted image: black.
  cv::Mat UndistortColour(const cv::Mat& rgb) const;

 private:
  PinholeCamera pinhole_;
  bool identity_ = true;
  cv::Mat map_x_, map_y_;  // CV_32FC1: distorted-image pixel of each pinhole pixel
};

struct DepthFilterOptions {
  double min_depth_m = 0.3;  // nearer pixels are dropped, m, >= 0
  double max_depth_m = 4.0;  // farther pixels are dropped, m, > min_depth_m
  // Bilateral filter (KinectFusion's, on valid pixels only; an invalid centre stays invalid),
  // with symmetric support: a neighbour counts only with its mirror image through the centre
  // (valid and within 3 range sigmas), so a window cut by the image border, a hole or an edge
  // does not shift a slanted surface's depth (first-order bias, mm per pixel of gradient).
  // Range weight (1 − t²/32)^16 ≈ exp(−t²/2) of t = Δz / range sigma, 0 beyond 3 sigma.
  int bilateral_radius_px = 2;         // window half-size, px, in [0, 10] (0: no filter)
  double bilateral_sigma_px = 1.5;     // spatial sigma, px, > 0
  double bilateral_sigma_depth_m = 0.03;  // range sigma at 1 m, m, > 0; grows as z² (the
                                          // sensor's disparity noise)
  // Flying pixels at depth edges (a real sensor's mixed pixels): a pixel whose 4-neighbour
  // depth differs by more than this fraction of its own depth is dropped. In (0, 1]; 1 keeps all.
  double edge_jump_fraction = 0.05;
  int num_levels = 3;  // pyramid levels, each half the size of the previous, in [1, 5]
  // Normals from neighbours at most this far (fraction of depth) from the centre, in (0, 1].
  double normal_max_jump_fraction = 0.05;
  // Levels finer than this get no point and normal maps (DepthLevel::map stays empty): the
  // pipeline does not track on them when it raycasts the model at a coarser level, and their
  // normals are a fifth of the pyramid's cost. In [0, num_levels).
  int first_map_level = 0;
  int num_threads = 0;  // row bands run at once, >= 0 (0: hardware concurrency)

  std::string Check() const;
};

// One level of a depth pyramid, camera frame.
struct DepthLevel {
  PinholeCamera camera;
  cv::Mat depth_m;  // CV_32FC1, filtered, 0 = none
  PointMap map;     // points and normals in the camera frame
  // Grey level of each pixel (CV_32FC1, in [0, 1]: Rec. 601 luma of the registered colour;
  // each level the 2×2 mean of the one above), for ICP's photometric term. Empty when the
  // pyramid was built without colour.
  cv::Mat intensity;
};

// A prepared depth frame: level 0 is full resolution.
struct DepthPyramid {
  cv::Mat raw_depth_m;  // undistorted, range-limited, unfiltered (what TSDF fusion takes)
  std::vector<DepthLevel> levels;
};

// Builds the pyramid of an undistorted depth image (CV_32FC1 metres) seen by `camera`:
// range limits and edge cleaning on raw_depth_m, the bilateral filter on level 0, each next
// level a 2×2 block mean of the one above over pixels within 3 sigma of the block's first
// valid pixel (KinectFusion's pyramid: it never averages across an edge), points by
// unprojection and normals from the cross product of central differences. Optional `rgb`
// (CV_8UC3, R G B order as PointMap::colours, the same size as the depth and registered to
// it: pixel (u, v) is the colour of depth pixel (u, v)) fills DepthLevel::intensity. Asserts
// the image types and sizes match the camera.
DepthPyramid BuildDepthPyramid(const cv::Mat& depth_m, const PinholeCamera& camera,
                               const DepthFilterOptions& options, const cv::Mat& rgb = cv::Mat());

// Sets level first_level's intensity to `grey` (CV_32FC1 in [0, 1], that level's size: the
// colour registered to its pixels, RegisterGrey), each coarser level's to the 2×2 means of
// the one above, and empties the finer levels' (ICP's photometric term reads only the levels
// it iterates on). num_threads as DepthFilterOptions::num_threads. Asserts the level, size
// and type.
void SetIntensity(DepthPyramid& pyramid, const cv::Mat& grey, int first_level, int num_threads);

}  // namespace hw::reconstruct
