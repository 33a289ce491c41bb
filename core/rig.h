#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/transform.h"

namespace hw::core {

// The thermal block of rig.yaml (scan-format.md).
struct ThermalSettings {
  double raw_scale = 0.01;       // apparent °C per raw count
  double raw_offset = -273.15;   // apparent °C at raw count 0
  std::array<double, 2> spectral_band_um = {7.5, 14.0};  // micrometres, 0 < lo < hi
  double netd_k = 0.04;          // noise-equivalent temperature difference of a frame, K, >= 0
  double emissivity = 0.95;      // default scene emissivity, (0, 1]
  double reflected_c = 20.0;     // reflected apparent temperature, °C

  // Apparent °C of a raw count and back.
  double ApparentFromRaw(double raw) const { return raw * raw_scale + raw_offset; }
  double RawFromApparent(double apparent_c) const { return (apparent_c - raw_offset) / raw_scale; }
};

// A sensor rig: rig.yaml of scan-format.md, version 1. The depth camera is the rig's
// reference frame; the other cameras are placed by depth_from_<camera>.
struct Rig {
  double depth_scale = 1000.0;  // raw depth units per metre, > 0 (TUM: 5000)
  CameraModel depth;
  std::optional<CameraModel> rgb;
  std::optional<CameraModel> thermal;
  Rigid3d depth_from_rgb;      // identity when there is no rgb camera
  Rigid3d depth_from_thermal;  // identity when there is no thermal camera
  double rgb_time_offset_s = 0;      // t_depth_clock = t_rgb + rgb_time_offset_s
  double thermal_time_offset_s = 0;  // t_depth_clock = t_thermal + thermal_time_offset_s
  std::optional<ThermalSettings> thermal_settings;  // present iff thermal is

  // "" when valid, else a message naming the key and the problem (cameras checked with
  // CameraModel::Check, prefixed with "cameras.<name>.").
  std::string Check() const;
};

// Reads rig.yaml strictly: unknown key, missing required key, wrong type, non-unit
// quaternion (|q| off by more than 1e-6 is an error, smaller errors are normalised),
// non-positive focal length, ... each throw InputError naming the file, the key path
// (e.g. "cameras.thermal.fx") and the problem. Optional keys: cameras.rgb, cameras.thermal
// and with them their extrinsics/time offset/thermal block (required iff the camera is).
Rig ReadRig(const std::filesystem::path& path);
Rig ParseRig(const std::string& yaml_text, const std::filesystem::path& path_for_errors);
// Writes rig.yaml atomically in the layout of scan-format.md, with full precision so that
// ReadRig(WriteRig(rig)) == rig to 1e-15 relative. Asserts rig.Check() is empty.
void WriteRig(const std::filesystem::path& path, const Rig& rig);
std::string FormatRig(const Rig& rig);

// Calibration target, target.yaml of scan-format.md.
enum class TargetType { kSquareGrid, kChessboard, kAprilGrid };
std::string TargetTypeName(TargetType type);  // "square_grid" | "chessboard" | "aprilgrid"

struct Target {
  TargetType type = TargetType::kChessboard;
  int rows = 0;           // square_grid: squares per column; chessboard: inner corners per column
  int cols = 0;           // square_grid: squares per row; chessboard: inner corners per row
  double square_m = 0;    // side of one square (aprilgrid: of one tag), metres, > 0
  double pitch_m = 0;     // square_grid, aprilgrid: centre-to-centre distance, metres, > square_m
  std::string family;     // aprilgrid only: e.g. "tag36h11"

  std::string Check() const;
};

// Strict like ReadRig. pitch_m is required for square_grid and aprilgrid and an error for
// chessboard; family is required for aprilgrid only.
Target ReadTarget(const std::filesystem::path& path);
Target ParseTarget(const std::string& yaml_text, const std::filesystem::path& path_for_errors);
void WriteTarget(const std::filesystem::path& path, const Target& target);

}  // namespace hw::core
