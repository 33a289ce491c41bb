#include "capture/oni_import.h"

#include <cmath>
#include <optional>

#include "capture/openni_source.h"
#include "core/error.h"
#include "core/scan_writer.h"

namespace hw::capture {

namespace {

void CheckAgainstRig(const OpenNiSource& source, const core::Rig& rig, const std::string& where) {
  const RgbdStreamMode depth = source.depth_mode();
  if (depth.width != rig.depth.width || depth.height != rig.depth.height) {
    throw core::InputError(where, "depth is " + std::to_string(depth.width) + "x" + std::to_string(depth.height) +
                                      " but the rig's depth camera is " + std::to_string(rig.depth.width) + "x" +
                                      std::to_string(rig.depth.height));
  }
  if (source.has_color() && rig.rgb) {
    const RgbdStreamMode color = *source.color_mode();
    if (color.width != rig.rgb->width || color.height != rig.rgb->height) {
      throw core::InputError(where, "colour is " + std::to_string(color.width) + "x" + std::to_string(color.height) +
                                        " but the rig's rgb camera is " + std::to_string(rig.rgb->width) + "x" +
                                        std::to_string(rig.rgb->height));
    }
  }
}

}  // namespace

void CheckOniImport(const std::filesystem::path& oni_path, const core::Rig& rig) {
  CheckAgainstRig(*OpenNiSource::OpenRecording(oni_path), rig, oni_path.string());
}

OniImportSummary ImportOni(const std::filesystem::path& oni_path, const core::Rig& rig,
                           const std::filesystem::path& folder, const std::function<void(int, int)>& progress) {
  const std::string where = oni_path.string();
  std::unique_ptr<OpenNiSource> source = OpenNiSource::OpenRecording(oni_path);
  OniImportSummary s;
  s.depth_recorded = source->NumRecordedFrames(RgbdFrame::Stream::kDepth);
  s.color_recorded = source->NumRecordedFrames(RgbdFrame::Stream::kColor);
  CheckAgainstRig(*source, rig, where);
  const bool use_color = source->has_color() && rig.rgb.has_value();
  s.color_ignored = source->has_color() && !rig.rgb;

  core::ScanWriter writer(folder, rig);
  const int total = s.depth_recorded + (source->has_color() ? s.color_recorded : 0);
  int done = 0;
  std::optional<double> last_depth_s, last_color_s;
  // A stall of the player longer than this is an error (a frame is decoded in milliseconds).
  constexpr double kStallTimeoutS = 5.0;
  while (std::optional<RgbdFrame> frame = source->Next(kStallTimeoutS)) {
    ++done;
    const double t_s = core::RoundToMicroseconds(static_cast<double>(frame->device_timestamp_us) * 1e-6);
    if (frame->stream == RgbdFrame::Stream::kDepth) {
      if (last_depth_s && t_s <= *last_depth_s) {
        ++s.skipped_not_increasing;
      } else {
        cv::Mat depth_m;
        frame->image.convertTo(depth_m, CV_32FC1, frame->depth_unit_m);
        s.depth_pixels_out_of_range += writer.AddDepth(t_s, depth_m);
        if (!last_depth_s) s.first_depth_s = t_s;
        last_depth_s = s.last_depth_s = t_s;
        ++s.depth_frames;
      }
    } else if (use_color) {
      if (last_color_s && t_s <= *last_color_s) {
        ++s.skipped_not_increasing;
      } else {
        writer.AddRgb(t_s, frame->image);
        if (!last_color_s) s.first_color_s = t_s;
        last_color_s = s.last_color_s = t_s;
        ++s.color_frames;
      }
    }
    if (progress) progress(done, total);
  }
  if (s.depth_frames == 0) throw core::InputError(where, "no depth frame could be read");
  writer.Finish();
  return s;
}

}  // namespace hw::capture
