#include "analyze/view_select.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <Eigen/Geometry>

#include "core/option_check.h"

namespace hw::analyze {

using core::InRange;
using core::OptionFail;

std::string ViewSelectOptions::Check() const {
  if (!InRange(width, 16, 16384)) return OptionFail("width", width, "in [16, 16384]");
  if (!InRange(height, 16, 16384)) return OptionFail("height", height, "in [16, 16384]");
  if (!InRange(fov_y_deg, 5, 120)) return OptionFail("fov_y_deg", fov_y_deg, "in [5, 120]");
  if (!InRange(margin_fraction, 0, 0.4)) return OptionFail("margin_fraction", margin_fraction, "in [0, 0.4]");
  if (!InRange(overview_count, 1, 36)) return OptionFail("overview_count", overview_count, "in [1, 36]");
  if (!InRange(elevation_deg, 0, 89)) return OptionFail("elevation_deg", elevation_deg, "in [0, 89]");
  if (!InRange(first_azimuth_deg, -360, 360)) {
    return OptionFail("first_azimuth_deg", first_azimuth_deg, "in [-360, 360]");
  }
  if (!(up_in_world.allFinite() && up_in_world.norm() > 1e-9)) {
    return OptionFail("up_in_world", up_in_world.norm(), "a finite non-zero vector (its norm shown)");
  }
  if (!(close_up_fill_fraction > 0 && close_up_fill_fraction <= 1)) {
    return OptionFail("close_up_fill_fraction", close_up_fill_fraction, "in (0, 1]");
  }
  if (!(close_up_min_distance_m > 0 && close_up_min_distance_m <= 100)) {
    return OptionFail("close_up_min_distance_m", close_up_min_distance_m, "in (0, 100]");
  }
  return "";
}

namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Two unit vectors completing `axis` (unit) to a right-handed orthonormal basis (first,
// second, axis): first is the world axis least aligned with `axis`, made perpendicular, so
// for z up first = x and second = y.
void CompleteBasis(const Eigen::Vector3d& axis, Eigen::Vector3d* first, Eigen::Vector3d* second) {
  Eigen::Index least = 0;
  axis.cwiseAbs().minCoeff(&least);
  const Eigen::Vector3d e = Eigen::Vector3d::Unit(least);
  *first = (e - e.dot(axis) * axis).normalized();
  *second = axis.cross(*first);
}

Camera BaseCamera(const ViewSelectOptions& options) {
  Camera camera;
  camera.width = options.width;
  camera.height = options.height;
  camera.fov_y_deg = options.fov_y_deg;
  return camera;
}

}  // namespace

std::vector<NamedView> OverviewViews(const ThermalMesh& mesh, const ViewSelectOptions& options) {
  assert(options.Check().empty());
  assert(mesh.NumFaces() > 0);
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3i& face : mesh.faces) {
    for (int k = 0; k < 3; ++k) box.extend(mesh.points_in_world[static_cast<size_t>(face[k])]);
  }
  const Eigen::Vector3d centre = box.center();
  const Eigen::Vector3d up = options.up_in_world.normalized();
  Eigen::Vector3d horizontal_1, horizontal_2;
  CompleteBasis(up, &horizontal_1, &horizontal_2);

  // Usable half extents of the image, pixels.
  const double half_width_px = options.width * (0.5 - options.margin_fraction);
  const double half_height_px = options.height * (0.5 - options.margin_fraction);
  std::vector<NamedView> views;
  const double elevation = options.elevation_deg * kDegToRad;
  // A partial scan (one side of a machine, one wall) faces where it was scanned from: its
  // area-weighted normal points there. The first overview then looks from that side, so
  // with back faces culled it shows the surface rather than nothing. A closed room's normals
  // cancel: the configured azimuth stays.
  double first_azimuth = options.first_azimuth_deg * kDegToRad;
  if (options.face_scanned_side) {
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
    double area = 0;
    for (int f = 0; f < mesh.NumFaces(); ++f) {
      const Eigen::Vector3i& face = mesh.faces[static_cast<size_t>(f)];
      const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(face[0])];
      const Eigen::Vector3d n = (mesh.points_in_world[static_cast<size_t>(face[1])] - a)
                                    .cross(mesh.points_in_world[static_cast<size_t>(face[2])] - a);
      weighted += n;
      area += n.norm();
    }
    const Eigen::Vector3d horizontal = weighted - weighted.dot(up) * up;
    if (area > 0 && horizontal.norm() > 0.2 * area) {
      first_azimuth = std::atan2(horizontal.dot(horizontal_2), horizontal.dot(horizontal_1));
    }
  }
  for (int k = 0; k < options.overview_count; ++k) {
    const double azimuth = first_azimuth + 2 * M_PI * k / options.overview_count;
    const Eigen::Vector3d to_eye = std::cos(elevation) * (std::cos(azimuth) * horizontal_1 +
                                                          std::sin(azimuth) * horizontal_2) +
                                   std::sin(elevation) * up;
    // The orientation does not depend on the distance: find it at distance 1, then the
    // nearest distance at which every corner (X, Y, Z relative to the centre, camera axes)
    // projects inside: f·|X| / (Z + D) <= half width, likewise Y.
    Camera camera = LookAt(centre + to_eye, centre, up, BaseCamera(options));
    const Eigen::Matrix3d camera_from_world = camera.world_from_camera.linear().transpose();
    const double focal_px = camera.FocalPx();
    double distance_m = 1e-3;  // a point-like model still gets a camera in front of it
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d p =
          camera_from_world * (box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)) - centre);
      distance_m = std::max(distance_m, focal_px * std::abs(p.x()) / half_width_px - p.z());
      distance_m = std::max(distance_m, focal_px * std::abs(p.y()) / half_height_px - p.z());
    }
    camera.world_from_camera.translation() = centre + distance_m * to_eye;
    views.push_back({"overview-" + std::to_string(k + 1), camera});
  }

  // The plan: orthographic, straight down, horizontal_2 up in the image (y for z up: a
  // plan with +y at the top and +x to the right).
  const double extent_up_m = (box.sizes().array() * up.cwiseAbs().array()).sum();
  Camera top = BaseCamera(options);
  top.orthographic = true;
  top = LookAt(centre + (0.5 * extent_up_m + 1.0) * up, centre, horizontal_2, top);
  const Eigen::Matrix3d camera_from_world = top.world_from_camera.linear().transpose();
  double height_m = 1e-3;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p =
        camera_from_world * (box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)) - centre);
    height_m = std::max(height_m, options.height * std::abs(p.x()) / half_width_px);
    height_m = std::max(height_m, options.height * std::abs(p.y()) / half_height_px);
  }
  top.ortho_height_m = height_m;
  views.push_back({"top", top});
  return views;
}

NamedView CloseUpView(const MeshRenderer& renderer, const Eigen::Vector3d& centroid_in_world,
                      const Eigen::Vector3d& normal_in_world, double radius_m,
                      const std::vector<Eigen::Vector3d>& region_points_in_world,
                      const ViewSelectOptions& options, double* visible_fraction) {
  assert(options.Check().empty());
  assert(normal_in_world.norm() > 0 && radius_m >= 0);
  const Eigen::Vector3d normal = normal_in_world.normalized();
  Eigen::Vector3d side_1, side_2;
  CompleteBasis(normal, &side_1, &side_2);

  const std::vector<Eigen::Vector3d> centroid_only{centroid_in_world};
  const std::vector<Eigen::Vector3d>& points = region_points_in_world.empty() ? centroid_only
                                                                              : region_points_in_world;
  double region_radius_m = radius_m;
  for (const Eigen::Vector3d& p : points) region_radius_m = std::max(region_radius_m, (p - centroid_in_world).norm());
  // The region's diameter spans fill × the image height: 2r = fill · 2 D tan(fov/2).
  const double fill_distance_m =
      region_radius_m / (options.close_up_fill_fraction * std::tan(0.5 * options.fov_y_deg * kDegToRad));
  // Points lie on the surface: the last millimetre of each sight line is that surface.
  constexpr double kSurfaceEpsilonM = 1e-3;

  const Camera base = BaseCamera(options);
  NamedView best{"close-up", base};
  double best_score = -1;
  constexpr double kConeDeg[] = {0, 25, 50};
  constexpr double kDistanceFactors[] = {1.0, 0.6};
  for (const double cone_deg : kConeDeg) {
    const int azimuths = cone_deg == 0 ? 1 : 8;
    for (int a = 0; a < azimuths; ++a) {
      const double azimuth = 2 * M_PI * a / azimuths;
      const Eigen::Vector3d direction =
          std::cos(cone_deg * kDegToRad) * normal +
          std::sin(cone_deg * kDegToRad) * (std::cos(azimuth) * side_1 + std::sin(azimuth) * side_2);
      double previous_distance_m = -1;
      for (const double factor : kDistanceFactors) {
        const double distance_m = std::max(factor * fill_distance_m, options.close_up_min_distance_m);
        if (distance_m == previous_distance_m) continue;  // both at the floor
        previous_distance_m = distance_m;
        const Eigen::Vector3d eye = centroid_in_world + distance_m * direction;
        const Camera camera = LookAt(eye, centroid_in_world, options.up_in_world, base);
        int visible = 0;
        for (const Eigen::Vector3d& p : points) {
          double depth_m = 0;
          const Eigen::Vector2d pixel = camera.Project(p, &depth_m);
          if (!(depth_m > 0 && pixel.x() >= 0 && pixel.x() < camera.width && pixel.y() >= 0 &&
                pixel.y() < camera.height)) {
            continue;
          }
          if (renderer.Unoccluded(eye, p, kSurfaceEpsilonM)) ++visible;
        }
        const double score = static_cast<double>(visible) / static_cast<double>(points.size());
        if (score > best_score) {
          best_score = score;
          best.camera = camera;
        }
      }
    }
  }
  if (visible_fraction != nullptr) *visible_fraction = best_score;
  return best;
}

}  // namespace hw::analyze
