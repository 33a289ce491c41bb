#include "core/scan.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <atomic>
#include <cassert>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <numbers>
#include <string_view>
#include <system_error>
#include <thread>

#include <opencv2/core.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/output_folder.h"
#include "core/text_lines.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

// At most this many individual missing-file / gap warnings per stream; the rest are counted.
constexpr int kMaxListedWarnings = 5;

std::string FormatSeconds(double t_s) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", t_s);
  return buf;
}

std::string FormatShort(double value, int precision = 3) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", precision, value);
  return buf;
}

// A token quoted for a one-line message: shortened when long.
std::string Quote(std::string_view token) {
  constexpr size_t kMax = 40;
  if (token.size() <= kMax) return "'" + std::string(token) + "'";
  return "'" + std::string(token.substr(0, kMax)) + "...'";
}

bool IsBlank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

// Splits index text into lines, strips comments ('#' at the start of the line or of a
// field) and splits the rest into fields. Calls on_fields(line_number, fields) for every
// line with at least one field. Throws on control characters.
template <typename OnFields>
void ForEachDataLine(const std::string& text, const fs::path& path, OnFields on_fields) {
  std::vector<std::string_view> fields;
  ForEachLine(text, [&](size_t line_number, std::string_view line) {
    fields.clear();
    size_t i = 0;
    while (i < line.size()) {
      const char c = line[i];
      if (IsBlank(c)) {
        ++i;
        continue;
      }
      if (c == '#') break;  // comment to the end of the line
      const size_t start = i;
      while (i < line.size() && !IsBlank(line[i])) {
        const auto u = static_cast<unsigned char>(line[i]);
        if (u < 0x20 || u == 0x7f) {
          char buf[16];
          std::snprintf(buf, sizeof(buf), "0x%02x", u);
          throw InputError(path,
                           "line " + std::to_string(line_number) + ": control character " + buf);
        }
        ++i;
      }
      fields.push_back(line.substr(start, i - start));
    }
    if (!fields.empty()) on_fields(static_cast<int>(line_number), fields);
  });
}

// True when `relative` stays inside the folder it is relative to, lexically: ".."
// components never climb above the start. (Symlinks inside the scan are followed: a folder
// linked in on purpose, e.g. frames on another disk, is the user's choice.)
bool StaysInside(const fs::path& relative) {
  int depth = 0;
  for (const fs::path& component : relative) {
    const std::string& name = component.native();
    if (name.empty() || name == ".") continue;
    if (name == "..") {
      if (--depth < 0) return false;
    } else {
      ++depth;
    }
  }
  return depth > 0;
}

double ParseTimestamp(std::string_view token, const fs::path& path, int line_number) {
  double value = 0;
  const char* first = token.data();
  const char* last = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || ptr != last || !std::isfinite(value)) {
    throw InputError(path, "line " + std::to_string(line_number) + ": bad timestamp " +
                               Quote(token) + ", expected a number of seconds");
  }
  return value;
}

void CheckIncreasing(double t, double previous_t, int previous_line, const fs::path& path,
                     int line_number) {
  if (previous_line > 0 && !(t > previous_t)) {
    throw InputError(path, "line " + std::to_string(line_number) + ": timestamp " +
                               FormatSeconds(t) + " is not after " + FormatSeconds(previous_t) +
                               " on line " + std::to_string(previous_line) +
                               " (timestamps must strictly increase)");
  }
}

std::string SizeName(int width, int height) {
  return std::to_string(width) + "x" + std::to_string(height);
}

// Index of the timestamp in `sorted` nearest to t (ties: the earlier), or -1 if empty.
int NearestIndex(const std::vector<double>& sorted, double t) {
  if (sorted.empty()) return -1;
  const auto it = std::lower_bound(sorted.begin(), sorted.end(), t);
  if (it == sorted.begin()) return 0;
  if (it == sorted.end()) return static_cast<int>(sorted.size()) - 1;
  const int after = static_cast<int>(it - sorted.begin());
  const int before = after - 1;
  return (t - sorted[before] <= sorted[after] - t) ? before : after;
}

}  // namespace

std::string StreamName(Stream stream) {
  switch (stream) {
    case Stream::kDepth:
      return "depth";
    case Stream::kRgb:
      return "rgb";
    case Stream::kThermal:
      return "thermal";
  }
  assert(false);
  return "";
}

std::vector<IndexEntry> ParseStreamIndex(const std::string& text, const fs::path& path) {
  std::vector<IndexEntry> entries;
  ForEachDataLine(text, path, [&](int line_number, const std::vector<std::string_view>& fields) {
    if (fields.size() != 2) {
      throw InputError(path, "line " + std::to_string(line_number) +
                                 ": expected 'timestamp path', got " +
                                 std::to_string(fields.size()) + " field(s)");
    }
    IndexEntry entry;
    entry.timestamp_s = ParseTimestamp(fields[0], path, line_number);
    entry.path = std::string(fields[1]);
    entry.line = line_number;
    if (fs::path(entry.path).is_absolute()) {
      throw InputError(path, "line " + std::to_string(line_number) + ": path " + Quote(entry.path) +
                                 " must be relative to the scan folder");
    }
    if (!StaysInside(entry.path)) {
      throw InputError(path, "line " + std::to_string(line_number) + ": path " + Quote(entry.path) +
                                 " does not name a file inside the scan folder");
    }
    if (!entries.empty()) {
      CheckIncreasing(entry.timestamp_s, entries.back().timestamp_s, entries.back().line, path,
                      line_number);
    }
    entries.push_back(std::move(entry));
  });
  return entries;
}

std::vector<IndexEntry> ReadStreamIndex(const fs::path& path) {
  return ParseStreamIndex(ReadFile(path, kMaxIndexFileBytes), path);
}

std::vector<double> ParseFfcEvents(const std::string& text, const fs::path& path) {
  std::vector<double> events;
  int previous_line = 0;
  ForEachDataLine(text, path, [&](int line_number, const std::vector<std::string_view>& fields) {
    if (fields.size() != 1) {
      throw InputError(path, "line " + std::to_string(line_number) +
                                 ": expected one timestamp, got " + std::to_string(fields.size()) +
                                 " fields");
    }
    const double t = ParseTimestamp(fields[0], path, line_number);
    if (!events.empty()) CheckIncreasing(t, events.back(), previous_line, path, line_number);
    events.push_back(t);
    previous_line = line_number;
  });
  return events;
}

std::vector<double> ReadFfcEvents(const fs::path& path) {
  return ParseFfcEvents(ReadFile(path, kMaxIndexFileBytes), path);
}

std::string ScanOptions::Check() const {
  if (max_association_dt_s &&
      !(std::isfinite(*max_association_dt_s) && *max_association_dt_s > 0)) {
    return "max_association_dt_s: must be > 0 and finite, got " +
           std::to_string(*max_association_dt_s);
  }
  if (!(std::isfinite(gap_factor) && gap_factor > 1)) {
    return "gap_factor: must be > 1 and finite, got " + std::to_string(gap_factor);
  }
  if (const std::string message = stamps.Check(); !message.empty()) return "stamps." + message;
  return "";
}

double MedianPeriod(const std::vector<double>& timestamps_s) {
  if (timestamps_s.size() < 2) return 0;
  std::vector<double> periods(timestamps_s.size() - 1);
  for (size_t i = 1; i < timestamps_s.size(); ++i) {
    periods[i - 1] = timestamps_s[i] - timestamps_s[i - 1];
  }
  const size_t n = periods.size();
  const size_t mid = n / 2;
  std::nth_element(periods.begin(), periods.begin() + static_cast<std::ptrdiff_t>(mid),
                   periods.end());
  const double upper = periods[mid];
  if (n % 2 == 1) return upper;
  const double lower =
      *std::max_element(periods.begin(), periods.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lower + upper);
}

GapStats FindGaps(const std::vector<double>& timestamps_s, double gap_factor) {
  GapStats stats;
  const double median = MedianPeriod(timestamps_s);
  for (size_t i = 1; i < timestamps_s.size(); ++i) {
    const double dt = timestamps_s[i] - timestamps_s[i - 1];
    stats.largest_s = std::max(stats.largest_s, dt);
    if (dt > gap_factor * median) {
      ++stats.count;
      stats.gaps.emplace_back(timestamps_s[i - 1], timestamps_s[i]);
    }
  }
  return stats;
}

// ---------------------------------------------------------------------------------------
// Scan

const Scan::StreamData& Scan::Data(Stream stream) const {
  return streams_[static_cast<size_t>(stream)];
}
Scan::StreamData& Scan::Data(Stream stream) { return streams_[static_cast<size_t>(stream)]; }

Scan Scan::Open(const fs::path& folder, const ScanOptions& options) {
  assert(options.Check().empty());
  const PathInfo folder_info = ProbePath(folder);
  if (folder_info.kind == PathKind::kMissing) throw InputError(folder, "no such scan folder");
  if (folder_info.kind != PathKind::kDirectory) {
    throw InputError(folder, folder_info.kind == PathKind::kRegularFile
                                 ? "is not a folder, expected a scan"
                                 : DescribeNotRegular(folder_info) + ", expected a scan folder");
  }
  if (::access(folder.c_str(), R_OK | X_OK) != 0 && (errno == EACCES || errno == EPERM)) {
    throw InputError(folder, "cannot read the scan folder: permission denied");
  }
  if (const FolderRun run = ProbeFolderRun(folder); run.state != FolderRunState::kComplete) {
    const std::string who = run.detail.empty() ? "" : " (" + run.detail + ")";
    throw InputError(folder, run.state == FolderRunState::kBeingWritten
                                 ? "scan is being written by another heatwave run" + who
                                 : "incomplete scan: the run that wrote it did not finish" + who +
                                       "; write it again");
  }

  Scan scan;
  scan.folder_ = folder;
  scan.options_ = options;
  scan.rig_path_ = options.rig_path.empty() ? folder / "rig.yaml" : options.rig_path;
  if (ProbePath(scan.rig_path_).kind == PathKind::kMissing) {
    throw InputError(scan.rig_path_,
                     options.rig_path.empty()
                         ? "no such file; a folder without rig.yaml (e.g. a TUM RGB-D "
                           "sequence) opens with a rig given separately (--rig)"
                         : "no such file");
  }
  scan.rig_ = ReadRig(scan.rig_path_);

  // Stream indexes. Depth is required and must have frames. An optional file is absent only
  // when nothing is at its path: a dangling link, a FIFO or a folder there is an error
  // (ReadFile says which), not a silently missing stream.
  const fs::path depth_index = scan.IndexPath(Stream::kDepth);
  if (ProbePath(depth_index).kind == PathKind::kMissing) {
    throw InputError(depth_index, "no such file; every scan needs a depth stream index");
  }
  for (const Stream stream : kAllStreams) {
    StreamData& data = scan.Data(stream);
    const fs::path index = scan.IndexPath(stream);
    if (ProbePath(index).kind == PathKind::kMissing) continue;
    const bool has_camera =
        stream == Stream::kDepth ||
        (stream == Stream::kRgb ? scan.rig_.rgb.has_value() : scan.rig_.thermal.has_value());
    if (!has_camera) {
      throw InputError(index, "a " + StreamName(stream) + " stream index, but the rig " +
                                  scan.rig_path_.string() + " has no cameras." +
                                  StreamName(stream));
    }
    data.has_index = true;
    data.entries = ReadStreamIndex(index);
    if (data.entries.empty() && stream != Stream::kDepth) {
      scan.warnings_.push_back(StreamName(stream) + ": " + index.string() +
                               " lists no frames (the stream is empty)");
    }
  }
  if (scan.Data(Stream::kDepth).entries.empty()) {
    throw InputError(depth_index, "no frames; a scan needs at least one depth frame");
  }

  const fs::path ffc_path = folder / "ffc.txt";
  if (ProbePath(ffc_path).kind != PathKind::kMissing) {
    if (!scan.rig_.thermal) {
      throw InputError(ffc_path, "flat-field events, but the rig " + scan.rig_path_.string() +
                                     " has no cameras.thermal");
    }
    scan.ffc_timestamps_s_ = ReadFfcEvents(ffc_path);
  }
  const fs::path groundtruth_path = folder / "groundtruth.txt";
  if (ProbePath(groundtruth_path).kind != PathKind::kMissing) {
    scan.groundtruth_ = ReadTumTrajectory(groundtruth_path);
    if (scan.groundtruth_->empty()) {
      scan.warnings_.push_back("groundtruth: " + groundtruth_path.string() + " holds no poses");
    }
  }

  // Frame files (a stat each), gaps, periods.
  for (const Stream stream : kAllStreams) {
    StreamData& data = scan.Data(stream);
    const std::string name = StreamName(stream);
    const double offset_s = scan.TimeOffset(stream);
    for (const IndexEntry& entry : data.entries) data.times_s.push_back(entry.timestamp_s);
    if (options.regularise_stamps && !data.times_s.empty()) {
      data.stamp_fit = RegulariseStamps(data.times_s, options.stamps);
      data.times_s = std::move(data.stamp_fit.times_s);
      data.stamp_fit.times_s.clear();
    }
    for (const double t : data.times_s) data.depth_clock_s.push_back(t + offset_s);
    data.exists.assign(data.entries.size(), true);
    for (size_t i = 0; i < data.entries.size(); ++i) {
      const fs::path file = folder / data.entries[i].path;
      const PathInfo info = ProbePath(file);
      if (info.kind == PathKind::kRegularFile) continue;
      data.exists[i] = false;
      if (++data.num_missing <= kMaxListedWarnings) {
        const std::string what = info.kind == PathKind::kMissing
                                     ? "missing file " + file.string()
                                     : "unusable file " + file.string() + ": " +
                                           DescribeNotRegular(info);
        scan.warnings_.push_back(name + ": " + what + " (" + name + ".txt line " +
                                 std::to_string(data.entries[i].line) +
                                 ", t=" + FormatSeconds(data.entries[i].timestamp_s) + ")");
      }
    }
    if (data.num_missing > kMaxListedWarnings) {
      scan.warnings_.push_back(name + ": " + std::to_string(data.num_missing - kMaxListedWarnings) +
                               " more missing files (" + std::to_string(data.num_missing) + " of " +
                               std::to_string(data.entries.size()) + ")");
    }
    const std::vector<double>& times = data.times_s;
    data.median_period_s = hw::core::MedianPeriod(times);
    const GapStats gaps = FindGaps(times, options.gap_factor);
    for (int g = 0; g < gaps.count && g < kMaxListedWarnings; ++g) {
      const auto& [start, end] = gaps.gaps[static_cast<size_t>(g)];
      scan.warnings_.push_back(name + ": gap of " + FormatShort(end - start) + " s between " +
                               FormatSeconds(start) + " and " + FormatSeconds(end) +
                               " (median period " + FormatShort(data.median_period_s, 4) + " s)");
    }
    if (gaps.count > kMaxListedWarnings) {
      scan.warnings_.push_back(name + ": " + std::to_string(gaps.count - kMaxListedWarnings) +
                               " more gaps (" + std::to_string(gaps.count) + " in all)");
    }
  }

  // Association of depth frames with rgb and thermal frames on the depth clock.
  const std::vector<double>& depth_times = scan.Timestamps(Stream::kDepth);
  const double depth_period = scan.Data(Stream::kDepth).median_period_s;
  for (const Stream stream : {Stream::kRgb, Stream::kThermal}) {
    StreamData& data = scan.Data(stream);
    const double slower_period = std::max(depth_period, data.median_period_s);
    data.max_association_dt_s = options.max_association_dt_s ? *options.max_association_dt_s
                                : slower_period > 0          ? 0.5 * slower_period
                                                             : kTimestampResolutionS;
    data.association.assign(depth_times.size(), -1);
    data.num_associated = 0;
    const std::vector<double>& times = data.depth_clock_s;
    for (size_t d = 0; d < depth_times.size(); ++d) {
      const int j = NearestIndex(times, depth_times[d]);
      if (j >= 0 &&
          std::abs(times[static_cast<size_t>(j)] - depth_times[d]) <= data.max_association_dt_s) {
        data.association[d] = j;
        ++data.num_associated;
      }
    }
    if (!times.empty() && data.num_associated == 0) {
      scan.warnings_.push_back(
          StreamName(stream) + ": no frame is within " + FormatShort(data.max_association_dt_s) +
          " s of a depth frame on the depth clock (" + StreamName(stream) + " " +
          FormatSeconds(times.front()) + ".." + FormatSeconds(times.back()) + ", depth " +
          FormatSeconds(depth_times.front()) + ".." + FormatSeconds(depth_times.back()) +
          "); check time_offset_s." + StreamName(stream) + " in " + scan.rig_path_.string());
    }
  }
  if (scan.groundtruth_ && !scan.groundtruth_->empty()) {
    const double start = scan.groundtruth_->StartTime();
    const double end = scan.groundtruth_->EndTime();
    if (depth_times.back() < start || depth_times.front() > end) {
      scan.warnings_.push_back("groundtruth: " + FormatSeconds(start) + ".." + FormatSeconds(end) +
                               " does not overlap the depth frames " +
                               FormatSeconds(depth_times.front()) + ".." +
                               FormatSeconds(depth_times.back()));
    }
  }
  return scan;
}

fs::path Scan::IndexPath(Stream stream) const { return folder_ / (StreamName(stream) + ".txt"); }

bool Scan::HasIndex(Stream stream) const { return Data(stream).has_index; }

int Scan::NumFrames(Stream stream) const { return static_cast<int>(Data(stream).entries.size()); }

const std::vector<IndexEntry>& Scan::Entries(Stream stream) const { return Data(stream).entries; }

double Scan::TimeOffset(Stream stream) const {
  switch (stream) {
    case Stream::kDepth:
      return 0;
    case Stream::kRgb:
      return rig_.rgb_time_offset_s;
    case Stream::kThermal:
      return rig_.thermal_time_offset_s;
  }
  assert(false);
  return 0;
}

double Scan::Timestamp(Stream stream, int i) const {
  assert(i >= 0 && i < NumFrames(stream));
  return Data(stream).times_s[static_cast<size_t>(i)];
}

double Scan::DepthClockTime(Stream stream, int i) const {
  assert(i >= 0 && i < NumFrames(stream));
  return Data(stream).depth_clock_s[static_cast<size_t>(i)];
}

const std::vector<double>& Scan::Timestamps(Stream stream) const { return Data(stream).times_s; }

const std::vector<double>& Scan::DepthClockTimes(Stream stream) const {
  return Data(stream).depth_clock_s;
}

fs::path Scan::FramePath(Stream stream, int i) const {
  assert(i >= 0 && i < NumFrames(stream));
  return folder_ / Data(stream).entries[static_cast<size_t>(i)].path;
}

bool Scan::FrameExists(Stream stream, int i) const {
  assert(i >= 0 && i < NumFrames(stream));
  return Data(stream).exists[static_cast<size_t>(i)];
}

int Scan::NumMissingFrames(Stream stream) const { return Data(stream).num_missing; }

double Scan::MedianPeriod(Stream stream) const { return Data(stream).median_period_s; }

double Scan::MaxAssociationDt(Stream stream) const {
  assert(stream != Stream::kDepth);
  return Data(stream).max_association_dt_s;
}

std::optional<int> Scan::AssociatedFrame(int depth_index, Stream stream) const {
  assert(stream != Stream::kDepth);
  assert(depth_index >= 0 && depth_index < NumFrames(Stream::kDepth));
  const int j = Data(stream).association[static_cast<size_t>(depth_index)];
  if (j < 0) return std::nullopt;
  return j;
}

int Scan::NumAssociatedDepthFrames(Stream stream) const {
  assert(stream != Stream::kDepth);
  return Data(stream).num_associated;
}

std::optional<int> Scan::NearestFrame(Stream stream, double t_depth_clock_s,
                                      double max_dt_s) const {
  const std::vector<double>& times = DepthClockTimes(stream);
  const int j = NearestIndex(times, t_depth_clock_s);
  if (j < 0 || !(std::abs(times[static_cast<size_t>(j)] - t_depth_clock_s) <= max_dt_s)) {
    return std::nullopt;
  }
  return j;
}

std::string Scan::FrameLabel(Stream stream, int i) const {
  return StreamName(stream) + " frame " + std::to_string(i) +
         " (t=" + FormatSeconds(Timestamp(stream, i)) + ")";
}

cv::Mat Scan::ReadImage(Stream stream, int i, const ImageHeaderCheck& check) const {
  const fs::path path = FramePath(stream, i);
  const PathInfo info = ProbePath(path);
  if (info.kind == PathKind::kMissing) throw InputError(path, "missing " + FrameLabel(stream, i));
  if (info.kind != PathKind::kRegularFile) {
    throw InputError(path, "unusable " + FrameLabel(stream, i) + ": " + DescribeNotRegular(info));
  }
  std::string bytes;
  try {
    bytes = ReadFile(path, kMaxFrameFileBytes);
  } catch (const InputError& e) {
    throw InputError(path, "cannot read " + FrameLabel(stream, i) + ": " + e.reason());
  }
  // The caller's check of the header (size, type against the rig) runs before any pixel is
  // decompressed; its messages pass unchanged, the decoder's get the frame's name.
  bool check_failed = false;
  const ImageHeaderCheck checked = [&](const ImageHeader& header) {
    try {
      check(header);
    } catch (...) {
      check_failed = true;
      throw;
    }
  };
  try {
    return DecodeImage(bytes, path, checked);
  } catch (const InputError& e) {
    if (check_failed) throw;
    throw InputError(path, "cannot decode " + FrameLabel(stream, i) + ": " + e.reason());
  }
}

namespace {

void CheckSize(const ImageHeader& header, const CameraModel& camera,
               const std::string& camera_name, const fs::path& path) {
  if (header.width != camera.width || header.height != camera.height) {
    throw InputError(path, "image is " + SizeName(header.width, header.height) + ", cameras." +
                               camera_name + " in the rig is " +
                               SizeName(camera.width, camera.height));
  }
}

}  // namespace

cv::Mat Scan::LoadDepth(int i) const {
  const fs::path path = FramePath(Stream::kDepth, i);
  const cv::Mat raw = ReadImage(Stream::kDepth, i, [&](const ImageHeader& header) {
    if (header.type() != CV_16UC1) {
      throw InputError(path, "depth image must be 16-bit unsigned 1-channel, got " +
                                 ImageTypeName(header.type()));
    }
    CheckSize(header, rig_.depth, "depth", path);
  });
  cv::Mat depth_m;
  raw.convertTo(depth_m, CV_32F, 1.0 / rig_.depth_scale);  // raw 0 stays 0.0f
  return depth_m;
}

cv::Mat Scan::LoadRgb(int i) const {
  assert(rig_.rgb);
  const fs::path path = FramePath(Stream::kRgb, i);
  const cv::Mat image = ReadImage(Stream::kRgb, i, [&](const ImageHeader& header) {
    if (header.depth != CV_8U || header.channels > 4) {
      throw InputError(path, "colour image must be 8-bit with 1 to 4 channels, got " +
                                 ImageTypeName(header.type()));
    }
    CheckSize(header, *rig_.rgb, "rgb", path);
  });
  // Decoded in file order (grey, grey+alpha, RGB, RGBA): grey is replicated, alpha dropped.
  if (image.channels() == 3) return image;
  cv::Mat rgb(image.rows, image.cols, CV_8UC3);
  if (image.channels() <= 2) {
    const int from_to[] = {0, 0, 0, 1, 0, 2};
    cv::mixChannels(&image, 1, &rgb, 1, from_to, 3);
  } else {
    const int from_to[] = {0, 0, 1, 1, 2, 2};
    cv::mixChannels(&image, 1, &rgb, 1, from_to, 3);
  }
  return rgb;
}

cv::Mat Scan::LoadThermal(int i) const {
  assert(rig_.thermal && rig_.thermal_settings);
  const fs::path path = FramePath(Stream::kThermal, i);
  const cv::Mat image = ReadImage(Stream::kThermal, i, [&](const ImageHeader& header) {
    CheckSize(header, *rig_.thermal, "thermal", path);
    if (header.type() != CV_32FC1 && header.type() != CV_16UC1) {
      throw InputError(path,
                       "thermal image must be 16-bit unsigned (raw counts) or 32-bit "
                       "float (apparent °C), 1-channel, got " +
                           ImageTypeName(header.type()));
    }
  });
  if (image.type() == CV_32FC1) {
    // NaN/inf are not temperatures: a camera marks bad pixels otherwise (raw counts).
    int non_finite = 0;
    for (int y = 0; y < image.rows; ++y) {
      const float* row = image.ptr<float>(y);
      for (int x = 0; x < image.cols; ++x) non_finite += !std::isfinite(row[x]);
    }
    if (non_finite > 0) {
      throw InputError(path, FrameLabel(Stream::kThermal, i) + ": " +
                                 std::to_string(non_finite) + " of " +
                                 std::to_string(image.total()) +
                                 " pixels are not finite (NaN or inf)");
    }
    return image;
  }
  cv::Mat apparent_c;
  image.convertTo(apparent_c, CV_32F, rig_.thermal_settings->raw_scale,
                  rig_.thermal_settings->raw_offset);
  return apparent_c;
}

cv::Mat Scan::Load(Stream stream, int i) const {
  switch (stream) {
    case Stream::kDepth:
      return LoadDepth(i);
    case Stream::kRgb:
      return LoadRgb(i);
    case Stream::kThermal:
      return LoadThermal(i);
  }
  assert(false);
  return {};
}

// ---------------------------------------------------------------------------------------
// Summary and frame check

ScanSummary SummarizeScan(const Scan& scan) {
  ScanSummary summary;
  summary.folder = scan.folder();
  summary.rig_path = scan.rig_path();
  const Rig& rig = scan.rig();
  summary.depth_scale = rig.depth_scale;
  for (const Stream stream : kAllStreams) {
    StreamSummary s;
    s.stream = stream;
    s.has_index = scan.HasIndex(stream);
    s.frames = scan.NumFrames(stream);
    s.time_offset_s = scan.TimeOffset(stream);
    if (s.frames > 0) {
      s.start_s = scan.Timestamp(stream, 0);
      s.end_s = scan.Timestamp(stream, s.frames - 1);
      s.span_s = s.end_s - s.start_s;
    }
    const double period = scan.MedianPeriod(stream);
    s.median_rate_hz = period > 0 ? 1.0 / period : 0.0;
    const GapStats gaps = FindGaps(scan.Timestamps(stream), scan.options().gap_factor);
    s.gaps = gaps.count;
    s.largest_interval_s = gaps.largest_s;
    s.missing_files = scan.NumMissingFrames(stream);
    if (stream != Stream::kDepth) {
      s.associated_depth_frames = scan.NumAssociatedDepthFrames(stream);
      s.max_association_dt_s = scan.MaxAssociationDt(stream);
    }
    summary.streams.push_back(s);
  }
  const auto add_camera = [&](const std::string& name, const CameraModel& camera,
                              const Rigid3d& depth_from_camera, double time_offset_s) {
    CameraSummary c;
    c.name = name;
    c.model = CameraModelTypeName(camera.type);
    c.width = camera.width;
    c.height = camera.height;
    c.fx = camera.fx;
    c.fy = camera.fy;
    c.distortion_coefficients = static_cast<int>(camera.distortion.size());
    c.baseline_m = depth_from_camera.translation.norm();
    c.rotation_deg = depth_from_camera.RotationAngle() * 180.0 / std::numbers::pi;
    c.time_offset_s = time_offset_s;
    summary.cameras.push_back(c);
  };
  add_camera("depth", rig.depth, Rigid3d::Identity(), 0.0);
  if (rig.rgb) add_camera("rgb", *rig.rgb, rig.depth_from_rgb, rig.rgb_time_offset_s);
  if (rig.thermal) {
    add_camera("thermal", *rig.thermal, rig.depth_from_thermal, rig.thermal_time_offset_s);
  }
  summary.thermal_settings = rig.thermal_settings;
  if (scan.groundtruth()) {
    summary.has_groundtruth = true;
    summary.groundtruth_poses = static_cast<int>(scan.groundtruth()->size());
    if (!scan.groundtruth()->empty()) {
      summary.groundtruth_span_s = scan.groundtruth()->EndTime() - scan.groundtruth()->StartTime();
    }
  }
  summary.ffc_events = static_cast<int>(scan.ffc_timestamps_s().size());
  summary.warnings = scan.warnings();
  return summary;
}

int TotalFrames(const Scan& scan) {
  int total = 0;
  for (const Stream stream : kAllStreams) total += scan.NumFrames(stream);
  return total;
}

std::vector<FrameProblem> CheckFrames(const Scan& scan, const std::function<void()>& frame_done,
                                      int num_threads) {
  std::vector<std::pair<Stream, int>> jobs;
  for (const Stream stream : kAllStreams) {
    for (int i = 0; i < scan.NumFrames(stream); ++i) jobs.emplace_back(stream, i);
  }
  if (num_threads <= 0) num_threads = static_cast<int>(std::thread::hardware_concurrency());
  num_threads = std::clamp(num_threads, 1, std::max(1, static_cast<int>(jobs.size())));

  std::vector<FrameProblem> problems;
  std::mutex mutex;  // guards problems and frame_done
  std::atomic<size_t> next{0};
  const auto work = [&] {
    for (size_t k = next++; k < jobs.size(); k = next++) {
      const auto [stream, i] = jobs[k];
      std::optional<FrameProblem> problem;
      try {
        scan.Load(stream, i);
      } catch (const InputError& e) {
        problem = FrameProblem{stream, i, e.path(), e.what()};
      } catch (const std::exception& e) {  // e.g. out of memory on a huge image
        problem = FrameProblem{stream, i, scan.FramePath(stream, i), e.what()};
      }
      std::lock_guard<std::mutex> lock(mutex);
      if (problem) problems.push_back(std::move(*problem));
      if (frame_done) frame_done();
    }
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < num_threads; ++t) threads.emplace_back(work);
  work();
  for (std::thread& thread : threads) thread.join();
  std::sort(problems.begin(), problems.end(), [](const FrameProblem& a, const FrameProblem& b) {
    return std::pair(static_cast<int>(a.stream), a.index) <
           std::pair(static_cast<int>(b.stream), b.index);
  });
  return problems;
}

}  // namespace hw::core
