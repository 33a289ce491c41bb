#pragma once

#include <filesystem>
#include <limits>
#include <optional>
#include <vector>

#include "core/transform.h"

namespace hw::core {

// A pose at a time: world_from_sensor at timestamp_s (seconds, on the depth clock for
// scan trajectories).
struct TimedPose {
  double timestamp_s = 0;
  Rigid3d world_from_sensor;
};

// A trajectory: poses sorted by strictly increasing time, evaluated at any time by
// interpolation (slerp + linear) between the two neighbouring poses.
class Trajectory {
 public:
  Trajectory() = default;
  // Asserts strictly increasing timestamps.
  explicit Trajectory(std::vector<TimedPose> poses);

  // Appends a pose; asserts its time is after the last one.
  void Add(double timestamp_s, const Rigid3d& world_from_sensor);

  const std::vector<TimedPose>& poses() const { return poses_; }
  size_t size() const { return poses_.size(); }
  bool empty() const { return poses_.empty(); }
  double StartTime() const;  // asserts non-empty
  double EndTime() const;    // asserts non-empty

  // world_from_sensor at time t. nullopt when t is outside [StartTime, EndTime] (beyond
  // a tolerance of 1e-9 s), or when the two poses around t are more than max_gap_s apart
  // (a tracking gap must not be bridged silently).
  std::optional<Rigid3d> At(double timestamp_s,
                            double max_gap_s = std::numeric_limits<double>::infinity()) const;

 private:
  std::vector<TimedPose> poses_;
};

// TUM trajectory text: "timestamp tx ty tz qx qy qz qw" per line, '#' starts a comment,
// blank lines allowed. Throws InputError naming the path and line number on malformed
// lines, non-finite values, non-unit quaternions (|q| off by more than 1e-3; others are
// normalised) or non-increasing timestamps.
Trajectory ReadTumTrajectory(const std::filesystem::path& path);
Trajectory ParseTumTrajectory(const std::string& text,
                              const std::filesystem::path& path_for_errors);
// Writes with full precision (round trip exact to 1e-12), atomically. Throws OutputError.
void WriteTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);

}  // namespace hw::core
