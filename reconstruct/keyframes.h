#pragma once

// Keyframes for relocalising after a long loss of tracking: a small blurred image of every
// place the rig has been (Klein & Murray 2008's "small blurry image", as ElasticFusion and
// BundleFusion use it), so that a frame lost far from where tracking last was — a lens
// covered while the operator walked back, a burst of frames out of range — can be aligned
// again once it sees a place the model holds. The relocalisation tracks nothing by itself:
// the most alike keyframes' poses are the starts of ICP against the model
// (Reconstruction::Track), and ICP's gates decide.

#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/transform.h"

namespace hw::reconstruct {

struct KeyframeOptions {
  // Keyframes tried per lost frame, best match first, when the relocalisation from the last
  // pose and the extrapolated one has failed or the loss has lasted over 0.5 s; 0 turns
  // keyframes off. In [0, 10]. Each costs a raycast of the model at its pose (once per loss),
  // an ICP run, and up to 3 raycasts and ICP runs refining a converged one.
  int candidates = 3;
  // A fused frame tracked normally becomes a keyframe when it is farther than this from
  // every keyframe, m, > 0: 0.1 m is a tenth of a view at 1 m, within ICP's widened
  // association gate at its coarsest level (2 × 5 cm on each side of a keyframe's half
  // spacing).
  double min_distance_m = 0.1;
  // ... or turned by more than this from every keyframe, degrees, > 0 (10°: a sixth of a
  // depth camera's 58° field).
  double min_angle_deg = 10;
  // Width of the descriptor, px, in [8, 160]; its height keeps the image's aspect. 40 × 30
  // is the small blurry image's size: coarse enough to be insensitive to a few centimetres
  // of viewpoint change, fine enough to tell one part of a room from another.
  int descriptor_width = 40;
  // A candidate is tried only if its descriptor distance (KeyframeDistance, in [0, 1]) is at
  // most this, in (0, 1]: a frame that looks like nothing in the map is not forced onto it.
  double max_distance = 0.5;

  bool enabled() const { return candidates > 0; }
  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// A frame reduced to a small blurred image: depth in metres (0 = none) and, when the frame
// had colour, its grey level normalised to zero mean and unit deviation over the valid
// pixels (insensitive to exposure changes). Row-major, width × height.
struct KeyframeDescriptor {
  int width = 0, height = 0;
  std::vector<float> depth_m;
  std::vector<float> grey;  // empty without colour
};

// The descriptor of a depth image (CV_32FC1 metres, 0 = none) and optional grey image
// (CV_32FC1 in [0, 1] of the same size, or empty): block means over valid pixels down to
// `width` columns (the image's own width when smaller), then a Gaussian blur of σ 1 px
// normalised by the valid pixels around (holes neither spread nor pull depth to 0); a
// descriptor pixel is valid when an eighth of its kernel-weighted neighbourhood has depth.
// Asserts the types and sizes.
KeyframeDescriptor DescribeFrame(const cv::Mat& depth_m, const cv::Mat& grey, int width);

// How unlike two descriptors of the same size are, in [0, 1]: the mean over pixels with
// depth in both of (min(|Δdepth| / 0.1 m, 1)² + min(|Δgrey| / 1 σ, 1)²) / 2 (the depth term
// alone when either lacks grey), pixels with depth in only one counting 0.5 each at half
// weight; 1 when fewer than a quarter of the pixels have depth in both. Asserts equal sizes.
double KeyframeDistance(const KeyframeDescriptor& a, const KeyframeDescriptor& b);

// The keyframes of one reconstruction: poses (world_from_depth) and descriptors.
class KeyframeDatabase {
 public:
  explicit KeyframeDatabase(const KeyframeOptions& options) : options_(options) {}

  // Whether a frame at this pose would be a new keyframe: farther than min_distance_m, or
  // turned more than min_angle_deg, from every keyframe.
  bool IsNewPlace(const core::Rigid3d& world_from_depth) const;
  // Whether two poses are within min_distance_m and min_angle_deg of each other (one place).
  bool SamePlace(const core::Rigid3d& a, const core::Rigid3d& b) const;
  void Add(const core::Rigid3d& world_from_depth, KeyframeDescriptor descriptor);

  // Indices of at most `count` keyframes whose distance to `query` is at most
  // options.max_distance, most alike first (ties: the older first).
  std::vector<int> MostAlike(const KeyframeDescriptor& query, int count) const;

  int size() const { return static_cast<int>(poses_.size()); }
  const core::Rigid3d& pose(int i) const { return poses_[i]; }
  const KeyframeDescriptor& descriptor(int i) const { return descriptors_[i]; }

 private:
  KeyframeOptions options_;
  std::vector<core::Rigid3d> poses_;
  std::vector<KeyframeDescriptor> descriptors_;
};

}  // namespace hw::reconstruct
