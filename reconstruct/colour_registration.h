#pragma once

// The colour stream registered to the depth pixels for ICP's photometric term (the grey level
// of each pixel of a pyramid level), and the rolling-shutter bands that integration also
// projects the colour with.

#include <functional>

#include <opencv2/core/mat.hpp>

#include "core/transform.h"
#include "reconstruct/camera_maps.h"

namespace hw::reconstruct {

// Bands of rows of a rolling-shutter colour image, each projected with one pose (registration
// and integration): at 100°/s and a 27 ms readout a band spans 0.08°, under a pixel at 640
// columns.
inline constexpr int kColourBands = 32;

// When band k of `bands` equal bands of rows of a rolling-shutter image `height` rows high
// was exposed relative to the frame's time (its middle row), s: the band's middle row is
// read readout_s · (row − (height − 1)/2) / height from it.
double BandOffsetS(int k, int bands, int height, double readout_s);

// The grey level (Rec. 601 luma in [0, 1], CV_32FC1, as DepthLevel::intensity) of each depth
// pixel from the colour frame: its point (depth_m, CV_32FC1 metres, of the pinhole
// depth_camera) moved by rgb_from_depth and projected into `rgb` (CV_8UC3 in R G B order,
// pinhole rgb_camera), nearest pixel. At a coarse pyramid level, whose pixels each cover
// samples_per_side × samples_per_side pixels of the full-resolution frame (2^level), it gives
// what registering the full frame and averaging down the pyramid gives, for a quarter of the
// projections per level: each coarse pixel's point is projected once and the colour image
// read at the samples_per_side² positions its finer pixels would have landed on (offsets of
// a fine pixel's footprint in the colour image, nearest pixel each; one outside the image
// counts black). 0 where there is no depth (non-finite counts as none) or every sample falls
// outside the colour image. Surfaces hidden from the colour camera by a nearer one take that
// one's colour (a few pixels at depth edges with a 2–5 cm baseline). num_threads: row bands
// run at once (0: hardware concurrency).
// A rolling-shutter colour camera (readout_s > 0, rig.yaml rolling_shutter_s.rgb): row v was
// exposed readout_s·(v − (H − 1)/2)/H after the frame's time, and rgb_from_depth_at(δ) gives
// the colour camera then (δ in s; rgb_from_depth is δ = 0): each point is projected with the
// pose of the rows it lands on (32 bands of rows), so that a rig turning during the readout
// does not shear the registered colour. Asserts the types and samples_per_side >= 1.
cv::Mat RegisterGrey(const cv::Mat& depth_m, const PinholeCamera& depth_camera, const cv::Mat& rgb,
                     const PinholeCamera& rgb_camera, int samples_per_side, const core::Rigid3d& rgb_from_depth,
                     int num_threads = 0, double readout_s = 0,
                     const std::function<core::Rigid3d(double)>& rgb_from_depth_at = nullptr);

}  // namespace hw::reconstruct
