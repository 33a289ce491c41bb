#include "analyze/spot_reflection.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>

#include "core/strings.h"

namespace hw::analyze {
namespace {

constexpr double kPi = 3.14159265358979323846;

}  // namespace

std::string ReflectionOptions::Check() const {
  if (!(operator_radius_m > 0 && operator_radius_m <= 5)) {
    return core::StringPrintf("reflections.operator_radius_m is %g: must be in (0, 5] m", operator_radius_m);
  }
  if (!(operator_max_c > -50 && operator_max_c <= 100)) {
    return core::StringPrintf("reflections.operator_max_c is %g: must be in (-50, 100] °C", operator_max_c);
  }
  if (!(min_fraction > 0 && min_fraction <= 1)) {
    return core::StringPrintf("reflections.min_fraction is %g: must be in (0, 1]", min_fraction);
  }
  if (max_faces < 1) return core::StringPrintf("reflections.max_faces is %d: must be >= 1", max_faces);
  return "";
}

void CheckReflections(const ThermalMesh& mesh, const MeshRenderer& renderer, const ReflectionOptions& options,
                      std::vector<Spot>* spots) {
  assert(options.Check().empty());
  if (!options.check || mesh.view_m.empty() || !mesh.HasTemperature()) return;
  for (Spot& spot : *spots) {
    const size_t stride = spot.faces.size() / static_cast<size_t>(options.max_faces) + 1;
    double checked = 0, incidence = 0, operator_area = 0, surface_area = 0, unseen_area = 0, source_c = 0;
    Eigen::Vector3d operator_at = Eigen::Vector3d::Zero(), surface_at = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < spot.faces.size(); i += stride) {
      const Eigen::Vector3i& face = mesh.faces[static_cast<size_t>(spot.faces[i])];
      const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(face[0])];
      const Eigen::Vector3d& b = mesh.points_in_world[static_cast<size_t>(face[1])];
      const Eigen::Vector3d& c = mesh.points_in_world[static_cast<size_t>(face[2])];
      Eigen::Vector3d view = Eigen::Vector3d::Zero();
      int with_view = 0;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d& v = mesh.view_m[static_cast<size_t>(face[k])];
        if (!v.allFinite()) continue;
        view += v;
        ++with_view;
      }
      Eigen::Vector3d normal = (b - a).cross(c - a);
      const double area = 0.5 * normal.norm();
      if (with_view == 0 || !(area > 0)) continue;
      view /= with_view;
      const double distance = view.norm();
      if (!(distance > 0)) continue;
      normal.normalize();
      // Oriented towards where it was seen from (marching cubes' winding is not trusted).
      if (normal.dot(view) < 0) normal = -normal;
      const Eigen::Vector3d to_camera = view / distance;
      const double cos_incidence = std::clamp(normal.dot(to_camera), 0.0, 1.0);
      checked += area;
      incidence += area * std::acos(cos_incidence) * 180 / kPi;
      // The mirror direction of the ray that arrived from the camera.
      const Eigen::Vector3d mirror = 2 * cos_incidence * normal - to_camera;
      const Eigen::Vector3d point = (a + b + c) / 3;
      // The camera's nearest approach along the mirror ray (behind the surface: never).
      const double along = view.dot(mirror);
      const double miss_m = along > 0 ? (view - along * mirror).norm() : std::numeric_limits<double>::infinity();
      // 1 cm out: the surface around the face itself is not a source.
      const MeshRenderer::Hit hit = renderer.Intersect(point, mirror, 0.01, 1e3);
      const bool operator_in_reach = miss_m <= options.operator_radius_m &&
                                     (hit.face < 0 || hit.t_m > along - options.operator_radius_m);
      if (operator_in_reach && spot.hot && spot.peak_c <= options.operator_max_c) {
        operator_area += area;
        operator_at += area * (point + view);
        continue;
      }
      if (hit.face < 0) continue;
      const double hit_c = InterpolateOnFace(mesh, mesh.temperature_c, hit.face, static_cast<double>(hit.bary_u),
                                             static_cast<double>(hit.bary_v));
      if (std::isnan(hit_c)) unseen_area += area;
      if (!(spot.hot ? hit_c >= spot.peak_c : hit_c <= spot.peak_c)) continue;
      surface_area += area;
      surface_at += area * (point + hit.t_m * mirror);
      source_c += area * hit_c;
    }
    if (!(checked > 0)) continue;
    spot.incidence_deg = incidence / checked;
    spot.reflection_fraction = (operator_area + surface_area) / checked;
    spot.reflection_unseen_fraction = unseen_area / checked;
    spot.possible_reflection = spot.reflection_fraction >= options.min_fraction;
    if (operator_area + surface_area > 0) {
      if (operator_area >= surface_area) {
        spot.reflection_source = "operator";
        spot.reflection_source_in_world = operator_at / operator_area;
      } else {
        spot.reflection_source = "surface";
        spot.reflection_source_in_world = surface_at / surface_area;
        spot.reflection_source_c = source_c / surface_area;
      }
    }
    if (!spot.possible_reflection) continue;
    const std::string what =
        spot.reflection_source == "operator"
            ? core::StringPrintf("the thermographer's own reflection (seen %.0f° from head-on)", spot.incidence_deg)
            : core::StringPrintf("the reflection of a %.1f °C surface %.2f m away", spot.reflection_source_c,
                                 (spot.reflection_source_in_world - spot.peak_in_world).norm());
    spot.action = "Verify first: possibly " + what + "; re-image from another angle. If it stays: " + spot.action;
  }
}

std::string ReflectionWarning(const Spot& s) {
  assert(s.possible_reflection);
  const std::string source =
      s.reflection_source == "operator"
          ? core::StringPrintf("the thermographer's body (the surface was seen %.0f° from head-on and the spot peaks at "
                               "%.1f °C, no warmer than a person)",
                               s.incidence_deg, s.peak_c)
          : core::StringPrintf("a %.1f °C surface at (%.2f, %.2f, %.2f) m", s.reflection_source_c,
                               s.reflection_source_in_world.x(), s.reflection_source_in_world.y(),
                               s.reflection_source_in_world.z());
  return core::StringPrintf(
      "%s may be a reflection: over %.0f %% of it the mirror direction of the views meets %s; re-image it from another "
      "angle before acting",
      s.id.c_str(), 100 * s.reflection_fraction, source.c_str());
}

}  // namespace hw::analyze
