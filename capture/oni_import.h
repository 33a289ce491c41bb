#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "core/rig.h"

namespace hw::capture {

// What an .oni import wrote.
struct OniImportSummary {
  int depth_frames = 0, color_frames = 0;          // written to the scan
  int depth_recorded = 0, color_recorded = 0;      // what the recording says it holds
  int skipped_not_increasing = 0;  // frames whose timestamp did not increase (dropped, counted)
  int depth_pixels_out_of_range = 0;  // beyond the rig's depth_scale range, written as 0
  double first_depth_s = 0, last_depth_s = 0;   // scan timestamps (s)
  double first_color_s = 0, last_color_s = 0;
  bool color_ignored = false;  // the recording has colour but the rig has no rgb camera
};

// Opens the recording and checks it against the rig (what ImportOni checks before it
// writes anything): throws core::InputError naming the file. Commands call it before they
// create the output folder.
void CheckOniImport(const std::filesystem::path& oni_path, const core::Rig& rig);

// Converts an OpenNI2 recording into a scan folder (scan-format.md) through OpenNI2's own
// player (capture/openni_source.h): depth frames to depth/ (metres through the rig's
// depth_scale), colour to rgb/, rig.yaml = `rig`. Frames are read in file order, one at a
// time (memory does not grow with the recording).
//
// Timestamps: the recording's, in seconds. OpenNI2's Recorder stores each stream's
// timestamps relative to that stream's first recorded frame, so both streams start at 0
// and the device's depth-to-colour offset (up to a frame period, 33 ms at 30 Hz) is not in
// the file: it belongs in rig.yaml's time_offset_s.rgb (heatwave calibrate latency).
//
// `folder` must exist and be owned by the caller's core::OutputFolder. Throws
// core::InputError naming the file (unplayable recording, no depth, a depth size that is
// not the rig's depth camera, a colour size that is not the rig's rgb camera) and
// core::OutputError for write failures. `progress(done, total)` is called after each frame.
OniImportSummary ImportOni(const std::filesystem::path& oni_path, const core::Rig& rig,
                           const std::filesystem::path& folder,
                           const std::function<void(int, int)>& progress = {});

}  // namespace hw::capture
