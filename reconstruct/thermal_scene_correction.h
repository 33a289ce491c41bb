#pragma once

// Scene-based correction of a thermal camera's read-out offsets against the fused model.
//
// An uncooled microbolometer's reading carries offsets no fusion rule averages out: one
// common to the whole frame that drifts with the camera body's temperature and jumps at each
// flat-field (shutter) event, and one per pixel (fixed-pattern and column noise, which grow
// between events; vignetting left by the camera's calibration is one too, near room
// temperature). Scene-based non-uniformity correction (Hardie et al. 2000, registration-based
// NUC) estimates them from the scene itself: the same surface seen by different pixels, or at
// different times, must read the same. A 3D model makes that exact for a moving camera: every
// ray already lands on a surface region whose temperature the earlier frames estimated, so
// its residual against that estimate is the pixel's offset plus this frame's, plus noise.
//
// The frame's offset is measured on pairs: each ray and its region's latest view from before
// the event differ by the offset's jump (plus the offset removed from that view), and, when
// the two pixels are near, by nothing the optics do at them (vignetting, narcissus, fixed
// pattern); the robust median of the nearest pairs that suffice is the frame's offset
// relative to the first frames'. Every such measurement stands on views that earlier
// corrections made, so any bias of it is carried on to every later frame: measured in every
// frame, residual vignetting wandered the offsets by 1.7–3.8 K over a 31 s fixture walk
// (pairs up to 8–16 px apart; README, Temperature). It is therefore measured once per
// shutter event (ffc.txt, or a frozen frame: the closure), on the first frame fused within
// event_window_s after it that has enough pairs, and held in between: a camera's slow drift
// between events (tenths of a kelvin a minute) is left alone. The pixel offsets are measured
// against the regions' means: what each pixel's residual keeps beyond the frame's median
// moves that pixel's estimate a step (an exponential mean over frames), re-centred so that
// the pixel estimates carry no common part. The model stays anchored to the first frames'
// level: a constant offset is invisible to any scene-based method (the camera's absolute
// calibration is the bench's job).
//
// Units: kelvin of apparent temperature (what the camera reads).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

namespace hw::reconstruct {

struct SceneCorrectionOptions {
  // Estimate and remove each frame's common offset where it jumps (shutter events).
  bool frame_offset = true;
  // Estimate and remove each pixel's own offset (fixed-pattern and column noise, vignetting
  // left over).
  bool pixel_offset = true;
  // A region is a reference once it has this many views, >= 1. 4: its mean then no longer
  // follows one frame, while a 30 Hz sweep still has references a fraction of a second
  // after a surface appears.
  int min_reference_views = 4;
  // ... and the spread (std) of its views is at most this, K, > 0: regions on a temperature
  // edge (a hot spot's border, a misregistered silhouette) read differently with every
  // sub-pixel shift and would teach the pixels the scene. 0.5 K: several times NETD plus the
  // offsets being estimated.
  double max_reference_std_k = 0.5;
  // The frame's offset is measured once per shutter event, on the first frame within this
  // time after it with enough pairs, s, >= 0, and held elsewhere; ThermalFusion counts it from
  // when the frames after the event are fused again (its confidence's ffc_settle_s +
  // ffc_ramp_s later). 1 s: the first frame fused after an event usually has thousands of
  // pairs; the rest of the window covers a camera looking at new surface.
  double event_window_s = 1.0;
  // ... on pairs: a ray and its region's latest view from before the event, taken by pixels
  // at most this far apart in x and in y, px, [0, 10000]. The nearest that suffice are used
  // (the smallest shift within which min_reference_rays pairs lie): near-same pixels see the
  // same optics (vignetting, narcissus, fixed pattern), so their difference is the jump alone.
  // Far pairs are not: on a 3.5 s fixture sweep (c5 drops the first half second after the
  // event, in which the camera moved on) the first pairs that sufficed were 60 px apart and
  // measured the jump as +0.56 K with the fixture's vignetting left in, −0.14 K with it
  // undone. 16: measured in every frame of the 31 s walk with the vignetting left in, pairs
  // up to 0/2/4/8/16 px apart moved the offsets by up to 0.03/0.17/0.38/1.7/3.8 K over ~260
  // measurements, about a hundredth each; once per event that is harmless. An event with
  // too few pairs within it is not measured (the offset is kept).
  int max_pair_shift_px = 16;
  // Rays further than this from their reference are not used, K, > 0 (reflections, blur
  // halos, a surface that changed). 1.5 K: above the offsets a camera drifts by between two
  // shutter events (the FLIR/Seek cores' 0.3–1 K), far below a reflection of a hot object.
  double max_residual_k = 1.5;
  // A frame's offset needs at least this many reference rays (its median is then good to
  // NETD/√n·1.25, 0.003 K at 0.05 K NETD); with fewer the last frame's estimate is kept. >= 1.
  int min_reference_rays = 500;
  // Each frame moves a pixel's estimate by this fraction of its residual: an exponential
  // mean over ~1/rate of the frames that saw a reference there (0.05: 20 frames, 0.7 s at
  // 30 Hz; NETD then leaves 0.05·√(0.05/2) ≈ 0.01 K in the estimate). (0, 1].
  double pixel_rate = 0.05;
  // |pixel estimate| is capped at this, K, > 0: a pixel whose residual keeps beyond it is
  // not an offset (a dead pixel, a stuck reflection) and is left as the camera gives it.
  double max_pixel_offset_k = 2.0;

  std::string Check() const;  // names the field, its value and the constraint
};

// One ray's residual against its reference: its apparent temperature (after the pixel
// correction) less what the reference region predicts for it, K; for a pair, how far apart
// (Chebyshev, px) the two pixels were.
struct SceneResidual {
  int32_t pixel;     // y · width + x
  float residual_k;
  int32_t shift_px = 0;
};

// What one frame's update found.
struct SceneCorrectionUpdate {
  int pair_rays = 0;           // pairs used, within max_residual_k (frame offset)
  int pair_shift_px = -1;      // the largest shift among the pairs used, px; -1: not measured
  int reference_rays = 0;      // residuals within max_residual_k (pixel offsets)
  bool frame_estimated = false;  // enough of them for this frame's own offset
  double frame_offset_k = 0;   // offset removed from this frame (K; the last one when not estimated)
  double pixel_offset_rms_k = 0;  // RMS of the pixel estimates after the update, K
};

// The estimates of one camera (not thread-safe; one per ThermalFusion).
class SceneCorrection {
 public:
  // Asserts options.Check() is empty, width and height > 0.
  SceneCorrection(const SceneCorrectionOptions& options, int width, int height);

  const SceneCorrectionOptions& options() const { return options_; }
  bool enabled() const { return options_.frame_offset || options_.pixel_offset; }

  // apparent_c (CV_32FC1, the camera's size) less each pixel's estimated offset; the input
  // itself when pixel_offset is off. Asserts the type and size.
  cv::Mat CorrectPixels(const cv::Mat& apparent_c) const;

  // When `after_event` (the frame lies within event_window_s of a shutter event), estimates
  // this frame's offset from the nearest of `pairs` that suffice (each ray's apparent
  // temperature less its region's latest view from before the event, with the two pixels'
  // shift: the change of the camera's offset since that view plus the offset removed from
  // it); otherwise keeps the last one.
  // Updates the pixel estimates from what each of `residuals` (apparent temperature less the
  // region's mean) keeps beyond their median. Both computed on the image CorrectPixels
  // returned, without the frame offset. Reorders both. The returned frame offset is to be
  // subtracted from every ray of the frame.
  SceneCorrectionUpdate Update(std::vector<SceneResidual>& pairs, std::vector<SceneResidual>& residuals,
                               bool after_event);

  // Current pixel estimates, K, CV_32FC1 (zeros until learnt).
  const cv::Mat& pixel_offset_k() const { return pixel_offset_k_; }
  double frame_offset_k() const { return frame_offset_k_; }

 private:
  SceneCorrectionOptions options_;
  cv::Mat pixel_offset_k_;
  double frame_offset_k_ = 0;
  std::vector<float> scratch_;

  std::pair<float, size_t> KeptMedian(std::vector<SceneResidual>& residuals);
};

}  // namespace hw::reconstruct
