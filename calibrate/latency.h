#pragma once

// Stream latency calibration (issue 13, "temporal calibration"): the clock offsets of the
// colour and thermal streams against the depth stream, from a recording of one object
// moving in front of a still background (a hand waving a hot, dark object; the fixtures'
// "latency" session: a hot dark disc swinging in front of a light wall).
//
// Method
//   1. Per stream, per frame, the moving blob's image centroid: a per-pixel median
//      background over (a subsample of) the sequence; the foreground is |frame − background|
//      above threshold_sigmas × the frame's robust noise (MAD); the largest connected
//      component (or the one continuing the track) not touching the border; its centroid
//      weighted by the contrast over the component dilated by a few pixels, so that a blur
//      tail below the threshold still counts and the centroid is that of the (linear)
//      blurred image. Contrast is linear in the light each pixel integrates: depth in
//      metres (holes, 0, ignored), colour as linear luma (sRGB decoded), thermal as band
//      radiance (apparent °C from the rig's raw_scale/raw_offset, then Planck over the
//      rig's spectral band). Frames without a good blob are missing (NaN), never zero.
//   2. One signal per stream: the centroid undistorted with the rig's camera, turned into
//      the depth camera's orientation (nominal extrinsic rotation) and projected on the
//      principal axis of the depth stream's motion — the same axis for every stream, so
//      the signs agree — then normalised (zero mean, unit variance).
//   3. Per pair (reference a, other b): coarse offset = the peak of the Pearson correlation
//      of s_a(t) and s_b(t − offset) (b linearly interpolated on its own stamps, never
//      across a gap) on a grid over ±max_offset_s; fine offset = the minimum over offset of
//      the residual of the fit s_a(t) ≈ P(s_b(t − offset)), P an affine map (plus
//      quadratic and cubic terms, LatencyOptions::map_degree; b interpolated by cubic Hermite), by Brent's method to 1e-6 s. Uncertainty: Gauss-Newton σ from the
//      residual variance and the fit's Jacobian (offset and P's coefficients), inflated by √(N / N_eff)
//      for correlated residuals (N_eff from their autocorrelation); and a moving-block
//      bootstrap over the reference samples. sigma_s is the larger.
//
// Sign convention (scan-format.md): t_depth_clock = t_stream + time_offset_s; a pair's
// offset_s is t_reference_clock = t_other_clock + offset_s, so the depth-referenced pairs
// give the streams' time_offset_s directly.
//
// Bolometer lag. A microbolometer integrates the scene through a first-order lag of time
// constant τ (~10 ms), so a thermal frame shows the scene as it was on average τ before the
// frame was read out; its blob centroid follows the motion τ late. What is estimated and
// written is the EFFECTIVE offset: the one that puts a thermal image at the time of the
// scene it shows (the centroid of its lag kernel), which is what thermal fusion needs to
// pick the pose a thermal image was seen from. It includes the lag: a camera that stamps
// frames at readout on the depth clock has time_offset_s = −τ, not 0. The fixtures render
// with this convention (fixtures/exposure.h BolometerExposure: a frame's true time is its
// kernel's centroid), so the estimate equals the true rig's thermal time_offset_s (verified
// in latency_test.cc with τ = 10 and 20 ms). Strictly, a first-order lag delays a motion
// of angular frequency ω by atan(ωτ)/ω, which is τ only for ωτ ≪ 1: the estimate is the
// delay at the frequencies of the recorded motion, (ωτ)²·τ/3 short of τ — 13 µs for a
// 10 ms bolometer and a 1 Hz wave, but 0.8 ms for τ = 40 ms (measured on the fixtures).
// Wave slowly (≤ 1 Hz) for the offset that fusion of a hand-held scan needs.
//
// Assumptions: a constant offset (no clock drift over the recording), a background that is
// still in most frames at every pixel, one moving object dominating the foreground. The
// motion must not repeat itself within ±max_offset_s (a pure swing of period ≤ 2 ·
// max_offset_s gives two near-equal correlation peaks: an error, not a guess).

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "core/scan.h"

namespace hw::calibrate {

struct LatencyOptions {
  double max_offset_s = 0.5;     // searched offsets: ±this around 0, s, (0, 10]
  double coarse_step_s = 0.002;  // grid step of the correlation search, s, (0, 0.05]
  int background_frames = 61;    // frames (evenly spaced) the median background is taken over, [5, 10000]
  double threshold_sigmas = 6;   // foreground: |frame − background| > this × the frame's noise σ (MAD), [2, 100]
  int min_blob_px = 9;           // smallest blob, pixels of the stream's image, [1, 1e6]
  int dilate_px = 3;             // the centroid sums the blob dilated by this (blur tails), px, [0, 20]
  double min_valid_fraction = 0.5;  // of a stream's frames that must show a blob, (0, 1]
  double min_motion_px = 2;      // RMS motion of the blob along its axis, each stream, px, (0, 1e4]
  double min_correlation = 0.5;  // the correlation peak must reach this, (0, 1)
  // The offset is ambiguous when the correlation curve has a second peak (outside the main
  // one's lobe) reaching this fraction of the main peak, (0, 1).
  double ambiguity_ratio = 0.9;
  double gap_factor = 1.5;       // an interval > this × the median frame period is a gap, (1, 100]
  // Degree of the map between two streams' signals in the fine fit, [1, 3]: 1 is affine;
  // 3 also absorbs the curvature that lens-model errors (a nominal rig's distortion) and
  // perspective leave between two cameras' views of one motion, which would otherwise
  // count as noise and inflate σ.
  int map_degree = 3;
  int bootstrap_samples = 200;   // moving-block bootstrap replicates, [0, 100000]; 0: none
  uint64_t bootstrap_seed = 1;   // the bootstrap's random draws (deterministic)

  // "" or "field: must be ..., got ...".
  std::string Check() const;
};

// One stream's blob track: every frame of the stream, missing ones NaN.
struct BlobTrack {
  core::Stream stream = core::Stream::kDepth;
  std::vector<double> time_s;                 // frame stamps, the stream's own clock, s
  std::vector<Eigen::Vector2d> centroid_px;   // weighted blob centroid, px (NaN: no blob)
  std::vector<Eigen::Vector2d> direction;     // undistorted (x/z, y/z) in the depth camera's orientation (NaN: none)
  std::vector<double> area_px;                // pixels of the blob's component (0: none)
  int frames = 0;
  int missing = 0;        // frames without a good blob
  double noise = 0;       // median per-frame noise σ (MAD), the stream's contrast unit (m, linear luma, W/(m²·sr))
  double motion_px = 0;   // RMS of the centroid along its principal axis, px
};

// Per-frame progress of the tracking (frames done, total over the three streams).
using LatencyProgressFn = std::function<void(int done, int total)>;

// The blob track of `stream` in `scan` (the stream must have frames; the rig its camera).
// Throws core::InputError (the scan folder, the stream) when a frame cannot be read. A
// stream with too few blobs is returned as is (EstimateLatency judges).
BlobTrack TrackBlob(const core::Scan& scan, core::Stream stream, const LatencyOptions& options,
                    const LatencyProgressFn& progress = nullptr, int progress_base = 0, int progress_total = 0);

// Principal axis (unit; its larger component positive, so that cameras looking the same
// way agree in sign) and RMS spread along it of the finite points (NaN ones skipped).
// Fewer than 2 points: (x axis, 0).
std::pair<Eigen::Vector2d, double> PrincipalAxis(const std::vector<Eigen::Vector2d>& points);

// A normalised 1D signal on a stream's own clock (NaN samples: missing).
struct LatencySignal {
  std::string name;            // "depth" / "rgb" / "thermal"
  std::vector<double> time_s;  // own clock, increasing, s
  std::vector<double> value;   // zero mean, unit variance over the valid samples; NaN: missing
  double period_s = 0;         // median frame period, s
};

// The offset of one pair of streams.
struct PairOffset {
  std::string reference, other;  // stream names
  double offset_s = 0;           // t_reference_clock = t_other_clock + offset_s
  double coarse_offset_s = 0;    // the correlation peak's grid offset, s
  double sigma_fit_s = 0;        // Gauss-Newton σ × √(N / N_eff), s
  double sigma_bootstrap_s = 0;  // moving-block bootstrap σ, s (0 when no replicate)
  double sigma_s = 0;            // max of the two: what is reported, s
  double peak_correlation = 0;   // Pearson correlation at the coarse peak
  double second_peak_correlation = 0;  // highest correlation outside the main lobe (−1: none)
  double gain = 0, bias = 0;     // the map s_a ≈ P(s_b): slope and value at s_b = 0
  std::vector<double> map_coefficients;  // P's coefficients c_0 … c_degree
  double residual_rms = 0;       // of the fit, units of s_a (normalised)
  int samples = 0;               // reference samples in the fine fit
  double effective_samples = 0;  // N_eff of the residuals
  int bootstrap_block = 0;       // moving-block length, samples
  std::vector<double> curve_offset_s, curve_correlation;  // the coarse correlation curve
};

// The offset of `other` against `reference` (see the method above). Throws core::InputError
// (path_for_errors) when the signals overlap too little, the correlation peak is below
// options.min_correlation, on the edge of the search range, or ambiguous.
PairOffset EstimatePairOffset(const LatencySignal& reference, const LatencySignal& other,
                              const LatencyOptions& options, const std::filesystem::path& path_for_errors);

// The signal value of `signal` at own-clock time t_s: cubic Hermite between valid samples,
// nullopt in a gap (interval > gap_factor × period or a missing sample) or outside.
std::optional<double> SampleSignal(const LatencySignal& signal, double t_s, double gap_factor);

struct LatencyResult {
  BlobTrack depth_track, rgb_track, thermal_track;
  LatencySignal depth_signal, rgb_signal, thermal_signal;
  Eigen::Vector2d motion_axis = Eigen::Vector2d::UnitX();  // in the depth camera's (x/z, y/z)
  PairOffset rgb;          // depth ← rgb: offset_s is rgb's time_offset_s
  PairOffset thermal;      // depth ← thermal: thermal's time_offset_s (effective, lag included)
  PairOffset thermal_rgb;  // rgb ← thermal: the closure check
  // thermal_rgb.offset_s − (thermal.offset_s − rgb.offset_s), s: 0 when the three agree.
  double closure_s = 0;
  double closure_sigma_s = 0;  // √ of the three σ² summed, s
  double seconds = 0;
};

// The clock offsets of rgb and thermal in `scan`. Throws core::InputError naming the scan
// folder when: rgb or thermal has no frames (or no camera), a stream shows a blob in fewer
// than min_valid_fraction of its frames ("no moving blob"), the motion is below
// min_motion_px, or a pair's correlation is weak, at the search edge or ambiguous.
// Asserts options.Check() is empty.
LatencyResult EstimateLatency(const core::Scan& scan, const LatencyOptions& options,
                              const LatencyProgressFn& progress = nullptr);

// diagnostics/signals.png (8-bit BGR, 1000 × 700): top, the three signals on the depth
// clock after correction (rgb and thermal mapped onto depth's by their fitted maps, the
// missing frames as gaps); bottom, the correlation curves of the pairs over the searched
// offsets with the estimates marked.
cv::Mat DrawLatencySignals(const LatencyResult& result);

}  // namespace hw::calibrate
