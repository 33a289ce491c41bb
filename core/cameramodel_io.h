#pragma once

#include <filesystem>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/camera.h"
#include "core/transform.h"

namespace hw::core {

// Exchange of one camera with mrcal (https://mrcal.secretsauce.net) through its
// `.cameramodel` text files, parsed by libmrcal itself.
//
// Lens models: pinhole <-> LENSMODEL_PINHOLE; opencv with 4, 5 or 8 coefficients <->
// LENSMODEL_OPENCV4/5/8; splined <-> LENSMODEL_SPLINED_STEREOGRAPHIC_order=O_Nx=X_Ny=Y_
// fov_x_deg=F (SplinedConfig; beyond scan-format.md's pinhole and opencv). mrcal's
// intrinsics are ours in the same order (fx fy cx cy k... or spline controls),
// and mrcal, like OpenCV and heatwave, puts pixel (0, 0) at the centre of the top-left
// pixel, so the numbers carry over unchanged. mrcal's extrinsics rt_cam_ref (Rodrigues
// vector r in radians, then t in metres) map a point in the reference frame into the
// camera frame: that is camera_from_ref.

struct MrcalCameraModel {
  CameraModel camera;
  Rigid3d camera_from_ref;  // mrcal's extrinsics; identity when the file has zero extrinsics
};

// mrcal's name of the lens model of `camera`, e.g. "LENSMODEL_OPENCV5" or
// "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=14_fov_x_deg=60" (from
// mrcal_lensmodel_name). Asserts camera.Check() is empty.
std::string MrcalLensModelName(const CameraModel& camera);

// The .cameramodel text of `camera` and its extrinsics: a Python-dict literal with keys
// 'lensmodel', 'intrinsics', 'extrinsics' (rt_cam_ref), 'imagersize', numbers in shortest
// round-trip form so that ParseMrcalCameraModel gives back the same doubles bit for bit.
// (libmrcal 2.2's mrcal_write_cameramodel_file prints "%f", i.e. 6 decimals: 1e-7 distortion
// coefficients would be written as 0, hence this formatter. Every text it produces is
// checked by parsing it back with libmrcal's parser.) Asserts camera.Check() is empty and
// the translation within CheckExtrinsicTranslation's 10 m (rig.h), so that whatever is
// written reads back.
std::string FormatMrcalCameraModel(const CameraModel& camera,
                                   const Rigid3d& camera_from_ref = Rigid3d());

// Writes FormatMrcalCameraModel atomically to `path`. Throws OutputError.
void WriteMrcalCameraModel(const std::filesystem::path& path, const CameraModel& camera,
                           const Rigid3d& camera_from_ref = Rigid3d());

// Reads a .cameramodel file with libmrcal's parser (mrcal_read_cameramodel_string), after
// the text rules of every config file (PrepareConfigText: a UTF-8 BOM and CR or CRLF line
// ends are accepted, a NUL or control character is an error naming line and column; files
// over 1 MiB are refused). Throws InputError, one line naming the path, when the file is
// unreadable, malformed (libmrcal then also prints its own diagnostic to stderr), uses a
// lens model other than the five above (the message names it; a splined configuration
// outside SplinedConfig's ranges is named as "splined.nx: ..."), holds a camera outside
// CameraModel::Check's ranges (camera.h: e.g. fx in [1, 1e6] px, imagersize at most 16384),
// or extrinsics with a rotation vector longer than 4 pi rad or a translation over 10 m.
MrcalCameraModel ReadMrcalCameraModel(const std::filesystem::path& path);
MrcalCameraModel ParseMrcalCameraModel(const std::string& text,
                                       const std::filesystem::path& path_for_errors);

// Rotation conversions for mrcal's Rodrigues vectors r = axis * angle (radians). Accurate
// near angle 0 (no division by a vanishing angle) and near pi. RodriguesFromQuaternion
// returns the angle in [0, pi]; q need not be normalised but must not be zero (asserted).
Eigen::Vector3d RodriguesFromQuaternion(const Eigen::Quaterniond& q);
Eigen::Quaterniond QuaternionFromRodrigues(const Eigen::Vector3d& r);

}  // namespace hw::core
