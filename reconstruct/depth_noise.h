#pragma once

// The axial noise of a structured-light depth sensor as a function of depth, shared by the
// TSDF's band (TsdfOptions) and ICP's gate (IcpOptions).

#include <cmath>
#include <string>

#include "reconstruct/option_check.h"

namespace hw::reconstruct {

// σ_z(z) = base_m + quadratic_per_m · (z − reference_m)² (m; z in m along the optical
// axis): Nguyen, Izadi & Lovell 2012, fitted on a Kinect. The defaults are theirs: 1.2 mm at
// 0.4 m, 6 mm at 2 m, 14 mm at 3 m, 26 mm at 4 m.
struct DepthNoiseModel {
  double base_m = 0.0012;          // σ_z at reference_m, m, >= 0
  double quadratic_per_m = 0.0019; // growth with (z − reference_m)², 1/m, >= 0
  double reference_m = 0.4;        // depth of least noise, m, >= 0

  double SigmaAt(double depth_m) const {
    const double dz = depth_m - reference_m;
    return base_m + quadratic_per_m * dz * dz;
  }

  // "" when valid, else a message naming the field ("base_m: ..."), value and constraint;
  // the owning options prefix their field name.
  std::string Check() const {
    using internal::Fail;
    if (!(base_m >= 0) || !std::isfinite(base_m)) return Fail("base_m", base_m, "finite and >= 0 m");
    if (!(quadratic_per_m >= 0) || !std::isfinite(quadratic_per_m)) {
      return Fail("quadratic_per_m", quadratic_per_m, "finite and >= 0 1/m");
    }
    if (!(reference_m >= 0) || !std::isfinite(reference_m)) return Fail("reference_m", reference_m, "finite and >= 0 m");
    return "";
  }
};

}  // namespace hw::reconstruct
