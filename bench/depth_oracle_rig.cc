// bench_depth_oracle_rig IN_RIG OUT_RIG [--nx N --ny N] [--no-affine]: writes IN_RIG with the
// fixtures' TRUE depth correction (fixtures::TrueDepthCorrection of the default depth sensor,
// the one every synthetic scan and session renders with) — the oracle that
// bench/depth_correction.sh compares `heatwave calibrate depth` against. Its affine part over
// the image's pixels is recorded as measured (plate_affine_per_m), as after `calibrate
// extrinsics`; --no-affine removes that part instead, which no wall recording can observe.
#include <array>
#include <cstdio>
#include <exception>
#include <string>

#include <Eigen/Dense>

#include "core/rig.h"
#include "fixtures/depth_sensor.h"

int main(int argc, char** argv) {
  using namespace hw;
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_depth_oracle_rig IN_RIG OUT_RIG [--nx N --ny N] [--no-affine]\n");
    return 2;
  }
  int nx = 17, ny = 13;
  bool no_affine = false;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--nx" && i + 1 < argc) nx = std::stoi(argv[++i]);
    else if (a == "--ny" && i + 1 < argc) ny = std::stoi(argv[++i]);
    else if (a == "--no-affine") no_affine = true;
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  try {
    core::Rig rig = core::ReadRig(argv[1]);
    core::DepthCorrection c = fixtures::TrueDepthCorrection(fixtures::DepthSensorOptions(), rig.depth, nx, ny);
    {
      // The field's affine part: least squares of 1, x, y over the pixels' rays (every 4th).
      Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      for (int v = 0; v < rig.depth.height; v += 4) {
        for (int u = 0; u < rig.depth.width; u += 4) {
          const auto ray = rig.depth.Unproject({double(u), double(v)});
          if (!ray) continue;
          const Eigen::Vector3d g(1, ray->x(), ray->y());
          a += g * g.transpose();
          b += g * c.OffsetAt(ray->x(), ray->y());
        }
      }
      const Eigen::Vector3d p = a.ldlt().solve(b);
      if (no_affine) {
        std::printf("affine part removed: %.6f %+.6f x %+.6f y (1/m)\n", p(0), p(1), p(2));
        c.AddAffine(-p(0), -p(1), -p(2));
      } else {
        // Known exactly, so recorded as measured, as `calibrate extrinsics` records the part
        // its plate measured: the oracle stands for a fully calibrated sensor, and
        // `reconstruct` treats its depth as such (ICP's noise gate on by default).
        c.plate_affine_per_m = std::array<double, 3>{p(0), p(1), p(2)};
        std::printf("affine part (measured): %.6f %+.6f x %+.6f y (1/m)\n", p(0), p(1), p(2));
      }
    }
    rig.depth_correction = c;
    core::WriteRig(argv[2], rig);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
