#pragma once

// Test support for align_test and compare_test (and the analyze and report CLI tests' plate):
// an asymmetric scene (a room corner — a
// 4 m × 3 m floor and two 2.5 m walls — with a box and a cylinder on the floor),
// tessellated at a chosen edge length, turned into a ThermalMesh after an optional rigid
// transform, vertex noise, temperature field and face cut.

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "analyze/thermal_mesh.h"
#include "core/ply.h"

namespace hw::analyze::test {

struct SceneMesh {
  std::vector<Eigen::Vector3d> points;  // scene frame, metres
  std::vector<Eigen::Vector3i> faces;   // counter-clockwise seen from outside
};

// A grid over origin + s·u + t·v, s, t ∈ [0, 1]; faces face u × v.
inline void AddGrid(SceneMesh* mesh, const Eigen::Vector3d& origin, const Eigen::Vector3d& u,
                    const Eigen::Vector3d& v, double edge_m) {
  const int nu = std::max(1, static_cast<int>(std::ceil(u.norm() / edge_m)));
  const int nv = std::max(1, static_cast<int>(std::ceil(v.norm() / edge_m)));
  const int base = static_cast<int>(mesh->points.size());
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) mesh->points.push_back(origin + u * i / nu + v * j / nv);
  }
  auto at = [&](int i, int j) { return base + j * (nu + 1) + i; };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      mesh->faces.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      mesh->faces.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
}

inline SceneMesh RoomScene(double edge_m) {
  SceneMesh m;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(), z = Eigen::Vector3d::UnitZ();
  AddGrid(&m, {0, 0, 0}, 4 * x, 3 * y, edge_m);      // floor, +z
  AddGrid(&m, {0, 0, 0}, 2.5 * z, 4 * x, edge_m);    // wall y = 0, +y
  AddGrid(&m, {0, 0, 0}, 3 * y, 2.5 * z, edge_m);    // wall x = 0, +x
  // Box 0.6 × 0.4 × 0.5 at (2.2..2.8, 1.0..1.4), outward faces, no bottom.
  const Eigen::Vector3d b(2.2, 1.0, 0), sx = 0.6 * x, sy = 0.4 * y, sz = 0.5 * z;
  AddGrid(&m, b + sz, sx, sy, edge_m);        // top +z
  AddGrid(&m, b, sx, sz, edge_m);             // −y
  AddGrid(&m, b + sy, sz, sx, edge_m);        // +y
  AddGrid(&m, b, sz, sy, edge_m);             // −x
  AddGrid(&m, b + sx, sy, sz, edge_m);        // +x
  // Cylinder r 0.2, h 0.8 at (1.2, 2.0): side (vertices shared around) and top fan.
  const double r = 0.2, h = 0.8;
  const Eigen::Vector3d c(1.2, 2.0, 0);
  const int na = std::max(8, static_cast<int>(std::ceil(2 * M_PI * r / edge_m)));
  const int nz = std::max(1, static_cast<int>(std::ceil(h / edge_m)));
  const int base = static_cast<int>(m.points.size());
  for (int j = 0; j <= nz; ++j) {
    for (int i = 0; i < na; ++i) {
      const double a = 2 * M_PI * i / na;
      m.points.push_back(c + Eigen::Vector3d(r * std::cos(a), r * std::sin(a), h * j / nz));
    }
  }
  auto at = [&](int i, int j) { return base + j * na + (i % na); };
  for (int j = 0; j < nz; ++j) {
    for (int i = 0; i < na; ++i) {
      m.faces.emplace_back(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      m.faces.emplace_back(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
  const int centre = static_cast<int>(m.points.size());
  m.points.push_back(c + h * z);
  for (int i = 0; i < na; ++i) m.faces.emplace_back(centre, at(i, nz), at(i + 1, nz));
  return m;
}

struct Variant {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  // applied to the scene
  double noise_m = 0;                                            // Gaussian, per axis
  unsigned seed = 7;
  // Temperature at a scene-frame point (before the transform), °C.
  std::function<double(const Eigen::Vector3d&)> temperature_c = [](const Eigen::Vector3d& p) {
    return 20 + 0.4 * p.z() + 0.2 * p.x();
  };
  // Faces kept (by their scene-frame centroid); all when empty.
  std::function<bool(const Eigen::Vector3d&)> keep_face;
};

inline ThermalMesh MakeVariant(const SceneMesh& scene, const Variant& variant) {
  std::mt19937_64 rng(variant.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  std::vector<double> temperature;
  for (const Eigen::Vector3d& p : scene.points) {
    Eigen::Vector3d q = variant.transform * p;
    if (variant.noise_m > 0) q += variant.noise_m * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    points.push_back(q);
    temperature.push_back(variant.temperature_c(p));
  }
  core::PlyMesh ply;
  ply.SetPositions(points, core::PlyType::kFloat64);
  ply.AddProperty("temperature_c", core::PlyType::kFloat64, temperature);
  for (const Eigen::Vector3i& f : scene.faces) {
    const Eigen::Vector3d centroid = (scene.points[f[0]] + scene.points[f[1]] + scene.points[f[2]]) / 3;
    if (!variant.keep_face || variant.keep_face(centroid)) ply.faces.push_back(f);
  }
  return MakeThermalMesh(ply, "scene.ply");
}

// Rotation by angle_deg about a (normalised) axis, then translation.
inline Eigen::Isometry3d Pose(double angle_deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& translation_m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle_deg * M_PI / 180, axis.normalized()).toRotationMatrix();
  T.translation() = translation_m;
  return T;
}

// The left correction x = (ω, δ) with truth = [exp(ω) | δ] · estimate (the convention of
// Alignment::covariance).
inline Eigen::Matrix<double, 6, 1> PoseError(const Eigen::Isometry3d& truth, const Eigen::Isometry3d& estimate) {
  const Eigen::Isometry3d E = truth * estimate.inverse();
  const Eigen::AngleAxisd aa(E.linear());
  Eigen::Matrix<double, 6, 1> x;
  x << aa.angle() * aa.axis(), E.translation();
  return x;
}

// A 1 m plate (z = 0, seen from +z) at 20 °C on a 1 cm grid with a 20 cm hot disc at 50 °C
// (a smooth 4 mm logistic edge), red on its left half: a spot whose area is π (0.1 m)² at
// the half-ΔT boundary.
inline core::PlyMesh HotDiscPlate(bool with_temperature = true) {
  const int n = 100;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> t;
  std::vector<core::Rgb8> colours;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = -0.5 + 0.01 * i, y = -0.5 + 0.01 * j;
      points.emplace_back(x, y, 0);
      t.push_back(20 + 30 / (1 + std::exp((std::hypot(x, y) - 0.1) / 0.004)));
      colours.emplace_back(x < 0 ? 200 : 90, 90, 90);
    }
  }
  core::PlyMesh ply;
  ply.SetPositions(points);
  if (with_temperature) ply.AddProperty("temperature_c", core::PlyType::kFloat32, t);
  ply.SetColors(colours);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i;
      ply.faces.emplace_back(a, a + 1, a + n + 2);
      ply.faces.emplace_back(a, a + n + 2, a + n + 1);
    }
  }
  return ply;
}

}  // namespace hw::analyze::test
