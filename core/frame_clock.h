#pragma once

// Exposure times from jittered stamps. A depth, colour or thermal camera exposes its frames
// on a regular clock, but a stream's index often holds the time each frame reached the host
// (the driver's arrival time: USB transfer, scheduling), a few ms late by a varying amount.
// Every pose the pipeline interpolates at a frame's time (the colour term of tracking, the
// thermal camera's pose) is off by that jitter times the rig's speed: 2 ms at 0.3 rad/s is
// 0.03°, 1 mm at 2 m. Where the stamps fit a regular grid (frames dropped are empty slots),
// each frame's exposure time is its slot on a line fitted to the stamps around it.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace hw::core {

struct StampRegularisationOptions {
  // Span of the line fitted around each frame, s (the frames whose slots lie within half of
  // it). Long enough to average the jitter (4 s: ~120 frames at 30 Hz, ~36 at 9 Hz, so the
  // fitted time's error is ~1/10 and ~1/6 of the jitter), short enough that the drift of a
  // device's clock against the host's (tens of ppm: µs over 4 s) does not bend the line. > 0.
  double window_s = 4;
  // A stream is regular when its jitter's robust σ (1.4826 · median absolute residual) is at
  // most this fraction of its period: 1/8 keeps 4σ of jitter within half a period, so that
  // every frame's slot is unambiguous. Otherwise its stamps are left as they are. (0, 0.5].
  double max_jitter_fraction = 0.125;
  // A stamp farther than this many σ from the line (a late delivery) is left out of the fits
  // and given its slot's time. > 0.
  double outlier_sigmas = 4;
  // More outliers than this fraction of the frames: the stream is not regular. [0, 1).
  double max_outlier_fraction = 0.05;
  // Fewer frames than this: the stamps are left as they are. >= 3.
  int min_frames = 10;

  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// What RegulariseStamps found for one stream.
struct StampFit {
  bool applied = false;   // times_s are fitted exposure times; false: the stamps as given
  std::string reason;     // why not applied, one line ("" when applied)
  std::vector<double> times_s;  // one per stamp, same clock, strictly increasing
  double period_s = 0;     // the frame period (median of the local fits' slopes; 0: not fitted)
  double jitter_s = 0;     // robust σ of the stamps about the fitted times (0: not fitted)
  double time_std_s = 0;   // median standard error of a fitted time (from jitter_s and the fit)
  double max_shift_s = 0;  // largest |fitted time − stamp|
  int outliers = 0;        // stamps beyond outlier_sigmas · σ, left out of the fits
  int64_t empty_slots = 0; // exposure slots without a frame (dropped frames) inside segments
  int segments = 0;        // runs of frames without a pause longer than window_s / 2
  int unfitted = 0;        // frames of segments too short to fit (fewer than 3): stamps kept
};

// Fits exposure times to increasing stamps (s, one stream's clock). Each frame gets an
// exposure slot — consecutive integers but for dropped frames — from a line fitted to the
// frames before it; then its time is its slot on the line fitted (least squares, outliers
// left out) to the frames whose slots lie within window_s / 2 of its own. A pause longer
// than window_s / 2 starts a new segment, fitted on its own (a device restarted, a stream
// paused). The stamps are returned unchanged (applied = false, reason says why) when there
// are fewer than min_frames, two frames would share a slot, the jitter exceeds
// max_jitter_fraction of the period, there are too many outliers, or more empty slots than
// frames (the median interval was not the clock's period): a stream that is not
// regular, which this must not bend onto a grid. Asserts options.Check() is empty and that
// the stamps are finite and strictly increasing.
StampFit RegulariseStamps(std::span<const double> stamps_s, const StampRegularisationOptions& options = {});

}  // namespace hw::core
