#include "core/trajectory.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <charconv>
#include <cmath>
#include <string>
#include <string_view>
#include <system_error>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/text_lines.h"

namespace hw::core {

namespace {

// Times within this distance (s) of the ends of a trajectory still evaluate to the end
// pose: timestamps written in decimal text rarely land exactly on the same double.
constexpr double kEndToleranceS = 1e-9;
// A quaternion whose norm is off by more than this is not a rotation, it is a bad file.
constexpr double kQuaternionNormTolerance = 1e-3;

constexpr std::array<const char*, 8> kTumFields = {"timestamp", "tx", "ty", "tz",
                                                   "qx",        "qy", "qz", "qw"};

std::string LineReason(size_t line_number, const std::string& reason) {
  return "line " + std::to_string(line_number) + ": " + reason;
}

// Splits on spaces and tabs (and a trailing '\r' from CRLF files).
std::vector<std::string_view> SplitFields(std::string_view line) {
  std::vector<std::string_view> fields;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t begin = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > begin) fields.push_back(line.substr(begin, i - begin));
  }
  return fields;
}

std::string Quoted(std::string_view text) {
  // Keep messages one short line even for binary garbage.
  std::string out = "'";
  for (const char c : text.substr(0, 40)) {
    out += (static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7f)
               ? c
               : '?';
  }
  if (text.size() > 40) out += "...";
  return out + "'";
}

std::string FormatDouble(double value) {
  // Shortest representation that reads back to the same double.
  std::array<char, 64> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  assert(result.ec == std::errc());
  return std::string(buffer.data(), result.ptr);
}

}  // namespace

Trajectory::Trajectory(std::vector<TimedPose> poses) : poses_(std::move(poses)) {
  for (size_t i = 1; i < poses_.size(); ++i) {
    assert(poses_[i].timestamp_s > poses_[i - 1].timestamp_s);
  }
}

void Trajectory::Add(double timestamp_s, const Rigid3d& world_from_sensor) {
  assert(poses_.empty() || timestamp_s > poses_.back().timestamp_s);
  poses_.push_back(TimedPose{timestamp_s, world_from_sensor});
}

double Trajectory::StartTime() const {
  assert(!poses_.empty());
  return poses_.front().timestamp_s;
}

double Trajectory::EndTime() const {
  assert(!poses_.empty());
  return poses_.back().timestamp_s;
}

std::optional<Rigid3d> Trajectory::At(double timestamp_s, double max_gap_s) const {
  if (poses_.empty() || !std::isfinite(timestamp_s)) return std::nullopt;
  if (timestamp_s < StartTime() - kEndToleranceS || timestamp_s > EndTime() + kEndToleranceS) {
    return std::nullopt;
  }
  if (timestamp_s <= StartTime()) return poses_.front().world_from_sensor;
  if (timestamp_s >= EndTime()) return poses_.back().world_from_sensor;
  // First pose strictly after t; it exists and is not the first (t in (start, end)).
  const auto after = std::upper_bound(
      poses_.begin(), poses_.end(), timestamp_s,
      [](double t, const TimedPose& pose) { return t < pose.timestamp_s; });
  const TimedPose& b = *after;
  const TimedPose& a = *(after - 1);
  // A sample time is known exactly: no gap to bridge.
  if (timestamp_s == a.timestamp_s) return a.world_from_sensor;
  const double gap_s = b.timestamp_s - a.timestamp_s;
  if (gap_s > max_gap_s) return std::nullopt;
  const double s = (timestamp_s - a.timestamp_s) / gap_s;
  return Interpolate(a.world_from_sensor, b.world_from_sensor, s);
}

Trajectory ReadTumTrajectory(const std::filesystem::path& path) {
  return ParseTumTrajectory(ReadFile(path, kMaxIndexFileBytes), path);
}

Trajectory ParseTumTrajectory(const std::string& text,
                              const std::filesystem::path& path_for_errors) {
  std::vector<TimedPose> poses;
  size_t previous_line = 0;
  ForEachLine(text, [&](size_t line_number, std::string_view line) {
    const size_t hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    const std::vector<std::string_view> fields = SplitFields(line);
    if (fields.empty()) return;
    if (fields.size() != kTumFields.size()) {
      throw InputError(path_for_errors,
                       LineReason(line_number, "expected 8 numbers (timestamp tx ty tz qx qy "
                                               "qz qw), got " +
                                                   std::to_string(fields.size())));
    }
    std::array<double, 8> values{};
    for (size_t i = 0; i < fields.size(); ++i) {
      const std::string_view field = fields[i];
      const char* first = field.data();
      // from_chars rejects a leading '+', which printf-style writers may emit.
      if (field.size() > 1 && field[0] == '+' && field[1] != '-') ++first;
      const auto result = std::from_chars(first, field.data() + field.size(), values[i]);
      if (result.ec == std::errc::result_out_of_range) {
        throw InputError(path_for_errors,
                         LineReason(line_number, std::string(kTumFields[i]) + ": " +
                                                     Quoted(field) + " is out of range"));
      }
      if (result.ec != std::errc() || result.ptr != field.data() + field.size()) {
        throw InputError(path_for_errors,
                         LineReason(line_number, std::string(kTumFields[i]) + ": " +
                                                     Quoted(field) + " is not a number"));
      }
      if (!std::isfinite(values[i])) {
        throw InputError(path_for_errors,
                         LineReason(line_number, std::string(kTumFields[i]) + ": " +
                                                     Quoted(field) + " is not finite"));
      }
    }
    const double timestamp_s = values[0];
    // Eigen's constructor order is (w, x, y, z); the file's is x y z w.
    const Eigen::Quaterniond q(values[7], values[4], values[5], values[6]);
    const double norm = q.norm();
    if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
      throw InputError(path_for_errors,
                       LineReason(line_number, "quaternion (qx qy qz qw) has norm " +
                                                   FormatDouble(norm) +
                                                   ", expected 1 (within 1e-3)"));
    }
    if (!poses.empty() && !(timestamp_s > poses.back().timestamp_s)) {
      throw InputError(
          path_for_errors,
          LineReason(line_number, "timestamp " + std::string(fields[0]) +
                                      " is not after the previous one (" +
                                      FormatDouble(poses.back().timestamp_s) + " on line " +
                                      std::to_string(previous_line) + ")"));
    }
    poses.push_back(TimedPose{timestamp_s,
                              Rigid3d(q, Eigen::Vector3d(values[1], values[2], values[3]))});
    previous_line = line_number;
  });
  return Trajectory(std::move(poses));
}

void WriteTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory) {
  std::string text = "# timestamp tx ty tz qx qy qz qw\n";
  for (const TimedPose& pose : trajectory.poses()) {
    const Eigen::Vector3d& t = pose.world_from_sensor.translation;
    const Eigen::Quaterniond& q = pose.world_from_sensor.rotation;
    for (const double value : {pose.timestamp_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z()}) {
      text += FormatDouble(value);
      text += ' ';
    }
    text += FormatDouble(q.w());
    text += '\n';
  }
  WriteFileAtomically(path, text);
}

}  // namespace hw::core
