#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "core/rig.h"

namespace hw::capture {

class OpenNiSource;
class ThermalCamera;

struct CaptureOptions {
  double duration_s = 0;        // s; stop after this long; 0 = until stopped (Ctrl-C)
  int max_queued_frames = 60;   // frames of all streams held in memory waiting for the disk,
                                // >= 1 (about 2 s at 30 Hz); a frame arriving at a full
                                // queue is dropped and counted: memory stays bounded
  double index_every_s = 2.0;   // s, > 0; the index files are rewritten this often, so a
                                // crash or power loss leaves a valid scan of what was written
  double max_silence_s = 2.0;   // s, > 0; a stream that has delivered frames and then none for
                                // this long ends the capture (a camera unplugged or stalled)
  double first_frame_timeout_s = 5.0;  // s, > 0; the same for a stream's first frame (a
                                       // Lepton takes about a second to deliver its first)
  std::string Check() const;
};

struct StreamCount {
  int64_t received = 0;   // frames that arrived
  int64_t written = 0;    // frames in the scan
  int64_t dropped = 0;    // dropped because the queue was full (the disk was too slow)
  int64_t gaps = 0;       // arrivals more than 1.5 nominal periods after the previous one
  double first_s = 0, last_s = 0;  // scan timestamps of the first and last frame written (s)
};

struct CaptureSummary {
  StreamCount depth, rgb, thermal;
  int64_t ffc_events = 0;
  double seconds = 0;              // wall time captured
  int64_t max_queue_frames = 0;    // high-water mark of the queue
  bool stopped_by_user = false;    // the stop flag (Ctrl-C) ended it, not the duration
  // Non-empty when a device failed or fell silent (max_silence_s) and ended the capture
  // early: one line naming the device. Everything it delivered before is in the scan.
  std::string device_error;
};

// Throws core::InputError naming the stream when the rig does not describe what the
// devices deliver (depth size; rgb size when the device has colour and the rig an rgb
// camera; thermal size, and a thermal camera in the rig, when `thermal` is given). Capture()
// calls it first; commands call it before they create the output folder.
void CheckCaptureRig(const OpenNiSource* rgbd, const ThermalCamera* thermal, const core::Rig& rig);

// Records RGB-D frames from `rgbd` (may be null) and thermal frames from `thermal` (may be
// null; at least one of the two) into the scan folder `folder` (scan-format.md), until
// `should_stop()` returns true or duration_s has passed.
//
// Every frame is timestamped on arrival on one host clock (capture/clock.h); the scan's
// timestamps are seconds since the capture started, on every stream (the depth clock is
// the host clock: rig.yaml's time_offset_s then holds each stream's latency relative to
// depth, as calibrate latency measures it). Frames go through a bounded queue to one writer
// thread (core::ScanWriter): memory does not grow with the length of the capture. A flat-
// field event is recorded in ffc.txt when a thermal frame starts one (ffc_in_progress
// rising). The index files are rewritten every index_every_s and at the end, so stopping
// at any time leaves a complete scan of everything written.
//
// A device that fails (an InputError from it) or falls silent ends the capture early: the
// scan is still completed with everything recorded, and summary.device_error says why.
// `rig` must have the streams' sizes (depth, rgb when colour is captured, thermal when
// thermal is): a mismatch throws core::InputError naming the stream before anything is
// recorded. `folder` must exist and be owned by the caller's core::OutputFolder. Write
// failures throw core::OutputError (the capture stops; the indexes are not rewritten).
// `progress(summary_so_far)` is called about twice a second from the calling thread.
CaptureSummary Capture(OpenNiSource* rgbd, ThermalCamera* thermal, const core::Rig& rig,
                       const std::filesystem::path& folder, const CaptureOptions& options,
                       const std::function<bool()>& should_stop,
                       const std::function<void(const CaptureSummary&)>& progress = {});

}  // namespace hw::capture
