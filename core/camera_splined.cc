// mrcal's lens models for CameraModel (core/camera_mrcal.h): the splined stereographic
// projection is mrcal's own, never re-implemented here, so a camera written to rig.yaml
// projects exactly as the .cameramodel mrcal reads.

#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include "core/camera_mrcal.h"

namespace hw::core {

mrcal_lensmodel_t MrcalLensModel(const CameraModel& camera) {
  mrcal_lensmodel_t lensmodel{};
  lensmodel.type = MRCAL_LENSMODEL_INVALID;
  switch (camera.type) {
    case CameraModelType::kPinhole:
      if (camera.distortion.empty()) lensmodel.type = MRCAL_LENSMODEL_PINHOLE;
      break;
    case CameraModelType::kOpenCV:
      switch (camera.distortion.size()) {
        case 4:
          lensmodel.type = MRCAL_LENSMODEL_OPENCV4;
          break;
        case 5:
          lensmodel.type = MRCAL_LENSMODEL_OPENCV5;
          break;
        case 8:
          lensmodel.type = MRCAL_LENSMODEL_OPENCV8;
          break;
        default:
          break;
      }
      break;
    case CameraModelType::kSplined: {
      const SplinedConfig& c = camera.splined;
      if (!c.Check().empty() ||
          camera.distortion.size() != static_cast<size_t>(c.NumControls())) {
        break;
      }
      lensmodel.type = MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC;
      auto& config = lensmodel.LENSMODEL_SPLINED_STEREOGRAPHIC__config;
      config.order = static_cast<uint16_t>(c.order);
      config.Nx = static_cast<uint16_t>(c.nx);
      config.Ny = static_cast<uint16_t>(c.ny);
      config.fov_x_deg = static_cast<uint16_t>(c.fov_x_deg);
      break;
    }
  }
  return lensmodel;
}

Eigen::Vector2d SplinedDistort(const CameraModel& camera, const Eigen::Vector2d& xy_undistorted,
                               Eigen::Matrix2d* J_xy,
                               Eigen::Matrix<double, 2, Eigen::Dynamic>* J_dist) {
  assert(camera.type == CameraModelType::kSplined);
  const auto num_controls = static_cast<Eigen::Index>(camera.distortion.size());
  const int n = 4 + static_cast<int>(num_controls);
  // Per thread: Distort runs per pixel in the reconstruction's hot loops, and mrcal wants
  // one contiguous intrinsics vector (and reports dq/dintrinsics densely).
  thread_local std::vector<double> intrinsics, dq_dintrinsics;
  intrinsics.assign({1.0, 1.0, 0.0, 0.0});
  intrinsics.insert(intrinsics.end(), camera.distortion.begin(), camera.distortion.end());
  if (J_dist != nullptr) dq_dintrinsics.resize(static_cast<size_t>(2 * n));
  const mrcal_lensmodel_t lensmodel = MrcalLensModel(camera);
  const mrcal_point3_t p{{xy_undistorted.x(), xy_undistorted.y(), 1.0}};
  mrcal_point2_t q{};
  std::array<mrcal_point3_t, 2> dq_dp{};
  const bool ok = lensmodel.type == MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC &&
                  mrcal_project(&q, J_xy != nullptr ? dq_dp.data() : nullptr,
                                J_dist != nullptr ? dq_dintrinsics.data() : nullptr, &p, 1,
                                &lensmodel, intrinsics.data());
  if (!ok) {
    constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
    if (J_xy != nullptr) J_xy->setConstant(kNaN);
    if (J_dist != nullptr) J_dist->setConstant(2, num_controls, kNaN);
    return {kNaN, kNaN};
  }
  if (J_xy != nullptr) {
    // q depends on p only through p / z; at z = 1, dq/d(x/z) = dq/dx.
    for (int r = 0; r < 2; ++r) {
      for (int c = 0; c < 2; ++c) (*J_xy)(r, c) = dq_dp[static_cast<size_t>(r)].xyz[c];
    }
  }
  if (J_dist != nullptr) {
    J_dist->resize(2, num_controls);
    for (int r = 0; r < 2; ++r) {
      for (Eigen::Index c = 0; c < num_controls; ++c) {
        (*J_dist)(r, c) = dq_dintrinsics[static_cast<size_t>(r * n + 4 + c)];
      }
    }
  }
  return {q.x, q.y};
}

}  // namespace hw::core
