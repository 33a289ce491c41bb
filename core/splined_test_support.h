#pragma once

// A splined (mrcal LENSMODEL_SPLINED_STEREOGRAPHIC) camera for tests: core's camera, rig
// and .cameramodel tests and calibrate's solver tests.

#include <cassert>
#include <vector>

#include "core/camera.h"
#include "core/camera_mrcal.h"

namespace hw::core::test {

// A width x height camera with focal length f_px, principal point near the centre, whose
// spline bends the stereographic projection like a lens with radial distortion
// du = k_radial u |u|^2 (k_radial < 0: barrel) plus a small decentring term, sampled at the
// knots (a smooth surface the spline represents nearly exactly).
inline CameraModel SplinedTestCamera(int width = 640, int height = 480, double f_px = 500,
                                     SplinedConfig config = {3, 16, 13, 80},
                                     double k_radial = -0.08) {
  CameraModel camera;
  camera.width = width;
  camera.height = height;
  camera.type = CameraModelType::kSplined;
  camera.fx = f_px;
  camera.fy = f_px * 1.004;
  camera.cx = (width - 1) / 2.0 + 1.7;
  camera.cy = (height - 1) / 2.0 - 2.3;
  camera.splined = config;
  camera.distortion.assign(static_cast<size_t>(config.NumControls()), 0.0);
  const mrcal_lensmodel_t lensmodel = MrcalLensModel(camera);
  std::vector<double> ux(static_cast<size_t>(config.nx)), uy(static_cast<size_t>(config.ny));
  const bool ok = mrcal_knots_for_splined_models(ux.data(), uy.data(), &lensmodel);
  assert(ok);
  (void)ok;
  for (int iy = 0; iy < config.ny; ++iy) {
    for (int ix = 0; ix < config.nx; ++ix) {
      const double x = ux[static_cast<size_t>(ix)], y = uy[static_cast<size_t>(iy)];
      const double r2 = x * x + y * y;
      const size_t i = 2 * static_cast<size_t>(iy * config.nx + ix);  // mrcal: y-major, (x, y)
      camera.distortion[i] = k_radial * x * r2 + 2e-3 * x * y + 1e-3 * (r2 + 2 * x * x);
      camera.distortion[i + 1] = k_radial * y * r2 + 1e-3 * (r2 + 2 * y * y) + 2e-3 * x * y;
    }
  }
  assert(camera.Check().empty());
  return camera;
}

}  // namespace hw::core::test
