#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "core/camera.h"
#include "core/depth_correction.h"
#include "core/transform.h"

namespace hw::core {

// The thermal block of rig.yaml (scan-format.md). Check() holds the ranges below, so that
// every reader and writer of rig.yaml refuses the same values. Ranges are wide enough for
// any real camera and exclude only what cannot be one (and what would make temperatures
// overflow or lose all precision):
//   raw_scale         |s| in [1e-6, 10] °C per count, either sign (centikelvin: 0.01;
//                     FLIR TLinear 0.04); 16-bit counts then span 0.07 °C to 655 000 °C
//   raw_offset        [-1000, 1000] °C (centikelvin: -273.15)
//   spectral_band_um  0.1 <= lo < hi <= 1000 µm (UV to the far-IR edge; LWIR 7.5-14)
//   netd_k            [0, 10] K (microbolometers 0.03-0.1 K)
//   emissivity        [0.01, 1] (polished gold 0.02; below, a surface temperature is
//                     1/ε times the measurement noise: nothing to measure)
//   reflected_c       (-273.15, 3000] °C (above absolute zero; furnaces are < 2000 °C)
struct ThermalSettings {
  static constexpr double kMinAbsRawScale = 1e-6, kMaxAbsRawScale = 10;  // °C per count
  static constexpr double kMaxAbsRawOffsetC = 1000;
  static constexpr double kMinBandUm = 0.1, kMaxBandUm = 1000;
  static constexpr double kMaxNetdK = 10;
  static constexpr double kMinEmissivity = 0.01;
  static constexpr double kMaxReflectedC = 3000;

  double raw_scale = 0.01;       // apparent °C per raw count
  double raw_offset = -273.15;   // apparent °C at raw count 0
  std::array<double, 2> spectral_band_um = {7.5, 14.0};  // micrometres, lo < hi
  double netd_k = 0.04;          // noise-equivalent temperature difference of a frame, K
  double emissivity = 0.95;      // default scene emissivity
  double reflected_c = 20.0;     // reflected apparent temperature, °C

  // Apparent °C of a raw count and back.
  double ApparentFromRaw(double raw) const { return raw * raw_scale + raw_offset; }
  double RawFromApparent(double apparent_c) const { return (apparent_c - raw_offset) / raw_scale; }

  // "" when every field is in its range above, else one message naming the field, value
  // and range, e.g. "emissivity: must be in [0.01, 1], got 0".
  std::string Check() const;
};

// A sensor rig: rig.yaml of scan-format.md, version 1. The depth camera is the rig's
// reference frame; the other cameras are placed by depth_from_<camera>.
//
// Ranges (Rig::Check; cameras by CameraModel::Check, camera.h; thermal block by
// ThermalSettings::Check):
//   depth_scale     [1, 1e6] raw units per metre: 1 = metres, 1e6 = micrometres (16-bit
//                   depth then reaches 65 mm); TUM 5000, Kinect/RealSense 1000
//   extrinsics t_m  |t| <= 10 m: cameras of one rig are centimetres apart; a 1e300 m
//                   baseline is a typo, not a rig (quaternion: unit to 1e-6)
//   time_offset_s   |offset| <= 1e10 s (317 years): clocks of different epochs are
//                   legitimate (thermal counting from boot, depth on Unix time, ~1.7e9 s
//                   apart); beyond, timestamps lose microsecond precision
inline constexpr double kMinDepthScale = 1, kMaxDepthScale = 1e6;
inline constexpr double kMaxExtrinsicTranslationM = 10;
inline constexpr double kMaxTimeOffsetS = 1e10;
//   rolling_shutter_s.rgb  [0, 0.1] s: colour sensors read out in 10–35 ms
inline constexpr double kMaxReadoutS = 0.1;

struct Rig {
  double depth_scale = 1000.0;  // raw depth units per metre (TUM: 5000)
  CameraModel depth;
  std::optional<CameraModel> rgb;
  std::optional<CameraModel> thermal;
  Rigid3d depth_from_rgb;      // identity when there is no rgb camera
  Rigid3d depth_from_thermal;  // identity when there is no thermal camera
  double rgb_time_offset_s = 0;      // t_depth_clock = t_rgb + rgb_time_offset_s
  double thermal_time_offset_s = 0;  // t_depth_clock = t_thermal + thermal_time_offset_s
  // Rolling shutter of the colour camera: time from the first row's exposure to the last's,
  // s, [0, 0.1] (0: global shutter); a frame's timestamp is the middle row's. A heatwave
  // extension of rig.yaml: key rolling_shutter_s.rgb (optional, default 0).
  double rgb_readout_s = 0;
  std::optional<ThermalSettings> thermal_settings;  // present iff thermal is
  // The depth camera's inverse-depth offset field (depth_correction.h), when calibrated
  // (`heatwave calibrate depth`). A heatwave extension of rig.yaml: key depth_correction.
  std::optional<DepthCorrection> depth_correction;

  // "" when valid, else a message naming the key, value and constraint (cameras checked
  // with CameraModel::Check, prefixed with "cameras.<name>.", the thermal block with
  // ThermalSettings::Check, prefixed with "thermal."; depth_correction with
  // DepthCorrection::Check, prefixed with "depth_correction.").
  std::string Check() const;
};

// "" when a translation between two cameras of a rig (metres) is finite and at most
// kMaxExtrinsicTranslationM long, else "must be at most 10 m long, got [x, y, z]". Shared
// by rig.yaml's t_m and the .cameramodel import.
std::string CheckExtrinsicTranslation(const Eigen::Vector3d& t_m);

// Reads rig.yaml strictly: unknown key, missing required key, wrong type, non-unit
// quaternion (|q| off by more than 1e-6 is an error, smaller errors are normalised), a
// value outside its range (Rig::Check), ... each throw InputError naming the file, the key
// path (e.g. "cameras.thermal.fx"), the problem and the line, on one line. The text may
// start with a UTF-8 byte order mark and use LF, CRLF or CR line ends; a NUL or other
// control character, nesting deeper than 32 levels and a file over 1 MiB
// (kMaxConfigFileBytes) are errors. Optional keys: cameras.rgb, cameras.thermal
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

// Ranges (Target::Check): rows, cols in [1, 1000] (chessboard: [2, 1000] inner corners);
// square_m in [1e-4, 10] m; pitch_m in (square_m, 10] m; thickness_m in [0, 0.05] m. A printed target's squares are
// millimetres to decimetres; 0.1 mm still covers microscope targets, 10 m a building wall.
struct Target {
  static constexpr int kMaxRowsCols = 1000;
  static constexpr double kMinSizeM = 1e-4, kMaxSizeM = 10;
  static constexpr double kMaxThicknessM = 0.05;

  TargetType type = TargetType::kChessboard;
  int rows = 0;           // square_grid: squares per column; chessboard: inner corners per column
  int cols = 0;           // square_grid: squares per row; chessboard: inner corners per row
  double square_m = 0;    // side of one square (aprilgrid: of one tag), metres
  double pitch_m = 0;     // square_grid, aprilgrid: centre-to-centre distance, metres, > square_m
  std::string family;     // aprilgrid only: e.g. "tag36h11"
  // square_grid only (heatwave extension of target.yaml, optional, default 0): thickness
  // of the plate the holes are cut through, metres, [0, 0.05]; the corners are those of
  // the front face. At a tilt a camera sees a hole's far walls, so its visible outline is
  // smaller than the front opening (calibrate/hole_corner.h); 0 = a thin plate.
  double thickness_m = 0;

  std::string Check() const;
};

// Every corner a detector of `target` must find, in the TARGET frame (metres, z = 0: x along
// the columns, y down the rows, z into the target), index = corner id: chessboard inner
// corners row-major; square_grid 4 per hole (holes row-major), clockwise from the top-left
// seen from the front; aprilgrid 4 per tag (tags in id order), in libapriltag's order
// bottom-left, bottom-right, top-right, top-left. The full convention, with a figure of each
// target, is in fixtures/calibration_targets.h. Asserts target.Check() is empty.
std::vector<Eigen::Vector3d> TargetCorners(const Target& target);

// Strict like ReadRig. pitch_m is required for square_grid and aprilgrid and an error for
// chessboard; family is required for aprilgrid only.
Target ReadTarget(const std::filesystem::path& path);
Target ParseTarget(const std::string& yaml_text, const std::filesystem::path& path_for_errors);
void WriteTarget(const std::filesystem::path& path, const Target& target);

}  // namespace hw::core
