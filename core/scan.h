#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "core/frame_clock.h"
#include "core/image_io.h"
#include "core/rig.h"
#include "core/trajectory.h"

namespace hw::core {

// Reading scan folders (scan-format.md, version 1):
//
//   scan/rig.yaml, depth.txt (required), rgb.txt, thermal.txt, ffc.txt, groundtruth.txt
//   (optional), and the frame files the stream indexes name.
//
// A plain TUM RGB-D sequence (no rig.yaml) opens when ScanOptions::rig_path names a rig.

// The image streams of a scan. The depth camera's clock is the scan's reference clock.
enum class Stream { kDepth = 0, kRgb = 1, kThermal = 2 };
inline constexpr std::array<Stream, 3> kAllStreams = {Stream::kDepth, Stream::kRgb,
                                                      Stream::kThermal};

// "depth" / "rgb" / "thermal": the stream's index file is <name>.txt, its rig camera
// cameras.<name>.
std::string StreamName(Stream stream);

// One line of a stream index: a frame's timestamp on its stream's own clock (seconds) and
// its file, relative to the scan folder.
struct IndexEntry {
  double timestamp_s = 0;
  std::string path;  // relative to the scan folder, as written in the index
  int line = 0;      // 1-based line number in the index file, for messages
};

// Parses a stream index ("timestamp path" per line; '#' at the start of a line or of a
// field starts a comment to the end of the line; blank lines, a UTF-8 BOM and LF, CRLF or
// CR-only line ends allowed: core/text_lines.h).
// Throws InputError(path_for_errors, "line N: ...") on: a line that is not exactly two
// fields, a timestamp that is not a finite number, an absolute path or one whose ".."
// components lead outside the scan folder, a control character, or a timestamp not
// strictly after the previous one. An index without frames is valid
// here (Scan::Open rejects an empty depth index).
std::vector<IndexEntry> ParseStreamIndex(const std::string& text,
                                         const std::filesystem::path& path_for_errors);
// ReadFile + ParseStreamIndex. Throws InputError when the file cannot be read.
std::vector<IndexEntry> ReadStreamIndex(const std::filesystem::path& path);

// Parses ffc.txt: one thermal-clock timestamp (seconds) per line, comments and blank lines
// as in a stream index, strictly increasing. Throws InputError naming the line.
std::vector<double> ParseFfcEvents(const std::string& text,
                                   const std::filesystem::path& path_for_errors);
std::vector<double> ReadFfcEvents(const std::filesystem::path& path);

// Options of opening a scan.
struct ScanOptions {
  // rig.yaml to use instead of <scan>/rig.yaml (which is then ignored, even if present).
  // Empty: <scan>/rig.yaml, which must exist.
  std::filesystem::path rig_path;
  // Largest |t_depth - t_other| (seconds, on the depth clock) for which a depth frame is
  // paired with an rgb or thermal frame. Unset: half the median frame period of the slower
  // stream of the pair, so that a frame is only paired with depth frames it is the nearest
  // sample to in time, never with ones a whole frame away (e.g. 30 Hz depth and 9 Hz
  // thermal: 0.056 s). When neither stream of a pair has two frames, only frames with equal
  // timestamps (within 1e-6 s, the resolution of index files) are paired. > 0 when set.
  std::optional<double> max_association_dt_s;
  // An interval between consecutive frames longer than gap_factor x the stream's median
  // frame period is reported as a gap (a warning). Dimensionless, > 1.
  double gap_factor = 1.5;
  // Replace each stream's stamps by exposure times fitted to a regular grid where they fit
  // one (core/frame_clock.h): the stamps of a driver's arrival times jitter by milliseconds,
  // which moves every pose interpolated at them. A stream that does not fit keeps its stamps
  // (StampRegularisation says why). Off: the stamps as given.
  bool regularise_stamps = false;
  StampRegularisationOptions stamps;

  // "" when valid, else a message naming the field, value and constraint.
  std::string Check() const;
};

// Timestamps within this distance are equal: index files store microseconds.
inline constexpr double kTimestampResolutionS = 1e-6;

// An opened scan folder. Open() reads the rig and every index (cheap); frames are decoded
// lazily by Load*(). A Scan is immutable once opened: the Load* functions may be called
// from several threads at once.
class Scan {
 public:
  // Opens `folder`. Throws InputError (naming the file and, where relevant, line or key)
  // when: the folder does not exist or is not a folder; another heatwave run is writing it,
  // or the run that wrote it did not finish (core/output_folder.h); the rig
  // (options.rig_path or <folder>/rig.yaml) is missing or invalid; depth.txt is missing, malformed or has no frames; rgb.txt,
  // thermal.txt, ffc.txt or groundtruth.txt are malformed; a stream index (or ffc.txt) is
  // present but the rig has no camera for it. A camera in the rig without an index is fine
  // (the stream has no frames). An optional file (rgb.txt, thermal.txt, ffc.txt,
  // groundtruth.txt) is absent only when nothing is at its path: a dangling link, a link
  // loop, a FIFO or a device there is an error saying so. Problems the scan can still be
  // used with are warnings(): frame files that do not exist or are not regular files, gaps
  // in a stream, a stream index or trajectory without entries, a stream that never
  // overlaps depth in time. Asserts options.Check() is empty.
  static Scan Open(const std::filesystem::path& folder, const ScanOptions& options = {});

  const std::filesystem::path& folder() const { return folder_; }
  const std::filesystem::path& rig_path() const { return rig_path_; }
  const Rig& rig() const { return rig_; }
  const ScanOptions& options() const { return options_; }

  // True when the stream has an index file (depth always does). Its frames may be none.
  bool HasIndex(Stream stream) const;
  int NumFrames(Stream stream) const;
  // Path of the stream's index file, <folder>/<name>.txt (it may not exist).
  std::filesystem::path IndexPath(Stream stream) const;
  // The stream's index entries, in time order.
  const std::vector<IndexEntry>& Entries(Stream stream) const;

  // time_offset_s of the stream in the rig (0 for depth): t_depth_clock = t + offset.
  double TimeOffset(Stream stream) const;
  // Timestamp of frame i on the stream's own clock, and on the depth clock (seconds).
  // Assert 0 <= i < NumFrames(stream).
  double Timestamp(Stream stream, int i) const;
  double DepthClockTime(Stream stream, int i) const;
  // All frames' timestamps, own clock / depth clock (seconds), in frame order. With
  // ScanOptions::regularise_stamps, the fitted exposure times of a stream that fits a grid
  // (Entries() keep the stamps as indexed).
  const std::vector<double>& Timestamps(Stream stream) const;
  const std::vector<double>& DepthClockTimes(Stream stream) const;
  // What ScanOptions::regularise_stamps found for the stream (applied = false and an empty
  // reason when it was off or the stream has no frames).
  const StampFit& StampRegularisation(Stream stream) const { return Data(stream).stamp_fit; }

  // Path of frame i's file: folder() / the path in the index.
  std::filesystem::path FramePath(Stream stream, int i) const;
  // Whether frame i's file existed when the scan was opened.
  bool FrameExists(Stream stream, int i) const;
  int NumMissingFrames(Stream stream) const;

  // Median interval between consecutive frames (seconds); 0 when fewer than 2 frames.
  double MedianPeriod(Stream stream) const;

  // Association of depth frames with rgb / thermal frames (stream is kRgb or kThermal).
  // The effective max |dt| (seconds) used for the pair depth-stream (ScanOptions).
  double MaxAssociationDt(Stream stream) const;
  // For depth frame `depth_index`, the index of the stream frame nearest in time on the
  // depth clock, if within MaxAssociationDt(stream); nullopt otherwise or when the stream
  // has no frames. Several depth frames can share one (slower) stream frame. Ties go to the
  // earlier frame.
  std::optional<int> AssociatedFrame(int depth_index, Stream stream) const;
  // How many depth frames have a partner in `stream`.
  int NumAssociatedDepthFrames(Stream stream) const;
  // The inverse lookup for stream frames that are processed on their own time (thermal
  // fusion interpolates the depth trajectory at DepthClockTime(kThermal, i) rather than
  // snapping to a depth frame): the frame of `stream` nearest to `t_depth_clock_s` (depth
  // clock, seconds) within max_dt_s, or nullopt.
  std::optional<int> NearestFrame(Stream stream, double t_depth_clock_s, double max_dt_s) const;

  // Thermal-clock timestamps of flat-field (shutter) events from ffc.txt (empty if none).
  const std::vector<double>& ffc_timestamps_s() const { return ffc_timestamps_s_; }
  // world_from_depth trajectory from groundtruth.txt, depth clock; nullopt if absent.
  const std::optional<Trajectory>& groundtruth() const { return groundtruth_; }

  // Problems the scan still loads with, one line each, naming paths and times.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // Depth frame i in metres (CV_32FC1, rig depth size): raw / depth_scale. Pixels without a
  // measurement (raw 0) are 0.0f, not NaN: callers test `depth_m > 0`. Throws InputError
  // naming the file when it is missing or not a regular file, cannot be decoded, is not
  // 16-bit single-channel or is not the size of cameras.depth. Type and size are checked
  // on the header, before decompression (core/image_io.h).
  cv::Mat LoadDepth(int i) const;
  // Colour frame i as CV_8UC3 in RGB order (a grey image is replicated, an alpha channel
  // dropped), rig rgb size. Throws InputError naming the file
  // when missing, undecodable, not 8-bit, or of the wrong size.
  cv::Mat LoadRgb(int i) const;
  // Thermal frame i as CV_32FC1 apparent °C, rig thermal size: a 16-bit image holds raw
  // counts (apparent = raw * raw_scale + raw_offset of the rig's thermal block), a 32-bit
  // float image (TIFF) holds apparent °C, returned as is. Throws InputError naming the file
  // when missing, undecodable, of another type, of the wrong size, or (float) holding
  // NaN or inf pixels.
  cv::Mat LoadThermal(int i) const;
  // LoadDepth / LoadRgb / LoadThermal by stream, as stored (no conversion beyond the above).
  cv::Mat Load(Stream stream, int i) const;

 private:
  struct StreamData {
    bool has_index = false;
    std::vector<IndexEntry> entries;
    std::vector<double> times_s;        // entries' timestamps, own clock
    std::vector<double> depth_clock_s;  // times_s + time offset
    StampFit stamp_fit;                 // without its times_s (times_s holds them)
    std::vector<bool> exists;
    int num_missing = 0;
    double median_period_s = 0;
    double max_association_dt_s = 0;  // rgb / thermal only
    std::vector<int> association;     // per depth frame, -1 = none; rgb / thermal only
    int num_associated = 0;
  };
  Scan() = default;
  const StreamData& Data(Stream stream) const;
  StreamData& Data(Stream stream);
  cv::Mat ReadImage(Stream stream, int i, const ImageHeaderCheck& check) const;
  std::string FrameLabel(Stream stream, int i) const;

  std::filesystem::path folder_;
  std::filesystem::path rig_path_;
  ScanOptions options_;
  Rig rig_;
  std::array<StreamData, 3> streams_;
  std::vector<double> ffc_timestamps_s_;
  std::optional<Trajectory> groundtruth_;
  std::vector<std::string> warnings_;
};

// Median interval between consecutive timestamps (seconds); 0 for fewer than 2.
double MedianPeriod(const std::vector<double>& timestamps_s);

// Intervals longer than gap_factor x the median period.
struct GapStats {
  int count = 0;
  double largest_s = 0;  // longest interval between consecutive frames, gap or not
  std::vector<std::pair<double, double>> gaps;  // (start, end) timestamps of each gap
};
GapStats FindGaps(const std::vector<double>& timestamps_s, double gap_factor);

// What `heatwave scan-info` reports.
struct StreamSummary {
  Stream stream = Stream::kDepth;
  bool has_index = false;
  int frames = 0;
  double start_s = 0;         // first timestamp, own clock (0 when no frames)
  double end_s = 0;           // last timestamp, own clock
  double span_s = 0;          // end - start
  double time_offset_s = 0;   // rig time_offset_s
  double median_rate_hz = 0;  // 1 / median period; 0 for fewer than 2 frames
  int gaps = 0;               // intervals > gap_factor x median period
  double largest_interval_s = 0;
  int missing_files = 0;
  // rgb / thermal: depth frames with a partner in this stream, and the max |dt| used.
  int associated_depth_frames = 0;
  double max_association_dt_s = 0;
};

struct CameraSummary {
  std::string name;           // depth | rgb | thermal
  std::string model;          // pinhole | opencv
  int width = 0, height = 0;  // pixels
  double fx = 0, fy = 0;      // pixels
  int distortion_coefficients = 0;
  double baseline_m = 0;    // |t| of depth_from_<name>; 0 for depth
  double rotation_deg = 0;  // rotation angle of depth_from_<name>
  double time_offset_s = 0;
};

struct ScanSummary {
  std::filesystem::path folder;
  std::filesystem::path rig_path;
  double depth_scale = 0;              // raw units per metre
  std::vector<StreamSummary> streams;  // depth, rgb, thermal, in this order
  std::vector<CameraSummary> cameras;  // the rig's cameras, depth first
  std::optional<ThermalSettings> thermal_settings;
  bool has_groundtruth = false;
  int groundtruth_poses = 0;
  double groundtruth_span_s = 0;
  int ffc_events = 0;
  std::vector<std::string> warnings;
};

// Summarises an opened scan (no frame is decoded).
ScanSummary SummarizeScan(const Scan& scan);

// A frame that cannot be loaded (CheckFrames).
struct FrameProblem {
  Stream stream = Stream::kDepth;
  int index = 0;
  std::filesystem::path path;
  std::string message;  // the InputError's what()
};

// Decodes every frame of every stream with Load*(), on `num_threads` threads (0: hardware
// concurrency), and returns those that fail, sorted by stream then index. `frame_done` is
// called once per frame (from one thread at a time) for a progress bar.
std::vector<FrameProblem> CheckFrames(const Scan& scan,
                                      const std::function<void()>& frame_done = nullptr,
                                      int num_threads = 0);
int TotalFrames(const Scan& scan);

}  // namespace hw::core
