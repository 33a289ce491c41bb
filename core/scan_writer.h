#pragma once

#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/rig.h"
#include "core/trajectory.h"

namespace hw::core {

// A time rounded to the resolution of index files (whole microseconds, FormatTimestamp's
// 6 decimals), so that what a writer plans with is exactly what readers get back.
inline double RoundToMicroseconds(double t_s) { return std::round(t_s * 1e6) / 1e6; }

// How thermal frames are stored (scan-format.md): uint16 raw counts through the rig's
// raw_scale / raw_offset (PNG; quantised to raw_scale), or 32-bit float TIFF holding
// apparent °C exactly.
enum class ThermalEncoding { kRawCounts16, kFloatTiff };

// Writes a scan folder (scan-format.md, version 1) frame by frame, as the synthetic-scan
// generator and capture produce them:
//
//   ScanWriter writer(folder, rig);          // creates folder, writes rig.yaml
//   writer.AddDepth(t, depth_m); writer.AddRgb(t, rgb); writer.AddThermal(t, apparent_c);
//   writer.Finish();                          // writes the index files
//
// Frame files are named by their timestamp with 6 decimals, as TUM does
// (depth/1305031102.175304.png), and stored in the index with the same 6 decimals, so the
// timestamps a reader gets are the given ones rounded to the microsecond. Every file is
// written atomically and checked byte for byte (core/atomic_file.h, core/image_io.h).
// Commands hold a core::OutputFolder on the folder for the whole run (one writer at a
// time; a run that does not finish leaves the folder marked incomplete). Until Finish() has run the folder has no
// depth.txt and is not a valid scan, so an interrupted writer leaves no half-scan behind.
// Finish() may be called again after more frames (e.g. periodically during capture): it
// rewrites the indexes with everything added so far. Files of an earlier scan in the same
// folder are not removed; only the indexes decide what the scan holds.
//
// Preconditions are asserted (they are bugs of the caller): the rig is valid and has the
// camera a frame is added for; images have the camera's size and the documented type;
// timestamps are finite and, rounded to the microsecond, strictly increasing per stream.
// Write failures throw OutputError naming the file. Not thread-safe.
class ScanWriter {
 public:
  // Creates `folder` (and parents) and writes folder/rig.yaml. Throws OutputError.
  ScanWriter(const std::filesystem::path& folder, const Rig& rig);

  const std::filesystem::path& folder() const { return folder_; }
  const Rig& rig() const { return rig_; }

  // Writes depth/<t>.png, uint16 raw = round(depth_m * depth_scale). Pixels that are
  // not a measurement (0, negative, NaN, inf) are written as 0 = no measurement; so are
  // depths beyond the format's range (raw > 65535, e.g. 13.1 m at depth_scale 5000):
  // clamping them to 65535 would turn them into false measurements at the range limit.
  // depth_m: CV_32FC1 metres, rig depth size. Returns the number of finite positive pixels
  // dropped as out of range.
  int AddDepth(double timestamp_s, const cv::Mat& depth_m);

  // Writes rgb/<t>.png from a CV_8UC3 image in RGB order (heatwave's convention; OpenCV's
  // BGR is handled here), of the rig's rgb size.
  void AddRgb(double timestamp_s, const cv::Mat& rgb);

  // Writes thermal/<t>.png (kRawCounts16: raw = round((apparent - raw_offset) / raw_scale),
  // saturated to [0, 65535] as a camera saturates, NaN -> 0) or thermal/<t>.tiff
  // (kFloatTiff: the values as they are; they must be finite, as readers refuse NaN/inf). apparent_c: CV_32FC1 °C, rig
  // thermal size. Returns the number of pixels saturated (kRawCounts16) or 0.
  int AddThermal(double timestamp_s, const cv::Mat& apparent_c,
                 ThermalEncoding encoding = ThermalEncoding::kRawCounts16);

  // Records a flat-field (shutter) event at a thermal-clock time (seconds, strictly
  // increasing). Written to ffc.txt by Finish().
  void AddFfcEvent(double timestamp_s);

  // The world_from_depth trajectory (depth clock) written to groundtruth.txt by Finish().
  void SetGroundTruth(const Trajectory& world_from_depth);

  // Writes depth.txt (always), rgb.txt / thermal.txt / ffc.txt when something was added to
  // them, groundtruth.txt when set. Throws OutputError.
  void Finish();

  int NumFrames(const std::string& stream) const;  // "depth" | "rgb" | "thermal"

  // "<t with 6 decimals><extension>", e.g. FrameFileName(1.5, ".png") = "1.500000.png".
  static std::string FrameFileName(double timestamp_s, const std::string& extension);
  // The timestamp as index files store it: "%.6f".
  static std::string FormatTimestamp(double timestamp_s);

 private:
  struct StreamIndex {
    std::vector<std::pair<std::string, std::string>> lines;  // formatted timestamp, path
    std::optional<double> last_rounded_s;                    // for the increasing check
  };
  // Checks the timestamp, returns the relative path "<stream>/<t><ext>" and records it.
  std::string Register(StreamIndex& index, const std::string& stream, double timestamp_s,
                       const std::string& extension);
  void WriteImage(const std::string& relative_path, const cv::Mat& image) const;
  void WriteIndex(const std::string& file, const std::string& header,
                  const StreamIndex& index) const;

  std::filesystem::path folder_;
  Rig rig_;
  StreamIndex depth_, rgb_, thermal_;
  std::vector<double> ffc_timestamps_s_;
  std::optional<Trajectory> groundtruth_;
};

}  // namespace hw::core
