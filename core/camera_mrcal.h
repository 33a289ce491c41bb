#pragma once

// CameraModel <-> mrcal's lens models (internal to core's camera and .cameramodel code,
// and to calibrate/, which solves with mrcal). Includes mrcal's C API (core/mrcal_c.h).

#include <Eigen/Core>

#include "core/camera.h"
#include "core/mrcal_c.h"

namespace hw::core {

// mrcal's lens model of `camera` with its configuration: LENSMODEL_PINHOLE,
// LENSMODEL_OPENCV4/5/8 by the coefficient count, LENSMODEL_SPLINED_STEREOGRAPHIC with
// camera.splined. MRCAL_LENSMODEL_INVALID for a camera Check() rejects (e.g. opencv with 6
// coefficients); the intrinsics vector is camera.Params() in every case.
mrcal_lensmodel_t MrcalLensModel(const CameraModel& camera);

// CameraModel::Distort of a kSplined camera (see there), by mrcal_project with the
// intrinsics core fx = fy = 1, cx = cy = 0, which makes mrcal's pixel the distorted
// normalised point. Jacobians as Distort's. NaN when mrcal refuses the configuration
// (a camera Check() rejects).
Eigen::Vector2d SplinedDistort(const CameraModel& camera, const Eigen::Vector2d& xy_undistorted,
                               Eigen::Matrix2d* J_xy,
                               Eigen::Matrix<double, 2, Eigen::Dynamic>* J_dist);

}  // namespace hw::core
